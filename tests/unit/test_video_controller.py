"""The video controller (streaming/controller.py): the one owner of the video parameters in effect. ROS-free."""

from __future__ import annotations

import math
import queue
import threading
from dataclasses import replace

import pytest

from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.streaming import BitrateMeter, ReaderConfig, StreamReader
from axis_ptz_ros2.streaming.adapter_config import h264_adapter_config
from axis_ptz_ros2.streaming.controller import BUDGET_ANNOUNCE_SLACK, VideoController
from axis_ptz_ros2.streaming.feedback import Decision, FeedbackReport, LinkAdapter
from axis_ptz_ros2.streaming.video_request import AUTO_PLACEHOLDER, VIDEO_FIELDS, requested_changes
from axis_ptz_ros2.streaming.video_types import VideoSettings
from axis_ptz_ros2.vapix.mjpeg import MjpegStats
from axis_ptz_ros2.vapix.models import Resolution, VideoParams
from tests.support.waiting import wait_until

pytestmark = pytest.mark.unit

HD = (Resolution(1920, 1080), Resolution(1280, 720), Resolution(640, 360))


class Clock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


#: H.264 with the ceiling at the start (no raising with feedback)
AT_START = H264Settings(bitrate_kbps=1000, max_bitrate_kbps=1000)


def make(settings: VideoSettings | None = None, **kw) -> tuple[VideoController, BitrateMeter, Clock, list[str]]:
    clock = Clock()
    meter = BitrateMeter(2.0)
    seen: list[str] = []
    holder: list[VideoController] = []
    ctl = VideoController(
        settings or VideoSettings(**kw), meter, on_change=lambda: seen.append(holder[0].state().source), clock=clock
    )
    holder.append(ctl)
    return ctl, meter, clock, seen


def feed(meter: BitrateMeter, t0: float, seconds: float, fps: float, nbytes: int) -> float:
    """Frames of ``nbytes`` at ``fps`` from ``t0``; returns the time of the last one."""
    n = int(seconds * fps)
    for i in range(n):
        meter.add(t0 + i / fps, nbytes)
    return t0 + (n - 1) / fps


def judged(consumer: str = "/op", frames: int = 15, kbps: float = 1000.0, queue_s: float = 0.0, gap: float = 0.01):
    return FeedbackReport(consumer, frames, frames / 1.0, kbps, 100.0 + queue_s, 100.0, gap, 1.0)


# -- what is asked for ----------------------------------------------------------------------------------------
def test_startup_request_and_refusal():
    ctl, _m, _c, seen = make(fps=10, compression=20, resolution="352x288")
    assert ctl.current == VideoParams(Resolution(352, 288), 10, 20)
    st = ctl.state()
    assert (st.source, st.level, st.budget_kbps, st.link_state) == ("startup", 0, 0.0, "off")
    assert seen == []
    with pytest.raises(ValueError, match="fps 0 outside 1..30"):
        make(fps=0)
    with pytest.raises(ValueError, match="resolution"):
        make(resolution="huge")


def test_check_refuses_with_the_reason_and_only_when_the_request_is_touched():
    ctl, *_ = make()
    assert ctl.check(replace(ctl.settings, fps=31), {"fps"}) == "fps 31 outside 1..30"
    assert "compression" in (ctl.check(replace(ctl.settings, compression=101), {"compression"}) or "")
    assert ctl.check(replace(ctl.settings, resolution="1920x1080"), {"resolution"}) is None  # list unknown yet
    ctl.learn_resolutions(HD)
    reason = ctl.check(replace(ctl.settings, resolution="704x576"), {"resolution"})
    assert reason is not None
    assert "1920x1080" in reason, "the camera's own list, once known"
    assert ctl.check(replace(ctl.settings, resolution="704x576"), {"adapt_to_link"}) is None


def test_apply_moves_the_one_value_in_effect_and_announces_it():
    ctl, _m, _c, seen = make()
    before = ctl.current
    ctl.apply(replace(ctl.settings, fps=7), {"fps"}, "service")
    assert ctl.current == replace(before, fps=7)
    assert ctl.state().params.fps == 7
    assert seen == ["service"]
    ctl.apply(replace(ctl.settings, link_release=10.0), {"link_release"})
    assert seen == ["service"], "link settings do not change what is streamed"
    assert ctl.state().source == "service"


def test_auto_resolution_follows_the_cameras_list_once():
    ctl, _m, _c, seen = make(resolution="")
    assert ctl.current.resolution == AUTO_PLACEHOLDER
    assert not ctl.resolutions_known
    ctl.learn_resolutions(())  # the camera could not say: nothing changes
    assert not ctl.resolutions_known
    assert seen == []
    ctl.learn_resolutions(HD)
    assert ctl.current.resolution == Resolution(1920, 1080)
    assert ctl.state().resolutions == tuple(reversed(HD)), "advertised smallest first"
    assert seen == ["startup"], "announced, the cause of the parameters unchanged"
    ctl.learn_resolutions((Resolution(176, 144),))
    assert ctl.current.resolution == Resolution(1920, 1080)
    assert len(seen) == 1, "learned once"


