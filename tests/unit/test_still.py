"""The still on demand, ROS-free (streaming/still.py) and its bytes in the video controller's budget."""

from __future__ import annotations

import threading

import cv2
import numpy as np
import pytest

from axis_ptz_ros2.streaming import BitrateMeter
from axis_ptz_ros2.streaming.budget import compression_size_factor
from axis_ptz_ros2.streaming.controller import VideoController
from axis_ptz_ros2.streaming.still import BUSY, ExtraBytes, StillOutcome, StillTaker, largest, still_request
from axis_ptz_ros2.streaming.video_types import VideoSettings
from axis_ptz_ros2.vapix.errors import CameraUnreachable
from axis_ptz_ros2.vapix.models import Resolution, VideoParams

pytestmark = pytest.mark.unit

PAL = (Resolution(176, 144), Resolution(704, 576), Resolution(352, 288), Resolution(704, 288))


def jpeg(width: int, height: int) -> bytes:
    ok, buf = cv2.imencode(".jpg", np.full((height, width, 3), 128, np.uint8))
    assert ok
    return buf.tobytes()


class FakeCamera:
    """A camera client double: records requests, answers with a JPEG of the size asked (or ``size``), can block."""

    def __init__(self, size: tuple[int, int] | None = None, fail: Exception | None = None) -> None:
        self.requests: list[VideoParams] = []
        self.listed = 0
        self.closed = 0
        self.size = size
        self.fail = fail
        self.gate = threading.Event()
        self.gate.set()

    def snapshot(self, params: VideoParams) -> bytes:
        self.requests.append(params)
        self.gate.wait(5)
        if self.fail is not None:
            raise self.fail
        w, h = self.size or (params.resolution.width, params.resolution.height)
        return jpeg(w, h)

    def supported_resolutions(self) -> tuple[Resolution, ...]:
        self.listed += 1
        return PAL

    def close(self) -> None:
        self.closed += 1


def test_the_request_is_compression_0_at_the_largest_listed_size():
    assert largest(PAL) == Resolution(704, 576)
    req = still_request(PAL, camera=2)
    assert req.query(include_fps=False) == {"resolution": "704x576", "compression": "0", "camera": "2"}
    with pytest.raises(ValueError, match="lists no resolution"):
        largest(())


def test_take_uses_the_known_list_else_asks_the_camera_and_closes_its_client():
    cam = FakeCamera()
    out = StillTaker(lambda: cam, lambda: (Resolution(352, 288), Resolution(176, 144))).take()
    assert out.still is not None
    assert out.still.resolution == Resolution(352, 288)
    assert cam.listed == 0
    assert cam.closed == 1
    out = StillTaker(lambda: cam, lambda: None).take()
    assert out.still is not None
    assert out.still.resolution == Resolution(704, 576)
    assert cam.listed == 1
    assert [r.compression for r in cam.requests] == [0, 0]


def test_a_jpeg_of_another_size_is_an_error_not_a_still():
    out = StillTaker(lambda: FakeCamera(size=(352, 288)), lambda: PAL).take()
    assert out.still is None
    assert "352x288 for a 704x576 still" in out.error


def test_a_failure_is_worded_without_the_password():
    cam = FakeCamera(fail=CameraUnreachable("GET /x (camera h:80): camera unreachable (s3cret-pw)"))
    out = StillTaker(lambda: cam, lambda: PAL, secrets=("s3cret-pw",)).take()
    assert out.still is None
    assert out.error.startswith("still failed: ")
    assert "unreachable" in out.error
    assert "s3cret-pw" not in out.error
    assert cam.closed == 1


def test_a_second_start_while_one_is_in_flight_is_refused_not_queued():
    cam = FakeCamera()
    cam.gate.clear()
    taker = StillTaker(lambda: cam, lambda: PAL)
    outcomes: list[StillOutcome] = []
    done = threading.Event()
    assert taker.start(lambda o: (outcomes.append(o), done.set())) is None
    assert taker.busy
    assert taker.start(outcomes.append) == BUSY
    cam.gate.set()
    assert done.wait(5)
    assert taker.close(5)
    assert not taker.busy
    assert len(outcomes) == 1
    assert len(cam.requests) == 1


