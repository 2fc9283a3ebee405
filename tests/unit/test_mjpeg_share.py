"""The MJPEG share of an H.264 stream's budget (streaming/mjpeg_share.py) and the ladder's predicted start
(BandwidthController.fit_from), ROS-free."""

from __future__ import annotations

from axis_ptz_ros2.streaming.budget import AXIS214_PAL_RESOLUTIONS, BandwidthController
from axis_ptz_ros2.streaming.mjpeg_share import MJPEG_SHARE, SHARE_MIN_FPS, MjpegShare, split_kbps
from axis_ptz_ros2.vapix.models import Resolution, VideoParams

PAL = Resolution(704, 576)
C0 = VideoParams(PAL, 30, 0)  # the transcoder's input
C0_BYTES = 245_000  # the simulated 214's compression-0 704x576 JPEG of its home view


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def share(total: float = 1000.0, clock: Clock | None = None) -> MjpegShare:
    return MjpegShare(VideoParams(PAL, 30, 30), lambda: total, clock=clock or Clock())


def test_split_gives_the_share_only_while_it_runs() -> None:
    assert split_kbps(1000, False) == (1000, 0)
    h264, mjpeg = split_kbps(1000, True)
    assert (h264, mjpeg) == (1000 - round(1000 * MJPEG_SHARE), round(1000 * MJPEG_SHARE))


def test_the_first_level_is_predicted_under_the_share_from_the_compression0_stream() -> None:
    s = share()
    s.active = True
    p = s.start(C0, C0_BYTES)
    assert s.budget_kbps == 1000 * MJPEG_SHARE
    # never the request (704x576 at compression 30 would be ~20 Mbit/s): a smaller size at a low rate
    assert p.resolution == Resolution(176, 144)
    assert p.fps <= SHARE_MIN_FPS
    assert p.compression >= 30


def test_without_a_measurement_it_starts_at_the_bottom() -> None:
    s = share()
    s.active = True
    p = s.start(C0, 0.0)
    assert p == s._ladder.ladder[-1]  # noqa: SLF001
    assert (p.resolution, p.fps) == (Resolution(176, 144), 1)


def test_fit_from_without_a_budget_is_the_request() -> None:
    b = BandwidthController(VideoParams(PAL, 25, 30), 0.0, AXIS214_PAL_RESOLUTIONS)
    assert b.fit_from(C0, C0_BYTES, 1.0) == VideoParams(PAL, 25, 30)


def test_fit_from_takes_the_first_level_predicted_under_the_budget() -> None:
    b = BandwidthController(VideoParams(PAL, 25, 0), 20_000.0, AXIS214_PAL_RESOLUTIONS)
    # 245 kB at 25 fps is 49 Mbit/s; 20 Mbit/s * 0.9 leaves room for about 10 compression-0 pictures a second
    p = b.fit_from(C0, C0_BYTES, 1.0)
    assert p.resolution == PAL
    assert C0_BYTES * 0.5 * p.fps * 8 / 1000 <= 18_000  # (compression 60's prior is about half the bytes)
    assert p.fps >= 10


def test_the_ladder_steps_down_when_the_stream_measures_over_its_share() -> None:
    clock = Clock()
    s = share(clock=clock)
    s.active = True
    start = s.start(C0, C0_BYTES)
    level = s._ladder.level  # noqa: SLF001
    # the stream measures 3x its share: 30 kB pictures at 4/s (960 kbit/s against 300)
    for k in range(20):
        clock.t += 0.25
        s.meter.add(clock.t, 30_000)
        stepped = s.on_frame(clock.t + 0.001 * k)
        if stepped is not None:
            break
    assert stepped is not None, start
    assert s._ladder.level > level, (start, stepped)  # noqa: SLF001


def test_a_new_request_while_the_stream_runs_starts_under_the_share_from_its_own_pictures() -> None:
    clock = Clock()
    s = share(clock=clock)
    s.active = True
    before = s.start(C0, C0_BYTES)
    for _ in range(8):  # the running stream measures its own pictures: 4 kB each at its rate
        clock.t += 1.0 / before.fps
        s.meter.add(clock.t, 4_000)
    s.configure(VideoParams(PAL, 25, 10), None, 60)
    p = s.current
    # never the request as asked (704x576 at compression 10 is megabits a second): under the 300 kbit/s share
    assert p != VideoParams(PAL, 25, 10)
    assert p.resolution == Resolution(176, 144), p
    assert 4_000 * p.fps * 8 / 1000 <= 1000 * MJPEG_SHARE, p


def test_a_new_request_while_the_stream_is_off_is_the_ladder_from_its_top() -> None:
    s = share()
    s.configure(VideoParams(Resolution(352, 288), 10, 30), None, 60)
    assert s.current == VideoParams(Resolution(352, 288), 10, 30)