# -- the budget -----------------------------------------------------------------------------------------------
def test_budget_steps_down_on_the_frame_path():
    ctl, meter, clock, seen = make(fps=30, compression=0, resolution="704x576", max_bitrate_kbps=1000)
    t = feed(meter, clock.t, 1.5, 30, 20_000)  # 4800 kbit/s
    clock.t = t
    assert ctl.on_frame(t) is None, "the budget settles 0.8 s after its first judgement"
    step = None
    for i in range(1, 10):
        step = ctl.on_frame(t + 0.3 * i)
        if step is not None:
            break
    assert step is not None
    assert step.after > step.before == 0
    assert ctl.current == step.params
    assert ctl.current != VideoParams(Resolution(704, 576), 30, 0)
    assert seen == ["bandwidth_budget"]
    assert "level 0 ->" in str(step)


def test_the_frame_path_measures_at_most_every_quarter_second():
    class CountingMeter(BitrateMeter):
        calls = 0

        def rate(self, now: float):
            CountingMeter.calls += 1
            return super().rate(now)

    meter = CountingMeter(2.0)
    ctl = VideoController(VideoSettings(max_bitrate_kbps=1000), meter)
    for i in range(100):  # 100 frames over 1 s
        ctl.on_frame(10.0 + i * 0.01)
    assert CountingMeter.calls == 4


def test_a_set_restarts_the_ladder_from_the_request():
    ctl, meter, clock, _seen = make(fps=30, compression=0, resolution="704x576", max_bitrate_kbps=1000)
    t = feed(meter, clock.t, 1.5, 30, 20_000)
    ctl.on_frame(t)
    for i in range(1, 10):
        if ctl.on_frame(t + 0.3 * i):
            break
    assert ctl.state().level > 0
    ctl.apply(ctl.settings, {"fps"})  # set to the value it had
    assert ctl.state().level == 0
    assert ctl.current == VideoParams(Resolution(704, 576), 30, 0)


def test_no_budget_no_measuring():
    ctl, meter, clock, seen = make()
    t = feed(meter, clock.t, 1.5, 30, 50_000)
    assert all(ctl.on_frame(t + 0.3 * i) is None for i in range(10))
    assert ctl.state().level == 0
    assert seen == []


# -- the link -------------------------------------------------------------------------------------------------
def test_feedback_sets_a_link_budget_the_tighter_one_wins_and_release_lets_go():
    ctl, meter, clock, _seen = make(fps=30, compression=0, resolution="704x576", max_bitrate_kbps=5000)
    clock.t = feed(meter, clock.t, 2.0, 30, 10_000)  # 2400 kbit/s sent
    j = ctl.feedback(judged(kbps=1500.0, queue_s=0.4), lambda _c: True)
    assert j is not None
    assert j.decision.state == "congested"
    st = ctl.state()
    assert st.link_state == "congested"
    assert st.link_budget_kbps == pytest.approx(0.8 * 1500.0)
    assert st.budget_kbps == pytest.approx(0.8 * 1500.0), "tighter than the hand-set 5000"
    assert "congested" in str(j)
    assert not math.isnan(st.link_queue_delay_s)
    clock.t += 31.0  # link_release 30 s without a report
    ctl.tick()
    st = ctl.state()
    assert st.link_budget_kbps == 0.0
    assert st.budget_kbps == 5000.0, "back to the hand budget"


def test_feedback_that_says_nothing_about_the_link_is_not_judged():
    ctl, meter, clock, _seen = make(fps=30, resolution="704x576")
    clock.t = feed(meter, clock.t, 2.0, 30, 10_000)
    asked: list[str] = []

    def subscribed(name: str) -> bool:
        asked.append(name)
        return False

    assert ctl.feedback(judged("/late", frames=0, kbps=0.0, gap=5.0), subscribed) is None
    assert asked == ["/late"], "nothing received by a consumer not yet discovered here"
    assert ctl.feedback(judged(), subscribed) is not None
    assert asked == ["/late"], "asked only about empty reports"
    meter.reset()
    meter.add(clock.t, 10_000)
    meter.add(clock.t + 0.1, 10_000)
    assert ctl.feedback(judged(frames=0, kbps=0.0, gap=5.0), lambda _c: True) is None, "the stream only restarted"


