"""The ROS-free PTZ core: command slot, state poller, pointing glue and the Axis backend (MockTransport)."""

from __future__ import annotations

import math
import subprocess
import sys
import threading
import time
from urllib.parse import parse_qs

import httpx
import numpy as np
import pytest

from axis_ptz_ros2.config import CameraModel
from axis_ptz_ros2.geometry import Mount, PanDirection, PtzKinematics, Transform, VapixConvention, ZoomModel
from axis_ptz_ros2.ptz.axis_backend import AxisBackend, speed_to_vapix
from axis_ptz_ros2.ptz.backend import PtzBackend, PtzBackendError, PtzLimitsRos, PtzReading
from axis_ptz_ros2.ptz.command_slot import CommandSlot, Outcome
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
from axis_ptz_ros2.ptz.state import StatePoller
from axis_ptz_ros2.vapix import CameraConfig, VapixClient
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

        def blocker() -> None:
            gate.wait(2.0)
            ran.append("blocker")

        first = slot.submit("blocker", blocker)
        time.sleep(0.05)  # the blocker is in flight now
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
    slot.submit("blocker", lambda: gate.wait(0.3) and None)
    time.sleep(0.05)
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
            time.sleep(0.005)

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
    zm = ZoomModel()
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
    zm = ZoomModel()
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
    b = _backend(CameraModel(), log)
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
    model = CameraModel(convention=VapixConvention(PanDirection.CW, Mount.CEILING))
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
    b = AxisBackend(cfg, CameraModel(), command_client=c, state_client=c)
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
        if name.split(".")[0] in {"rclpy", "sensor_msgs", "std_msgs", "geometry_msgs", "axis_ptz_interfaces"}:
            raise ImportError(f"ROS module {name} imported by the ROS-free PTZ core")
        return None
sys.meta_path.insert(0, _Blocker())
import axis_ptz_ros2.ptz.axis_backend, axis_ptz_ros2.ptz.command_slot, axis_ptz_ros2.ptz.control
import axis_ptz_ros2.ptz.state
print("ok")
"""


def test_ptz_core_imports_with_ros_blocked() -> None:
    result = subprocess.run(
        [sys.executable, "-c", ROS_FREE_PROBE], capture_output=True, text=True, timeout=60, check=False
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "ok"
