"""Seeded synthetic calibration scenes with ground truth (ROS-free), for tests and the benchmark.

A scene is a true mount ``T_base_ptz`` (and optionally true encoder offsets), a camera model and a list of
:class:`~axis_ptz_ros2.calibration.correspondences.View` whose pixels are the exact projections of the true
3-D points plus Gaussian pixel noise (σ per axis), whose 3-D points carry Gaussian picking noise (σ per axis),
and, optionally, gross outliers (mis-picked pixels 30–150 px away from the truth).

Points are drawn by picking a pixel uniformly inside the image (10 % margin) and a depth along the optical
axis uniformly in ``depth_range`` (default 2–15 m), then back-projecting through the *true* model, so every
point is visible in its view; points below ``ground_z`` are redrawn closer.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt

from axis_ptz_ros2.calibration.correspondences import Correspondence, View
from axis_ptz_ros2.camera_info import CameraInfoData, project, undistort_pixels
from axis_ptz_ros2.config import CameraModel, load_camera_model
from axis_ptz_ros2.geometry import PtzKinematics
from axis_ptz_ros2.transforms import Transform, rot_z

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
Made = tuple[View, BoolArray, FloatArray]  #: what :func:`make_view` returns

THESIS_MOUNT = Transform.from_xyz_rpy(-0.214, -0.044, 0.455, 0.0, 0.0, 0.0)


@dataclass(frozen=True, slots=True)
class SyntheticScene:
    """Views plus the ground truth that produced them."""

    views: tuple[View, ...]
    truth: Transform  # true T_base_ptz
    camera_model: CameraModel
    pan_offset: float = 0.0  # rad, true encoder offsets (reported + offset = true)
    tilt_offset: float = 0.0
    outliers: tuple[BoolArray, ...] = field(default_factory=tuple)  # per view, which points are outliers
    true_points: tuple[FloatArray, ...] = field(default_factory=tuple)  # per view (N, 3), before 3-D noise

    @property
    def equivalent_truth(self) -> Transform:
        """The true mount with the (unobservable) pan offset folded into its yaw: what the solver recovers."""
        return Transform(self.truth.R @ rot_z(self.pan_offset), self.truth.t.copy())

    @property
    def outlier_mask(self) -> BoolArray:
        """Outlier flags in the solver's flattened order (views, then points)."""
        if not self.outliers:
            return np.zeros(sum(len(v.points) for v in self.views), dtype=bool)
        return np.concatenate(self.outliers)


def default_camera_model() -> CameraModel:
    """The camera of a scene that names none: the Axis 214 of ``config/axis214.yaml`` with its optical centre on
    the tilt axis (``d_opt`` zero, as these scenes have always had it)."""
    cm = load_camera_model()
    return replace(cm, head=replace(cm.head, d_opt=(0.0, 0.0, 0.0)))


def random_mount(rng: np.random.Generator, around: Transform = THESIS_MOUNT) -> Transform:
    """A mount near ``around``: ±5 cm per axis, ±3° roll/pitch, ±10° yaw."""
    x, y, z, r, p, yw = around.xyz_rpy()
    d = rng.uniform(-0.05, 0.05, 3)
    a = np.radians(rng.uniform([-3.0, -3.0, -10.0], [3.0, 3.0, 10.0]))
    return Transform.from_xyz_rpy(x + d[0], y + d[1], z + d[2], r + a[0], p + a[1], yw + a[2])


def _true_camera(
    cm: CameraModel, truth: Transform, pan: float, tilt: float, pan_off: float, tilt_off: float
) -> Transform:
    return truth @ cm.head.optical_in_ptz_base(pan + pan_off, tilt + tilt_off)


