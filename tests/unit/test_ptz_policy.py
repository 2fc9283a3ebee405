"""The PTZ node's policy, ROS-free: the state loop (schedule, self-restart, limits refresh), health, request
checks and clamps, following orders (arrival, cancel, pre-emption), drive-safe cap, ptz/move goals."""

from __future__ import annotations

import math
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest

from axis_ptz_ros2.geometry import PtzKinematics
from axis_ptz_ros2.ptz.backend import PtzBackendError, PtzLimitsRos, PtzReading
from axis_ptz_ros2.ptz.command_slot import CommandSlot, SlotStats
from axis_ptz_ros2.ptz.commander import Commander
from axis_ptz_ros2.ptz.control import JointOffsets, area_zoom_command, clamp_zoom, pixel_center_target
from axis_ptz_ros2.ptz.drive_safe import DriveSafeCap, DriveSafeConfig, DriveSafeZoom
from axis_ptz_ros2.ptz.goals import Follower, GoalBook, GoalStatus
from axis_ptz_ros2.ptz.health import (
    DIAG_ERROR,
    DIAG_OK,
    DIAG_STALE,
    DIAG_WARN,
    diagnostic_values,
    judge,
    stale_after,
    state_age,
)
from axis_ptz_ros2.ptz.orders import CommanderStats, Tolerances
from axis_ptz_ros2.ptz.requests import GoalKind, MoveGoal, Requests
from axis_ptz_ros2.ptz.state import PollStats, StatePoller, StateSample
from axis_ptz_ros2.ptz.state_loop import LIMITS_REFRESH_POLLS, StateLoop
from axis_ptz_ros2.transforms import Transform
from tests.support.models import AXIS_214_ZOOM
from tests.unit.test_ptz_core import LIM, FakeClock, MemoryHead, RosFreeWait, _done

pytestmark = pytest.mark.unit

ZOOM = AXIS_214_ZOOM
HEAD = PtzKinematics(h_tilt=0.0687)


# ------------------------------------------------------------------------------------------------------
# state loop
# ------------------------------------------------------------------------------------------------------
class CountingHead(MemoryHead):
    """A memory head that counts limit reads and can fail its state reads."""

    def __init__(self) -> None:
        super().__init__()
        self.limit_reads = 0
        self.read_fails = False

    def limits(self) -> PtzLimitsRos:
        self.limit_reads += 1
        return LIM

    def read_state(self) -> PtzReading:
        if self.read_fails:
            raise PtzBackendError("connection refused")
        return super().read_state()


def test_state_loop_tick_refreshes_limits_now_and_then_and_after_failures() -> None:
    head = CountingHead()
    poller = StatePoller(head.read_state, 0.05, clock=FakeClock())
    got: list[StateSample] = []
    before: list[int] = []
    loop = StateLoop(poller, head.limits, got.append, before_poll=lambda: before.append(1))
    assert head.limit_reads == 1  # read once at construction
    assert loop.head_limits == LIM
    loop.tick()
    assert len(got) == 1
    assert got[0].seq == 1
    assert head.limit_reads == 2  # the first successful poll (ok % 100 == 1)
    for _ in range(LIMITS_REFRESH_POLLS - 1):
        loop.tick()
    assert head.limit_reads == 2  # polls 2..100: no re-read
    loop.tick()
    assert head.limit_reads == 3  # poll 101
    assert len(before) == LIMITS_REFRESH_POLLS + 1 == len(got)
    head.read_fails = True
    loop.tick()
    assert head.limit_reads == 4  # a failed poll: limits retried
    assert len(got) == LIMITS_REFRESH_POLLS + 1  # nothing handed over


def test_state_loop_keeps_the_old_limits_when_the_camera_cannot_say() -> None:
    head = CountingHead()
    poller = StatePoller(head.read_state, 0.05, clock=FakeClock())
    reads = {"n": 0}

    def limits() -> PtzLimitsRos:
        reads["n"] += 1
        if reads["n"] > 1:
            raise PtzBackendError("HTTP 503")
        return LIM

    loop = StateLoop(poller, limits, lambda _s: None)
    head.read_fails = True
    loop.tick()
    assert reads["n"] == 2
    assert loop.head_limits == LIM


