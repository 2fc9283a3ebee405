"""Where the PTZ camera looks, drawn on the panorama (ROS-free): the picture of ``axis_visualizer``.

The thesis (§3.4.3) drew a red circle at the panorama pixel of (pan, tilt) through a linear function, as if the PTZ
sat at the panorama's centre. Here the PTZ's optical axis and the border of its image are taken out to a depth from
the PTZ's real optical centre and projected into the panorama from the panorama's own pose
(:func:`axis_ptz_ros2.pointing.footprint_on_panorama`), so what is drawn is what the PTZ sees at that range.

:class:`PanoramaOverlay` holds what the node has heard (PTZ state, ``ptz/transform``, the panorama's and the laser's
poses, the laser cloud) and decides:

* the pose: ``T_base_opt`` from ``ptz/transform`` while it is fresh, else mount · kinematics(state); the state is
  in joint coordinates (the PTZ node has already added the mount's encoder offsets), so no offset is added here;
* the intrinsics: the state's hfov/vfov, else the zoom model at the state's zoom, else at its widest;
* the depth: fixed, or with ``auto_depth`` the laser along the optical axis → the ground → the fixed depth;
* the drawing: the footprint (yellow), split at the panorama seam and drawn as an open band when it winds around
  a pole; the look point (red, as in the thesis); a text line with pan, tilt, zoom, hfov and depth.

Messages are read through a small protocol (the ``PtzState`` fields used), so tests use plain objects.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import cv2
import numpy as np

from axis_ptz_ros2.config import CameraModel, MountConfig, RobotConfig
from axis_ptz_ros2.optics import Intrinsics
from axis_ptz_ros2.pointing import footprint_on_panorama, point_along_ray, project_to_panorama
from axis_ptz_ros2.transforms import FloatArray, Transform

MARKER_BGR = (0, 0, 255)  # red, as in the thesis
FOOTPRINT_BGR = (0, 255, 255)  # yellow
U8Image = np.ndarray[Any, np.dtype[np.uint8]]


class PtzStateLike(Protocol):
    """The fields of ``axis_ptz_interfaces/PtzState`` the overlay uses (REP-103 rad, zoom units, rad)."""

    pan: float
    tilt: float
    zoom: float
    hfov: float
    vfov: float


@dataclass(frozen=True, slots=True)
class OverlaySettings:
    """The visualizer's live parameters (same names; their defaults are these)."""

    depth: float = 10.0  #: m along the PTZ rays (the look point and the footprint)
    auto_depth: bool = False  #: laser → ground → ``depth``
    marker_radius: int = 0  #: px; 0 = width/200 (min 4)
    ptz_transform_timeout: float = 2.0  #: s: ``ptz/transform`` older than this is not used
    stream_width: int = 704  #: px: the PTZ image size, for the footprint when the state has no vfov
    stream_height: int = 576


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


def intrinsics_from_state(state: PtzStateLike, width: int, height: int) -> Intrinsics | None:
    """A pinhole with the state's hfov/vfov (None when the state has no field of view)."""
    if not (state.hfov > 0.0 and math.isfinite(state.hfov)):
        return None
    fx = (width / 2.0) / math.tan(state.hfov / 2.0)
    has_vfov = state.vfov > 0.0 and math.isfinite(state.vfov)
    fy = (height / 2.0) / math.tan(state.vfov / 2.0) if has_vfov else fx
    return Intrinsics(width, height, fx, fy, (width - 1) / 2.0, (height - 1) / 2.0)