def make_view(
    rng: np.random.Generator,
    cm: CameraModel,
    truth: Transform,
    name: str,
    pan: float,
    tilt: float,
    zoom: float,
    n_points: int,
    *,
    width: int = 704,
    height: int = 576,
    pixel_noise_px: float = 1.0,
    point_noise_m: float = 0.0,
    outlier_fraction: float = 0.0,
    depth_range: tuple[float, float] = (2.0, 15.0),
    ground_z: float = -0.3,
    pan_offset: float = 0.0,
    tilt_offset: float = 0.0,
    planar_relief_m: float | None = None,
    fixed: bool = False,
) -> tuple[View, BoolArray, FloatArray]:
    """One view with ``n_points`` correspondences; returns (view, outlier flags, true 3-D points).

    ``planar_relief_m`` (thesis-like scenes): the points lie on one plane facing the camera at a random depth,
    displaced off it by at most this many metres. With ``fixed`` the camera has no head: ``truth`` is the
    optical frame's pose ``T_reference_optical`` and the view carries no pan/tilt/zoom. Pixels are raw: the
    camera model's measured ``camera_info`` (distortion included) projects them when it has one.
    """
    ci = cm.camera_info_at(cm.zoom.min_zoom if fixed else zoom, width, height)
    K = ci.intrinsics()
    T = truth if fixed else _true_camera(cm, truth, pan, tilt, pan_offset, tilt_offset)
    mu, mv = 0.1 * width, 0.1 * height
    uv = np.column_stack([rng.uniform(mu, width - 1 - mu, n_points), rng.uniform(mv, height - 1 - mv, n_points)])
    ideal = undistort_pixels(uv, ci)
    rays = K.ray(ideal[:, 0], ideal[:, 1])
    if planar_relief_m is not None:
        depth0 = rng.uniform(*depth_range)
        n = np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), -1.0])
        n /= np.linalg.norm(n)
        # plane n·X = n·(0, 0, depth0) in the optical frame, then relief along n
        s = (n @ np.array([0.0, 0.0, depth0])) / (rays @ n)
        P_opt = rays * s[:, None] + np.outer(rng.uniform(-planar_relief_m, planar_relief_m, n_points), n)
    else:
        depth = rng.uniform(*depth_range, n_points)
        P_opt = rays * depth[:, None]
        for _ in range(50):
            below = T.apply(P_opt)[:, 2] < ground_z
            if not below.any():
                break
            lo = min(depth_range[0], 1.0)
            P_opt[below] = rays[below] * rng.uniform(lo, np.maximum(depth[below] * 0.7, lo + 0.1))[:, None]
            depth[below] = P_opt[below, 2]
    X_true = T.apply(P_opt)
    pix = project(P_opt, ci)
    pix = pix + rng.normal(0.0, pixel_noise_px, pix.shape) if pixel_noise_px > 0 else pix
    X = X_true + rng.normal(0.0, point_noise_m, X_true.shape) if point_noise_m > 0 else X_true.copy()
    out = np.zeros(n_points, dtype=bool)
    n_out = round(outlier_fraction * n_points)
    if n_out:
        idx = rng.choice(n_points, n_out, replace=False)
        out[idx] = True
        for i in idx:
            ang = rng.uniform(0, 2 * math.pi)
            r = rng.uniform(30.0, 150.0)
            pix[i] = pix[i] + r * np.array([math.cos(ang), math.sin(ang)])
    pix[:, 0] = np.clip(pix[:, 0], 0.0, width - 1.0)
    pix[:, 1] = np.clip(pix[:, 1], 0.0, height - 1.0)
    pts = tuple(
        Correspondence((float(pix[i, 0]), float(pix[i, 1])), (float(X[i, 0]), float(X[i, 1]), float(X[i, 2])), f"p{i}")
        for i in range(n_points)
    )
    if fixed:
        return View(name, math.nan, math.nan, math.nan, width, height, pts), out, X_true
    return View(name, pan, tilt, float(zoom), width, height, pts), out, X_true


def _assemble(
    made: Sequence[Made], truth: Transform, cm: CameraModel, pan_offset: float, tilt_offset: float
) -> SyntheticScene:
    """A scene of the views :func:`make_view` made (with their outlier flags and true points)."""
    return SyntheticScene(
        tuple(m[0] for m in made),
        truth,
        cm,
        pan_offset,
        tilt_offset,
        tuple(m[1] for m in made),
        tuple(m[2] for m in made),
    )


