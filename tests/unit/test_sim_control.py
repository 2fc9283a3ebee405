"""The simulator's ``/sim/*`` control surface (:mod:`axis_ptz_ros2.sim.control`), without HTTP.

``handle`` is called as the HTTP listener calls it (path, query pairs in order) on a camera that is built but not
started (no sockets); what each request sets is read back from the camera and from the JSON it answers.
"""

from __future__ import annotations

import json
import threading
from typing import Any
from urllib.parse import parse_qsl

import pytest

from axis_ptz_ros2.sim import control
from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.sim.counts import RequestCounts
from axis_ptz_ros2.sim.digest import NONCE_LIFETIME_S
from axis_ptz_ros2.sim.faults import FaultConfig

pytestmark = pytest.mark.unit


@pytest.fixture(scope="module")
def camera() -> SimulatedCamera:
    return SimulatedCamera(port=0, rtsp_port=None)


@pytest.fixture
def cam(camera: SimulatedCamera) -> SimulatedCamera:
    """The module's camera, back at defaults for each test."""
    camera.set_faults(FaultConfig())
    camera.set_auth_options(nonce_lifetime_s=NONCE_LIFETIME_S, challenge_style="current")
    camera.teleport(0.0, 0.0, 1.0)
    camera.reset_counts()
    return camera


def ctl(cam: SimulatedCamera, query: str) -> control.ControlReply:
    """``GET /sim/control?<query>``, the pairs split as the HTTP listener splits them."""
    return control.handle(cam, "/sim/control", parse_qsl(query, keep_blank_values=True))


def body(reply: control.ControlReply) -> dict[str, Any]:
    out = json.loads(reply.body)
    assert isinstance(out, dict)
    return out


# --------------------------------------------------------------------------------------------------------
# paths
# --------------------------------------------------------------------------------------------------------
def test_sim_state_is_the_ground_truth_as_json(cam: SimulatedCamera) -> None:
    cam.teleport(12.5, -7.0, 300.0)
    reply = control.handle(cam, "/sim/state", [])
    assert reply.status == 200
    state = body(reply)
    assert (state["pan"], state["tilt"], state["zoom"]) == pytest.approx((12.5, -7.0, 300.0))
    assert state["faults"] == FaultConfig().as_dict()
    assert state["nonce_lifetime_s"] == NONCE_LIFETIME_S
    assert state["challenge_style"] == "current"
    assert state["rebooting"] is False
    assert reply.reboot_s is None


@pytest.mark.parametrize("path", ["/sim/other", "/sim/state/", "/sim", "/sim/control/x"])
def test_other_sim_paths_are_not_found(cam: SimulatedCamera, path: str) -> None:
    reply = control.handle(cam, path, [("teleport", "10,10,10")])
    assert (reply.status, reply.body, reply.reboot_s) == (404, "", None)
    assert cam.position() == pytest.approx((0.0, 0.0, 1.0))  # and nothing was done


# --------------------------------------------------------------------------------------------------------
# what each request sets
# --------------------------------------------------------------------------------------------------------
def test_faults_are_set_converted_from_text_and_answered_with_the_new_state(cam: SimulatedCamera) -> None:
    reply = ctl(cam, "stall_after_frames=10&stall_seconds=2.5&garbage_between_parts=yes&http_error=503"
                     "&http_error_scope=video")  # fmt: skip
    assert reply.status == 200
    f = cam.faults
    assert (f.stall_after_frames, f.stall_seconds, f.garbage_between_parts) == (10, 2.5, True)
    assert (f.http_error, f.http_error_scope) == (503, "video")
    assert f.drop_after_frames == 0  # untouched faults keep their values
    assert body(reply)["faults"] == f.as_dict()
    # a later request changes only what it names
    assert ctl(cam, "latency_ms=40").status == 200
    assert (cam.faults.latency_ms, cam.faults.stall_after_frames) == (40.0, 10)


