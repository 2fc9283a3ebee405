"""The ROS-free PTZ core: command slot, state poller, pointing glue and the Axis backend (MockTransport)."""

from __future__ import annotations

import math
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import replace
from typing import Any
from urllib.parse import parse_qs

import httpx
import numpy as np
import pytest

from axis_ptz_ros2.config import CameraModel, load_camera_model
from axis_ptz_ros2.geometry import Mount, PanDirection, PtzKinematics, VapixConvention
from axis_ptz_ros2.ptz.axis_backend import AxisBackend, speed_to_vapix
from axis_ptz_ros2.ptz.backend import PresetInfo, PtzBackend, PtzBackendError, PtzLimitsRos, PtzReading
from axis_ptz_ros2.ptz.command_slot import CommandSlot, Outcome
from axis_ptz_ros2.ptz.commander import Commander
from axis_ptz_ros2.ptz.control import (
    JointOffsets,
    Target,
    area_zoom_target,
    center_target,
    look_at_target,
    merge_target,
    normalize_target,
    zoom_target,
)
from axis_ptz_ros2.ptz.drive_safe import DriveSafeConfig, DriveSafeZoom
from axis_ptz_ros2.ptz.orders import Order, Tolerances, axis_value, rate_value
from axis_ptz_ros2.ptz.preemption import Preemption
from axis_ptz_ros2.ptz.state import StatePoller
from axis_ptz_ros2.transforms import Transform
from axis_ptz_ros2.vapix import CameraConfig, VapixClient
from tests.support.models import AXIS_214_ZOOM
from tests.support.waiting import wait_until
from tests.unit.fixtures_vapix import LIMITS_RESPONSE, POSITION_RESPONSE

pytestmark = pytest.mark.unit

LIM = PtzLimitsRos(math.radians(-170), math.radians(170), math.radians(-30), math.radians(90), 1.0, 9999.0)


# ------------------------------------------------------------------------------------------------------
# command slot
# ------------------------------------------------------------------------------------------------------
def test_slot_latest_wins_keeps_non_supersedable_and_order() -> None:
    slot = CommandSlot(error_types=(RuntimeError,))
    gate = threading.Event()
    ran: list[str] = []
    slot.start()
    try:
        in_flight = threading.Event()

        def blocker() -> None:
            in_flight.set()
            gate.wait(2.0)
            ran.append("blocker")

        first = slot.submit("blocker", blocker)
        assert in_flight.wait(5.0)  # the blocker is in flight now
        moves = [slot.submit(f"m{i}", lambda i=i: ran.append(f"m{i}")) for i in range(10)]
        keep = slot.submit("preset", lambda: ran.append("preset"), supersedable=False)
        last = slot.submit("m_last", lambda: ran.append("m_last"))
        assert not slot.idle
        gate.set()
        assert last.wait(2.0)
        assert first.outcome is Outcome.SENT
        assert all(m.outcome is Outcome.SUPERSEDED for m in moves)
        assert keep.outcome is Outcome.SENT
        assert ran == ["blocker", "preset", "m_last"]
        assert slot.stats.superseded == 10
        assert slot.stats.sent == 3
    finally:
        slot.stop()


def test_slot_failure_is_reported_and_worker_survives() -> None:
    errors: list[str] = []
    slot = CommandSlot(error_types=(PtzBackendError,), on_error=lambda t, e: errors.append(f"{t.label}: {e}"))
    slot.start()

    def boom() -> None:
        raise PtzBackendError("HTTP 503")

    try:
        bad = slot.submit("bad", boom)
        assert bad.wait(1.0)
        assert bad.outcome is Outcome.FAILED
        assert bad.error == "HTTP 503"
        good = slot.submit("good", lambda: None)
        assert good.wait(1.0)
        assert good.outcome is Outcome.SENT
        assert errors == ["bad: HTTP 503"]
        assert slot.stats.failed == 1
    finally:
        slot.stop()


def test_slot_stop_cancels_pending_and_joins() -> None:
    slot = CommandSlot()
    gate = threading.Event()
    slot.start()
    in_flight = threading.Event()
    slot.submit("blocker", lambda: in_flight.set() or gate.wait(0.3) and None)
    assert in_flight.wait(5.0)  # the blocker is in flight: the next command has to wait
    pending = slot.submit("pending", lambda: None, supersedable=False)
    slot.stop(timeout=2.0)
    assert pending.outcome is Outcome.CANCELLED
    assert not any(t.name == "ptz-commands" for t in threading.enumerate())
    assert slot.submit("late", lambda: None).outcome is Outcome.CANCELLED