def test_state_loop_paces_itself_and_restarts_after_a_bug() -> None:
    head = CountingHead()
    poller = StatePoller(head.read_state, 0.02)
    got: list[StateSample] = []
    crashes: list[str] = []
    bugs = {"n": 0}

    def on_sample(s: StateSample) -> None:
        if bugs["n"] < 2:
            bugs["n"] += 1
            raise RuntimeError("injected bug")
        got.append(s)

    loop = StateLoop(poller, head.limits, on_sample, on_crash=crashes.append)
    loop.start()
    try:
        RosFreeWait.until(lambda: len(got) >= 5, 5.0)
        assert loop.restarts == 2
        assert crashes == ["RuntimeError: injected bug"] * 2
        assert loop.last_crash == "RuntimeError: injected bug"
        assert loop.alive
        n0, t0 = len(got), time.monotonic()
        time.sleep(0.5)  # a measuring window: the thing under test is the tick rate over it
        rate = (len(got) - n0) / (time.monotonic() - t0)
        assert 10.0 < rate <= 60.0  # 50 Hz nominal: paced (no busy loop), not stalled (loaded machine: loose)
    finally:
        loop.stop(2.0)
    assert not loop.alive
    n = len(got)
    time.sleep(0.1)  # five periods in which a (wrong) tick could come: the thing under test is that none does
    assert len(got) == n  # stopped means stopped


def test_state_loop_does_not_burst_after_a_slow_tick() -> None:
    head = CountingHead()
    poller = StatePoller(head.read_state, 0.02)
    stamps: list[float] = []
    slow = threading.Event()

    def on_sample(_s: StateSample) -> None:
        stamps.append(time.monotonic())
        if len(stamps) == 3:
            slow.set()
            time.sleep(0.3)  # a slow callback, fifteen periods late: the thing under test is what follows it

    loop = StateLoop(poller, head.limits, on_sample)
    loop.start()
    try:
        RosFreeWait.until(lambda: len(stamps) >= 8, 5.0)
    finally:
        loop.stop(2.0)
    gaps = [b - a for a, b in zip(stamps[3:8], stamps[4:8], strict=False)]
    assert min(gaps) > 0.01  # no catch-up burst of back-to-back polls


def test_state_loop_stop_ends_the_wait_between_ticks_at_once() -> None:
    head = CountingHead()
    poller = StatePoller(head.read_state, 30.0)  # a tick every 30 s: the thread waits between them
    got: list[StateSample] = []
    loop = StateLoop(poller, head.limits, got.append)
    loop.start()
    RosFreeWait.until(lambda: len(got) == 1, 5.0)

    def in_its_wait() -> bool:  # the loop thread has reached its 30 s wait between ticks
        assert loop._thread is not None  # noqa: SLF001 - which frame the thread is in is the point
        frame = sys._current_frames().get(loop._thread.ident or 0)  # noqa: SLF001
        return frame is not None and frame.f_code.co_name == "_sleep"

    RosFreeWait.until(in_its_wait, 5.0)
    t0 = time.monotonic()
    loop.stop(5.0)
    assert not loop.alive
    assert time.monotonic() - t0 < 1.0
    loop.stop(1.0)  # stopping twice is harmless
    assert not loop.ensure_running()
    assert len(got) == 1


def test_state_loop_ends_quietly_on_shutdown_and_ensure_running_restarts_a_dead_thread() -> None:
    head = CountingHead()
    poller = StatePoller(head.read_state, 0.01)
    running = {"ok": True}
    crashes: list[str] = []

    def on_sample(_s: StateSample) -> None:
        running["ok"] = False
        raise RuntimeError("during shutdown")

    loop = StateLoop(poller, head.limits, on_sample, on_crash=crashes.append, keep_running=lambda: running["ok"])
    loop.start()
    RosFreeWait.until(lambda: not loop.alive, 5.0)
    assert crashes == []  # the owner is shutting down: not a crash
    assert loop.restarts == 0
    running["ok"] = True
    loop._on_sample = lambda _s: None  # noqa: SLF001 - the bug is gone
    assert loop.ensure_running()
    assert loop.restarts == 1
    assert loop.last_crash == "the state poll thread ended"
    assert loop.alive
    assert not loop.ensure_running()  # alive: nothing to do
    loop.stop(2.0)
    assert not loop.ensure_running()  # stopped on purpose: stays stopped
    assert not loop.alive


