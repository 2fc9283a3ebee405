"""Panorama double-click → the 3-D point to look at (ROS-free): ray, laser depth in base_link, the answer text.

The console node only hands over the click (checked by :func:`axis_ptz_ros2.web.api.pixel_click`) and the
newest laser cloud (any object shaped like ``sensor_msgs/PointCloud2``); everything else is here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from axis_ptz_ros2.config import RobotConfig
from axis_ptz_ros2.pointcloud import decode_cloud_msg
from axis_ptz_ros2.pointing import panorama_ray, point_along_ray
from axis_ptz_ros2.transforms import FloatArray
from axis_ptz_ros2.web.api import PixelClick


def cloud_in_base(xyz: FloatArray | None, frame: str, robot: RobotConfig) -> tuple[FloatArray | None, str]:
    """The laser points in base_link, or (None, why not): known frames are base_link ('' too) and the laser's."""
    if xyz is None:
        return None, "no laser data"
    frame = frame.lstrip("/")
    if frame in ("", robot.base_frame):
        return xyz, ""
    if frame == robot.laser.frame:
        return np.asarray(robot.laser.pose.apply(xyz), dtype=np.float64), ""
    return None, f"laser frame {frame!r} unknown (expected {robot.laser.frame!r})"


def cloud_msg_in_base(msg: Any, robot: RobotConfig) -> tuple[FloatArray | None, str]:  # noqa: ANN401 - PointCloud2
    """:func:`cloud_in_base` of a ``PointCloud2`` message (None = none received yet)."""
    if msg is None:
        return None, "no laser data"
    try:
        xyz = decode_cloud_msg(msg)[:, :3]
    except ValueError as err:
        return None, f"laser cloud unusable: {err}"
    return cloud_in_base(xyz, str(msg.header.frame_id), robot)


@dataclass(frozen=True, slots=True)
class LookTarget:
    """Where a panorama click points: the point in base_link, how its depth was found, what to tell the user."""

    point: tuple[float, float, float]
    range_m: float
    depth_source: str
    message: str
    click: dict[str, Any]


def look_target(click: PixelClick, robot: RobotConfig, cloud: FloatArray | None, warn: str, now: float) -> LookTarget:
    """The point the operator most likely meant by ``click`` (laser depth, else ground, else default range)."""
    origin, direction = panorama_ray(click.x, click.y, click.width, click.height, robot.panorama.pose)
    rp = point_along_ray(
        origin,
        direction,
        cloud,
        ground_z=robot.ground_z,
        default_range=robot.default_range,
        cone_deg=robot.depth_cone_deg,
    )
    point = (float(rp.point_base[0]), float(rp.point_base[1]), float(rp.point_base[2]))
    info = {
        "x": click.x, "y": click.y, "width": click.width, "height": click.height, "depth_source": str(rp.source),
        "range_m": rp.range_m, "point": list(point), "laser_points": 0 if cloud is None else len(cloud),
        "time": now,
    }  # fmt: skip
    pt = ", ".join(f"{c:.2f}" for c in point)
    msg = f"looking at ({pt}) m in {robot.base_frame}, depth {rp.source} {rp.range_m:.1f} m"
    if warn:
        msg += f" ({warn})"
    return LookTarget(point, rp.range_m, str(rp.source), msg, info)
