"""``axis_visualizer``: where the PTZ camera looks, drawn on the panorama (thesis §3.4.3, done with parallax).

ROS glue over :class:`axis_ptz_ros2.panorama_overlay.PanoramaOverlay`, which holds the inputs and decides the pose
(fresh ``ptz/transform``, else mount · kinematics), the intrinsics, the depth (fixed, or laser → ground → fixed
with ``auto_depth``) and the drawing: the PTZ's optical axis and the border of its image taken out to that depth
from the PTZ's real optical centre and projected into the panorama from the panorama's own pose, split at the
seam and closed correctly when it encloses a pole.

Inputs: the panorama (CompressedImage, ``panorama_topic``), ``ptz/state`` (PtzState: pan/tilt/zoom, hfov/vfov),
``ptz/transform`` (base_link → optical frame, preferred over the configured mount + kinematics when fresh),
``panorama/transform`` (latched, else ``config/robot.yaml``), optionally ``laser/points`` (+ ``laser/transform``).
Output: ``axis_visualizer/compressed`` (JPEG), encoded only while subscribed and at most ``rate`` times per
second, only when an input changed.
"""

from __future__ import annotations

import sys
from typing import Any

import cv2
import numpy as np
from geometry_msgs.msg import TransformStamped
from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import CompressedImage, PointCloud2

from axis_ptz_interfaces.msg import PtzState
from axis_ptz_ros2.config import load_camera_model, load_mount, load_robot
from axis_ptz_ros2.nodes.common import (
    LATCHED_QOS,
    STREAM_QOS,
    ParamSpec,
    field_spec,
    jpeg_image_msg,
    publisher,
    transform_from_msg,
)
from axis_ptz_ros2.nodes.live_params import LiveParams
from axis_ptz_ros2.nodes.runner import run_nodes
from axis_ptz_ros2.panorama_overlay import OverlaySettings, PanoramaOverlay
from axis_ptz_ros2.pointcloud import decode_cloud_msg

PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("panorama_topic", "panorama/image_raw/compressed", "panorama input (CompressedImage)",
              read_only=True),
    field_spec(OverlaySettings, "depth", "range along the PTZ rays at which the look point and footprint are drawn",
               "m", float_range=(0.1, 1000.0)),
    field_spec(OverlaySettings, "auto_depth", "take the range from the laser cloud, else the ground, else `depth`"),
    ParamSpec("rate", 5.0, "maximum re-encoding rate", "Hz", read_only=True, float_range=(0.1, 60.0)),
    ParamSpec("jpeg_quality", 85, "JPEG quality of the output", "", int_range=(1, 100)),
    field_spec(OverlaySettings, "marker_radius", "radius of the look-point circle; 0 = width/200 (min 4)", "px",
               int_range=(0, 200)),
    field_spec(OverlaySettings, "ptz_transform_timeout", "use ptz/transform only if newer than this (else "
               "mount+state)", "s", float_range=(0.0, 3600.0)),
    field_spec(OverlaySettings, "stream_width", "PTZ image width for the footprint when ptz/state has no vfov", "px",
               int_range=(16, 8192)),
    field_spec(OverlaySettings, "stream_height", "PTZ image height for the footprint when ptz/state has no vfov",
               "px", int_range=(16, 8192)),
    ParamSpec("camera_model_file", "", "camera model YAML ('' = config/axis214.yaml)", read_only=True),
    ParamSpec("mount_file", "", "mount YAML ('' = config/mount.yaml)", read_only=True),
    ParamSpec("robot_file", "", "robot frames YAML ('' = config/robot.yaml)", read_only=True),
)  # fmt: skip


