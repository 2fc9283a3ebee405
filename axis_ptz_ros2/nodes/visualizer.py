"""``axis_visualizer``: where the PTZ camera looks, drawn on the panorama (thesis §3.4.3, done with parallax).

The thesis drew a red circle at the panorama pixel of (pan, tilt) through a linear function, as if the PTZ sat
at the panorama's centre. Here the PTZ's optical axis and the border of its image are taken out to a depth
(fixed, or laser → ground → fixed with ``auto_depth``) from the PTZ's real optical centre and projected into
the panorama from the panorama's own pose (``pointing.footprint_on_panorama``), so what is drawn is what the
PTZ sees at that range. The footprint polygon is split at the panorama seam and closed correctly when it
encloses a pole.

Inputs: the panorama (CompressedImage, ``panorama_topic``), ``ptz/state`` (PtzState: pan/tilt/zoom, hfov/vfov),
``ptz/transform`` (base_link → optical frame, preferred over the configured mount + kinematics when fresh),
``panorama/transform`` (latched, else ``config/robot.yaml``), optionally ``laser/points`` (+ ``laser/transform``).
Output: ``axis_visualizer/compressed`` (JPEG), encoded only while subscribed and at most ``rate`` times per
second, only when an input changed.
"""

from __future__ import annotations

import math
import sys
import time
from typing import Any

import cv2
import numpy as np
from geometry_msgs.msg import TransformStamped
from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import CompressedImage, PointCloud2

from axis_ptz_interfaces.msg import PtzState
from axis_ptz_ros2.config import load_camera_model, load_mount, load_robot
from axis_ptz_ros2.geometry import FloatArray, Intrinsics, Transform
from axis_ptz_ros2.nodes.common import (
    LATCHED_QOS,
    STREAM_QOS,
    ParamSpec,
    declare_params,
    jpeg_image_msg,
    publisher,
    transform_from_msg,
)
from axis_ptz_ros2.nodes.runner import run_nodes
from axis_ptz_ros2.pointcloud import decode_cloud_msg
from axis_ptz_ros2.pointing import footprint_on_panorama, point_along_ray, project_to_panorama

PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("panorama_topic", "panorama/image_raw/compressed", "panorama input (CompressedImage)",
              read_only=True),
    ParamSpec("depth", 10.0, "range along the PTZ rays at which the look point and footprint are drawn", "m",
              float_range=(0.1, 1000.0)),
    ParamSpec("auto_depth", False, "take the range from the laser cloud, else the ground, else `depth`"),
    ParamSpec("rate", 5.0, "maximum re-encoding rate", "Hz", read_only=True, float_range=(0.1, 60.0)),
    ParamSpec("jpeg_quality", 85, "JPEG quality of the output", "", int_range=(1, 100)),
    ParamSpec("marker_radius", 0, "radius of the look-point circle; 0 = width/200 (min 4)", "px",
              int_range=(0, 200)),
    ParamSpec("ptz_transform_timeout", 2.0, "use ptz/transform only if newer than this (else mount+state)",
              "s", float_range=(0.0, 3600.0)),
    ParamSpec("stream_width", 704, "PTZ image width for the footprint when ptz/state has no vfov", "px",
              int_range=(16, 8192)),
    ParamSpec("stream_height", 576, "PTZ image height for the footprint when ptz/state has no vfov", "px",
              int_range=(16, 8192)),
    ParamSpec("camera_model_file", "", "camera model YAML ('' = config/axis214.yaml)", read_only=True),
    ParamSpec("mount_file", "", "mount YAML ('' = config/mount.yaml)", read_only=True),
    ParamSpec("robot_file", "", "robot frames YAML ('' = config/robot.yaml)", read_only=True),
)  # fmt: skip

MARKER_BGR = (0, 0, 255)  # red, as in the thesis
FOOTPRINT_BGR = (0, 255, 255)  # yellow


def footprint_polylines(pts: FloatArray, width: int) -> tuple[list[FloatArray], bool]:
    """Unwrap a closed panorama polygon across the seam; return copies shifted by −W, 0, +W (draw all three:
    each part of the polygon then appears once inside the image) and whether it is closed (False when it
    winds around a pole, where it must be drawn as an open band edge)."""
    x = pts[:, 0].copy()
    jumps = np.diff(x)
    x[1:] -= width * np.cumsum(np.round(jumps / width))
    closing = x[0] - x[-1]
    encircles = abs(closing) > width / 2
    un = np.stack([x, pts[:, 1]], -1)
    if encircles:  # continue the band to one full turn so the open polyline spans the whole width
        un = np.vstack([un, un[:1] + [np.sign(x[-1] - x[0]) * width, 0.0]])
    return [un + [s, 0.0] for s in (-width, 0.0, width)], not encircles


def intrinsics_from_state(state: PtzState, width: int, height: int) -> Intrinsics | None:
    """A pinhole with the state's hfov/vfov (None when the state has no field of view)."""
    if not (state.hfov > 0.0 and math.isfinite(state.hfov)):
        return None
    fx = (width / 2.0) / math.tan(state.hfov / 2.0)
    has_vfov = state.vfov > 0.0 and math.isfinite(state.vfov)
    fy = (height / 2.0) / math.tan(state.vfov / 2.0) if has_vfov else fx
    return Intrinsics(width, height, fx, fy, (width - 1) / 2.0, (height - 1) / 2.0)


