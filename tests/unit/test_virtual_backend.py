"""The virtual PTZ head (axis_ptz_ros2.virtual.backend): protocol, slew, velocity, limits, presets, threads."""

import math
import threading

import pytest

from axis_ptz_ros2.optics import ZoomModel
from axis_ptz_ros2.ptz.backend import OutOfLimits, PtzBackend, PtzBackendError, PtzLimitsRos
from axis_ptz_ros2.virtual.backend import VirtualDynamics, VirtualPtzBackend, virtual_limits

pytestmark = pytest.mark.unit

ZM = ZoomModel(hfov_wide_deg=90.0, max_magnification=8.0, image_aspect=4.0 / 3.0)
DEG = math.pi / 180.0


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def make(dyn: VirtualDynamics | None = None, limits: PtzLimitsRos | None = None, **kw):
    clock = FakeClock()
    b = VirtualPtzBackend(limits or virtual_limits(ZM), ZM, dyn, clock=clock, **kw)
    return b, clock


def test_implements_the_protocol_and_limits():
    b, _ = make()
    assert isinstance(b, PtzBackend)
    lim = b.limits()
    assert lim.full_turn
    assert (lim.pan_min, lim.pan_max) == (-math.pi, math.pi)
    assert (lim.tilt_min, lim.tilt_max) == (-math.pi / 2, math.pi / 2)
    assert (lim.zoom_min, lim.zoom_max) == (1.0, 9999.0)
    r = b.read_state()
    assert (r.pan, r.tilt, r.zoom) == (0.0, 0.0, 1.0)
    assert r.stamp_ns > 0


def test_finite_slew_reaches_target_at_the_configured_rate():
    b, clock = make()  # 180°/s default
    b.move_to(90 * DEG, -45 * DEG, None)
    assert b.moving
    clock.t += 0.25  # 45° of travel
    r = b.read_state()
    assert r.pan == pytest.approx(45 * DEG, abs=1e-12)
    assert r.tilt == pytest.approx(-45 * DEG, abs=1e-12)  # 45° done in 0.25 s: arrived
    assert b.moving
    clock.t += 0.25
    r = b.read_state()
    assert r.pan == pytest.approx(90 * DEG, abs=1e-12)
    assert not b.moving


def test_speed_fraction_scales_the_slew():
    b, clock = make()
    b.move_to(90 * DEG, None, None, speed=0.5)
    clock.t += 0.5
    assert b.read_state().pan == pytest.approx(45 * DEG, abs=1e-12)
    clock.t += 0.5
    assert b.read_state().pan == pytest.approx(90 * DEG, abs=1e-12)


def test_instant_dynamics_jump():
    b, _ = make(VirtualDynamics(instant=True))
    b.move_to(1.0, 0.5, 5000.0)
    r = b.read_state()
    assert (r.pan, r.tilt, r.zoom) == (1.0, 0.5, 5000.0)
    assert not b.moving


def test_pan_takes_the_short_way_across_the_seam_and_wraps():
    b, clock = make(initial=(170 * DEG, 0.0, 1.0))
    b.move_to(-170 * DEG, None, None)
    clock.t += 10 / 180  # 10° of travel: exactly at the seam
    assert abs(b.read_state().pan) == pytest.approx(math.pi, abs=1e-9)
    clock.t += 10 / 180
    assert b.read_state().pan == pytest.approx(-170 * DEG, abs=1e-12)
    assert not b.moving


def test_out_of_limits_is_refused_and_nothing_moves():
    b, clock = make()
    with pytest.raises(OutOfLimits, match="tilt"):
        b.move_to(0.5, 100 * DEG, None)
    with pytest.raises(OutOfLimits, match="zoom"):
        b.move_to(None, None, 10000.0)
    with pytest.raises(OutOfLimits, match="not finite"):
        b.move_to(math.nan, None, None)
    clock.t += 1.0
    r = b.read_state()
    assert (r.pan, r.tilt, r.zoom) == (0.0, 0.0, 1.0)
    # a full-turn head wraps any finite pan instead of refusing it
    b.move_to(3 * math.pi / 2, None, None)
    clock.t += 1.0
    assert b.read_state().pan == pytest.approx(-math.pi / 2, abs=1e-12)


def test_limited_pan_head_stops_at_its_limits():
    lim = PtzLimitsRos(-170 * DEG, 170 * DEG, -30 * DEG, 90 * DEG, 1.0, 9999.0)
    b, clock = make(limits=lim)
    assert not lim.full_turn
    with pytest.raises(OutOfLimits):
        b.move_to(175 * DEG, None, None)
    b.velocity(-10.0, -10.0, 0.0)  # clipped to 180°/s
    clock.t += 0.5
    r = b.read_state()
    assert r.pan == pytest.approx(-90 * DEG, abs=1e-12)
    assert r.tilt == pytest.approx(-30 * DEG, abs=1e-12)
    clock.t += 5.0
    r = b.read_state()
    assert r.pan == pytest.approx(-170 * DEG, abs=1e-12)
    assert not b.moving  # pinned at both limits


def test_velocity_integrates_wraps_and_zero_stops():
    b, clock = make()
    b.velocity(0.5, 0.1, 0.5)  # zoom: half of full travel (9998 units / 0.5 s) per second
    clock.t += 0.2
    r = b.read_state()
    assert r.pan == pytest.approx(0.1, abs=1e-12)
    assert r.tilt == pytest.approx(0.02, abs=1e-12)
    assert r.zoom == pytest.approx(1.0 + 0.2 * 0.5 * 9998 / 0.5, abs=1e-9)
    clock.t += 10.0
    r = b.read_state()
    assert r.pan == pytest.approx(math.remainder(0.1 + 5.0, 2 * math.pi), abs=1e-9)
    assert r.zoom == 9999.0
    b.velocity(0.0, 0.0, 0.0)
    clock.t += 1.0
    assert b.read_state().pan == pytest.approx(r.pan, abs=1e-12)
    assert not b.moving
    with pytest.raises(PtzBackendError):
        b.velocity(math.inf, 0.0, 0.0)