def make_scene(
    seed: int | np.random.Generator,
    *,
    n_views: int = 5,
    points_per_view: int = 8,
    pixel_noise_px: float = 1.0,
    point_noise_m: float = 0.0,
    outlier_fraction: float = 0.0,
    zoom_range: tuple[float, float] = (1.0, 1200.0),
    pan_span_deg: float = 300.0,
    tilt_range_deg: tuple[float, float] = (-20.0, 20.0),
    depth_range: tuple[float, float] = (2.0, 15.0),
    camera_model: CameraModel | None = None,
    truth: Transform | None = None,
    pan_offset: float = 0.0,
    tilt_offset: float = 0.0,
    width: int = 704,
    height: int = 576,
) -> SyntheticScene:
    """A multi-view scene: pans evenly spread over ``pan_span_deg`` (±jitter), random tilt and zoom."""
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    cm = camera_model or default_camera_model()
    T = truth if truth is not None else random_mount(rng)
    span = math.radians(pan_span_deg)
    base = np.linspace(-span / 2, span / 2, n_views) if n_views > 1 else np.zeros(1)
    jitter = span / max(n_views, 1) / 4.0
    made: list[Made] = []
    for k in range(n_views):
        pan = float(base[k] + rng.uniform(-jitter, jitter))
        tilt = math.radians(float(rng.uniform(*tilt_range_deg)))
        zoom = float(rng.uniform(*zoom_range))
        made.append(
            make_view(
                rng,
                cm,
                T,
                f"view{k}",
                pan,
                tilt,
                zoom,
                points_per_view,
                width=width,
                height=height,
                pixel_noise_px=pixel_noise_px,
                point_noise_m=point_noise_m,
                outlier_fraction=outlier_fraction,
                depth_range=depth_range,
                pan_offset=pan_offset,
                tilt_offset=tilt_offset,
            )
        )
    return _assemble(made, T, cm, pan_offset, tilt_offset)


def real_like_camera_info(
    model: str = "plumb_bob", width: int = 704, height: int = 576, fx: float = 791.0 * 0.97
) -> CameraInfoData:
    """A measured-looking calibration: principal point ~30 px off centre, fy from the PAL aspect, and a
    distortion like a real wide-angle lens (plumb_bob k1 −0.20 as in the real-data report; or equidistant)."""
    cx, cy = (width - 1) / 2.0 + 30.0, (height - 1) / 2.0 - 18.0
    fy = fx * (height / width) * (4.0 / 3.0)
    D: tuple[float, ...]
    if model == "plumb_bob":
        D = (-0.20, 0.08, 0.0012, -0.0008, -0.01)
    elif model == "rational_polynomial":
        D = (-0.20, 0.08, 0.0012, -0.0008, -0.01, 0.02, 0.01, 0.0)
    elif model == "equidistant":
        D = (-0.03, 0.012, -0.004, 0.0008)
    else:
        raise ValueError(f"unknown distortion model {model!r}")
    K = (fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0)
    return CameraInfoData(width, height, K, model, D, camera_name="synthetic")


def fixed_truth(rng: np.random.Generator, around: Transform = THESIS_MOUNT) -> Transform:
    """A fixed camera's optical frame in the reference frame: near ``around``, looking roughly forward
    (±20° yaw, −15…+5° pitch, ±3° roll)."""
    head = PtzKinematics(0.0, (0.0, 0.0, 0.0)).optical_in_ptz_base(
        math.radians(float(rng.uniform(-20.0, 20.0))), math.radians(float(rng.uniform(-15.0, 5.0)))
    )
    roll = Transform.from_xyz_rpy(0.0, 0.0, 0.0, 0.0, 0.0, math.radians(float(rng.uniform(-3.0, 3.0))))
    return random_mount(rng, around) @ head @ roll


