"""Automatic picking of 2-D/3-D pairs on calibration boards (ROS-free; geometry-and-calibration.md §6).

What a person does with an image viewer and a point-cloud viewer, done by code for boards with coloured dots
(the simulated scene's ``calib`` targets: a white board with a red, green, blue and yellow dot):

* **Image side** — :func:`detect_dots`: colour thresholding in HSV, connected components, rejection of blobs
  that touch the image border, are too small, are not elliptic (filled-ellipse test) or are not surrounded by
  the white board; then a sub-pixel centroid weighted by colour saturation (uses the anti-aliased edge).
* **Which board / dot is it** — :func:`associate_dots`: the operator knows roughly where the camera looks.
  Here the candidate 3-D features are projected with a *guessed* camera pose (the nominal mount, never the
  true one) and each detected dot takes the nearest candidate of its colour inside an angular gate.
* **Laser side** — :func:`pick_laser_point`: the cloud point an operator would click, i.e. the laser point
  closest to the dot (``mode="nearest"``); optionally refined by fitting the board plane to the laser points
  around it and projecting onto it (``"plane"``), or by taking the centroid of the laser returns *on* the dot
  (a dot is darker than the white board in the intensity channel) projected onto the board plane (``"blob"``).

The candidate :class:`Feature` s come from the caller: for the simulated scene, its true dot positions
(``tests/support/sim_picker.py``), which may be used ONLY to choose which cloud point an operator would click
and to measure the picking noise — the calibration never sees the true mount. :func:`picking_noise` reports
the 3-D error of the picked points against the features' positions.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
import numpy.typing as npt

from axis_ptz_ros2.calibration.correspondences import Correspondence
from axis_ptz_ros2.config import CameraModel
from axis_ptz_ros2.optics import Intrinsics
from axis_ptz_ros2.transforms import Transform

FloatArray = npt.NDArray[np.float64]
U8Array = npt.NDArray[np.uint8]

PickMode = Literal["nearest", "plane", "blob"]

#: OpenCV hue ranges (0…180) of the board dot colours (``sim.textures.CALIB_DOTS``: BGR red (0, 0, 255),
#: green (0, 200, 0), blue (255, 0, 0), yellow (0, 230, 255) → hue 0, 60, 120, 27).
DOT_HUES: dict[str, tuple[tuple[int, int], ...]] = {
    "red": ((0, 8), (172, 180)),
    "yellow": ((19, 35),),
    "green": ((45, 80),),
    "blue": ((105, 135),),
}
#: Radius of the board dots (m): ``0.08`` × the 0.8 m board width of ``sim.textures.calib_texture``.
DEFAULT_DOT_RADIUS = 0.064


# --------------------------------------------------------------------------------------------------------
# Image side
# --------------------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Dot:
    """A coloured dot found in an image."""

    colour: str
    u: float  # px, sub-pixel centroid (origin at the centre of the top-left pixel)
    v: float
    area: float  # px, pixels above the colour threshold
    fill: float  # area / area of the moment ellipse (≈ 1 for a filled ellipse)


def detect_dots(
    image: U8Array,
    *,
    colours: Sequence[str] = ("red", "green", "blue", "yellow"),
    min_area: float = 40.0,
    min_saturation: int = 150,
    min_value: int = 90,
    border_px: int = 2,
    fill_range: tuple[float, float] = (0.85, 1.12),
    surround_min_value: int = 150,
    surround_max_saturation: int = 70,
) -> list[Dot]:
    """Board dots in a BGR image, sorted by colour then position.

    A blob counts when it has ``≥ min_area`` px of saturated pixels (``S ≥ min_saturation``,
    ``V ≥ min_value``, hue in :data:`DOT_HUES`), keeps ``border_px`` away from the image border, fills its
    moment ellipse (``fill_range``; lines, rings and partial blobs fail) and is surrounded by a bright,
    unsaturated ring (the white board). The centre is the saturation-weighted centroid over the blob dilated
    by two pixels, which uses the anti-aliased edge pixels too.
    """
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"expected a BGR image, got shape {image.shape}")
    H, W = image.shape[:2]
    hsv = cv2.cvtColor(image, cv2.COLOR_BGR2HSV)
    hue, sat, val = hsv[:, :, 0], hsv[:, :, 1], hsv[:, :, 2]
    strong = (sat >= min_saturation) & (val >= min_value)
    out: list[Dot] = []
    for colour in colours:
        in_hue = np.zeros((H, W), bool)
        for lo, hi in DOT_HUES[colour]:
            in_hue |= (hue >= lo) & (hue <= hi)
        mask = (strong & in_hue).astype(np.uint8)
        n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        for k in range(1, n):
            x, y, w, h, area = (int(s) for s in stats[k])
            if area < min_area:
                continue
            if x < border_px or y < border_px or x + w > W - border_px or y + h > H - border_px:
                continue
            pad = max(4, int(0.6 * max(w, h)))
            x0, y0 = max(0, x - pad), max(0, y - pad)
            x1, y1 = min(W, x + w + pad), min(H, y + h + pad)
            blob = (labels[y0:y1, x0:x1] == k).astype(np.uint8)
            m = cv2.moments(blob, binaryImage=True)
            if m["m00"] <= 0:
                continue
            mu20, mu02, mu11 = m["mu20"] / m["m00"], m["mu02"] / m["m00"], m["mu11"] / m["m00"]
            det = mu20 * mu02 - mu11 * mu11
            if det <= 0:
                continue
            fill = float(m["m00"] / (4.0 * math.pi * math.sqrt(det)))
            if not fill_range[0] <= fill <= fill_range[1]:
                continue
            # The ring around the dot must be the white board.
            r_in = cv2.dilate(blob, np.ones((5, 5), np.uint8))
            r_out = cv2.dilate(blob, np.ones((3 + 2 * max(2, int(0.25 * max(w, h))),) * 2, np.uint8))
            ring = (r_out > 0) & (r_in == 0)
            if ring.sum() < 8:
                continue
            if float(np.median(val[y0:y1, x0:x1][ring])) < surround_min_value:
                continue
            if float(np.median(sat[y0:y1, x0:x1][ring])) > surround_max_saturation:
                continue
            # Sub-pixel centre: saturation-weighted centroid over the blob grown by 2 px.
            grown = cv2.dilate(blob, np.ones((5, 5), np.uint8)) > 0
            wgt = np.where(grown & in_hue[y0:y1, x0:x1], sat[y0:y1, x0:x1].astype(np.float64), 0.0)
            s = float(wgt.sum())
            if s <= 0:
                continue
            yy, xx = np.mgrid[y0:y1, x0:x1]
            out.append(Dot(colour, float((wgt * xx).sum() / s), float((wgt * yy).sum() / s), float(area), fill))
    return out


# --------------------------------------------------------------------------------------------------------
# Association: which 3-D feature is this dot
# --------------------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Feature:
    """A candidate 3-D feature (``base_link``): a dot of known colour on a board."""

    label: str  # e.g. "calib_front/dot_red"
    colour: str
    point: tuple[float, float, float]
    radius: float = DEFAULT_DOT_RADIUS  # m, of the dot (board design: 0.08 × the board width)


def associate_dots(
    dots: Sequence[Dot],
    features: Sequence[Feature],
    T_base_opt_guess: Transform,
    intrinsics: Intrinsics,
    *,
    max_angle_deg: float = 3.0,
) -> list[tuple[Dot, Feature]]:
    """Pair detected dots with candidate features by projecting the features with a *guessed* camera pose.

    Each dot takes the nearest feature of its colour whose projection lies within ``max_angle_deg``
    (converted to pixels with ``fx``) and in front of the camera; a feature claimed by two dots, or a dot with
    two candidates closer than twice the gate to each other, is dropped (ambiguous).
    """
    if not dots or not features:
        return []
    pts = np.array([f.point for f in features], dtype=np.float64)
    P = T_base_opt_guess.inverse().apply(pts)
    in_front = P[:, 2] > 0.1
    uv = intrinsics.project(np.where(in_front[:, None], P, np.array([0.0, 0.0, 1.0])))
    gate = intrinsics.fx * math.tan(math.radians(max_angle_deg))
    pairs: list[tuple[Dot, int]] = []
    for d in dots:
        cand = [
            (float(np.hypot(uv[i, 0] - d.u, uv[i, 1] - d.v)), i)
            for i, f in enumerate(features)
            if f.colour == d.colour and in_front[i]
        ]
        cand.sort()
        if not cand or cand[0][0] > gate:
            continue
        if len(cand) > 1 and cand[1][0] < 2.0 * gate:
            continue
        pairs.append((d, cand[0][1]))
    counts: dict[int, int] = {}
    for _, i in pairs:
        counts[i] = counts.get(i, 0) + 1
    return [(d, features[i]) for d, i in pairs if counts[i] == 1]


# --------------------------------------------------------------------------------------------------------
# Laser side
# --------------------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class LaserPick:
    """A picked 3-D point (``base_link``) and how it was obtained."""

    point: tuple[float, float, float]
    mode: str  # the mode actually used ("nearest" when a refinement had too little support)
    n_support: int  # laser points used (1 for nearest; plane or blob points otherwise)
    click_distance: float  # m, distance of the clicked (nearest) laser point from the requested position


def fit_plane(points: FloatArray, *, iterations: int = 3, inlier_m: float = 0.015) -> tuple[FloatArray, float]:
    """Least-squares plane ``n·x = d`` (unit ``n``) with iterative trimming of points farther than
    ``inlier_m``; returns ``(n, d)``."""
    P = np.asarray(points, dtype=np.float64)
    keep = np.ones(len(P), bool)
    n = np.array([0.0, 0.0, 1.0])
    d = 0.0
    for _ in range(max(1, iterations)):
        if keep.sum() < 3:
            break
        c = P[keep].mean(axis=0)
        _, _, Vt = np.linalg.svd(P[keep] - c, full_matrices=False)
        n = Vt[2]
        d = float(n @ c)
        new = np.abs(P @ n - d) <= inlier_m
        if new.sum() < 3 or np.array_equal(new, keep):
            break
        keep = new
    return np.asarray(n, dtype=np.float64), d


def pick_laser_point(
    cloud: FloatArray,
    near: npt.ArrayLike,
    *,
    mode: PickMode = "nearest",
    dot_radius: float = DEFAULT_DOT_RADIUS,
    plane_radius: float = 0.25,
    min_support: int = 6,
) -> LaserPick:
    """The laser point an operator would click next to ``near`` (m, ``base_link``), optionally refined.

    ``cloud`` is (N, 3) or (N, 4) (x, y, z[, intensity]) in ``base_link``. ``"plane"``: the clicked point
    projected onto the plane fitted to the cloud within ``plane_radius`` of it. ``"blob"``: the centroid of
    the returns within ``1.2 · dot_radius`` of the click that are darker than the board (intensity below the
    midpoint of the click's and the surrounding board's median intensity), iterated twice around the new
    centre, projected onto the board plane (needs the intensity column).
    """
    C = np.asarray(cloud, dtype=np.float64)
    if C.ndim != 2 or C.shape[1] < 3 or len(C) == 0:
        raise ValueError(f"cloud must be a non-empty (N, 3|4) array, got shape {C.shape}")
    xyz = C[:, :3]
    target = np.asarray(near, dtype=np.float64).reshape(3)
    dist = np.linalg.norm(xyz - target, axis=1)
    i = int(np.argmin(dist))
    click = xyz[i]
    if mode == "nearest":
        return LaserPick(_tuple3(click), "nearest", 1, float(dist[i]))
    local = np.linalg.norm(xyz - click, axis=1) <= plane_radius
    if local.sum() < max(3, min_support):
        return LaserPick(_tuple3(click), "nearest", 1, float(dist[i]))
    n, d = fit_plane(xyz[local])
    on_plane = local & (np.abs(xyz @ n - d) <= 0.015)
    if mode == "plane":
        return LaserPick(_tuple3(click - (click @ n - d) * n), "plane", int(on_plane.sum()), float(dist[i]))
    if mode != "blob":
        raise ValueError(f"unknown pick mode {mode!r}")
    if C.shape[1] < 4:
        raise ValueError("mode 'blob' needs the intensity column (N, 4)")
    inten = C[:, 3]
    board = on_plane & (np.linalg.norm(xyz - click, axis=1) > 1.5 * dot_radius)
    if board.sum() < min_support:
        return LaserPick(_tuple3(click - (click @ n - d) * n), "plane", int(on_plane.sum()), float(dist[i]))
    board_level = float(np.median(inten[board]))
    centre = click
    sel = np.zeros(len(C), bool)
    for _ in range(3):
        r = np.linalg.norm(xyz - centre, axis=1)
        cand = on_plane & (r <= 1.2 * dot_radius)
        if cand.sum() == 0:
            break
        dot_level = (
            float(np.median(inten[cand & (r <= 0.6 * dot_radius)]))
            if (cand & (r <= 0.6 * dot_radius)).any()
            else float(inten[i])
        )
        if board_level - dot_level < 0.02:  # the dot is not darker than the board: no blob to centre on
            break
        sel = cand & (inten < 0.5 * (board_level + dot_level))
        if sel.sum() < 3:
            break
        centre = xyz[sel].mean(axis=0)
    if sel.sum() < 3:
        return LaserPick(_tuple3(click - (click @ n - d) * n), "plane", int(on_plane.sum()), float(dist[i]))
    centre = centre - (centre @ n - d) * n
    return LaserPick(_tuple3(centre), "blob", int(sel.sum()), float(dist[i]))


def _tuple3(p: npt.ArrayLike) -> tuple[float, float, float]:
    a = np.asarray(p, dtype=np.float64).reshape(3)
    return float(a[0]), float(a[1]), float(a[2])


# --------------------------------------------------------------------------------------------------------
# Picking noise against known feature positions
# --------------------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class NoiseStats:
    """3-D picking error against the truth (m)."""

    n: int
    rms: float  # RMS of the 3-D error norm
    rms_per_axis: float  # RMS over the x, y, z components
    median: float
    max: float


def picking_noise(picked: Sequence[npt.ArrayLike], truth: Sequence[npt.ArrayLike]) -> NoiseStats:
    """Error statistics of picked points against their true positions."""
    if len(picked) != len(truth):
        raise ValueError("picked and truth differ in length")
    if not picked:
        return NoiseStats(0, math.nan, math.nan, math.nan, math.nan)
    e = np.asarray(picked, dtype=np.float64).reshape(-1, 3) - np.asarray(truth, dtype=np.float64).reshape(-1, 3)
    norm = np.linalg.norm(e, axis=1)
    return NoiseStats(
        len(norm),
        float(np.sqrt(np.mean(norm**2))),
        float(np.sqrt(np.mean(e**2))),
        float(np.median(norm)),
        float(norm.max()),
    )


def features_by_label(features: Sequence[Feature]) -> Mapping[str, Feature]:
    """Index features by label."""
    return {f.label: f for f in features}


# --------------------------------------------------------------------------------------------------------
# One view, end to end
# --------------------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class PickedPoint:
    """One automatically picked pair with its provenance."""

    dot: Dot
    feature: Feature
    laser: LaserPick

    def correspondence(self) -> Correspondence:
        """The pair as stored in a correspondence file (label = the feature's label)."""
        return Correspondence((self.dot.u, self.dot.v), self.laser.point, self.feature.label)


def pick_view(
    image: U8Array,
    cloud: FloatArray,
    pan: float,
    tilt: float,
    zoom: float,
    features: Sequence[Feature],
    camera_model: CameraModel,
    T_base_ptz_guess: Transform,
    *,
    mode: PickMode = "blob",
    max_angle_deg: float = 3.0,
    max_click_distance: float = 0.05,
) -> list[PickedPoint]:
    """Detect the dots of one view, tell which feature each is (with the *guessed* mount) and pick the laser
    point for it. Pairs whose nearest laser point is farther than ``max_click_distance`` from the feature
    (the laser does not see it: occluded or out of range) are dropped. The dot radius of the ``"blob"``
    refinement is the feature's."""
    H, W = image.shape[:2]
    K = camera_model.intrinsics(zoom, W, H)  # the measured K when the model has a camera_info
    T_guess = T_base_ptz_guess @ camera_model.head.optical_in_ptz_base(pan, tilt)
    out: list[PickedPoint] = []
    for dot, feat in associate_dots(detect_dots(image), features, T_guess, K, max_angle_deg=max_angle_deg):
        lp = pick_laser_point(cloud, feat.point, mode=mode, dot_radius=feat.radius)
        if lp.click_distance <= max_click_distance:
            out.append(PickedPoint(dot, feat, lp))
    return out