def test_reset_faults_then_new_ones(cam: SimulatedCamera) -> None:
    cam.set_faults(drop_after_frames=5, bandwidth_kbps=100.0)
    reply = ctl(cam, "reset_faults&truncate_every=3")
    assert reply.status == 200
    assert cam.faults == FaultConfig(truncate_every=3)
    assert ctl(cam, "reset_faults=1").status == 200
    assert cam.faults == FaultConfig()


def test_reset_counts(cam: SimulatedCamera) -> None:
    cam.requests.count("ptz.cgi", 200)
    cam.requests.log_ptz("GET", "query=position", [("query", "position")])
    assert cam.request_counts.endpoints == {"ptz.cgi": 1}
    assert len(cam.request_counts.ptz_log) == 1
    reply = ctl(cam, "reset_counts")
    assert reply.status == 200
    assert cam.request_counts == RequestCounts()
    assert body(reply)["counts"]["endpoints"] == {}


def test_teleport_sets_the_pose_clamped_to_the_limits(cam: SimulatedCamera) -> None:
    reply = ctl(cam, "teleport=-45.5,20,2500")
    assert reply.status == 200
    assert cam.position() == pytest.approx((-45.5, 20.0, 2500.0))
    state = body(reply)
    assert (state["pan"], state["tilt"], state["zoom"], state["moving"]) == (
        pytest.approx(-45.5),
        pytest.approx(20.0),
        pytest.approx(2500.0),
        False,
    )
    lim = cam.world.limits
    assert ctl(cam, "teleport=1000,-1000,1e9").status == 200
    assert cam.position() == pytest.approx((lim.max_pan, lim.min_tilt, lim.max_zoom))


def test_auth_options(cam: SimulatedCamera) -> None:
    reply = ctl(cam, "nonce_lifetime=2.5&challenge_style=legacy")
    assert reply.status == 200
    assert (cam.nonce_lifetime_s, cam.challenge_style) == (2.5, "legacy")
    assert (body(reply)["nonce_lifetime_s"], body(reply)["challenge_style"]) == (2.5, "legacy")
    assert cam.authenticator.nonce_lifetime_s == 2.5  # the one CameraAuth the listeners ask


def test_a_reboot_is_only_described_until_the_reply_went_out(cam: SimulatedCamera) -> None:
    reply = ctl(cam, "reboot=3&reboot_blackhole=on&reboot_errors_s=1.5&reboot_error=empty")
    assert reply.status == 200
    assert reply.reboot_s == 3.0
    assert reply.reboot_opts == {"blackhole": True, "errors_s": 1.5, "error_kind": "empty"}
    assert body(reply)["rebooting"] is False  # nothing started yet
    assert not cam.rebooting
    plain = ctl(cam, "reboot=0.5")
    assert (plain.reboot_s, plain.reboot_opts) == (0.5, {})
    assert ctl(cam, "reboot_blackhole=0").reboot_opts == {"blackhole": False}
    assert ctl(cam, "reboot_blackhole=0").reboot_s is None  # options alone start nothing


class _RebootRecorder:
    def __init__(self) -> None:
        self.calls: list[tuple[tuple[Any, ...], dict[str, Any]]] = []
        self.called = threading.Event()

    def reboot(self, *args: Any, **kwargs: Any) -> None:
        self.calls.append((args, kwargs))
        self.called.set()


def test_start_reboot_calls_the_camera_in_the_background() -> None:
    rec = _RebootRecorder()
    reply = control.ControlReply(200, "{}", 2.0, {"blackhole": True, "errors_s": 1.0, "error_kind": "401"})
    reply.start_reboot(rec)  # type: ignore[arg-type]  # duck-typed: only reboot() is called
    assert rec.called.wait(5.0)
    assert rec.calls == [((2.0,), {"blackhole": True, "errors_s": 1.0, "error_kind": "401"})]
    idle = _RebootRecorder()
    control.ControlReply(200, "{}").start_reboot(idle)  # type: ignore[arg-type]
    assert not idle.called.wait(0.2)


