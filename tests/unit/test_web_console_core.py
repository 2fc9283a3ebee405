"""The web console's ROS-free layers: API parsing (bounded numbers), the page's view model, panorama clicks and
the token throttle's networks."""

from __future__ import annotations

import math
import types
from typing import Any

import numpy as np
import pytest

from axis_ptz_ros2.config import load_robot
from axis_ptz_ros2.geometry import direction_to_equirect
from axis_ptz_ros2.streaming.limits import BUDGET_RANGE_KBPS
from axis_ptz_ros2.teleop import keymap
from axis_ptz_ros2.web import api
from axis_ptz_ros2.web.api import BadRequest
from axis_ptz_ros2.web.auth import AuthThrottle, client_key
from axis_ptz_ros2.web.backend import CommandResult
from axis_ptz_ros2.web.panorama import cloud_in_base, look_target
from axis_ptz_ros2.web.view import (
    ConsoleModel,
    budget_answer,
    finite,
    in_turn,
    keymap_json,
    move_text,
    service_answer,
    video_answer,
    video_text,
)

pytestmark = pytest.mark.unit

CLICK = {"u": 300, "v": 200, "width": 352, "height": 288}


# ---------------------------------------------------------------------------------------------------------
# API parsing: the defects found by hand (issue 25) each refused with a reason
# ---------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("body", "words"),
    [
        ({**CLICK, "u": 10**400}, ["'u'", "out of range"]),  # was OverflowError → 500
        ({**CLICK, "width": 1e300}, ["'width'", "out of range", "4294967295"]),  # was SystemError → 500
        ({**CLICK, "height": 1e300}, ["'height'", "out of range"]),
        ({**CLICK, "width": 2**32 + 352, "height": 2**32 + 288}, ["'width'", "out of range"]),  # was wrapped
        ({**CLICK, "width": 0}, ["'width'", "1..4294967295"]),
        ({**CLICK, "width": -352}, ["'width'"]),
        ({**CLICK, "u": 400}, ["outside the 352x288 image"]),
        ({**CLICK, "u": -1}, ["outside"]),
        ({**CLICK, "u": "1"}, ["'u' must be a number"]),
        ({**CLICK, "u": True}, ["'u' must be a number"]),
        ({**CLICK, "u": math.inf}, ["'u' must be finite"]),
        ({**CLICK, "u": math.nan}, ["'u' must be finite"]),
        ({**CLICK, "width": 352.5}, ["'width' must be an integer"]),
        ({**CLICK, "zoom_delta": 1e30}, ["'zoom_delta'", "out of range"]),
        ({"u": 1, "v": 1, "width": 10}, ["missing 'height'"]),
    ],
)
def test_center_refusals_say_what_is_wrong(body: dict[str, Any], words: list[str]) -> None:
    with pytest.raises(BadRequest) as err:
        api.center_request(body)
    for w in words:
        assert w in str(err.value), (body, str(err.value))


def test_center_accepts_the_image_edges_and_the_largest_size() -> None:
    c = api.center_request({**CLICK, "u": 352, "v": 0, "zoom_delta": -9999})
    assert (c.click.x, c.click.y, c.click.width, c.click.height, c.zoom_delta) == (352, 0, 352, 288, -9999)
    big = api.center_request({"u": 0, "v": 0, "width": 2**32 - 1, "height": 2**32 - 1})
    assert big.click.width == api.UINT32_MAX
    assert api.center_request({**CLICK, "width": 352.0}).click.width == 352  # JSON 352.0 is an integer


@pytest.mark.parametrize(
    ("body", "words"),
    [
        ({"max_bitrate_kbps": 1e30}, ["'max_bitrate_kbps'", "out of range", "0..1000000"]),  # was 500
        ({"max_bitrate_kbps": 2**63}, ["'max_bitrate_kbps'", "out of range"]),  # was 500
        ({"max_bitrate_kbps": -2}, ["-1 = keep"]),
        ({"fps": 99}, ["'fps'", "1..30", "0 = keep"]),
        ({"fps": 2**64}, ["'fps'"]),
        ({"compression": 101}, ["'compression'", "0..100"]),
        ({"resolution": 704}, ["'resolution' must be a string"]),
        ({"resolution": "x" * 33}, ["at most 32 characters"]),
        ({"resolution": "704x576\x00"}, ["printable"]),  # a NUL would cut the ROS string: 704x576 was set
        ({}, ["nothing to change"]),
        ({"fps": 0, "compression": -1, "max_bitrate_kbps": -1}, ["nothing to change"]),
    ],
)
def test_video_refusals(body: dict[str, Any], words: list[str]) -> None:
    with pytest.raises(BadRequest) as err:
        api.video_request(body)
    for w in words:
        assert w in str(err.value), (body, str(err.value))