class PanoramaOverlay:
    """What the visualizer knows, and the picture drawn from it (see the module docstring). Not thread-safe: the
    node feeds it and draws from callbacks that never overlap."""

    def __init__(
        self,
        model: CameraModel,
        mount: MountConfig,
        robot: RobotConfig,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """``model``/``mount``: the PTZ's kinematics and zoom, used without a fresh ``ptz/transform``; ``robot``:
        the panorama and laser poses until they are heard, the ground and the depth cone; ``clock``: monotonic s."""
        self.model = model
        self.mount = mount
        self.robot = robot
        self._clock = clock
        self.T_base_pano = robot.panorama.pose
        self.T_base_laser = robot.laser.pose
        self.state: PtzStateLike | None = None
        self._ptz_tf: tuple[float, Transform] | None = None  # (clock at receipt, T_base_opt)
        self._cloud_laser: FloatArray | None = None
        self.last_look_pixel: tuple[float, float] | None = None  # of the last drawing (diagnostics, tests)

    # ---- inputs -----------------------------------------------------------------------------------------
    def ptz_state(self, state: PtzStateLike) -> None:
        """The newest ``ptz/state``."""
        self.state = state

    def ptz_transform(self, T_base_opt: Transform) -> None:
        """The newest ``ptz/transform`` (base_link → optical frame), received now."""
        self._ptz_tf = (self._clock(), T_base_opt)

    def panorama_pose(self, T_base_pano: Transform) -> None:
        """The panorama's pose in base_link (``panorama/transform``)."""
        self.T_base_pano = T_base_pano

    def laser_pose(self, T_base_laser: Transform) -> None:
        """The laser's pose in base_link (``laser/transform``)."""
        self.T_base_laser = T_base_laser

    def laser_cloud(self, xyz_laser: FloatArray) -> None:
        """The newest laser points (N, 3) in the laser frame."""
        self._cloud_laser = xyz_laser

    # ---- decisions --------------------------------------------------------------------------------------
    def optical_pose(self, ptz_transform_timeout: float) -> Transform | None:
        """``T_base_opt``: from ``ptz/transform`` when at most ``ptz_transform_timeout`` s old, else
        mount · kinematics(state) (the state is in joint coordinates: the mount's offsets are not added again);
        None with neither."""
        if self._ptz_tf is not None and self._clock() - self._ptz_tf[0] <= ptz_transform_timeout:
            return self._ptz_tf[1]
        if self.state is None:
            return None
        return self.mount.transform @ self.model.head.optical_in_ptz_base(self.state.pan, self.state.tilt)

    def intrinsics(self, width: int, height: int) -> Intrinsics:
        """The PTZ image's pinhole (``width``×``height``): the state's hfov/vfov, else the zoom model at the state's
        zoom, else (no state yet) at the widest zoom."""
        zoom = self.model.zoom
        if self.state is None:
            return zoom.intrinsics(zoom.min_zoom, width, height)
        intr = intrinsics_from_state(self.state, width, height)
        return intr if intr is not None else zoom.intrinsics(self.state.zoom, width, height)

    def depth(self, T_base_opt: Transform, depth: float, auto_depth: bool) -> float:
        """The range (m) along the optical axis to draw at: ``depth``, or with ``auto_depth`` the laser points in a
        small cone around the axis, else the ground, else ``depth``."""
        if not auto_depth:
            return depth
        cloud = None if self._cloud_laser is None else self.T_base_laser.apply(self._cloud_laser)
        r = point_along_ray(
            T_base_opt.t, T_base_opt.R[:, 2], cloud, ground_z=self.robot.ground_z, default_range=depth,
            cone_deg=self.robot.depth_cone_deg,
        )  # fmt: skip
        return r.range_m

    def draw(self, img: U8Image, settings: OverlaySettings) -> U8Image:
        """The panorama ``img`` with the look point and the footprint drawn (a copy; unchanged without a pose)."""
        out = img.copy()
        T = self.optical_pose(settings.ptz_transform_timeout)
        if T is None:
            return out
        H, W = out.shape[:2]
        depth = self.depth(T, settings.depth, settings.auto_depth)
        intr = self.intrinsics(settings.stream_width, settings.stream_height)
        fp = footprint_on_panorama(intr, T, self.T_base_pano, W, H, depth, samples_per_edge=16)
        lines, closed = footprint_polylines(fp, W)
        thick = max(1, W // 1000)
        for pl in lines:
            cv2.polylines(out, [np.round(pl).astype(np.int32)], closed, FOOTPRINT_BGR, thick, cv2.LINE_AA)
        centre = project_to_panorama(T.t + depth * T.R[:, 2], self.T_base_pano, W, H)[0]
        self.last_look_pixel = (float(centre[0]), float(centre[1]))
        r = settings.marker_radius or max(4, W // 200)
        for s in (-W, 0, W):
            c = (int(round(centre[0] + s)), int(round(centre[1])))
            cv2.circle(out, c, r, MARKER_BGR, -1, cv2.LINE_AA)
        if self.state is not None:
            st = self.state
            text = (
                f"PTZ pan {math.degrees(st.pan):+.1f} deg  tilt {math.degrees(st.tilt):+.1f} deg  "
                f"zoom {st.zoom:.0f}  hfov {math.degrees(intr.hfov):.1f} deg  depth {depth:.1f} m"
            )
            scale = max(0.4, H / 1500.0)
            org = (6, int(24 * scale / 0.6))
            cv2.putText(out, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 3, cv2.LINE_AA)
            cv2.putText(out, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), 1, cv2.LINE_AA)
        return out