def test_a_report_whose_window_holds_a_switch_waits():
    ctl, meter, clock, _seen = make(fps=30, compression=0, resolution="704x576", max_bitrate_kbps=1000)
    t = feed(meter, clock.t, 1.5, 30, 20_000)
    ctl.on_frame(t)
    for i in range(1, 10):
        if ctl.on_frame(t + 0.3 * i):
            clock.t = t + 0.3 * i
            break
    assert ctl.state().level > 0
    clock.t += 1.0  # window 1 s + settle 0.5 s not yet over
    assert ctl.feedback(judged(queue_s=0.4), lambda _c: True) is None
    clock.t += 0.6
    assert ctl.feedback(judged(queue_s=0.4), lambda _c: True) is not None


def test_reports_that_straddle_a_step_of_this_hosts_clock_are_not_judged():
    """This host's wall clock steps (chrony): the frames' stamps jump with it, so the consumers' delays do, against a
    smallest delay from before the step (their 10 s base window): a step back by 0.4 s reads as a 0.4 s queue. Such
    reports are not judged until the base window and the report's own have passed (the link is alive: no silence);
    then they are again."""
    ctl, meter, clock, _seen = make(fps=30, compression=0, resolution="704x576", max_bitrate_kbps=5000)
    clock.t = feed(meter, clock.t, 2.0, 30, 10_000)
    ctl.host_clock_stepped()
    for _ in range(22):  # 11 s of reports twice a second
        clock.t += 0.5
        feed(meter, clock.t - 0.5, 0.5, 30, 10_000)
        assert ctl.feedback(judged(kbps=1500.0, queue_s=0.4), lambda _c: True) is None
    assert ctl.state().link_budget_kbps == 0.0
    clock.t += 0.6  # base window 10 s + the report's 1 s + settle 0.5 s after the step
    feed(meter, clock.t - 0.6, 0.6, 30, 10_000)
    j = ctl.feedback(judged(kbps=1500.0, queue_s=0.4), lambda _c: True)
    assert j is not None
    assert j.decision.state == "congested"


def test_adaptation_off_ignores_feedback():
    ctl, meter, clock, _seen = make(adapt_to_link=False)
    clock.t = feed(meter, clock.t, 2.0, 30, 10_000)
    assert ctl.feedback(judged(queue_s=0.5), lambda _c: True) is None
    assert ctl.state().link_state == "off"
    ctl.apply(replace(ctl.settings, adapt_to_link=True), {"adapt_to_link"})
    assert ctl.feedback(judged(queue_s=0.5), lambda _c: True) is not None


def _send_h264(ctl: VideoController, clock: Clock, seconds: float, kbps: float) -> None:
    """``seconds`` of 30 access units/s at ``kbps`` sent (h264 mode: what reports are judged against)."""
    for _i in range(int(seconds * 30)):
        clock.t += 1 / 30
        ctl.on_h264_frame(clock.t, int(kbps * 1000 / 8 / 30))


def test_h264_mode_advertises_the_budget_in_force_and_announces_when_it_moves():
    """In h264 mode the ladder stands still and the budget drives the encoder's bitrate; what is advertised
    (``video/params``' ``max_bitrate_kbps``) is still the budget in force, the tighter of ``max_bitrate_kbps`` and
    the link's, announced when the link moves it (as a ladder step is in MJPEG), not on every report."""
    ctl, _meter, clock, seen = make(codec="h264", fps=30, resolution="704x576", max_bitrate_kbps=5000, h264=AT_START)
    assert ctl.state().budget_kbps == 5000.0, "the hand-set budget caps the encoder"
    _send_h264(ctl, clock, 4.0, 1500.0)
    for _i in range(4):  # a link that carries what is sent: no budget of the link's (ceiling = start), nothing new
        ctl.feedback(FeedbackReport("/op", 60, 30.0, 1500.0, 0.02, 0.01, 0.04, 2.0), lambda _c: True)
        _send_h264(ctl, clock, 0.5, 1500.0)
    assert ctl.state().budget_kbps == 5000.0
    assert seen == []
    # a third of the access units arrive: the link's budget, under what arrived, is the one in force
    congested = FeedbackReport("/op", 20, 10.0, 500.0, 0.02, 0.01, 0.1, 2.0)
    j = ctl.feedback(congested, lambda _c: True)
    assert j is not None
    assert j.decision.state == "congested"
    st = ctl.state()
    assert 0 < st.budget_kbps <= 500
    assert st.budget_kbps == st.link_budget_kbps
    assert ctl.h264_settings().bitrate_kbps <= st.budget_kbps
    assert (st.level, ctl.current.compression) == (0, 0), "the ladder stands still"
    assert seen == ["bandwidth_budget"]
    for _i in range(3):  # the same report again within the decrease hold: the budget stays, nothing announced
        _send_h264(ctl, clock, 0.3, 500.0)
        ctl.feedback(congested, lambda _c: True)
    assert ctl.state().budget_kbps == st.budget_kbps
    assert seen == ["bandwidth_budget"]
    clock.t += 31.0  # link_release 30 s without a report: back to the hand-set budget, announced
    ctl.tick()
    assert ctl.state().budget_kbps == 5000.0
    assert len(seen) == 2