def test_video_keep_values_and_full_ranges() -> None:
    v = api.video_request({"fps": 30, "resolution": "704x576", "compression": 0, "max_bitrate_kbps": 1_000_000})
    assert (v.fps, v.resolution, v.compression, v.max_bitrate_kbps) == (30, "704x576", 0, 1_000_000)
    only_budget = api.video_request({"max_bitrate_kbps": 0})
    assert not only_budget.changes_stream
    assert only_budget.max_bitrate_kbps == 0


def test_video_ranges_are_the_stream_nodes_parameter_ranges() -> None:
    from axis_ptz_ros2.nodes.stream_node import PARAMS  # noqa: PLC0415 - the ROS tier may be missing

    specs = {p.name: p for p in PARAMS}
    limits = api.video_limits()
    assert set(limits) == {"fps", "compression", "max_bitrate_kbps"}
    for name, (lo, hi) in limits.items():
        assert specs[name].int_range == (lo, hi), name
    assert limits["max_bitrate_kbps"] == BUDGET_RANGE_KBPS == (0, 1_000_000)


def test_the_page_gets_the_video_ranges_with_the_state() -> None:
    limits = ConsoleModel().state(False, {})["limits"]
    assert limits == {"fps": [1, 30], "compression": [0, 100], "max_bitrate_kbps": [0, 1_000_000]}
    assert all(isinstance(x, int) for pair in limits.values() for x in pair)  # JSON 1, not 1.0


def test_route_table_covers_every_command() -> None:
    posts = {r.path for r in api.ROUTES if r.method == "POST" and r.path.startswith("/api/")}
    assert posts == {f"/api/{c}" for c in api.COMMANDS}


# ---------------------------------------------------------------------------------------------------------
# view model
# ---------------------------------------------------------------------------------------------------------
class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def _video(**kw: Any) -> Any:
    base = {"fps": 10, "resolution": "704x576", "width": 704, "height": 576, "compression": 30,
            "max_bitrate_kbps": 800, "source": "camera", "available_resolutions": ["704x576", "176x144"],
            "codec": "mjpeg", "h264_bitrate_kbps": 1000, "h264_max_bitrate_kbps": 1500}  # fmt: skip
    return types.SimpleNamespace(**{**base, **kw})


def test_view_model_meters_the_ptz_frames_and_reports_latency() -> None:
    clock, wall = Clock(), Clock()
    wall.t = 1_700_000_000.0
    m = ConsoleModel(clock, wall)
    for i in range(11):  # 10 fps, 1000 bytes
        clock.t = 100.0 + i * 0.1
        m.ptz_frame(1000, wall.t - 0.05)
    s = m.state(True, {})
    assert s["stream"]["fps"] == pytest.approx(10.0)
    assert s["stream"]["kbps"] == pytest.approx(80.0)
    assert s["stream"]["latency_ms"] == pytest.approx(50.0)
    assert m.state(False, {})["stream"]["latency_ms"] is None
    assert m.state(False, {})["stream"]["measured_at"] == "none"


def test_view_model_video_resolutions_diagnostics_errors_and_extra() -> None:
    m = ConsoleModel()
    m.video_params(_video())
    m.diagnostics("axis_stream: stream", "ok", {"fps": "9.8", "kbit/s": "700"})
    m.diagnostics("axis_ptz: ptz", "ok", {"fps": "1"})  # not a stream status: ignored
    m.error("center: refused")
    s = m.state(False, {"stream": {"watchers": {"ptz": 0}}, "services": {"center": True}})
    assert s["resolutions"] == ["176x144", "704x576"]
    assert s["budget_kbps"] == 800
    assert s["driver"]["name"] == "axis_stream: stream"
    assert s["driver"]["kbit/s"] == "700"
    assert s["errors"][0]["message"] == "center: refused"
    assert s["stream"]["watchers"] == {"ptz": 0}  # merged into the model's own stream section
    assert "fps" in s["stream"]
    assert s["services"] == {"center": True}


