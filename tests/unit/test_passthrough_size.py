"""The passthrough's size choice (streaming/passthrough_size.py): bits per pixel per picture, shape, hysteresis."""

from __future__ import annotations

import threading

import pytest

from axis_ptz_ros2.sim.persona import MODERN_RESOLUTIONS
from axis_ptz_ros2.streaming.passthrough_size import (
    MIN_BITS_PER_PIXEL,
    PassthroughSize,
    SizeConfig,
    bits_per_pixel,
    candidate_sizes,
    size_for,
)
from axis_ptz_ros2.vapix.models import Resolution

R = Resolution.parse
# the simulated current-Axis persona's list, 16:9 and 4:3 mixed
Q6075 = [Resolution(w, h) for w, h in MODERN_RESOLUTIONS.values()]
HD = R("1920x1080")


def test_bits_per_pixel() -> None:
    assert bits_per_pixel(1000, R("1000x100"), 10) == pytest.approx(1.0)
    assert bits_per_pixel(1866, HD, 30) == pytest.approx(0.03, rel=1e-3)
    with pytest.raises(ValueError, match="fps"):
        bits_per_pixel(1000, HD, 0)


def test_candidates_keep_the_shape_largest_first() -> None:
    sizes = candidate_sizes(Q6075, HD)
    assert sizes[0] == HD
    assert sizes[-1] == R("160x90")
    assert all(abs(s.width * 9 - s.height * 16) <= 16 for s in sizes)  # never 4:3
    assert R("1280x960") not in sizes
    assert R("640x480") not in sizes
    assert candidate_sizes(Q6075, R("1280x720"))[0] == R("1280x720")  # nothing larger than the shape
    assert candidate_sizes(Q6075, R("640x480"))[0] == R("640x480")


@pytest.mark.parametrize(
    ("kbps", "fps", "size"),
    [
        (4000, 30, "1920x1080"),
        (1870, 30, "1920x1080"),  # 0.0301 bit/px
        (1860, 30, "1280x720"),  # 0.0299 at 1080p: the next size down
        (1000, 30, "1280x720"),
        (1000, 15, "1920x1080"),  # half the pictures, twice the bits for each
        (600, 30, "1024x576"),
        (400, 30, "800x450"),
        (220, 30, "640x360"),
        (100, 30, "320x180"),
        (10, 30, "160x90"),  # none has the threshold: the smallest
    ],
)
def test_largest_size_over_the_threshold(kbps: int, fps: int, size: str) -> None:
    got = size_for(Q6075, HD, fps, kbps)
    assert got == R(size)
    if got != R("160x90"):
        assert bits_per_pixel(kbps, got, fps) >= MIN_BITS_PER_PIXEL


def test_monotone_in_bitrate() -> None:
    pixels = [size_for(Q6075, HD, 30, k).width for k in range(50, 5000, 25)]
    assert pixels == sorted(pixels)
    assert pixels[0] == 160
    assert pixels[-1] == 1920


def test_no_listed_size_of_that_shape_keeps_the_request() -> None:
    assert size_for([R("704x576"), R("352x288")], HD, 30, 100) == HD
    assert size_for([], HD, 30, 100) == HD


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="threshold"):
        size_for(Q6075, HD, 30, 1000, threshold=0)
    with pytest.raises(ValueError, match="up_margin"):
        SizeConfig(up_margin=0.9)
    with pytest.raises(ValueError, match="hold"):
        SizeConfig(down_hold_s=-1)


def test_first_choice_is_immediate() -> None:
    p = PassthroughSize()
    assert p.size is None
    assert p.update(0.0, Q6075, HD, 30, 400) == R("800x450")
    assert p.size == R("800x450")
    assert p.changes == 0


