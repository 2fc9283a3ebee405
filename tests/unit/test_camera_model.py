"""The simulated camera's picture model (sim/camera_model.py): refusals, noise, softness, quality curve."""

from __future__ import annotations

import numpy as np
import pytest

from axis_ptz_ros2.sim.camera_model import CameraModel, PicturePool, thesis_kbit_s
from axis_ptz_ros2.sim.persona import AXIS_214, AXIS_Q6075
from tests.support.picture import figure_6_4, unusable_headroom
from tests.support.sim import decode


def _scene(w: int = 176, h: int = 144) -> np.ndarray:
    rng = np.random.default_rng(1)
    img = np.zeros((h, w, 3), np.uint8)
    img[:, : w // 2] = (40, 120, 200)
    img[h // 3 :, :] = rng.integers(0, 255, (h - h // 3, w, 3), dtype=np.uint8)
    return img


@pytest.mark.parametrize(
    ("field", "value", "reason"),
    [
        ("noise_luma", -1.0, "outside"),
        ("noise_luma", float("nan"), "not a finite number"),
        ("kell_factor", 1.5, "outside"),
        ("pool_frames", 2.5, "must be an integer"),
        ("luma_bandwidth_mhz", 0.1, "below 0.5 MHz"),
        ("quality_at_0", 3.0, "must not be better"),
    ],
)
def test_out_of_range_values_are_refused_with_a_reason(field: str, value: float, reason: str) -> None:
    with pytest.raises(ValueError, match=reason) as e:
        CameraModel(**{field: value})  # type: ignore[arg-type]
    assert field in str(e.value)


def test_quality_curve_falls_with_compression_and_matches_the_documented_points() -> None:
    m = AXIS_214.picture
    assert [m.quality(c, 704) for c in (0, 10, 30, 60, 100)] == [98, 97, 89, 67, 17]
    assert [m.quality(c, 352) for c in (0, 10, 30, 60, 100)] == [98, 97, 89, 64, 11]
    assert [m.quality(c, 176) for c in (0, 10, 30, 60, 100)] == [98, 97, 88, 62, 5]
    for w in (704, 352, 176):
        q = [m.quality(c, w) for c in range(0, 101, 5)]
        assert q == sorted(q, reverse=True)
    assert m.quality(-5) == m.quality(0)
    assert m.quality(500) == m.quality(100)


def test_still_camera_frames_differ_in_content_and_size_and_cycle_through_the_pool() -> None:
    m = AXIS_214.picture
    pool = PicturePool(m)
    img = _scene()
    frames = [pool.jpeg("v", lambda: img, 1.0, 30) for _ in range(2 * m.pool_frames)]
    assert len(set(frames[: m.pool_frames])) == m.pool_frames  # every new frame carries new noise
    assert frames[m.pool_frames :] == frames[: m.pool_frames]  # then the pool is cycled
    assert len({len(f) for f in frames}) > 1
    assert pool.encodes == m.pool_frames
    a, b = decode(frames[0]).astype(int), decode(frames[1]).astype(int)
    assert 0.5 < float(np.std(a - b)) < 8.0  # noise of a plausible magnitude, not a different picture


def test_noise_free_model_serves_one_frame_and_softness_lowers_detail() -> None:
    sharp = CameraModel(quality_at_0=90, quality_at_100=90)
    soft = CameraModel(
        quality_at_0=90, quality_at_100=90, luma_bandwidth_mhz=3.0, lens_sigma_wide=1.0, lens_sigma_tele=2.0
    )
    img = _scene(704, 576)
    p = PicturePool(sharp)
    assert p.jpeg("v", lambda: img, 1.0, 0) == p.jpeg("v", lambda: img, 1.0, 0)
    assert p.encodes == 1
    assert len(PicturePool(soft).jpeg("v", lambda: img, 1.0, 0)) < len(p.jpeg("v", lambda: img, 1.0, 0))
    assert soft.sigmas(704, 9999)[0] > soft.sigmas(704, 1)[0]  # the lens is softer at tele (as configured)


def test_render_is_called_once_per_view_and_overlay_is_drawn() -> None:
    calls = []
    img = _scene()

    def render() -> np.ndarray:
        calls.append(1)
        return img

    drawn = []
    pool = PicturePool(AXIS_Q6075.picture)
    for _ in range(3):
        pool.jpeg("v", render, 1.0, 30, "txt", lambda im, t: drawn.append(t))
    assert len(calls) == 1
    assert drawn == ["txt"] * 3


def test_thesis_cells_are_read_as_kilobytes() -> None:
    assert thesis_kbit_s("704x576", 0, 30) == 3440 * 8
    assert thesis_kbit_s("176x144", 100, 1) == pytest.approx(10.4)


def test_memory_stays_bounded_with_a_changing_overlay() -> None:
    pool = PicturePool(AXIS_214.picture, views=2)
    img = _scene()
    for second in range(50):  # a clock overlay: a new text every second on a still camera
        for _ in range(3):
            pool.jpeg("v", lambda: img, 1.0, 30, f"t={second}", lambda im, t: None)
    for v in range(5):
        pool.jpeg(("view", v), lambda: img, 1.0, 30)
    views = pool._views  # noqa: SLF001 - the bound is the point of this test
    assert len(views) == 2
    assert all(len(v.pools) <= 4 for v in views.values())


@pytest.mark.parametrize(("width", "height"), [(704, 576), (352, 288), (176, 144)])
def test_thesis_figure_6_4_bands(width: int, height: int) -> None:
    """Compression up to 30 almost indistinguishable from 0, 60 visibly worse but usable, above 60 not usable
    (the measure: tests/support/picture.py), on the demo world's home view."""
    fig = figure_6_4(AXIS_214.picture, width, height)
    g = fig.grades
    assert fig.up_to_30_like_0, g[30]
    assert g[10].ssim_vs_0 >= g[30].ssim_vs_0  # and 10 closer to 0 than 30
    assert fig.at_60_usable, g[60]
    assert g[60].ssim_vs_0 < g[30].ssim_vs_0  # visibly worse than 30
    assert [g[c].nbytes for c in (0, 10, 30, 60, 80, 100)] == sorted((g[c].nbytes for c in g), reverse=True)
    assert fig.at_100_not_usable, g[100]
    assert fig.holds


def test_unusable_headroom_is_the_best_quality_the_measure_calls_not_usable() -> None:
    """The bench's "Fig. 6.4 and the tables together" row: at 704x576 the largest frame the measure calls not
    usable is at least the smallest compression-100 frame the tables allow (0.5 x 43 kB, the 1-fps cell), and it
    is smaller than compression 60's frame (which the measure calls usable)."""
    head = unusable_headroom(AXIS_214.picture, 704, 576)
    assert 1 <= head.quality < AXIS_214.picture.quality(60, 704)
    assert head.psnr_db < 30.0 or head.ssim < 0.90
    fig = figure_6_4(AXIS_214.picture, 704, 576)
    assert 21_500 <= head.nbytes < fig.grades[60].nbytes