def test_view_model_nan_is_null_and_keys_follow_the_keymap() -> None:
    m = ConsoleModel()
    ptz = types.SimpleNamespace(pan=0.1, tilt=-0.2, zoom=1.0, magnification=1.0, hfov=1.0, vfov=0.7, moving=False,
                                zoom_min=1.0, zoom_max=9999.0, zoom_capped=False, zoom_cap=math.nan,
                                requested_zoom=math.nan)  # fmt: skip
    m.ptz_state(ptz)
    s = m.state(False, {})
    assert s["ptz"]["zoom_cap"] is None
    assert s["ptz"]["pan_deg"] == pytest.approx(math.degrees(0.1))
    assert finite({"a": [math.inf, 1.0]}) == {"a": [None, 1.0]}
    label, commands, step = m.key("ArrowLeft")
    assert label == keymap.key_label("<left>")
    assert isinstance(commands[0], keymap.RelativeMove)
    assert "pan" in move_text(commands[0])
    assert step == 1
    with pytest.raises(BadRequest, match="not in the key map"):
        m.key("F13")
    quits = [k for k, a in keymap.KEYMAP.items() if a.kind is keymap.Kind.QUIT]
    with pytest.raises(BadRequest):
        m.key(quits[0])
    assert {k["key"] for k in keymap_json()["keys"]}.isdisjoint(quits)


# ---------------------------------------------------------------------------------------------------------
# panorama clicks
# ---------------------------------------------------------------------------------------------------------
def test_panorama_click_uses_laser_then_ground_and_names_unknown_frames() -> None:
    robot = load_robot(None)
    w, h = 2048, 1024
    # a wall of laser points 4 m ahead of the panorama in base_link, around its forward direction
    centre = np.asarray(robot.panorama.pose.t, dtype=np.float64)
    ahead = centre + np.array([4.0, 0.0, 0.0])
    cloud = ahead + np.random.default_rng(1).normal(0, 0.01, (200, 3))
    d_pano = robot.panorama.pose.inverse().R @ np.array([1.0, 0.0, 0.0])
    x, y = (float(c) for c in direction_to_equirect(d_pano, w, h))
    click = api.pixel_click({"x": x, "y": y, "width": w, "height": h}, "x", "y", "panorama")
    base, warn = cloud_in_base(cloud, "base_link", robot)
    assert warn == ""
    t = look_target(click, robot, base, warn, 5.0)
    assert t.depth_source == "laser"
    assert t.range_m == pytest.approx(4.0, abs=0.1)
    assert t.click["laser_points"] == 200
    assert "laser" in t.message
    none, why = cloud_in_base(cloud, "elsewhere", robot)
    assert none is None
    assert "unknown" in why
    assert cloud_in_base(None, "", robot) == (None, "no laser data")
    t2 = look_target(click, robot, None, "no laser data", 5.0)
    assert t2.depth_source != "laser"
    assert "(no laser data)" in t2.message


# ---------------------------------------------------------------------------------------------------------
# throttle: rotating source addresses buy no fresh guesses
# ---------------------------------------------------------------------------------------------------------
def test_client_key_groups_loopback_and_ipv6_prefixes() -> None:
    assert client_key("127.0.0.1") == client_key("127.8.9.10") == client_key("::1") == "loopback"
    assert client_key("::ffff:127.0.0.5") == "loopback"
    assert client_key("2001:db8:1:2::5") == client_key("2001:db8:1:2:ffff::1") == "2001:db8:1:2::/64"
    assert client_key("2001:db8:1:3::5") != client_key("2001:db8:1:2::5")
    assert client_key("192.0.2.7") == "192.0.2.7"
    assert client_key("::ffff:192.0.2.7") == "192.0.2.7"
    assert client_key("fe80::1%eth0") == "fe80::/64"