def test_absolute_move_cancels_velocity_and_velocity_cancels_move():
    b, clock = make()
    b.velocity(1.0, 0.0, 0.0)
    clock.t += 0.1
    b.move_to(None, 10 * DEG, None)  # pan not commanded: it stops where it is
    clock.t += 1.0
    r = b.read_state()
    assert r.pan == pytest.approx(0.1, abs=1e-12)
    assert r.tilt == pytest.approx(10 * DEG, abs=1e-12)
    b.move_to(1.0, None, None)
    b.velocity(0.0, 0.0, 0.0)
    clock.t += 1.0
    assert b.read_state().pan == pytest.approx(0.1, abs=1e-12)


def test_home_and_presets():
    b, clock = make(VirtualDynamics(instant=True), home=(0.2, -0.1, 3000.0))
    b.move_to(1.0, 0.3, 2000.0)
    b.set_preset("door")
    b.move_to(-1.0, 0.0, 1.0)
    b.set_preset("window")
    assert [(p.number, p.name) for p in b.list_presets()] == [(1, "door"), (2, "window")]
    b.goto_preset("door")
    r = b.read_state()
    assert (r.pan, r.tilt, r.zoom) == (1.0, 0.3, 2000.0)
    b.remove_preset("door")
    b.home()
    r = b.read_state()
    assert (r.pan, r.tilt, r.zoom) == (0.2, -0.1, 3000.0)
    b.set_preset("hall")  # takes the freed number
    assert [(p.number, p.name) for p in b.list_presets()] == [(1, "hall"), (2, "window")]
    with pytest.raises(PtzBackendError, match="no preset"):
        b.goto_preset("door")
    with pytest.raises(PtzBackendError, match="no preset"):
        b.remove_preset("door")
    with pytest.raises(PtzBackendError, match="invalid preset name"):
        b.set_preset("a:b")
    with pytest.raises(PtzBackendError, match="invalid preset name"):
        b.set_preset("x" * 32)


def test_closed_backend_refuses():
    b, _ = make()
    b.close()
    with pytest.raises(PtzBackendError):
        b.read_state()
    with pytest.raises(PtzBackendError):
        b.move_to(0.0, 0.0, None)


def test_dynamics_from_dict_and_validation():
    d = VirtualDynamics.from_dict({"pan_dps": 90, "tilt_dps": 45, "zoom_travel_s": 2, "instant": True})
    assert d.max_pan_rate == pytest.approx(math.pi / 2)
    assert d.max_tilt_rate == pytest.approx(math.pi / 4)
    assert (d.zoom_travel_s, d.instant) == (2.0, True)
    with pytest.raises(ValueError, match="positive"):
        VirtualDynamics(max_pan_rate=0.0)
    with pytest.raises(ValueError, match="zoom_travel_s"):
        VirtualDynamics(zoom_travel_s=0.0)


def test_read_state_is_thread_safe_while_commands_arrive():
    b = VirtualPtzBackend(virtual_limits(ZM), ZM)  # real clock
    stop = threading.Event()
    errors: list[BaseException] = []
    readings = []

    def reader() -> None:
        try:
            while not stop.is_set():
                readings.append(b.read_state())
        except BaseException as err:  # noqa: BLE001 - reported below
            errors.append(err)

    threads = [threading.Thread(target=reader) for _ in range(3)]
    for t in threads:
        t.start()
    for i in range(300):
        if i % 2:
            b.move_to(math.sin(i), 0.5 * math.cos(i), 1.0 + 30.0 * i)
        else:
            b.velocity(0.3, -0.2, 0.1)
    stop.set()
    for t in threads:
        t.join()
    assert not errors
    assert len(readings) > 10
    lim = b.limits()
    for r in readings:
        assert -math.pi <= r.pan <= math.pi
        assert lim.tilt_min <= r.tilt <= lim.tilt_max
        assert lim.zoom_min <= r.zoom <= lim.zoom_max


def test_limits_and_dynamics_from_the_virtual_camera_model():
    import yaml

    from axis_ptz_ros2.config import camera_model_from_dict, default_config_path
    from axis_ptz_ros2.virtual.backend import dynamics_from_model, limits_from_model

    raw = yaml.safe_load(default_config_path("virtual_camera.yaml").read_text(encoding="utf-8"))
    model = camera_model_from_dict(raw)
    lim = limits_from_model(model)
    assert (lim.pan_min, lim.pan_max) == pytest.approx((-math.pi, math.pi))
    assert lim.full_turn
    assert (lim.tilt_min, lim.tilt_max) == pytest.approx((-math.pi / 2, math.pi / 2))
    assert (lim.zoom_min, lim.zoom_max) == (1.0, 9999.0)
    dyn = dynamics_from_model(model, raw["dynamics"])
    assert dyn.max_pan_rate == pytest.approx(math.pi)  # 180°/s
    assert dyn.max_tilt_rate == pytest.approx(math.pi)
    assert (dyn.zoom_travel_s, dyn.instant) == (0.5, False)
    assert model.zoom.hfov(1) == pytest.approx(math.pi / 2)
    assert model.zoom.magnification(9999) == pytest.approx(8.0)
    assert (model.head.h_tilt, model.head.d_opt) == (0.0, (0.0, 0.0, 0.0))