# ------------------------------------------------------------------------------------------------------
# health
# ------------------------------------------------------------------------------------------------------
def test_health_levels_and_staleness() -> None:
    assert stale_after(0.05, 1.0) == 2.0
    assert stale_after(0.5, 0.1) == 2.5
    assert stale_after(0.01, 0.1) == 1.0
    sample = StateSample(PtzReading(0.0, 0.0, 1.0, 1_000_000_000), 0.0, 0.0, 0.0, False, 1)
    assert state_age(None, 5) == math.inf
    assert state_age(sample, 3_500_000_000) == pytest.approx(2.5)
    assert state_age(sample, 0) == 0.0  # a clock step backwards is not a negative age

    assert judge(PollStats(), math.inf, 2.0).level == DIAG_STALE
    ok = judge(PollStats(ok=10), 0.05, 2.0)
    assert (ok.level, ok.message) == (DIAG_OK, "ok")
    warn = judge(PollStats(ok=10, failed=1, consecutive_failures=1, last_error="timeout"), 0.1, 2.0)
    assert (warn.level, warn.message) == (DIAG_WARN, "state poll failing: timeout")
    err = judge(PollStats(ok=10, failed=5, consecutive_failures=5, last_error="refused"), 0.1, 2.0)
    assert (err.level, err.message) == (DIAG_ERROR, "camera not answering: refused")
    stale = judge(PollStats(ok=10, last_error="timeout"), 3.0, 2.0)
    assert stale.level == DIAG_ERROR
    assert stale.message == "state is stale: the newest is 3.0 s old (> 2.0 s); last poll error: timeout"

    values = diagnostic_values(judge(PollStats(ok=3), math.inf, 2.0), PollStats(ok=3), 2, "bug", SlotStats(),
                               CommanderStats(refused=1, refused_at_send=2))  # fmt: skip
    assert values["state_age_s"] == -1.0
    assert values["poller_restarts"] == 2
    assert values["poller_last_crash"] == "bug"
    assert values["commands_refused"] == 3
    assert values["polls_ok"] == 3


# ------------------------------------------------------------------------------------------------------
# request checks and clamps
# ------------------------------------------------------------------------------------------------------
def test_pixel_centre_checks_the_pixel_and_clamps_the_zoom() -> None:
    r = PtzReading(0.1, 0.2, 9000.0, 1)
    lim = PtzLimitsRos(-3.0, 3.0, -1.0, 1.0, 1.0, 9999.0)
    pan, tilt, zoom = pixel_center_target(r, 351.5, 287.5, 704, 576, ZOOM, math.nan, lim)
    assert (pan, tilt, zoom) == (pytest.approx(0.1), pytest.approx(0.2), None)  # the centre pixel: no change
    assert pixel_center_target(r, 100.0, 100.0, 704, 576, ZOOM, 5000.0, lim)[2] == 9999.0  # clamped
    assert pixel_center_target(r, 100.0, 100.0, 704, 576, ZOOM, -9500.0, lim)[2] == 1.0
    assert pixel_center_target(r, 100.0, 100.0, 704, 576, ZOOM, 0.0, lim)[2] is None  # 0: zoom unchanged
    for args, reason in (
        ((r, 10.0, 10.0, 704, 576, ZOOM, math.inf, lim), "zoom_delta is infinite"),
        ((None, 10.0, 10.0, 704, 576, ZOOM, 0.0, lim), "not known yet"),
        ((r, 704.0, 10.0, 704, 576, ZOOM, 0.0, lim), "outside the 704x576 image"),
        ((r, -0.5, 10.0, 704, 576, ZOOM, 0.0, lim), "outside"),
        ((r, math.nan, 10.0, 704, 576, ZOOM, 0.0, lim), "outside"),
    ):
        with pytest.raises(ValueError, match=reason):
            pixel_center_target(*args)  # type: ignore[arg-type]