# --------------------------------------------------------------------------------------------------------
# bad input: 400 with the reason, nothing half-applied to the faults
# --------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("query", "reason"),
    [
        ("bogus=1", "unknown fault 'bogus'"),
        ("stall_after_frames=ten", "invalid literal for int()"),
        ("stall_after_frames=-1", "stall_after_frames must be >= 0"),
        ("latency_ms=-5", "must be >= 0"),
        ("http_error=404", "http_error must be 0 or one of (401, 500, 503)"),
        ("http_error_scope=some", "http_error_scope must be one of ('all', 'video')"),
        ("teleport=1,2", "not enough values to unpack"),
        ("teleport=1,2,3,4", "too many values to unpack"),
        ("teleport=a,b,c", "could not convert string to float"),
        ("teleport=nan,0,1", "pose must be finite"),
        ("nonce_lifetime=0", "nonce_lifetime_s must be > 0"),
        ("nonce_lifetime=soon", "could not convert string to float"),
        ("challenge_style=modern", "challenge_style must be one of ('current', 'legacy')"),
        ("reboot=now", "could not convert string to float"),
        ("reboot=1&reboot_errors_s=x", "could not convert string to float"),
        ("reboot=1&reboot_error=418", "reboot_error must be one of ('503', 'empty', '401')"),
    ],
)
def test_bad_input_is_refused_with_the_reason(cam: SimulatedCamera, query: str, reason: str) -> None:
    before = (cam.faults, cam.position(), cam.nonce_lifetime_s, cam.challenge_style)
    reply = ctl(cam, query)
    assert reply.status == 400
    assert reason in body(reply)["error"]
    assert set(body(reply)) == {"error"}
    assert reply.reboot_s is None
    assert (cam.faults, cam.position(), cam.nonce_lifetime_s, cam.challenge_style) == before


@pytest.mark.parametrize(
    "good",
    ["teleport=30,-10,500", "nonce_lifetime=2.5&challenge_style=legacy", "reset_faults", "reset_counts",
     "stall_after_frames=10"],
)  # fmt: skip
@pytest.mark.parametrize("bad", ["http_error=999", "teleport=1,2", "challenge_style=modern", "reboot=-1"])
def test_good_arguments_before_a_bad_one_change_nothing(cam: SimulatedCamera, good: str, bad: str) -> None:
    """Bad input loses nothing: every argument is checked before any is applied (the teleport, auth options,
    fault reset and count reset of a request that also held a bad argument were applied up to 4a38692)."""
    cam.set_faults(truncate_every=7)
    cam.requests.count("ptz.cgi", 200)
    before = (cam.faults, cam.position(), cam.nonce_lifetime_s, cam.challenge_style, cam.request_counts)
    reply = ctl(cam, f"{good}&{bad}")
    assert reply.status == 400
    assert (reply.reboot_s, set(body(reply))) == (None, {"error"})
    assert (cam.faults, cam.position(), cam.nonce_lifetime_s, cam.challenge_style, cam.request_counts) == before


def test_reset_faults_resets_the_faults_named_before_it(cam: SimulatedCamera) -> None:
    assert ctl(cam, "truncate_every=3&reset_faults&latency_ms=40").status == 200
    assert cam.faults == FaultConfig(latency_ms=40.0)


def test_one_bad_fault_leaves_every_fault_of_the_request_unset(cam: SimulatedCamera) -> None:
    reply = ctl(cam, "stall_after_frames=10&drop_after_frames=3&http_error=999")
    assert reply.status == 400
    assert cam.faults == FaultConfig()


@pytest.mark.parametrize(
    "query", ["reboot=-1", "reboot=1&reboot_errors_s=-1", "reboot=nan", "reboot=inf", "reboot=1&reboot_errors_s=inf"]
)
def test_negative_reboot_durations_are_refused(cam: SimulatedCamera, query: str) -> None:
    reply = ctl(cam, query)
    assert reply.status == 400
    assert "must be >= 0" in body(reply)["error"]