def test_extra_bytes_count_for_one_window():
    extra = ExtraBytes(2.0)
    extra.add(10.0, 250_000)
    assert extra.kbps(10.5) == pytest.approx(1000.0)
    assert extra.kbps(12.1) == 0.0


def live(ctl: VideoController, meter: BitrateMeter, t0: float, seconds: float, still_at: float | None = None) -> list:
    """10 fps of live frames through the frame path (8 kB = 640 kbit/s at the request), a 150 kB still at
    ``still_at``."""
    steps = []
    for i in range(int(round(seconds * 10))):
        t = t0 + i * 0.1
        p = ctl.current  # a camera's frames shrink with the settings: pixels and the compression prior
        pixels = p.resolution.width * p.resolution.height / (704 * 576)
        meter.add(t, int(8000 * pixels * compression_size_factor(p.compression)))
        if still_at is not None and still_at <= t < still_at + 0.1:
            ctl.on_still(t, 150_000)  # 1200 kbit over the 2 s window: 600 kbit/s, capped at half the budget
        step = ctl.on_frame(t)
        if step is not None:
            steps.append((t, step))
            meter.reset()  # the reader reconnects with the new settings: its meter starts again
    return steps


def test_a_still_takes_its_share_of_the_budget_the_live_stream_steps_down_once_and_climbs_back():
    meter = BitrateMeter(2.0)
    settings = VideoSettings(fps=10, resolution="704x576", compression=0, max_bitrate_kbps=1000, adapt_to_link=False)
    ctl = VideoController(settings, meter)
    assert live(ctl, meter, 100.0, 5.0) == [], "640 kbit/s alone is under the budget"
    steps = live(ctl, meter, 105.0, 2.0, still_at=105.0)
    assert steps, "the still's bytes did not count"
    t, step = steps[0]
    assert t - 105.0 <= 0.3  # the next judgement (every 0.25 s)
    assert step.after > step.before
    assert step.rate.bytes_per_frame == pytest.approx(8000), "the still entered the frame-size learning"
    # one step to calibrate the compression prior, then one jump to the level predicted under what is left: no
    # cascade of steps while the still counts, and the frame rate and size are kept (compression does it)
    assert len(steps) <= 2, f"a cascade of steps while the still counted: {[s.after for _, s in steps]}"
    assert ctl.current.fps == 10
    assert ctl.current.resolution == Resolution(704, 576)
    assert ctl.current.compression > 0
    # the still has left the window: the live stream climbs back to the request
    back = live(ctl, meter, 107.0, 8.0)
    assert back
    assert back[-1][1].after == 0
    # without a budget a still changes nothing
    meter2 = BitrateMeter(2.0)
    ctl2 = VideoController(VideoSettings(fps=10, resolution="704x576", compression=0, adapt_to_link=False), meter2)
    assert live(ctl2, meter2, 100.0, 5.0, still_at=102.0) == []


class _Clock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


def _send(ctl: VideoController, clock: _Clock, seconds: float, kbps: float) -> None:
    """``seconds`` of 25 access units/s at ``kbps`` sent (what reports are judged against)."""
    for _i in range(int(seconds * 25)):
        clock.t += 1 / 25
        ctl.on_h264_frame(clock.t, int(kbps * 1000 / 8 / 25))


