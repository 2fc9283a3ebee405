"""Virtual PTZ camera rendering from an equirectangular panorama (axis_ptz_ros2.virtual.render)."""

import math

import cv2
import numpy as np
import pytest

from axis_ptz_ros2 import geometry as g
from axis_ptz_ros2 import transforms
from axis_ptz_ros2.virtual.render import (
    ViewSpec,
    VirtualCameraRenderer,
    direction_pixel,
    equirect_maps,
)

pytestmark = pytest.mark.unit

PW, PH = 3600, 1800  # panorama size for the marker tests (0.1° per pixel)
R_YAW = transforms.rot_z(math.radians(54.0))  # TRADR: panorama yawed against the robot
R_TILTED = transforms.rpy_to_matrix(0.04, -0.07, 0.9)  # a panorama frame not level with base_link (no fast path)


def _spherical_blob(d_pano: np.ndarray, sigma: float) -> np.ndarray:
    """A float32 panorama, zero except a Gaussian of angular distance (sigma rad) around direction d_pano."""
    pano = np.zeros((PH, PW), np.float32)
    cx, cy = g.direction_to_equirect(d_pano, PW, PH)
    r = int(math.ceil(5 * sigma / (2 * math.pi / PW) / max(math.cos(g.direction_to_pan_tilt(d_pano)[1]), 0.05)))
    rows = np.arange(max(0, int(cy) - r), min(PH, int(cy) + r + 2))
    cols = np.arange(int(cx) - r, int(cx) + r + 2)  # may run past either end: wrapped below
    xx, yy = np.meshgrid(cols, rows)
    dirs = g.equirect_to_direction(xx, yy, PW, PH)
    theta = np.arccos(np.clip(dirs @ (d_pano / np.linalg.norm(d_pano)), -1.0, 1.0))
    pano[yy, xx % PW] = np.exp(-0.5 * (theta / sigma) ** 2)
    return pano


def _centroid(img: np.ndarray, u: float, v: float, half: int) -> tuple[float, float]:
    u0, v0 = round(u), round(v)
    win = img[v0 - half : v0 + half + 1, u0 - half : u0 + half + 1].astype(np.float64)
    vv, uu = np.mgrid[v0 - half : v0 + half + 1, u0 - half : u0 + half + 1]
    s = win.sum()
    return float((uu * win).sum() / s), float((vv * win).sum() / s)


def _expected_pixel(view: ViewSpec, d_base: np.ndarray) -> np.ndarray:
    """K·R⁻¹·d with R = Rz(pan)·Ry(−tilt)·R_body_opt, written out from geometry primitives."""
    R = transforms.rot_z(view.pan) @ transforms.rot_y(-view.tilt) @ transforms.R_BODY_OPT
    p = view.intrinsics.K @ (R.T @ d_base)
    return p[:2] / p[2]


MARKER_CASES = [
    # (pan°, tilt°, hfov°, (u, v) of the marker in the view, R_pano_base)
    (0.0, 0.0, 60.0, (351.5, 287.5), None),
    (0.0, 0.0, 60.0, (100.3, 80.7), None),
    (179.9, 0.0, 47.98, (352.0, 288.0), None),  # view straddles the ±180° seam
    (-179.5, 10.0, 30.0, (600.2, 500.9), None),
    (180.0, -20.0, 60.0, (40.0, 300.0), None),
    (35.0, 60.0, 60.0, (500.0, 100.0), None),
    (-120.0, -60.0, 20.0, (200.0, 450.0), None),
    (90.0, 60.0, 90.0, (351.5, 60.0), None),  # near the zenith
    (-150.0, 5.0, 10.0, (640.0, 60.0), None),  # tele: view pixels 7x smaller than panorama pixels
    (126.0, 0.0, 48.0, (352.0, 288.0), R_YAW),  # seam of a yawed panorama in the view centre
    (10.0, -30.0, 48.0, (120.0, 400.0), R_YAW),
    (-170.0, 45.0, 60.0, (600.0, 100.0), R_TILTED),
]


@pytest.mark.parametrize(("pan_deg", "tilt_deg", "hfov_deg", "uv", "R"), MARKER_CASES)
def test_marker_lands_at_projection(pan_deg, tilt_deg, hfov_deg, uv, R):
    view = ViewSpec(704, 576, math.radians(pan_deg), math.radians(tilt_deg), math.radians(hfov_deg))
    R_pb = np.eye(3) if R is None else R
    d_base = g.pixel_direction_in_ptz_base(view.pan, view.tilt, uv[0], uv[1], view.intrinsics)
    # blob: >= 1.5 view pixels and >= 1.5 panorama pixels (angular sigma)
    sigma = max(1.5 / view.intrinsics.fx, 1.5 * 2 * math.pi / PW)
    pano = _spherical_blob(R_pb @ d_base, sigma)
    img = VirtualCameraRenderer(PW, PH, R).render(pano, view)
    assert img.shape == (576, 704)

    expected = _expected_pixel(view, d_base)
    assert expected == pytest.approx(uv, abs=1e-9)
    assert direction_pixel(view, d_base) == pytest.approx(tuple(expected), abs=1e-9)
    half = int(math.ceil(5 * sigma * view.intrinsics.fx))
    u, v = _centroid(img, *expected, half)
    # spec: 0.5 px; measured ≤ 0.02 px, so 0.1 px also catches half-pixel convention slips
    assert math.hypot(u - expected[0], v - expected[1]) < 0.1, (u, v, expected)
    # and nothing is drawn anywhere else (the marker is the only bright thing in the view)
    assert img.max() > 0.5
    assert np.count_nonzero(img > 0.05) < (2 * half + 1) ** 2