# ------------------------------------------------------------------------------------------------------
# state poller
# ------------------------------------------------------------------------------------------------------
class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_poller_rates_motion_backoff_and_resume() -> None:
    clock = FakeClock()
    script: list[PtzReading | Exception] = []

    def read() -> PtzReading:
        item = script.pop(0)
        if isinstance(item, Exception):
            raise item
        return item

    poller = StatePoller(read, period_s=0.05, max_backoff_s=1.0, clock=clock)
    script += [PtzReading(0.0, 0.0, 1.0, 1_000_000_000), PtzReading(0.1, -0.05, 1.0, 1_100_000_000)]
    s1 = poller.poll()
    clock.t += 0.1
    s2 = poller.poll()
    assert s1 is not None
    assert s2 is not None
    assert not s1.head_moving
    assert s2.head_moving
    assert (s2.pan_rate, s2.tilt_rate) == pytest.approx((1.0, -0.5))
    assert s2.seq == s1.seq + 1
    # failures: counted, back-off doubles up to the cap, no read while backing off
    script += [PtzBackendError("HTTP 500")] * 6
    delays = []
    for _ in range(6):
        clock.t += 5.0  # always due
        assert poller.poll() is None
        delays.append(poller.backoff_s())
        assert poller.poll() is None  # not due: no read consumed
    assert delays == [0.1, 0.2, 0.4, 0.8, 1.0, 1.0]
    assert poller.stats.failed == 6
    assert poller.stats.consecutive_failures == 6
    assert poller.stats.last_error == "HTTP 500"
    # resumes with the right value at the full rate
    script += [PtzReading(0.3, 0.2, 500.0, 9_000_000_000), PtzReading(0.3, 0.2, 500.0, 9_050_000_000)]
    clock.t += 1.0
    s3 = poller.poll()
    assert s3 is not None
    assert s3.reading.pan == 0.3
    assert poller.stats.consecutive_failures == 0
    assert poller.poll() is not None  # immediately due again
    assert poller.latest is not None
    assert not poller.latest.head_moving


def test_poller_wait_for_wakes_on_new_samples() -> None:
    readings = iter(PtzReading(0.01 * i, 0.0, 1.0, 10**9 + i * 10**7) for i in range(100))
    poller = StatePoller(lambda: next(readings), period_s=0.01)
    stop = threading.Event()

    def run() -> None:
        while not stop.is_set():
            poller.poll()
            time.sleep(0.005)  # the poll thread's period (a busy loop would use up the 100 readings at once)

    th = threading.Thread(target=run)
    th.start()
    try:
        s = poller.wait_for(lambda s: s.reading.pan >= 0.1, timeout=2.0)
        assert s is not None
        assert s.reading.pan == pytest.approx(0.1)
        assert poller.wait_for(lambda s: False, timeout=0.05) is None
    finally:
        stop.set()
        th.join()


# ------------------------------------------------------------------------------------------------------
# pointing glue
# ------------------------------------------------------------------------------------------------------
def test_relative_accumulates_on_the_target_not_the_measured_pose() -> None:
    lagging = PtzReading(0.0, 0.0, 1.0, 0)  # the head has not moved yet
    t: Target | None = None
    for _ in range(300):
        t = merge_target(t, lagging, 0.002, None, None, relative=True)
    assert t is not None
    assert t.pan == pytest.approx(0.6, abs=1e-12)
    assert t.tilt is None  # never commanded
    t = merge_target(t, lagging, None, 0.1, 100.0, relative=True)
    assert (t.pan, t.tilt, t.zoom) == pytest.approx((0.6, 0.1, 101.0))
    t = merge_target(t, lagging, -0.2, None, None, relative=False)
    assert (t.pan, t.tilt, t.zoom) == pytest.approx((-0.2, 0.1, 101.0))
    with pytest.raises(ValueError, match="not known"):
        merge_target(None, None, 0.1, None, None, relative=True)