def test_rotating_addresses_share_one_allowance_and_a_global_cap_holds() -> None:
    t = AuthThrottle(max_failures=3, window=10.0, global_cap=5)
    for i in range(3):
        t.failed(f"127.0.0.{i + 2}", now=0.0)
    assert t.retry_after("127.0.0.99", now=1.0) == pytest.approx(9.0)
    for i in range(3):
        t.failed(f"2001:db8::{i + 1}", now=0.0)
    assert t.retry_after("2001:db8::ffff", now=1.0) == pytest.approx(9.0)
    # 6 failures from two networks: every network, even a new one, waits for the global window
    assert t.retry_after("192.0.2.1", now=1.0) == pytest.approx(9.0)
    assert t.retry_after("192.0.2.1", now=10.0) == 0.0
    t2 = AuthThrottle(max_failures=3, window=10.0, global_cap=5)
    t2.failed("192.0.2.1", now=0.0)
    assert t2.retry_after("192.0.2.2", now=0.0) == 0.0  # IPv4 sources are separate below the cap
    with pytest.raises(ValueError, match="global_cap"):
        AuthThrottle(max_failures=5, global_cap=4)


# ---- answers to the operator's commands -------------------------------------------------------------------
def test_service_answers_say_what_was_done_or_why_not():
    assert service_answer(True, "", "going home").body() == {"ok": True, "message": "going home"}
    assert service_answer(True, "clamped", "centring").message == "centring (clamped)"
    refused = service_answer(False, "", "centring")
    assert (refused.ok, refused.status, refused.message) == (False, 409, "centring: refused: no reason given")
    assert service_answer(False, "outside the image", "centring").message == "centring: refused: outside the image"


def test_the_quality_keys_act_on_the_compression_or_in_h264_mode_on_the_bitrates() -> None:
    """As the keyboard teleop's: Y/H step the JPEG compression with MJPEG, the H.264 bitrates (the start and the
    ceiling, together) in H.264 mode; the page's video line says which."""
    m = ConsoleModel()
    m.video_params(_video())
    _label, commands, _step = m.key("y")
    assert commands == [keymap.SetVideo(compression=30 + keymap.COMPRESSION_STEP)]
    assert m.state(False, {})["video"]["codec"] == "mjpeg"
    m.video_params(_video(codec="h264"))
    _label, commands, _step = m.key("y")  # compression up = a smaller picture: a lower bitrate
    (c,) = commands
    assert isinstance(c, keymap.SetVideo)
    assert c.h264_bitrate_kbps < 1000
    assert c.h264_max_bitrate_kbps < 1500
    assert c.h264_bitrate_kbps <= c.h264_max_bitrate_kbps
    assert c.compression == -1  # the compression is kept
    _label, commands, _step = m.key("h")
    assert commands[0].h264_bitrate_kbps > 1000
    video = m.state(False, {})["video"]
    assert (video["codec"], video["h264_bitrate_kbps"], video["h264_max_bitrate_kbps"]) == ("h264", 1000, 1500)
    assert video["text"] == "704x576 at 10 fps, H.264 1000 kbit/s (up to 1500 with feedback)"  # the page's line
    assert video_text(_video(codec="h264")) == "704x576 at 10 fps, H.264 1000 kbit/s (up to 1500 with feedback)"
    assert video_text(_video()) == "704x576 at 10 fps, compression 30"


def test_video_and_budget_answers():
    assert video_answer(True, "", "CIF at 5 fps, compression 30").message == "video CIF at 5 fps, compression 30"
    assert video_answer(True, "nothing to change", "x").message == "video x (nothing to change)"
    refused = video_answer(False, "", "x")
    assert (refused.message, refused.status) == ("video parameters refused", 409)
    assert video_answer(False, "not in the camera's list", "x").message == "not in the camera's list"
    assert budget_answer(True, "", 500).message == "bandwidth budget 500 kbit/s"
    assert budget_answer(True, "", 0).message == "bandwidth budget off"
    assert budget_answer(False, "", 5).message == "bandwidth budget refused: no reason given"


def test_the_steps_of_a_command_stop_at_the_first_refusal():
    ran: list[str] = []

    def step(name: str, ok: bool = True):
        def run() -> CommandResult:
            ran.append(name)
            return CommandResult(ok, name, 200 if ok else 409)

        return run

    assert in_turn([step("a"), step("b")]).message == "a; b"
    assert in_turn([]).body() == {"ok": True, "message": ""}
    ran.clear()
    result = in_turn([step("a"), step("b", ok=False), step("c")])
    assert (result.ok, result.message, result.status) == (False, "b", 409)
    assert ran == ["a", "b"]  # c never ran