def test_marker_straddling_the_panorama_seam():
    # The marker itself sits on the panorama's first/last column (azimuth ±π) at the view centre.
    view = ViewSpec(704, 576, math.pi, 0.1, math.radians(10.0))
    d_base = g.pan_tilt_to_direction(math.pi, 0.1)
    sigma = 3 * 2 * math.pi / PW
    pano = _spherical_blob(d_base, sigma)
    assert pano[:, 0].max() > 0.9
    assert pano[:, -1].max() > 0.9
    img = VirtualCameraRenderer(PW, PH).render(pano, view)
    u, v = _centroid(img, view.intrinsics.cx, view.intrinsics.cy, int(5 * sigma * view.intrinsics.fx))
    assert (u, v) == pytest.approx((view.intrinsics.cx, view.intrinsics.cy), abs=0.5)


def test_view_intrinsics_are_the_square_pixel_pinhole():
    view = ViewSpec(704, 576, 0.2, -0.1, math.radians(47.98))
    k = view.intrinsics
    assert k.fx == pytest.approx(352.0 / math.tan(math.radians(47.98) / 2))
    assert k.fy == k.fx
    assert (k.cx, k.cy) == (351.5, 287.5)
    assert k.hfov == pytest.approx(view.hfov, abs=1e-15)
    # ~791 px at the Axis 214 wide end (geometry-and-calibration.md §2)
    assert k.fx == pytest.approx(791, abs=1.0)


@pytest.mark.parametrize("R", [None, R_YAW, R_TILTED])
def test_maps_use_exactly_the_published_intrinsics(R):
    # Every pixel's panorama coordinate equals geometry.direction_to_equirect of R·R_base_opt·K⁻¹·[u,v,1]
    # with K = view.intrinsics.K: the K a CameraInfo would publish is the K the maps were built with.
    W, H = 5400, 2700
    view = ViewSpec(641, 480, math.radians(-100.0), math.radians(33.0), math.radians(75.0))
    x, y = equirect_maps(view, W, H, R)
    assert x.shape == y.shape == (480, 641)
    uu, vv = np.meshgrid(np.arange(641.0), np.arange(480.0))
    rays = np.stack([uu, vv, np.ones_like(uu)], -1) @ np.linalg.inv(view.intrinsics.K).T
    R_pb = np.eye(3) if R is None else R
    ref = g.direction_to_equirect(rays @ (R_pb @ view.R_base_opt).T, W, H)
    dx = (x - ref[..., 0] + W / 2) % W - W / 2  # the renderer wraps x into [0, W)
    assert np.abs(dx).max() < 2e-3
    assert np.abs(y - np.clip(ref[..., 1], 0, H - 1)).max() < 2e-3
    assert x.min() >= 0.0
    assert x.max() < W
    # The renderer's fixed-point maps are these, to 1/32 px.
    m1, m2 = VirtualCameraRenderer(W, H, R).maps(view)
    fx = m1[..., 0] + (m2 & 31) / 32.0
    fy = m1[..., 1] + (m2 >> 5) / 32.0
    assert np.abs((fx - x + W / 2) % W - W / 2).max() <= 1 / 64 + 2e-3
    assert np.abs(fy - y).max() <= 1 / 64 + 1e-3


def _textured_pano(w: int, h: int, seed: int = 0) -> np.ndarray:
    """uint8 BGR: blurred noise (smooth enough that a 1/32 px shift changes < 1 grey level)."""
    noise = np.random.default_rng(seed).standard_normal((h, w, 3)).astype(np.float32)
    padded = np.pad(noise, ((0, 0), (32, 32), (0, 0)), mode="wrap")  # periodic in azimuth
    smooth = cv2.GaussianBlur(padded, (0, 0), 4.0)[:, 32:-32]
    return np.clip(128 + smooth * (40 / smooth.std()), 0, 255).astype(np.uint8)