def test_limits_violation_and_wrap() -> None:
    assert LIM.violation(math.radians(170), math.radians(90), 9999.0) is None
    assert "pan" in (LIM.violation(math.radians(170.01), None, None) or "")
    assert "tilt" in (LIM.violation(None, math.radians(-31), None) or "")
    assert "zoom" in (LIM.violation(None, None, 0.0) or "")
    assert "finite" in (LIM.violation(math.nan, None, None) or "")
    full = PtzLimitsRos(-math.pi, math.pi, -1.0, 1.0, 1.0, 9999.0)
    assert full.full_turn
    t = normalize_target(Target(math.radians(190.0), 0.0, None), full)
    assert t.pan == pytest.approx(math.radians(-170.0))
    assert full.violation(t.pan, t.tilt, None) is None


def test_joint_offsets_round_trip() -> None:
    off = JointOffsets(0.01, -0.02)
    r = off.from_head(PtzReading(0.5, 0.1, 10.0, 5))
    assert (r.pan, r.tilt) == pytest.approx((0.51, 0.08))
    assert off.to_head(r.pan, r.tilt) == pytest.approx((0.5, 0.1))
    assert off.limits(LIM).pan_max == pytest.approx(LIM.pan_max + 0.01)


def test_center_and_area_zoom_use_the_exact_geometry() -> None:
    zm = AXIS_214_ZOOM
    r = PtzReading(0.3, math.radians(40.0), 2000.0, 0)
    # centring on the principal point is a no-op
    p, t = center_target(r, (704 - 1) / 2, (576 - 1) / 2, 704, 576, zm)
    assert (p, t) == pytest.approx((0.3, math.radians(40.0)), abs=1e-12)
    # a pixel: after the move the same 3-D ray is the optical axis
    intr = zm.intrinsics(2000.0, 704, 576)
    p, t = center_target(r, 600.0, 100.0, 704, 576, zm)
    from axis_ptz_ros2.geometry import pan_tilt_to_direction, pixel_direction_in_ptz_base

    d = pixel_direction_in_ptz_base(0.3, math.radians(40.0), 600.0, 100.0, intr)
    assert pan_tilt_to_direction(p, t) == pytest.approx(d, abs=1e-12)
    assert t > math.radians(40.0)  # the pixel is above the centre
    # area zoom: a box a quarter of the width (and flatter than the image) -> 4x the magnification
    box = (300.0, 250.0, 300.0 + 176.0, 250.0 + 60.0)
    p, t, z = area_zoom_target(r, box, 704, 576, zm)
    assert zm.magnification(z) == pytest.approx(4.0 * zm.magnification(2000.0))
    assert (p, t) == pytest.approx(center_target(r, 388.0, 280.0, 704, 576, zm))
    with pytest.raises(ValueError, match="positive"):
        area_zoom_target(r, (10.0, 10.0, 10.0, 50.0), 704, 576, zm)


def test_zoom_target_forms() -> None:
    zm = AXIS_214_ZOOM
    assert zoom_target(zm, 1234.0, None, None) == 1234.0
    assert zm.magnification(zoom_target(zm, None, 5.0, None)) == pytest.approx(5.0)
    assert zm.hfov(zoom_target(zm, None, None, math.radians(10.0))) == pytest.approx(math.radians(10.0))
    for bad in ((None, None, None), (1.0, 2.0, None)):
        with pytest.raises(ValueError, match="exactly one"):
            zoom_target(zm, *bad)
    with pytest.raises(ValueError, match="magnification"):
        zoom_target(zm, None, 30.0, None)
    with pytest.raises(ValueError, match="hfov"):
        zoom_target(zm, None, None, math.radians(60.0))


def test_look_at_transforms_from_the_mount_parent_frame() -> None:
    kin = PtzKinematics(0.0687, (0.03, 0.0, 0.0))
    mount = Transform.from_xyz_rpy(-0.2, -0.05, 0.46, 0.01, -0.005, 0.02)
    P_base = np.array([0.3, 3.0, 0.5])
    pan, tilt = look_at_target(P_base, "base_link", "axis_ptz_base", "base_link", mount, kin)
    T = mount @ kin.optical_in_ptz_base(pan, tilt)
    ray = (P_base - T.t) / np.linalg.norm(P_base - T.t)
    assert float(ray @ T.R[:, 2]) == pytest.approx(1.0, abs=1e-12)
    same = look_at_target(mount.inverse().apply(P_base), "axis_ptz_base", "axis_ptz_base", "base_link", mount, kin)
    assert same == pytest.approx((pan, tilt), abs=1e-12)
    with pytest.raises(ValueError, match="unknown frame"):
        look_at_target(P_base, "map", "axis_ptz_base", "base_link", mount, kin)