def test_area_zoom_command_refuses_bad_boxes_and_clamps() -> None:
    r = PtzReading(0.0, 0.0, 9000.0, 1)
    lim = PtzLimitsRos(-3.0, 3.0, -1.0, 1.0, 1.0, 9500.0)
    assert area_zoom_command(r, (300.0, 250.0, 404.0, 326.0), 704, 576, ZOOM, lim)[2] == 9500.0
    with pytest.raises(ValueError, match="not known yet"):
        area_zoom_command(None, (0.0, 0.0, 10.0, 10.0), 704, 576, ZOOM, lim)
    with pytest.raises(ValueError, match="not finite"):
        area_zoom_command(r, (0.0, 0.0, math.inf, 10.0), 704, 576, ZOOM, lim)
    with pytest.raises(ValueError, match="positive width"):
        area_zoom_command(r, (5.0, 0.0, 5.0, 10.0), 704, 576, ZOOM, lim)
    # found by the fuzz tier: a finite but absurd box overflowed inside numpy (an exception under -W error,
    # inf/NaN set-points otherwise); its centre lies outside the image: refused with the reason
    with pytest.raises(ValueError, match="not inside the 704x576 image"):
        area_zoom_command(r, (1e308, 3.8e-232, -8.27, math.pi), 704, 576, ZOOM, lim)
    assert clamp_zoom(0.0, lim) == 1.0


@pytest.fixture
def rig() -> Iterator[tuple[MemoryHead, Commander, StatePoller, StateLoop]]:
    """A commander over the in-memory head, its state polled by a real StateLoop every 10 ms."""
    head = MemoryHead()
    slot = CommandSlot(error_types=(PtzBackendError,))
    slot.start()
    poller = StatePoller(head.read_state, period_s=0.01)
    cmd = Commander(head, slot, poller, lambda: LIM, Tolerances(0.002, 2.0, 0.5))

    def on_sample(sample: StateSample) -> None:  # what the node does before publishing
        cmd.on_sample(sample)

    loop = StateLoop(poller, head.limits, on_sample)
    loop.start()
    RosFreeWait.until(lambda: poller.latest is not None)
    try:
        yield head, cmd, poller, loop
    finally:
        loop.stop(2.0)
        slot.stop()


def test_requests_refuse_with_reasons_and_use_the_stream_size(rig: Any) -> None:
    head, cmd, poller, _ = rig
    size = [704, 576]
    frames = ("axis_ptz_base", "base_link")
    mount = Transform.from_xyz_rpy(0, 0, 0, 0, 0, 0)
    req = Requests(cmd, ZOOM, HEAD, frames, mount, lambda: LIM, lambda: (size[0], size[1]))
    assert req.size() == (704, 576)
    assert req.size(1920, 0) == (1920, 576)
    assert "pan" in req.move("absolute", math.inf, math.nan, math.nan, math.nan, relative=False).reason
    assert "speed" in req.move("absolute", 0.1, math.nan, math.nan, -math.inf, relative=False).reason
    _done(req.move("absolute", 0.25, math.nan, math.nan, math.nan, relative=False))
    assert head.pose[0] == 0.25
    assert head.speeds[-1] is None  # NaN speed: the camera's default
    size[0] = 100  # the stream got smaller: a pixel beyond it is now refused
    assert "outside the 100x576 image" in req.center(150.0, 10.0, 0, 0, math.nan).reason
    assert "exactly one" in req.set_zoom(100.0, 2.0, math.nan).reason
    assert "hfov" in req.set_zoom(math.nan, math.nan, math.inf).reason
    assert "unknown frame" in req.look_at((1.0, 0.0, 0.0), "map", math.nan).reason
    assert "not finite" in req.area_zoom((0.0, 0.0, math.nan, 5.0), 0, 0).reason
    _done(req.look_at((1.0, 1.0, HEAD.h_tilt), "", 3000.0))
    assert head.pose == [pytest.approx(math.pi / 4), pytest.approx(0.0, abs=1e-9), 3000.0]
    assert cmd.stats.refused == 7