class Visualizer(Node):
    """Draws the PTZ's look point and footprint on the panorama."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("axis_visualizer", **kwargs)
        self._live = LiveParams(self, PARAMS, on_change=self._on_params)
        p = self._live.params
        self._settings = self._live.config(OverlaySettings)
        self.overlay = PanoramaOverlay(
            load_camera_model(p["camera_model_file"] or None),
            load_mount(p["mount_file"] or None),
            load_robot(p["robot_file"] or None),
        )
        self._pano_msg: CompressedImage | None = None
        self._pano_img: np.ndarray[Any, np.dtype[np.uint8]] | None = None
        self._state: PtzState | None = None
        self._dirty = False
        self.frames_published = 0
        self._pub = publisher(self, CompressedImage, "axis_visualizer/compressed", STREAM_QOS)
        self.create_subscription(CompressedImage, p["panorama_topic"], self._on_pano, STREAM_QOS)
        self.create_subscription(PtzState, "ptz/state", self._on_state, STREAM_QOS)
        self.create_subscription(TransformStamped, "ptz/transform", self._on_ptz_tf, STREAM_QOS)
        self.create_subscription(TransformStamped, "panorama/transform", self._on_pano_tf, LATCHED_QOS)
        self.create_subscription(TransformStamped, "laser/transform", self._on_laser_tf, LATCHED_QOS)
        self.create_subscription(PointCloud2, "laser/points", self._on_cloud, LATCHED_QOS)
        self._timer = self.create_timer(1.0 / float(p["rate"]), self._tick)

    # ---- inputs -----------------------------------------------------------------------------------------
    def _on_pano(self, msg: CompressedImage) -> None:
        self._pano_msg, self._pano_img, self._dirty = msg, None, True

    def _on_state(self, msg: PtzState) -> None:
        self._state, self._dirty = msg, True
        self.overlay.ptz_state(msg)

    def _on_ptz_tf(self, msg: TransformStamped) -> None:
        self.overlay.ptz_transform(transform_from_msg(msg))
        self._dirty = True

    def _on_pano_tf(self, msg: TransformStamped) -> None:
        self.overlay.panorama_pose(transform_from_msg(msg))
        self._dirty = True

    def _on_laser_tf(self, msg: TransformStamped) -> None:
        self.overlay.laser_pose(transform_from_msg(msg))

    def _on_cloud(self, msg: PointCloud2) -> None:
        try:
            self.overlay.laser_cloud(decode_cloud_msg(msg)[:, :3])
        except ValueError as err:  # a cloud without x/y/z: keep the last usable one
            self.get_logger().warn(f"laser cloud unusable: {err}", throttle_duration_sec=10.0)

    # ---- output -----------------------------------------------------------------------------------------
    @property
    def live_params(self) -> LiveParams:
        """The node's parameters: ``.params`` is the snapshot in effect (what ``ros2 param get`` tells)."""
        return self._live

    def _on_params(self, names: frozenset[str]) -> None:
        """post-set: the overlay's settings rebuilt once per accepted set (not per tick)."""
        self._settings = self._live.config(OverlaySettings)

    def settings(self) -> OverlaySettings:
        """The overlay's parameters in effect now."""
        return self._settings

    def _tick(self) -> None:
        if not self._dirty or self._pano_msg is None or self._pub.get_subscription_count() == 0:
            return
        msg_in = self._pano_msg
        pano = self._pano_img
        if pano is None:
            decoded = cv2.imdecode(np.frombuffer(bytes(msg_in.data), np.uint8), cv2.IMREAD_COLOR)
            if decoded is None:
                self.get_logger().warn("cannot decode the panorama frame", throttle_duration_sec=10.0)
                self._dirty = False
                return
            pano = self._pano_img = np.asarray(decoded, dtype=np.uint8)
        self._dirty = False
        out = self.overlay.draw(pano, self.settings())
        q = int(self._live.params["jpeg_quality"])
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, q])
        if not ok:  # pragma: no cover
            return
        stamps = [msg_in.header.stamp]
        if self._state is not None:
            stamps.append(self._state.header.stamp)
        self._pub.publish(jpeg_image_msg(buf, msg_in.header.frame_id, max(stamps, key=Time.from_msg)))
        self.frames_published += 1


def main(args: list[str] | None = None) -> int:
    """Entry point of ``axis_visualizer``."""
    return run_nodes([Visualizer], args if args is not None else sys.argv)


if __name__ == "__main__":
    sys.exit(main())