# ------------------------------------------------------------------------------------------------------
# Axis backend over MockTransport (real replies; the convention decides every sign)
# ------------------------------------------------------------------------------------------------------
def _backend(model: CameraModel, log: list[dict[str, list[str]]], limits_ok: bool = True) -> AxisBackend:
    def handler(request: httpx.Request) -> httpx.Response:
        q = parse_qs(request.url.query.decode(), keep_blank_values=True)
        log.append(q)
        if q.get("query") == ["position"]:
            return httpx.Response(200, text=POSITION_RESPONSE)
        if q.get("query") == ["limits"]:
            return httpx.Response(200, text=LIMITS_RESPONSE) if limits_ok else httpx.Response(500)
        if "action" in q:
            return httpx.Response(500)
        return httpx.Response(204)

    transport = httpx.MockTransport(handler)
    cfg = CameraConfig(port=8080)
    return AxisBackend(
        cfg,
        model,
        command_client=VapixClient(cfg, transport=transport),
        state_client=VapixClient(cfg, transport=transport),
    )


def test_axis_backend_signs_units_and_limits() -> None:
    log: list[dict[str, list[str]]] = []
    b = _backend(load_camera_model(), log)
    assert isinstance(b, PtzBackend)
    lim = b.limits()
    assert (lim.pan_min, lim.pan_max) == pytest.approx((math.radians(-170), math.radians(170)))
    assert (lim.tilt_min, lim.tilt_max) == pytest.approx((math.radians(-20), math.radians(90)))
    assert b.limits_source == "camera"
    r = b.read_state()
    assert (r.pan, r.tilt, r.zoom) == pytest.approx((-math.radians(51.2891), math.radians(46.1914), 1.0))
    b.move_to(math.radians(30.0), math.radians(-10.0), 1234.4, speed=0.5)
    assert log[-1] == {"pan": ["-30.0000"], "tilt": ["-10.0000"], "zoom": ["1234"], "speed": ["50"]}
    b.move_to(None, math.radians(5.0), None)
    assert log[-1] == {"tilt": ["5.0000"]}
    b.velocity(math.radians(50.0), -math.radians(90.0), 0.25)  # left at half the 100 deg/s, down at full
    assert log[-1] == {"continuouspantiltmove": ["-50,-100"], "continuouszoommove": ["25"]}
    b.velocity(0.0, 0.0, 0.0)
    assert log[-1]["continuouspantiltmove"] == ["0,0"]
    b.home()
    assert log[-1] == {"move": ["home"]}
    b.close()


def test_axis_backend_ceiling_mount_and_fallback_limits() -> None:
    log: list[dict[str, list[str]]] = []
    model = replace(load_camera_model(), convention=VapixConvention(PanDirection.CW, Mount.CEILING))
    b = _backend(model, log, limits_ok=False)
    lim = b.limits()
    assert b.limits_source == "camera_model"
    assert (lim.tilt_min, lim.tilt_max) == pytest.approx((math.radians(-90), math.radians(30)))
    b.move_to(math.radians(30.0), math.radians(-10.0), None)
    assert log[-1] == {"pan": ["30.0000"], "tilt": ["10.0000"]}


def test_axis_backend_errors_become_backend_errors() -> None:
    def handler(request: httpx.Request) -> httpx.Response:
        return httpx.Response(503)

    cfg = CameraConfig(port=8080, username="root", password="s3cret")
    c = VapixClient(cfg, transport=httpx.MockTransport(handler))
    b = AxisBackend(cfg, load_camera_model(), command_client=c, state_client=c)
    with pytest.raises(PtzBackendError) as err:
        b.read_state()
    assert "s3cret" not in str(err.value)
    assert "s3cret" not in repr(b)
    with pytest.raises(PtzBackendError):
        b.move_to(0.0, 0.0, None)