# ------------------------------------------------------------------------------------------------------
# following orders: services and the ptz/move goal
# ------------------------------------------------------------------------------------------------------
def test_follow_accepted_or_arrived(rig: Any) -> None:
    head, cmd, poller, _ = rig
    f = Follower(cmd, poller, JointOffsets(), 2.0)
    ok, msg, _ = f.follow(cmd.move("abs", 0.3, None, None), False, 2.0)
    assert (ok, msg) == (True, "sent")
    ok, msg, sample = f.follow(cmd.move("abs", 0.4, None, None), True, 3.0)
    assert ok, msg
    assert "arrived" in msg
    assert sample is not None
    assert sample.reading.pan == pytest.approx(0.4)
    ok, msg, _ = f.follow(cmd.refuse("abs", "the box is not finite"), True, 1.0)
    assert (ok, msg) == (False, "the box is not finite")
    assert f.preset("GOTO ", "nowhere", False, 2.0)[0]  # case and blanks ignored; the camera accepts
    assert f.preset("set", "door", False, 2.0) == (True, "sent")
    assert f.preset("rename", "door", False, 2.0) == (False, "unknown action 'rename' (goto, set, remove)")


def test_goal_succeeds_with_feedback_and_cancel_stops_the_head(rig: Any) -> None:
    head, cmd, poller, _ = rig
    offsets = JointOffsets(0.1, 0.0)
    f = Follower(cmd, poller, offsets, 2.0)
    feedback: list[Any] = []
    end = f.run_goal(cmd.move("abs", 0.3, None, None), 3.0, lambda: False, lambda: False, feedback.append)
    assert end.status is GoalStatus.SUCCEEDED, end.message
    # cancelled while a move is in flight: the head is stopped and the answer says where, in joint coordinates
    gate = head.gate = threading.Event()  # the next command hangs in flight until released
    order = cmd.move("abs", 1.0, None, None)
    cancel, cancel_seen = threading.Event(), threading.Event()

    def cancel_requested() -> bool:
        if cancel.is_set():
            cancel_seen.set()
            return True
        return False

    def cancel_then_release() -> None:
        head.gated.wait(5.0)  # the move is in flight (held at the gate) ...
        cancel.set()
        cancel_seen.wait(5.0)  # ... when the goal sees the cancel; then the camera answers
        gate.set()

    th = threading.Thread(target=cancel_then_release)
    th.start()
    end = f.run_goal(order, 3.0, cancel_requested, lambda: False, feedback.append)
    th.join()
    head.gate = None
    assert end.status is GoalStatus.CANCELED, end.message
    assert end.message == f"cancelled: the head stopped at pan {math.degrees(1.1):.3f} deg, tilt 0.000 deg, zoom 1"
    assert head.calls[-1] == ("velocity", (0.0, 0.0, 0.0))  # the stop
    assert end.sample is not None
    assert not end.sample.head_moving


def test_goal_cancel_leaves_a_newer_command_alone_and_preemption_aborts(rig: Any) -> None:
    head, cmd, poller, _ = rig
    f = Follower(cmd, poller, JointOffsets(), 2.0)
    order = cmd.move("abs", 0.2, None, None)
    _done(cmd.move("abs", -0.2, None, None))  # newer: in charge of the head
    msg, _ = f.stop_for_cancel(order)
    assert msg == "cancelled (a newer command is already in charge of the head)"
    assert all(c[0] != "velocity" for c in head.calls)  # nothing was stopped
    end = f.run_goal(cmd.move("abs", 0.5, None, None), 3.0, lambda: False, lambda: True, lambda _p: None)
    assert end.status is GoalStatus.ABORTED
    assert end.message == "pre-empted by a newer ptz/move goal"
    end = f.run_goal(cmd.refuse("move", "unknown goal kind 9"), 1.0, lambda: False, lambda: False, lambda _p: None)
    assert (end.status, end.message) == (GoalStatus.ABORTED, "unknown goal kind 9")