class Visualizer(Node):
    """Draws the PTZ's look point and footprint on the panorama."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("axis_visualizer", **kwargs)
        p = declare_params(self, PARAMS)
        self._model = load_camera_model(p["camera_model_file"] or None)
        self._mount = load_mount(p["mount_file"] or None)
        self._robot = load_robot(p["robot_file"] or None)
        self._T_base_pano = self._robot.panorama.pose
        self._T_base_laser = self._robot.laser.pose
        self._pano_msg: CompressedImage | None = None
        self._pano_img: np.ndarray[Any, np.dtype[np.uint8]] | None = None
        self._state: PtzState | None = None
        self._ptz_tf: tuple[float, Transform] | None = None  # (monotonic receipt time, T_base_opt)
        self._cloud_laser: FloatArray | None = None
        self._dirty = False
        self.frames_published = 0
        self.last_look_pixel: tuple[float, float] | None = None  # for diagnostics and tests
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

    def _on_ptz_tf(self, msg: TransformStamped) -> None:
        self._ptz_tf, self._dirty = (time.monotonic(), transform_from_msg(msg)), True

    def _on_pano_tf(self, msg: TransformStamped) -> None:
        self._T_base_pano, self._dirty = transform_from_msg(msg), True

    def _on_laser_tf(self, msg: TransformStamped) -> None:
        self._T_base_laser = transform_from_msg(msg)

    def _on_cloud(self, msg: PointCloud2) -> None:
        try:
            self._cloud_laser = decode_cloud_msg(msg)[:, :3]
        except ValueError as err:  # a cloud without x/y/z: keep the last usable one
            self.get_logger().warn(f"laser cloud unusable: {err}", throttle_duration_sec=10.0)

    # ---- geometry ---------------------------------------------------------------------------------------
    def optical_pose(self) -> Transform | None:
        """``T_base_opt``: from ``ptz/transform`` when fresh, else mount · kinematics(state). ``ptz/state``
        is in joint coordinates (the PTZ node has already added the mount's encoder offsets to the head's
        reading), which is what the kinematics take: the offsets are not added again here."""
        timeout = float(self.get_parameter("ptz_transform_timeout").value)
        if self._ptz_tf is not None and time.monotonic() - self._ptz_tf[0] <= timeout:
            return self._ptz_tf[1]
        if self._state is None:
            return None
        return self._mount.transform @ self._model.head.optical_in_ptz_base(self._state.pan, self._state.tilt)

    def _intrinsics(self) -> Intrinsics:
        w = int(self.get_parameter("stream_width").value)
        h = int(self.get_parameter("stream_height").value)
        if self._state is not None:
            intr = intrinsics_from_state(self._state, w, h)
            if intr is not None:
                return intr
            return self._model.zoom.intrinsics(self._state.zoom, w, h)
        return self._model.zoom.intrinsics(self._model.zoom.min_zoom, w, h)

    def _depth(self, T_base_opt: Transform) -> float:
        d = float(self.get_parameter("depth").value)
        if not self.get_parameter("auto_depth").value:
            return d
        cloud = None if self._cloud_laser is None else self._T_base_laser.apply(self._cloud_laser)
        axis = T_base_opt.R[:, 2]
        r = point_along_ray(
            T_base_opt.t, axis, cloud, ground_z=self._robot.ground_z, default_range=d,
            cone_deg=self._robot.depth_cone_deg,
        )  # fmt: skip
        return r.range_m

    def draw(self, img: np.ndarray[Any, np.dtype[np.uint8]]) -> np.ndarray[Any, np.dtype[np.uint8]]:
        """The panorama with the look point and the footprint drawn (a copy)."""
        out = img.copy()
        T = self.optical_pose()
        if T is None:
            return out
        H, W = out.shape[:2]
        depth = self._depth(T)
        intr = self._intrinsics()
        fp = footprint_on_panorama(intr, T, self._T_base_pano, W, H, depth, samples_per_edge=16)
        lines, closed = footprint_polylines(fp, W)
        thick = max(1, W // 1000)
        for pl in lines:
            cv2.polylines(out, [np.round(pl).astype(np.int32)], closed, FOOTPRINT_BGR, thick, cv2.LINE_AA)
        centre = project_to_panorama(T.t + depth * T.R[:, 2], self._T_base_pano, W, H)[0]
        self.last_look_pixel = (float(centre[0]), float(centre[1]))
        r = int(self.get_parameter("marker_radius").value) or max(4, W // 200)
        for s in (-W, 0, W):
            c = (int(round(centre[0] + s)), int(round(centre[1])))
            cv2.circle(out, c, r, MARKER_BGR, -1, cv2.LINE_AA)
        if self._state is not None:
            st = self._state
            text = (
                f"PTZ pan {math.degrees(st.pan):+.1f} deg  tilt {math.degrees(st.tilt):+.1f} deg  "
                f"zoom {st.zoom:.0f}  hfov {math.degrees(intr.hfov):.1f} deg  depth {depth:.1f} m"
            )
            scale = max(0.4, H / 1500.0)
            org = (6, int(24 * scale / 0.6))
            cv2.putText(out, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 3, cv2.LINE_AA)
            cv2.putText(out, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), 1, cv2.LINE_AA)
        return out

    # ---- output -----------------------------------------------------------------------------------------
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
        out = self.draw(pano)
        q = int(self.get_parameter("jpeg_quality").value)
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