def test_speed_to_vapix() -> None:
    assert speed_to_vapix(50.0, 100.0) == 50
    assert speed_to_vapix(-500.0, 100.0) == -100
    assert speed_to_vapix(0.1, 100.0) == 1  # a tiny non-zero rate never becomes a stop
    assert speed_to_vapix(-0.1, 100.0) == -1
    assert speed_to_vapix(0.0, 100.0) == 0
    assert speed_to_vapix(math.nan, 100.0) == 0


ROS_FREE_PROBE = """
import sys
class _Blocker:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in {"rclpy", "sensor_msgs", "std_msgs", "geometry_msgs", "nav_msgs", "action_msgs",
                                  "axis_ptz_interfaces"}:
            raise ImportError(f"ROS module {name} imported by the ROS-free PTZ core")
        return None
sys.meta_path.insert(0, _Blocker())
import axis_ptz_ros2.ptz.axis_backend, axis_ptz_ros2.ptz.command_slot, axis_ptz_ros2.ptz.control
import axis_ptz_ros2.ptz.state, axis_ptz_ros2.ptz.commander, axis_ptz_ros2.ptz.drive_safe
import axis_ptz_ros2.ptz.state_loop, axis_ptz_ros2.ptz.health, axis_ptz_ros2.ptz.goals
import axis_ptz_ros2.ptz.requests
print("ok")
"""