def test_h264_a_still_gets_most_of_the_link_while_it_crosses_and_its_queue_is_not_congestion():
    """h264 mode: a 245 kB still on a link whose budget is 2000 kbit/s: the encoder's target drops to
    STILL_H264_VIDEO_SHARE of the budget until the still has crossed (the node says so once every reader has
    acknowledged it), reports covering that time are not judged (a delay that would cut the budget changes nothing),
    and afterwards the target is back."""
    from axis_ptz_ros2.media.h264_settings import H264Settings
    from axis_ptz_ros2.streaming.feedback import FeedbackReport
    from axis_ptz_ros2.streaming.still import STILL_H264_VIDEO_SHARE

    clock = _Clock()
    settings = VideoSettings(
        codec="h264", fps=25, resolution="704x576", h264=H264Settings(bitrate_kbps=1000, max_bitrate_kbps=1500)
    )
    ctl = VideoController(settings, BitrateMeter(2.0), clock=clock)
    ctl.set_h264_possible(True)
    _send(ctl, clock, 3.0, 1000.0)
    clear = FeedbackReport("/op", 50, 25.0, 1000.0, 0.03, 0.01, 0.04, 2.0)
    while ctl.h264_settings().bitrate_kbps < 1500:  # a clear link: the budget climbs, the target to the ceiling
        ctl.feedback(clear, lambda _c: True)
        _send(ctl, clock, 0.5, 0.9 * ctl.h264_settings().bitrate_kbps)
        assert clock.t < 1100.0, "the budget never climbed"
    budget = ctl.state().link_budget_kbps
    assert budget > 1600
    ctl.on_still(clock.t, 245_000)
    target = ctl.h264_settings().bitrate_kbps
    assert target == int(STILL_H264_VIDEO_SHARE * budget)
    queued = FeedbackReport("/op", 50, 25.0, 900.0, 0.7, 0.01, 0.04, 2.0)  # a 690 ms queue: congestion by itself
    assert ctl.feedback(queued, lambda _c: True) is None  # not judged: the still's own queue
    assert ctl.state().link_budget_kbps == budget
    _send(ctl, clock, 3.0, target)  # past its bits over the room left (1.1 s): crossing until acknowledged
    assert ctl.h264_settings().bitrate_kbps == target
    ctl.still_crossed(clock.t)
    assert ctl.h264_settings().bitrate_kbps == 1500  # crossed: the target is back
    _send(ctl, clock, 0.2, 1500.0)
    assert ctl.feedback(queued, lambda _c: True) is None  # a report whose window still covers the crossing
    _send(ctl, clock, 2.6, 1500.0)
    j = ctl.feedback(queued, lambda _c: True)  # past it: the same queue is congestion again
    assert j is not None
    assert j.decision.state == "congested"


def test_mjpeg_a_still_does_not_cap_or_hide_anything_of_h264():
    """MJPEG mode keeps its own reservation (the ladder); the H.264 window is not opened."""
    clock = _Clock()
    ctl = VideoController(VideoSettings(fps=10, resolution="704x576"), BitrateMeter(2.0), clock=clock)
    before = ctl.h264_settings().bitrate_kbps
    ctl.on_still(clock.t, 245_000)
    assert ctl.h264_settings().bitrate_kbps == before


def test_h264_a_still_reported_crossed_holds_the_cap_until_then_not_by_an_estimate():
    """The cap lasts until the node says every reader acknowledged the still (a 245 kB still took 1.8-5.0 s on
    2 Mbit/s + 2 % where 1.85 s was estimated from its size), at most STILL_CROSSING_MAX_S."""
    from axis_ptz_ros2.media.h264_settings import H264Settings
    from axis_ptz_ros2.media.limits import BITRATE_RANGE_KBPS
    from axis_ptz_ros2.streaming.still import STILL_CROSSING_MAX_S, STILL_H264_VIDEO_SHARE, StillWindow

    clock = _Clock()
    settings = VideoSettings(codec="h264", fps=25, resolution="704x576", h264=H264Settings(bitrate_kbps=1000))
    ctl = VideoController(settings, BitrateMeter(2.0), clock=clock)
    ctl.set_h264_possible(True)
    ctl.on_still(clock.t, 245_000)
    capped = ctl.h264_settings().bitrate_kbps
    # of h264_bitrate_kbps without feedback, never under the parameters' lowest bitrate
    assert capped == max(BITRATE_RANGE_KBPS[0], int(STILL_H264_VIDEO_SHARE * 1000))
    assert 0 < capped < 1000
    clock.t += 4.5  # past its 1960 kbit over the rest of 1000 kbit/s (2.2 s), not yet acknowledged
    assert ctl.h264_settings().bitrate_kbps == capped
    ctl.still_crossed(clock.t)
    assert ctl.h264_settings().bitrate_kbps == 1000
    w = StillWindow()
    w.start(0.0, 1000.0)
    assert w.cap(STILL_CROSSING_MAX_S - 0.01, 1000) == capped
    assert w.cap(STILL_CROSSING_MAX_S, 1000) == 1000  # never acknowledged: the longest wait ends it
    with pytest.raises(ValueError, match="reference_kbps"):
        w.start(0.0, 0.0)
