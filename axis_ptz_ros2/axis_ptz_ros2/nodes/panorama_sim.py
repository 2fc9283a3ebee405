"""``axis_panorama_sim``: the simulated omnidirectional (Ladybug-like) camera.

An equirectangular panorama (geometry.py: column 0 at azimuth +π, row 0 at elevation +π/2) of the simulated
scene (``axis_ptz_ros2.sim.scene``) seen from the panorama camera's own true pose (``SimWorld.T_base_pano``),
so the parallax between panorama and PTZ head is real. The scene is static: the image is ray-traced once at
start-up; each frame stamps a small clock overlay into a copy and is JPEG-encoded anew, so no two frames carry
the same bytes under different stamps. Frames are encoded only while someone subscribes.

Topics: ``panorama/image_raw/compressed`` (sensor_msgs/CompressedImage, JPEG), ``panorama/transform``
(geometry_msgs/TransformStamped ``parent_frame → frame_id``, latched).
"""

from __future__ import annotations

import sys
import time
from typing import Any

import cv2
import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import CompressedImage

from axis_ptz_ros2.nodes.common import STREAM_QOS, ParamSpec, jpeg_image_msg, publisher, stamp_from_ns
from axis_ptz_ros2.nodes.live_params import LiveParams
from axis_ptz_ros2.nodes.runner import run_nodes
from axis_ptz_ros2.nodes.tf_publish import publish_fixed_transform
from axis_ptz_ros2.sim.scene import shared_scene
from axis_ptz_ros2.sim.world import load_world

PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("width", 2048, "panorama width; height = width/2", "px", read_only=True, int_range=(64, 8192)),
    ParamSpec("rate", 2.0, "publishing rate", "Hz", read_only=True, float_range=(0.05, 30.0)),
    ParamSpec("jpeg_quality", 90, "JPEG quality of the published frames", "", int_range=(1, 100)),
    ParamSpec("frame_id", "panorama_link", "frame of the panorama (its optical centre)", read_only=True),
    ParamSpec("parent_frame", "base_link", "parent frame of panorama/transform", read_only=True),
    ParamSpec("world_file", "", "simulated world YAML ('' = config/sim_world.yaml)", read_only=True),
    ParamSpec("overlay", True, "stamp the publishing time into the bottom-left corner", ""),
)


class PanoramaSim(Node):
    """Publishes the simulated equirectangular panorama and its pose."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("axis_panorama_sim", **kwargs)
        self._live = LiveParams(self, PARAMS)  # overlay, jpeg_quality: read from the snapshot at each frame
        p = self._live.params
        self._frame_id: str = p["frame_id"]
        world = load_world(p["world_file"] or None)
        self.T_base_pano = world.T_base_pano
        width = int(p["width"])
        t0 = time.monotonic()
        self._base = shared_scene(world).render_equirect(world.T_base_pano, width, width // 2)
        self.get_logger().info(
            f"rendered {width}x{width // 2} panorama in {time.monotonic() - t0:.1f} s "
            f"from {world.T_base_pano.t.round(3).tolist()}"
        )
        self._count = 0
        self._pub = publisher(self, CompressedImage, "panorama/image_raw/compressed", STREAM_QOS)
        self._tf_pub = publish_fixed_transform(
            self, self.T_base_pano, p["parent_frame"], self._frame_id, "panorama/transform"
        )
        self._timer = self.create_timer(1.0 / float(p["rate"]), self._tick)

    def frame(self, stamp_ns: int) -> np.ndarray[Any, np.dtype[np.uint8]]:
        """The BGR frame for a publishing time (the static render plus the clock overlay)."""
        img = self._base.copy()
        if self._live.params["overlay"]:
            h = img.shape[0]
            text = time.strftime("%H:%M:%S", time.gmtime(stamp_ns / 1e9)) + f".{stamp_ns // 1_000_000 % 1000:03d}"
            text += f" #{self._count}"
            scale = max(0.35, h / 1400.0)
            (tw, th), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
            cv2.rectangle(img, (0, h - th - base - 6), (tw + 8, h), (0, 0, 0), -1)
            cv2.putText(img, text, (4, h - base - 3), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), 1, cv2.LINE_AA)
        return img

    def _tick(self) -> None:
        if self._pub.get_subscription_count() == 0:
            return
        now = self.get_clock().now()
        ns = now.nanoseconds
        img = self.frame(ns)
        q = int(self._live.params["jpeg_quality"])
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, q])
        if not ok:  # pragma: no cover - cv2 fails only on invalid images
            self.get_logger().error("JPEG encoding failed")
            return
        self._pub.publish(jpeg_image_msg(buf, self._frame_id, stamp_from_ns(ns)))
        self._count += 1


def main(args: list[str] | None = None) -> int:
    """Entry point of ``axis_panorama_sim``."""
    return run_nodes([PanoramaSim], args if args is not None else sys.argv)


if __name__ == "__main__":
    sys.exit(main())