def test_ptz_core_imports_with_ros_blocked() -> None:
    result = subprocess.run(
        [sys.executable, "-c", ROS_FREE_PROBE], capture_output=True, text=True, timeout=60, check=False
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "ok"


# ------------------------------------------------------------------------------------------------------
# commander: commands that never fight (an in-memory head, no ROS)
# ------------------------------------------------------------------------------------------------------
class MemoryHead:
    """A head that jumps to every accepted command; ``refuse`` makes the next commands fail like a camera
    answering ``Error:``; ``gate`` holds a command in flight."""

    def __init__(self) -> None:
        self.pose = [0.0, 0.0, 1.0]
        self.rates = [0.0, 0.0, 0.0]
        self.calls: list[tuple[str, tuple[object, ...]]] = []
        self.refuse = False
        self.fail_next = 0  # fail this many of the next commands
        self.gate: threading.Event | None = None
        self.gated = threading.Event()  # set when a command is held at the gate
        self.stamp = 0
        self.speeds: list[float | None] = []

    def _cmd(self, name: str, *args: object) -> None:
        if self.gate is not None:
            self.gated.set()
            self.gate.wait(5.0)
        if self.fail_next > 0:
            self.fail_next -= 1
            raise PtzBackendError(f"Error: {name} refused")
        if self.refuse and name != "velocity":
            raise PtzBackendError(f"Error: {name} refused")
        self.calls.append((name, args))

    def limits(self) -> PtzLimitsRos:
        return LIM

    def read_state(self) -> PtzReading:
        self.stamp += 50_000_000
        return PtzReading(self.pose[0], self.pose[1], self.pose[2], self.stamp)

    def move_to(self, pan: float | None, tilt: float | None, zoom: float | None, speed: float | None = None) -> None:
        self._cmd("move_to", pan, tilt, zoom)
        self.speeds.append(speed)
        self.rates = [0.0, 0.0, 0.0]
        for i, v in enumerate((pan, tilt, zoom)):
            if v is not None:
                self.pose[i] = v

    def velocity(self, pan_rate: float, tilt_rate: float, zoom_rate: float) -> None:
        self._cmd("velocity", pan_rate, tilt_rate, zoom_rate)
        self.rates = [pan_rate, tilt_rate, zoom_rate]

    def home(self) -> None:
        self._cmd("home")

    def goto_preset(self, name: str) -> None:
        self._cmd("goto_preset", name)

    def set_preset(self, name: str) -> None:
        self._cmd("set_preset", name)

    def remove_preset(self, name: str) -> None:
        self._cmd("remove_preset", name)

    def list_presets(self) -> list[PresetInfo]:
        return []

    def close(self) -> None:
        pass


class SkewClock:
    """``time.monotonic()`` that a test moves forward (:meth:`advance`) instead of sleeping."""

    def __init__(self) -> None:
        self.offset = 0.0

    def __call__(self) -> float:
        return time.monotonic() + self.offset

    def advance(self, seconds: float) -> None:
        self.offset += seconds


@pytest.fixture
def commander_clock() -> SkewClock:
    return SkewClock()


@pytest.fixture
def head_and_commander(commander_clock: SkewClock) -> Iterator[tuple[MemoryHead, Commander, StatePoller]]:
    """A commander over the in-memory head, its state polled every 10 ms in the background; its clock is
    ``commander_clock``."""
    head = MemoryHead()
    slot = CommandSlot(error_types=(PtzBackendError,))
    slot.start()
    poller = StatePoller(head.read_state, period_s=0.01)
    cmd = Commander(head, slot, poller, lambda: LIM, tolerances=Tolerances(0.002, 2.0, 0.5), clock=commander_clock)
    stop = threading.Event()

    def polls() -> None:  # what the node's poll thread does
        while not stop.is_set():
            sample = poller.poll()
            if sample is not None:
                cmd.on_sample(sample)
            stop.wait(0.01)

    poller.poll()
    th = threading.Thread(target=polls, daemon=True)
    th.start()
    try:
        yield head, cmd, poller
    finally:
        stop.set()
        th.join()
        slot.stop()


class RosFreeWait:
    @staticmethod
    def until(predicate: Any, timeout: float = 5.0) -> None:
        wait_until(predicate, timeout, 0.005)


def _done(order: Order) -> None:
    assert order.ticket is not None, order.reason
    assert order.ticket.wait(5.0)


def test_infinite_fields_are_refused_never_read_as_keep_or_stop() -> None:
    assert axis_value(float("nan"), "pan") is None
    assert axis_value(0.25, "pan") == 0.25
    for v in (math.inf, -math.inf):
        with pytest.raises(ValueError, match="inf"):
            axis_value(v, "tilt")
        with pytest.raises(ValueError, match="finite"):
            rate_value(v, "pan_rate")
    with pytest.raises(ValueError, match="finite"):
        rate_value(float("nan"), "zoom_rate")


def test_infinite_velocity_is_refused_not_sent(head_and_commander: Any) -> None:
    head, cmd, _ = head_and_commander
    order = cmd.velocity(math.inf, 0.0, 0.0)
    assert order.refused
    assert "finite" in order.reason
    assert cmd.velocity(0.1, float("nan"), 0.0).refused
    assert head.calls == []
    assert cmd.stats.refused == 2


def test_target_is_recorded_on_acceptance_not_submission(head_and_commander: Any) -> None:
    head, cmd, poller = head_and_commander
    _done(cmd.move("abs", 0.5, 0.1, 1000.0))
    assert cmd.target == Target(0.5, 0.1, 1000.0)
    head.refuse = True
    order = cmd.move("rel", 0.2, None, None, relative=True)
    _done(order)
    assert order.ticket.outcome is Outcome.FAILED
    assert cmd.target == Target(0.5, 0.1, 1000.0)  # the refused step never became the target
    head.refuse = False
    _done(cmd.move("rel", 0.1, None, None, relative=True))
    assert head.calls[-1] == ("move_to", (pytest.approx(0.6), pytest.approx(0.1), 1000.0))
    assert cmd.target is not None
    assert cmd.target.pan == pytest.approx(0.6)


def test_queued_relative_steps_compose_and_are_rebased_after_a_failure(head_and_commander: Any) -> None:
    head, cmd, _ = head_and_commander
    _done(cmd.move("abs", 0.0, 0.0, 1.0))
    head.gate = threading.Event()
    head.fail_next = 1
    in_flight = cmd.move("rel", 0.3, None, None, relative=True)  # will fail
    assert in_flight.ticket is not None
    RosFreeWait.until(lambda: in_flight.ticket.started_ns > 0)
    queued = [cmd.move("rel", 0.01, None, None, relative=True) for _ in range(5)]
    assert all(q.ticket is not None for q in queued)
    assert queued[-1].target is not None
    assert queued[-1].target.pan == pytest.approx(0.35)  # provisional: assumes the one in flight succeeds
    head.gate.set()
    _done(in_flight)
    assert in_flight.ticket.outcome is Outcome.FAILED
    _done(queued[-1])
    # the failed 0.3 is gone; the five queued 0.01 steps were superseded into one request of their sum
    sent = [c for c in head.calls if c[0] == "move_to"]
    assert sent[-1][1][0] == pytest.approx(0.05)
    assert [q.ticket.outcome for q in queued[:-1]] == [Outcome.SUPERSEDED] * 4


def test_a_move_ends_velocity_mode_so_the_watchdog_never_stops_it(
    head_and_commander: Any, commander_clock: SkewClock
) -> None:
    head, cmd, _ = head_and_commander
    _done(cmd.velocity(0.5, 0.0, 0.0))
    assert cmd.velocity_active
    _done(cmd.home())
    assert not cmd.velocity_active
    commander_clock.advance(0.6)  # past velocity_timeout (0.5 s)
    assert cmd.check_velocity_timeout() is False
    assert [c[0] for c in head.calls] == ["velocity", "move_to"]
    assert head.calls[-1][1] == (0.0, 0.0, 1.0)  # home: pan 0, tilt 0, widest zoom
    # without the move the watchdog does stop a stale velocity command
    _done(cmd.velocity(0.0, 0.3, 0.0))
    assert cmd.check_velocity_timeout() is False  # fresh
    commander_clock.advance(0.6)
    assert cmd.check_velocity_timeout() is True
    wait_until(lambda: head.calls[-1] == ("velocity", (0.0, 0.0, 0.0)), 2.0, scaled=False, raises=False)
    assert head.calls[-1] == ("velocity", (0.0, 0.0, 0.0))


def test_a_failed_move_after_velocity_stops_the_head(head_and_commander: Any) -> None:
    head, cmd, _ = head_and_commander
    _done(cmd.velocity(0.5, 0.0, 0.0))
    head.refuse = True
    order = cmd.goto_preset("nowhere")
    _done(order)
    assert order.ticket.outcome is Outcome.FAILED
    assert head.rates == [0.0, 0.0, 0.0]  # the continuous motion was stopped, not left running
    assert cmd.stats.halted_after_failure == 1


def test_refused_at_submission_keeps_velocity_mode(head_and_commander: Any) -> None:
    _, cmd, _ = head_and_commander
    _done(cmd.velocity(0.5, 0.0, 0.0))
    order = cmd.move("abs", math.radians(200.0), None, None)
    assert order.refused
    assert "limits" in order.reason
    assert cmd.velocity_active  # the watchdog still guards the running velocity command


def test_track_reports_arrival_short_stop_and_supersession(head_and_commander: Any) -> None:
    head, cmd, poller = head_and_commander
    order = cmd.move("abs", 0.2, None, None)
    _done(order)
    steps = list(cmd.track(order, 2.0))
    assert steps[-1].done
    assert steps[-1].success, steps[-1].message
    assert "arrived" in steps[-1].message
    # the head stops short (another client / a camera clamp): reported with where it is, after settling
    order = cmd.move("abs", 0.4, None, None)
    _done(order)
    head.pose[0] = 0.3
    steps = list(cmd.track(order, 5.0))
    assert not steps[-1].success
    assert "stopped at" in steps[-1].message
    assert steps[-1].error[0] == pytest.approx(0.1)
    # a newer command supersedes the one being followed
    order = cmd.move("abs", 0.1, None, None)
    _done(order)
    gen = cmd.generation
    _done(cmd.move("abs", 0.15, None, None))
    assert cmd.generation == gen + 1
    steps = list(cmd.track(order, 2.0))
    assert not steps[-1].success
    assert "superseded" in steps[-1].message


def test_presets_are_tracked_to_a_known_pose(head_and_commander: Any) -> None:
    head, cmd, poller = head_and_commander
    _done(cmd.move("abs", 0.3, -0.1, 2500.0))
    poller.wait_for(lambda s: s.reading.zoom == 2500.0 and not s.head_moving, 2.0)
    assert cmd.set_preset("door").wait(2.0)
    assert cmd.preset_pose("door") == Target(0.3, -0.1, 2500.0)
    order = cmd.goto_preset("door")
    assert order.target == Target(0.3, -0.1, 2500.0)
    assert cmd.remove_preset("door").wait(2.0)
    assert cmd.preset_pose("door") is None


def test_zoom_cap_caps_commands_and_restores_the_operators_zoom(head_and_commander: Any) -> None:
    head, cmd, poller = head_and_commander
    _done(cmd.move("abs", 0.1, 0.0, 8000.0))
    poller.wait_for(lambda s: s.reading.zoom == 8000.0, 2.0)
    order = cmd.set_zoom_cap(4000.0)
    assert order is not None
    _done(order)
    assert head.pose[2] == 4000.0
    assert cmd.requested_zoom == 8000.0
    assert cmd.target == Target(0.1, 0.0, 8000.0)  # the operator's target is kept
    _done(cmd.move("rel", None, None, 500.0, relative=True))  # zoom in while capped: held at the cap
    assert head.pose[2] == 4000.0
    assert cmd.requested_zoom == 8500.0
    _done(cmd.move("abs", None, None, 2000.0))  # below the cap: obeyed
    assert head.pose[2] == 2000.0
    _done(cmd.move("abs", None, None, 9000.0))
    poller.wait_for(lambda s: s.reading.zoom == 4000.0, 2.0)
    order = cmd.set_zoom_cap(None)
    assert order is not None
    _done(order)
    assert head.pose[2] == 9000.0  # restored
    assert cmd.zoom_cap is None


def test_drive_safe_zoom_thresholds_and_hold() -> None:
    clock = FakeClock()
    d = DriveSafeZoom(DriveSafeConfig(speed_mps=0.2, turn_rps=0.3, zoom_cap=4000.0, hold_s=2.0), clock=clock)
    assert not d.update(0.1, 0.1)
    assert d.update(0.25, 0.0)
    assert d.update(0.0, -0.5)  # turning on the spot
    clock.t += 1.0
    assert d.update(0.0, 0.0)  # stopped, within the hold
    clock.t += 1.01
    assert not d.update(0.0, 0.0)
    assert d.update(math.nan, 0.0)  # unknown speed: the safe side
    clock.t += 5.0
    assert not d.tick()  # no messages for the hold time: released
    with pytest.raises(ValueError, match="zoom_cap"):
        DriveSafeConfig(zoom_cap=-1.0)


def test_preemption_bookkeeping() -> None:
    p = Preemption()
    p.start(b"a")
    assert not p.preempted(b"a")
    p.start(b"b")
    assert p.preempted(b"a")
    assert not p.preempted(b"b")
    p.finish(b"a")
    assert not p.preempted(b"a")
    p.finish(b"b")
    p.start(b"c")
    assert not p.preempted(b"c")


def test_zoom_cap_stops_a_continuous_zoom_in_and_pulls_back_an_overshoot(head_and_commander: Any) -> None:
    head, cmd, poller = head_and_commander
    _done(cmd.move("abs", 0.0, 0.0, 3999.0))
    poller.wait_for(lambda s: s.reading.zoom == 3999.0, 2.0)
    assert cmd.set_zoom_cap(4000.0) is None  # below the cap: nothing to do
    _done(cmd.velocity(0.1, 0.0, 0.5))  # pan and zoom in: the zoom part is dropped at the cap
    assert head.calls[-1] == ("velocity", (0.1, 0.0, 0.0))
    _done(cmd.velocity(0.0, 0.0, -0.5))  # zooming out is always allowed
    assert head.calls[-1] == ("velocity", (0.0, 0.0, -0.5))
    _done(cmd.stop())
    head.pose[2] = 6000.0  # someone zoomed past the cap (another client, a preset)
    RosFreeWait.until(lambda: head.pose[2] == 4000.0)  # the next samples pull it back to the cap
    assert head.calls[-1] == ("move_to", (None, None, 4000.0))


def test_a_slow_move_does_not_leave_the_camera_slow(head_and_commander: Any) -> None:
    head, cmd, _ = head_and_commander
    _done(cmd.move("abs", 0.1, None, None))
    _done(cmd.move("abs", 0.2, None, None, speed=0.1))
    _done(cmd.move("abs", 0.3, None, None))  # no speed given: full speed again (VAPIX speed persists)
    _done(cmd.move("abs", 0.4, None, None))
    assert head.speeds == [None, 0.1, 1.0, None]


def test_a_target_lists_only_its_commanded_axes():
    assert Target(0.5, None, 1200).commanded() == {"pan": 0.5, "zoom": 1200.0}
    assert Target().commanded() == {}
    assert Target(0.0, -0.1, None).commanded() == {"pan": 0.0, "tilt": -0.1}  # 0 is a commanded value