def test_goal_book_latest_valid_goal_preempts() -> None:
    book = GoalBook()
    slotless = Commander(MemoryHead(), CommandSlot(), StatePoller(lambda: PtzReading(0, 0, 1, 1), 0.1),
                         lambda: LIM, Tolerances(0.002, 2.0, 0.5))  # fmt: skip
    bad = slotless.refuse("y", "refused")
    book.accept(b"a", slotless.move("abs", 0.1, None, None))
    book.accept(b"b", bad)  # an invalid goal does not pre-empt the running one
    assert not book.preempted(b"a")
    book.accept(b"c", slotless.move("abs", 0.2, None, None))
    assert book.preempted(b"a")
    assert book.take(b"b") is bad
    assert book.take(b"b") is None
    book.finish(b"a")
    assert not book.preempted(b"a")


# ------------------------------------------------------------------------------------------------------
# drive-safe cap
# ------------------------------------------------------------------------------------------------------
def test_drive_safe_cap_applies_changes_once_and_reconfigures(rig: Any) -> None:
    head, cmd, poller, _ = rig
    _done(cmd.move("abs", 0.0, 0.0, 8000.0))
    clock = FakeClock()
    log: list[str] = []
    cap = DriveSafeCap(DriveSafeZoom(DriveSafeConfig(0.2, 0.3, 4000.0, 2.0), clock=clock), cmd, log.append)
    cap.on_speed(1.0, 0.0)
    assert cmd.zoom_cap == 4000.0
    cap.on_speed(1.0, 0.0)  # no change: nothing sent, nothing logged
    assert log == ["robot moving: zoom capped at 4000 (zoom_cap sent)"]
    RosFreeWait.until(lambda: head.pose[2] == 4000.0)
    cap.reconfigure(DriveSafeConfig(0.2, 0.3, 3000.0, 2.0))  # a new cap value applies at once
    assert cmd.zoom_cap == 3000.0
    RosFreeWait.until(lambda: head.pose[2] == 3000.0)
    clock.t += 2.5
    cap.tick()
    assert cmd.zoom_cap is None
    assert log[-1].startswith("robot stopped: zoom cap lifted")
    RosFreeWait.until(lambda: head.pose[2] == 8000.0)


def test_move_goals_become_orders(rig: Any) -> None:
    head, cmd, poller, _ = rig
    mount = Transform.from_xyz_rpy(0, 0, 0, 0, 0, 0)
    req = Requests(cmd, ZOOM, HEAD, ("axis_ptz_base", "base_link"), mount, lambda: LIM, lambda: (704, 576))
    nan = math.nan

    def goal(kind: int, command: tuple[float, float, float, float] = (nan, nan, nan, nan), **kw: Any) -> MoveGoal:
        fields: dict[str, Any] = {"magnification": nan, "hfov": nan, "point": (0.0, 0.0, 0.0), "frame": "",
                                  "preset": ""}  # fmt: skip
        fields.update(kw)
        return MoveGoal(kind, command, **fields)

    _done(req.goal(goal(GoalKind.ABSOLUTE, (0.3, nan, nan, nan))))
    _done(req.goal(goal(GoalKind.RELATIVE, (0.1, nan, nan, nan))))
    assert head.pose[0] == pytest.approx(0.4)
    # ZOOM: a 0 in the unused fields counts as not given (a goal message's default is 0, not NaN)
    _done(req.goal(goal(GoalKind.ZOOM, (nan, nan, 0.0, nan), magnification=2.0, hfov=0.0)))
    assert head.pose[2] == pytest.approx(ZOOM.zoom_for_magnification(2.0), abs=0.5)
    _done(req.goal(goal(GoalKind.LOOK_AT, (nan, nan, 0.0, nan), point=(0.0, 1.0, HEAD.h_tilt))))
    assert head.pose[0] == pytest.approx(math.pi / 2)
    assert head.pose[2] == pytest.approx(ZOOM.zoom_for_magnification(2.0), abs=0.5)  # zoom 0: unchanged
    _done(req.goal(goal(GoalKind.HOME)))
    assert head.calls[-1][0] == "move_to"  # home: an absolute move to the home pose (followed like any move)
    assert req.goal(goal(GoalKind.PRESET)).reason == "kind PRESET needs a preset name"
    _done(req.goal(goal(GoalKind.PRESET, preset="door")))
    assert head.calls[-1] == ("goto_preset", ("door",))
    assert req.goal(goal(9)).reason == "unknown goal kind 9 (0..5: ABSOLUTE..PRESET)"