def make_fixed_scene(
    seed: int | np.random.Generator,
    camera_model: CameraModel,
    *,
    n_views: int = 1,
    points_per_view: int = 16,
    pixel_noise_px: float = 1.0,
    point_noise_m: float = 0.0,
    outlier_fraction: float = 0.0,
    depth_range: tuple[float, float] = (2.0, 15.0),
    width: int | None = None,
    height: int | None = None,
) -> SyntheticScene:
    """A fixed camera (no head) seen in ``n_views`` captures (e.g. different moments of a moving target);
    ``truth`` is ``T_reference_optical``. The image size defaults to the camera model's camera_info."""
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    ci = camera_model.camera_info
    w = width or (ci.width if ci is not None else 704)
    h = height or (ci.height if ci is not None else 576)
    T = fixed_truth(rng)
    made: list[Made] = []
    for k in range(n_views):
        made.append(
            make_view(
                rng,
                camera_model,
                T,
                f"capture{k}",
                0.0,
                0.0,
                1.0,
                points_per_view,
                width=w,
                height=h,
                pixel_noise_px=pixel_noise_px,
                point_noise_m=point_noise_m,
                outlier_fraction=outlier_fraction,
                depth_range=depth_range,
                ground_z=-10.0,
                fixed=True,
            )
        )
    return _assemble(made, T, camera_model, 0.0, 0.0)


def thesis_like_scene(
    seed: int | np.random.Generator,
    *,
    pixel_noise_px: float = 1.0,
    point_noise_m: float = 0.02,
    relief_m: float = 0.05,
    camera_model: CameraModel | None = None,
) -> SyntheticScene:
    """The 2015 set-up (thesis §6.4): one wide view, 6 nearly coplanar points 2.5–4 m away, 2 cm picks."""
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    cm = camera_model or default_camera_model()
    T = random_mount(rng)
    made = make_view(
        rng,
        cm,
        T,
        "thesis",
        math.pi + float(rng.uniform(-0.2, 0.2)),  # the camera sat at the rear, looking back
        math.radians(float(rng.uniform(-15.0, 0.0))),
        1.0,
        6,
        pixel_noise_px=pixel_noise_px,
        point_noise_m=point_noise_m,
        depth_range=(2.5, 4.0),
        planar_relief_m=relief_m,
    )
    return _assemble([made], T, cm, 0.0, 0.0)


def prediction_errors(
    scene: SyntheticScene,
    estimate: Transform,
    tilt_offset: float,
    rng: np.random.Generator,
    *,
    n_views: int = 5,
    points_per_view: int = 20,
    zoom_range: tuple[float, float] = (1.0, 1200.0),
    depth_range: tuple[float, float] = (2.0, 15.0),
    camera_model: CameraModel | None = None,
) -> FloatArray:
    """Ground-truth held-out error (px): fresh noise-free points in fresh views, reprojected with the estimate
    (and ``camera_model``, default the scene's) against their true pixels."""
    cm = scene.camera_model
    cm_est = camera_model or cm
    errs: list[FloatArray] = []
    for k in range(n_views):
        pan = float(rng.uniform(-math.pi, math.pi))
        tilt = math.radians(float(rng.uniform(-20.0, 20.0)))
        zoom = float(rng.uniform(*zoom_range))
        v, _, X = make_view(
            rng,
            cm,
            scene.truth,
            f"test{k}",
            pan,
            tilt,
            zoom,
            points_per_view,
            pixel_noise_px=0.0,
            depth_range=depth_range,
            pan_offset=scene.pan_offset,
            tilt_offset=scene.tilt_offset,
        )
        ci = cm_est.camera_info_at(zoom, v.image_width, v.image_height)
        T_est = estimate @ cm_est.head.optical_in_ptz_base(pan, tilt + tilt_offset)
        pred = project(T_est.inverse().apply(X), ci)
        true = np.array([c.pixel for c in v.points])
        errs.append(np.linalg.norm(pred - true, axis=1))
    return np.concatenate(errs)


def translation_error_m(scene: SyntheticScene, estimate: Transform) -> float:
    """‖t_est − t_true‖ (m)."""
    return float(np.linalg.norm(estimate.t - scene.equivalent_truth.t))