def test_cached_and_rebuilt_maps_give_identical_images():
    pano = _textured_pano(2048, 1024)
    r = VirtualCameraRenderer(2048, 1024, R_YAW, cache_size=2)
    v1 = ViewSpec(704, 576, 0.5, 0.2, math.radians(40.0))
    first = r.render(pano, v1)
    maps = r.maps(v1)
    assert r.maps(v1) is maps  # served from the cache
    assert not maps[0].flags.writeable  # shared: callers cannot corrupt the cache
    assert not maps[1].flags.writeable
    for k in range(4):  # evict v1 (and its pan-0 maps)
        r.render(pano, ViewSpec(704, 576, 0.1 * k, -0.3 * k, math.radians(30.0 + k)))
    assert r.maps(v1) is not maps
    assert np.array_equal(r.render(pano, v1), first)
    assert np.array_equal(VirtualCameraRenderer(2048, 1024, R_YAW).render(pano, v1), first)
    out = np.zeros_like(first)
    assert r.render(pano, v1, out=out) is out
    assert np.array_equal(out, first)


@pytest.mark.parametrize("R", [None, R_YAW])
def test_pan_only_fast_path_equals_full_rebuild(R):
    pano = _textured_pano(2048, 1024, seed=1)
    r = VirtualCameraRenderer(2048, 1024, R)
    assert r.pan_shift_fast_path
    tilt, hfov = math.radians(-25.0), math.radians(55.0)
    r.render(pano, ViewSpec(704, 576, 0.0, tilt, hfov))
    for pan_deg in (0.37, 91.0, 179.95, -179.95, -45.123):
        view = ViewSpec(704, 576, math.radians(pan_deg), tilt, hfov)
        fast = r.render(pano, view)  # x shift of the cached pan-0 maps
        x, y = equirect_maps(view, 2048, 1024, R)  # from scratch
        full = cv2.remap(pano, x, y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
        m1, m2 = cv2.convertMaps(x, y, cv2.CV_16SC2)
        full_fixed = cv2.remap(pano, m1, m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
        diff = np.abs(fast.astype(int) - full_fixed.astype(int))
        assert diff.max() <= 1
        assert np.count_nonzero(diff) < 0.01 * diff.size
        assert np.abs(fast.astype(int) - full.astype(int)).max() <= 1  # fixed point vs float maps


def test_seam_is_seamless():
    # Rolling the panorama by half a turn moves its seam to the other side; the same scene seen across the
    # seam must render the same.
    pano = _textured_pano(2048, 1024, seed=2)
    rolled = np.roll(pano, 1024, axis=1)
    r = VirtualCameraRenderer(2048, 1024)
    for pan_deg, tilt_deg in [(180.0, 0.0), (-178.0, 30.0), (175.0, -60.0)]:
        view = ViewSpec(704, 576, math.radians(pan_deg), math.radians(tilt_deg), math.radians(60.0))
        shifted = ViewSpec(704, 576, view.pan + math.pi, view.tilt, view.hfov)
        a = r.render(pano, view).astype(int)
        b = r.render(rolled, shifted).astype(int)
        assert np.abs(a - b).max() <= 1


def test_zenith_and_nadir_render_without_wrapping_rows():
    # Looking straight up/down: rows are clamped, never wrapped from one pole to the other.
    pano = np.zeros((1024, 2048), np.uint8)
    pano[:512] = 200  # bright sky, dark ground
    r = VirtualCameraRenderer(2048, 1024)
    up = r.render(pano, ViewSpec(320, 240, 0.3, math.pi / 2, math.radians(60.0)))
    down = r.render(pano, ViewSpec(320, 240, 0.3, -math.pi / 2, math.radians(60.0)))
    assert (up == 200).all()
    assert (down == 0).all()


def test_direction_pixel_behind_and_centre():
    view = ViewSpec(704, 576, 1.0, 0.3, math.radians(60.0))
    assert direction_pixel(view, g.pan_tilt_to_direction(1.0, 0.3)) == pytest.approx((351.5, 287.5))
    u, v = direction_pixel(view, -g.pan_tilt_to_direction(1.0, 0.3))
    assert math.isnan(u)
    assert math.isnan(v)
    # left of the optical axis (positive pan offset) is left in the image
    assert direction_pixel(view, g.pan_tilt_to_direction(1.1, 0.3))[0] < 351.5


def test_invalid_inputs_are_rejected():
    with pytest.raises(ValueError, match="hfov"):
        ViewSpec(704, 576, 0.0, 0.0, math.pi)
    with pytest.raises(ValueError, match="size"):
        ViewSpec(0, 576, 0.0, 0.0, 1.0)
    with pytest.raises(ValueError, match="finite"):
        ViewSpec(704, 576, math.nan, 0.0, 1.0)
    with pytest.raises(ValueError, match="rotation"):
        VirtualCameraRenderer(2048, 1024, np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="panorama size"):
        VirtualCameraRenderer(40000, 20000)
    r = VirtualCameraRenderer(2048, 1024)
    with pytest.raises(ValueError, match="renderer expects"):
        r.render(np.zeros((1000, 2000, 3), np.uint8), ViewSpec(64, 48, 0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="out must be"):
        r.render(np.zeros((1024, 2048, 3), np.uint8), ViewSpec(64, 48, 0.0, 0.0, 1.0), np.zeros((48, 64)))
    assert not VirtualCameraRenderer(2048, 1024, R_TILTED).pan_shift_fast_path
