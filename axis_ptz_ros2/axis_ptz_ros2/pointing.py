"""Panorama ↔ PTZ pointing with parallax (ROS-free; geometry-and-calibration.md §3-§4).

A click in the panorama is a ray from the panorama camera's centre, not from the PTZ head: the two are
0.43 m apart on TRADR, which is 8° of error for a target 3 m to the side. So: ray → depth (laser points in a
small cone around it, else the ground plane, else a default range flagged "no depth") → 3-D point in
base_link → the PTZ node's look-at (exact pan/tilt from the PTZ head). The reverse (where the PTZ looks, drawn
on the panorama) projects points along the PTZ's optical rays into the panorama.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
import numpy.typing as npt

from axis_ptz_ros2.geometry import direction_to_equirect, equirect_to_direction
from axis_ptz_ros2.optics import Intrinsics
from axis_ptz_ros2.transforms import FloatArray, Transform


class DepthSource(StrEnum):
    """Where a click's range came from."""

    LASER = "laser"
    GROUND = "ground"
    DEFAULT = "default"  # no depth known: the parallax correction uses an assumed range


@dataclass(frozen=True, slots=True)
class RayPoint:
    """A 3-D point picked along a panorama ray."""

    point_base: FloatArray  # (3,) metres in base_link
    range_m: float  # metres from the panorama centre
    source: DepthSource


def panorama_ray(x: float, y: float, width: int, height: int, T_base_pano: Transform) -> tuple[FloatArray, FloatArray]:
    """Origin and unit direction in base_link of the ray through panorama pixel (x, y)."""
    d_pano = equirect_to_direction(x, y, width, height)
    d = T_base_pano.R @ np.asarray(d_pano, dtype=np.float64)
    return np.asarray(T_base_pano.t, dtype=np.float64), np.asarray(d / np.linalg.norm(d), dtype=np.float64)


def laser_depth(
    origin: FloatArray,
    direction: FloatArray,
    cloud_base: npt.ArrayLike | None,
    cone_deg: float = 1.0,
    min_range: float = 0.3,
) -> float | None:
    """Range along the ray to the nearest cluster of laser points inside a cone of half-angle ``cone_deg``.

    Takes the 20th percentile of the in-cone ranges (robust to a stray near point, and to the far background
    showing through the cone's edge), or None when no point is in the cone.
    """
    if cloud_base is None:
        return None
    P = np.asarray(cloud_base, dtype=np.float64).reshape(-1, 3)
    if P.size == 0:
        return None
    v = P - origin
    along = v @ direction
    ok = along > min_range
    if not np.any(ok):
        return None
    v, along = v[ok], along[ok]
    perp = np.linalg.norm(v - np.outer(along, direction), axis=1)
    inside = perp <= along * math.tan(math.radians(cone_deg))
    if not np.any(inside):
        return None
    return float(np.percentile(along[inside], 20.0))


def ground_depth(origin: FloatArray, direction: FloatArray, ground_z: float = 0.0) -> float | None:
    """Range along a downward ray to the ground plane z = ``ground_z`` (None for rays at or above horizon)."""
    if direction[2] >= -1e-6:
        return None
    r = (ground_z - origin[2]) / direction[2]
    return float(r) if r > 0 else None


def point_along_ray(
    origin: FloatArray,
    direction: FloatArray,
    cloud_base: npt.ArrayLike | None = None,
    *,
    ground_z: float = 0.0,
    default_range: float = 10.0,
    cone_deg: float = 1.0,
) -> RayPoint:
    """The 3-D point an operator most likely meant: laser depth, else ground, else ``default_range``."""
    r = laser_depth(origin, direction, cloud_base, cone_deg)
    src = DepthSource.LASER
    if r is None:
        r, src = ground_depth(origin, direction, ground_z), DepthSource.GROUND
    if r is None:
        r, src = default_range, DepthSource.DEFAULT
    return RayPoint(np.asarray(origin + r * direction, dtype=np.float64), float(r), src)


def project_to_panorama(points_base: npt.ArrayLike, T_base_pano: Transform, width: int, height: int) -> FloatArray:
    """Panorama pixel coordinates (N, 2) of base_link points (N, 3) as seen from the panorama centre."""
    P = np.atleast_2d(np.asarray(points_base, dtype=np.float64))
    d = T_base_pano.inverse().apply(P)
    return direction_to_equirect(d, width, height)


def footprint_rays(intr: Intrinsics, T_base_opt: Transform, samples_per_edge: int = 8) -> FloatArray:
    """Unit directions (N, 3) in base_link along the border of the PTZ image (clockwise from top-left)."""
    w, h = intr.width - 1.0, intr.height - 1.0
    t = np.linspace(0.0, 1.0, samples_per_edge, endpoint=False)
    u = np.concatenate([t * w, np.full_like(t, w), (1 - t) * w, np.zeros_like(t)])
    v = np.concatenate([np.zeros_like(t), t * h, np.full_like(t, h), (1 - t) * h])
    rays = intr.ray(u, v)
    d = rays @ T_base_opt.R.T
    return np.asarray(d / np.linalg.norm(d, axis=1, keepdims=True), dtype=np.float64)


def footprint_on_panorama(
    intr: Intrinsics,
    T_base_opt: Transform,
    T_base_pano: Transform,
    width: int,
    height: int,
    depth_m: float = 10.0,
    samples_per_edge: int = 8,
) -> FloatArray:
    """Panorama pixels (N, 2) of the PTZ image border, optical rays taken to ``depth_m`` (parallax)."""
    d = footprint_rays(intr, T_base_opt, samples_per_edge)
    pts = T_base_opt.t + depth_m * d
    return project_to_panorama(pts, T_base_pano, width, height)
