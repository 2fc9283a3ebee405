"""``axis_laser_sim``: a simulated 3-D laser scanner of the simulated scene.

The scanner's maths is :mod:`axis_ptz_ros2.sim.laser`: rays on a regular elevation × azimuth grid from the
scanner's true pose (``SimWorld.T_base_laser``) traced through the scene (targets, ground, skyline); returns within
``[min_range, max_range]`` become points (x, y, z in ``laser_link``, metres; intensity = luminance of the hit
surface, 0…1), optionally with Gaussian range noise. This node publishes them as ``sensor_msgs/PointCloud2`` on
``laser/points`` (latched: a late subscriber gets the newest scan) plus the scanner pose as latched
``laser/transform``.

The scene is static, so the geometry is traced once; each scan gets its own stamp and, with ``noise_per_scan``
(the default), its own noise draw from the stream ``seed`` starts, like a real scanner looking at a static scene.
Which draw a consumer gets then depends on when it takes a scan: the n-th scan since the node started, n set by
timing (a calibration capture takes the first scan after the head stopped; with the same seed its clouds, so its
result, differed run to run). With ``noise_per_scan`` false the noise is a function of ``seed`` and
``range_noise`` alone, the same in every scan, so a run is reproducible; a test or bench that wants independent
noise per view sets another ``seed`` before each view (a change of ``seed``, ``range_noise`` or
``noise_per_scan`` publishes a scan at once, so every scan received after the set carries the new noise).
"""

from __future__ import annotations

import math
import sys
import threading
from dataclasses import replace
from typing import Any

import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import PointCloud2, PointField

from axis_ptz_ros2.nodes.common import LATCHED_QOS, ParamSpec, publisher
from axis_ptz_ros2.nodes.live_params import LiveParams
from axis_ptz_ros2.nodes.runner import run_nodes
from axis_ptz_ros2.nodes.tf_publish import publish_fixed_transform
from axis_ptz_ros2.sim.laser import StaticScan, scan_directions
from axis_ptz_ros2.sim.scene import shared_scene
from axis_ptz_ros2.sim.world import load_world
from axis_ptz_ros2.transforms import FloatArray

PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("rate", 1.0, "scan rate", "Hz", read_only=True, float_range=(0.05, 20.0)),
    ParamSpec("min_elevation", -math.radians(30.0), "lowest ray elevation", "rad", read_only=True,
              float_range=(-math.pi / 2, math.pi / 2)),
    ParamSpec("max_elevation", math.radians(30.0), "highest ray elevation", "rad", read_only=True,
              float_range=(-math.pi / 2, math.pi / 2)),
    ParamSpec("elevation_step", math.radians(0.5), "elevation spacing of the rays", "rad", read_only=True,
              float_range=(1e-3, 0.5)),
    ParamSpec("azimuth_step", math.radians(0.5), "azimuth spacing of the rays (full 360 deg)", "rad",
              read_only=True, float_range=(1e-3, 0.5)),
    ParamSpec("min_range", 0.3, "returns nearer than this are dropped", "m", read_only=True,
              float_range=(0.0, 10.0)),
    ParamSpec("max_range", 30.0, "returns farther than this are dropped", "m", read_only=True,
              float_range=(0.5, 500.0)),
    ParamSpec("range_noise", 0.0, "standard deviation of Gaussian range noise (0 = exact)", "m",
              float_range=(0.0, 1.0)),
    ParamSpec("seed", 0, "random seed of the range noise (a change restarts the noise from it)", "",
              int_range=(0, 2**31 - 1)),
    ParamSpec("noise_per_scan", True, "draw the range noise anew for every scan (false: the same noise in every "
              "scan, a function of seed and range_noise alone)"),
    ParamSpec("frame_id", "laser_link", "frame of the points", read_only=True),
    ParamSpec("parent_frame", "base_link", "parent frame of laser/transform", read_only=True),
    ParamSpec("world_file", "", "simulated world YAML ('' = config/sim_world.yaml)", read_only=True),
)  # fmt: skip

FIELDS = [
    PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
    for i, n in enumerate(("x", "y", "z", "intensity"))
]


def cloud_msg(points: FloatArray, intensity: FloatArray, frame_id: str, stamp: Any) -> PointCloud2:
    """An unordered PointCloud2 (height 1) with float32 x, y, z, intensity."""
    arr = np.empty((points.shape[0], 4), dtype="<f4")
    arr[:, :3] = points
    arr[:, 3] = intensity
    m = PointCloud2()
    m.header.frame_id = frame_id
    m.header.stamp = stamp
    m.height, m.width = 1, int(points.shape[0])
    m.fields = FIELDS
    m.is_bigendian = False
    m.point_step = 16
    m.row_step = 16 * m.width
    m.is_dense = True
    m.data = arr.tobytes()
    return m


def cloud_points(msg: PointCloud2) -> np.ndarray[Any, np.dtype[np.float32]]:
    """(N, 4) float32 array x, y, z, intensity of a cloud published by this node (for consumers/tests)."""
    return np.frombuffer(bytes(msg.data), dtype="<f4").reshape(-1, 4)


class LaserSim(Node):
    """Publishes scans of the simulated scene."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("axis_laser_sim", **kwargs)
        # range_noise, seed, noise_per_scan: read from the snapshot at each scan; a change publishes a scan at once
        self._live = LiveParams(self, PARAMS, on_change=self._on_change)
        p = self._live.params
        if p["max_elevation"] < p["min_elevation"]:
            raise ValueError("max_elevation must not be below min_elevation")
        if p["max_range"] <= p["min_range"]:
            raise ValueError("max_range must exceed min_range")
        self._frame_id: str = p["frame_id"]
        world = load_world(p["world_file"] or None)
        self.T_base_laser = world.T_base_laser
        dirs = scan_directions(p["min_elevation"], p["max_elevation"], p["elevation_step"], p["azimuth_step"])
        self._returns = StaticScan.trace(
            shared_scene(world), world.T_base_laser, dirs, p["min_range"], p["max_range"], int(p["seed"])
        )
        self._lock = threading.Lock()  # a scan by the timer and one on a parameter change, one after the other
        self.get_logger().info(f"{dirs.shape[0]} rays, {self._returns.ranges.size} returns per scan")
        self._pub = publisher(self, PointCloud2, "laser/points", LATCHED_QOS)
        self._tf_pub = publish_fixed_transform(
            self, self.T_base_laser, p["parent_frame"], self._frame_id, "laser/transform"
        )
        self._scan()
        self._timer = self.create_timer(1.0 / float(p["rate"]), self._scan)

    def _scan(self) -> None:
        with self._lock:  # the parameters read inside: a scan published after a set carries the new values
            p = self._live.params
            rng = None if p["noise_per_scan"] else np.random.default_rng(int(p["seed"]))
            pts = self._returns.points(float(p["range_noise"]), rng)
            stamp = self.get_clock().now().to_msg()
            self._pub.publish(cloud_msg(pts, self._returns.intensity, self._frame_id, stamp))

    def _on_change(self, names: frozenset[str]) -> None:
        if "seed" in names:
            with self._lock:
                self._returns = replace(self._returns, rng=np.random.default_rng(int(self._live.params["seed"])))
        if names & {"seed", "range_noise", "noise_per_scan"}:
            self._scan()


def main(args: list[str] | None = None) -> int:
    """Entry point of ``axis_laser_sim``."""
    return run_nodes([LaserSim], args if args is not None else sys.argv)


if __name__ == "__main__":
    sys.exit(main())