def test_down_after_a_lasting_drop_not_a_blip() -> None:
    cfg = SizeConfig(down_hold_s=2.0, up_hold_s=10.0, min_interval_s=10.0)
    p = PassthroughSize(cfg)
    assert p.update(0.0, Q6075, HD, 30, 4000) == HD
    # a blip under the threshold shorter than the hold: no restart
    assert p.update(20.0, Q6075, HD, 30, 600) == HD
    assert p.update(21.5, Q6075, HD, 30, 600) == HD
    assert p.update(21.6, Q6075, HD, 30, 4000) == HD
    assert p.update(22.5, Q6075, HD, 30, 4000) == HD
    assert p.changes == 0
    # a lasting drop: down after the hold, to the size the latest bitrate wants
    assert p.update(30.0, Q6075, HD, 30, 1000) == HD
    assert p.update(31.0, Q6075, HD, 30, 600) == HD
    assert p.update(32.0, Q6075, HD, 30, 600) == R("1024x576")
    assert p.changes == 1


def test_at_most_one_change_per_interval() -> None:
    cfg = SizeConfig(down_hold_s=1.0, up_hold_s=1.0, min_interval_s=10.0)
    p = PassthroughSize(cfg)
    p.update(0.0, Q6075, HD, 30, 4000)
    assert p.update(1.0, Q6075, HD, 30, 1000) == HD  # within 10 s of the first choice
    assert p.update(9.9, Q6075, HD, 30, 1000) == HD
    assert p.update(10.0, Q6075, HD, 30, 1000) == R("1280x720")
    # the bitrate falls further at once: held until 10 s after the last change
    for t in (11.0, 15.0, 19.9):
        assert p.update(t, Q6075, HD, 30, 200) == R("1280x720")
    assert p.update(20.0, Q6075, HD, 30, 200) == R("480x270")
    assert p.changes == 2


def test_up_needs_a_margin_and_a_long_hold() -> None:
    cfg = SizeConfig(up_margin=1.25, down_hold_s=1.0, up_hold_s=10.0, min_interval_s=0.0)
    p = PassthroughSize(cfg)
    assert p.update(0.0, Q6075, HD, 30, 1000) == R("1280x720")
    # 1900 kbit/s gives 1080p 0.0305 bit/px: over the threshold, not over 1.25 x it: stays
    for t in range(1, 30):
        assert p.update(float(t), Q6075, HD, 30, 1900) == R("1280x720")
    # 2400 kbit/s (0.0386 bit/px at 1080p) for 10 s: up
    assert p.update(30.0, Q6075, HD, 30, 2400) == R("1280x720")
    assert p.update(39.9, Q6075, HD, 30, 2400) == R("1280x720")
    assert p.update(40.0, Q6075, HD, 30, 2400) == HD
    # a dip in between restarts the hold
    p2 = PassthroughSize(cfg)
    p2.update(0.0, Q6075, HD, 30, 1000)
    p2.update(1.0, Q6075, HD, 30, 2400)
    p2.update(8.0, Q6075, HD, 30, 1000)
    assert p2.update(12.0, Q6075, HD, 30, 2400) == R("1280x720")
    assert p2.update(21.9, Q6075, HD, 30, 2400) == R("1280x720")
    assert p2.update(22.0, Q6075, HD, 30, 2400) == HD


def test_a_new_request_decides_at_once() -> None:
    p = PassthroughSize(SizeConfig(min_interval_s=60.0))
    assert p.update(0.0, Q6075, HD, 30, 1000) == R("1280x720")
    assert p.update(1.0, Q6075, HD, 10, 1000) == HD  # another frame rate: a new request, no session of it yet
    assert p.update(2.0, Q6075, R("1280x960"), 10, 1000) == R("1280x960")  # another shape (4:3)
    assert p.changes == 0


def test_threads_share_one_choice() -> None:
    p = PassthroughSize(SizeConfig(down_hold_s=0.0, min_interval_s=0.0))
    p.update(0.0, Q6075, HD, 30, 4000)
    got: list[Resolution] = []

    def run(t0: float) -> None:
        for k in range(200):
            got.append(p.update(t0 + k * 0.01, Q6075, HD, 30, 600))

    threads = [threading.Thread(target=run, args=(1.0 + i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert p.size == R("1024x576")
    assert got[-1] == R("1024x576")
    assert p.changes == 1