def test_h264_adaptation_switched_off_announces_the_hand_set_budget_again():
    ctl, _meter, clock, seen = make(codec="h264", fps=30, resolution="704x576", max_bitrate_kbps=5000, h264=AT_START)
    _send_h264(ctl, clock, 4.0, 1500.0)
    assert ctl.feedback(FeedbackReport("/op", 20, 10.0, 500.0, 0.02, 0.01, 0.1, 2.0), lambda _c: True) is not None
    assert ctl.state().budget_kbps <= 500
    assert seen == ["bandwidth_budget"]
    ctl.apply(replace(ctl.settings, adapt_to_link=False), {"adapt_to_link"})
    assert ctl.state().budget_kbps == 5000.0
    assert len(seen) == 2, "the link's budget is gone: what is in force is announced"


def test_h264_budget_changes_are_announced_only_when_material():
    """A change of the budget in force under BUDGET_ANNOUNCE_SLACK of the one last announced is not announced
    (the state, and so diagnostics, still read it); one past it, or on or off, is."""

    class ScriptedLink(LinkAdapter):  # the budget the test says: the rule under test is the controller's
        next_kbps = 0.0

        def report(self, now, report, *_args, **_kw):
            self._budget = self.next_kbps
            return Decision(self._budget, "steady", 0.0, 1.0)

    ctl, _meter, clock, seen = make(codec="h264", fps=30, resolution="704x576")
    link = ScriptedLink(h264_adapter_config())
    ctl._link = link
    report = FeedbackReport("/op", 60, 30.0, 1000.0, 0.02, 0.01, 0.04, 2.0)
    announced = []
    for kbps in (1000.0, 1050.0, 1000.0 * (1 + BUDGET_ANNOUNCE_SLACK) - 1, 1200.0, 1100.0, 1350.0, 0.0, 0.0):
        _send_h264(ctl, clock, 0.5, 1000.0)
        link.next_kbps = kbps
        n = len(seen)
        assert ctl.feedback(report, lambda _c: True) is not None
        assert ctl.state().budget_kbps == kbps
        if len(seen) > n:
            announced.append(kbps)
    assert announced == [1000.0, 1200.0, 1350.0, 0.0]
    assert set(seen) == {"bandwidth_budget"}


def test_settings_fields_are_the_video_parameters():
    assert {f for f in VideoSettings.__dataclass_fields__} > VIDEO_FIELDS


# -- the reader follows the one owner ---------------------------------------------------------------------------
class _Source:
    def __init__(self) -> None:
        self.closed = threading.Event()
        self.stats = MjpegStats()

    def __iter__(self):
        while not self.closed.wait(0.02):
            yield b"\xff\xd8\xff\xd9"

    def close(self) -> None:
        self.closed.set()


def test_the_reader_streams_what_the_controller_says_without_a_copy():
    meter = BitrateMeter(2.0)
    opened: queue.Queue[VideoParams] = queue.Queue()
    holder: list[StreamReader] = []
    ctl = VideoController(VideoSettings(fps=10, resolution="352x288"), meter, on_change=lambda: holder[0].refresh())

    def opener(params: VideoParams, _timeout: float) -> _Source:
        opened.put(params)
        return _Source()

    reader = StreamReader(opener, lambda _j, _t: None, lambda: ctl.current, ReaderConfig(), meter=meter)
    holder.append(reader)
    reader.start()
    try:
        assert opened.get(timeout=2).fps == 10
        ctl.apply(replace(ctl.settings, fps=5), {"fps"})
        assert reader.params.fps == 5
        assert opened.get(timeout=2).fps == 5, "reconnected with the controller's value"
        wait_until(lambda: reader.stats().state.value == "streaming", 2.0, scaled=False, raises=False)
        assert reader.stats().params.fps == 5
        with pytest.raises(TypeError):
            reader.set_params(VideoParams(Resolution(176, 144), 1, 0))
    finally:
        assert reader.stop(2.0)


def test_a_video_set_params_request_changes_only_what_it_names():
    assert requested_changes(0, "", -1) == {}
    assert requested_changes(5, "", -1) == {"fps": 5}
    assert requested_changes(0, "352x288", 0) == {"resolution": "352x288", "compression": 0}
    assert requested_changes(30, "CIF", 100) == {"fps": 30, "resolution": "CIF", "compression": 100}
    assert requested_changes(0, "", -1, 0, 0) == {}
    assert requested_changes(0, "", -1, 700, 0) == {"h264_bitrate_kbps": 700}
    assert requested_changes(0, "", -1, 700, 1000) == {"h264_bitrate_kbps": 700, "h264_max_bitrate_kbps": 1000}
