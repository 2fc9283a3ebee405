"""Every ROS input of the PTZ node, generated (issue 25): services and command topics with NaN, ±inf, huge and
negative numbers, sizes up to the top of uint32, odd strings and frames — against the simulated camera over real
DDS. Properties: every service answers (the node keeps working), a refusal says why, and nothing reaches the
camera that is not valid: every number in every ``ptz.cgi`` request the simulator received is finite and within
the camera's limits.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any
from urllib.parse import parse_qsl

import pytest

pytest.importorskip("rclpy")

from geometry_msgs.msg import PointStamped  # noqa: E402
from hypothesis import given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from axis_ptz_interfaces.msg import PixelTarget, PtzCommand, PtzVelocity  # noqa: E402
from axis_ptz_interfaces.srv import AreaZoom, CenterOnPixel, LookAt, MovePtz, Preset, SetZoom  # noqa: E402
from axis_ptz_ros2.nodes.common import COMMAND_QOS  # noqa: E402
from axis_ptz_ros2.nodes.ptz_node import PtzNode  # noqa: E402
from axis_ptz_ros2.sim.camera import SimulatedCamera  # noqa: E402
from axis_ptz_ros2.sim.ptz import Speeds  # noqa: E402
from axis_ptz_ros2.sim.world import load_world  # noqa: E402
from tests.fuzz.ros_profile import ros_settings  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402

pytestmark = [pytest.mark.fuzz, pytest.mark.timeout(600)]


_f64 = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(-10.0, 10.0),
    st.sampled_from([0.0, -0.0, 1e308, -1e308, 5e-324, math.pi, -math.pi, 9999.0, 10000.0, -1.0]),
)
_u32 = st.one_of(st.integers(0, 2**32 - 1), st.sampled_from([0, 1, 352, 704, 2**31, 2**32 - 1]))
_text = st.one_of(st.text(max_size=40), st.sampled_from(["", "home", "Home", "a" * 31, "a" * 32, 'x"<>~:', "\x00"]))


@pytest.fixture(scope="module")
def rig() -> Iterator[tuple[RosHarness, SimulatedCamera, PtzNode, Any]]:
    cam = SimulatedCamera(load_world(), port=0, speeds=Speeds(300.0, 300.0, 0.5, 0.5)).start()
    ros = RosHarness()
    try:
        node = ros.add(PtzNode(context=ros.context, parameter_overrides=[Parameter("port", value=cam.port)]))
        ros.wait_for(lambda: node.poller.latest is not None, 10.0)
        probe = ros.probe("fuzz_probe")
        yield ros, cam, node, probe
    finally:
        ros.close()
        cam.stop()


def _answer(ros: RosHarness, probe: Any, srv_type: Any, name: str, request: Any) -> Any:
    clients = probe.__dict__.setdefault("_fuzz_clients", {})
    if name not in clients:
        clients[name] = probe.create_client(srv_type, name)
    response = ros.call(clients[name], request, timeout=10.0)
    assert response is not None, f"{name}: no answer"
    if hasattr(response, "success") and not response.success:
        assert response.message.strip(), f"{name} refused {request} without a reason"
    return response


def _camera_saw_only_valid_requests(cam: SimulatedCamera) -> None:
    lim = cam.world.limits
    for entry in cam.request_counts.ptz_log:
        args = dict(parse_qsl(entry.query, keep_blank_values=True))
        for key, value in args.items():
            for part in value.split(","):
                try:
                    number = float(part)
                except ValueError:
                    continue
                assert math.isfinite(number), f"camera got {key}={value} ({entry.query})"
        if "pan" in args:
            assert lim.min_pan - 1e-6 <= float(args["pan"]) <= lim.max_pan + 1e-6, entry.query
        if "tilt" in args:
            assert lim.min_tilt - 1e-6 <= float(args["tilt"]) <= lim.max_tilt + 1e-6, entry.query
        if "zoom" in args:
            assert lim.min_zoom <= float(args["zoom"]) <= lim.max_zoom, entry.query
        for size in ("imagewidth", "imageheight"):
            if size in args:
                assert 1 <= int(args[size]) <= 16384, entry.query


@ros_settings
@given(st.tuples(_f64, _f64, _f64, _f64), st.booleans())
def test_move_services(rig: Any, values: tuple[float, float, float, float], relative: bool) -> None:
    ros, cam, _node, probe = rig
    request = MovePtz.Request(command=PtzCommand(pan=values[0], tilt=values[1], zoom=values[2], speed=values[3]))
    _answer(ros, probe, MovePtz, "ptz/move_relative" if relative else "ptz/move_absolute", request)
    _camera_saw_only_valid_requests(cam)


@ros_settings
@given(_f64, _f64, _u32, _u32, _f64)
def test_center_on_pixel(rig: Any, u: float, v: float, width: int, height: int, zoom_delta: float) -> None:
    ros, cam, _node, probe = rig
    target = PixelTarget(u=u, v=v, image_width=width, image_height=height, zoom_delta=zoom_delta)
    _answer(ros, probe, CenterOnPixel, "ptz/center", CenterOnPixel.Request(target=target))
    _camera_saw_only_valid_requests(cam)


@ros_settings
@given(st.tuples(_f64, _f64, _f64, _f64), _u32, _u32)
def test_area_zoom(rig: Any, box: tuple[float, float, float, float], width: int, height: int) -> None:
    ros, cam, _node, probe = rig
    request = AreaZoom.Request(u_min=box[0], v_min=box[1], u_max=box[2], v_max=box[3])
    request.image_width, request.image_height = width, height
    _answer(ros, probe, AreaZoom, "ptz/area_zoom", request)
    _camera_saw_only_valid_requests(cam)


@ros_settings
@given(_f64, _f64, _f64)
def test_set_zoom(rig: Any, zoom: float, magnification: float, hfov: float) -> None:
    ros, cam, _node, probe = rig
    _answer(ros, probe, SetZoom, "ptz/set_zoom", SetZoom.Request(zoom=zoom, magnification=magnification, hfov=hfov))
    _camera_saw_only_valid_requests(cam)


@ros_settings
@given(st.tuples(_f64, _f64, _f64), _text, _f64)
def test_look_at(rig: Any, point: tuple[float, float, float], frame: str, zoom: float) -> None:
    ros, cam, _node, probe = rig
    target = PointStamped()
    target.header.frame_id = frame
    target.point.x, target.point.y, target.point.z = point
    _answer(ros, probe, LookAt, "ptz/look_at", LookAt.Request(target=target, zoom=zoom))
    _camera_saw_only_valid_requests(cam)


@ros_settings
@given(st.one_of(_text, st.sampled_from(["go", "set", "remove", "list"])), _text)
def test_presets(rig: Any, action: str, name: str) -> None:
    ros, cam, _node, probe = rig
    _answer(ros, probe, Preset, "ptz/preset", Preset.Request(action=action, name=name))
    _camera_saw_only_valid_requests(cam)


def test_command_topics_then_the_node_still_moves_the_camera(rig: Any) -> None:
    """Garbage on every command topic, then a valid absolute move still arrives at the camera."""
    ros, cam, node, probe = rig
    absolute = probe.create_publisher(PtzCommand, "ptz/cmd/absolute", COMMAND_QOS)
    velocity = probe.create_publisher(PtzVelocity, "ptz/cmd/velocity", COMMAND_QOS)
    center = probe.create_publisher(PixelTarget, "ptz/cmd/center", COMMAND_QOS)
    ros.wait_for(lambda: absolute.get_subscription_count() > 0 and velocity.get_subscription_count() > 0)
    bad = [math.nan, math.inf, -math.inf, 1e308, -1e308]
    for x in bad:
        absolute.publish(PtzCommand(pan=x, tilt=x, zoom=x, speed=x))
        velocity.publish(PtzVelocity(pan_rate=x, tilt_rate=x, zoom_rate=x))
        center.publish(PixelTarget(u=x, v=x, image_width=2**32 - 1, image_height=0, zoom_delta=x))

    # Messages on different topics are not ordered with each other: re-send a valid absolute command on the same
    # topic as the garbage until the camera holds it, so no garbage is still in flight when the service is called.
    def holds_topic_target() -> bool:  # checked, then sent again, every 0.5 s (the wait's period)
        pan, tilt, _ = cam.position()
        if abs(pan - 10.0) < 0.5 and abs(tilt - 5.0) < 0.5:
            return True
        absolute.publish(PtzCommand(pan=math.radians(-10.0), tilt=math.radians(5.0), zoom=math.nan, speed=math.nan))
        return False

    ros.wait_for(holds_topic_target, 20.0, period=0.5)
    request = MovePtz.Request(command=PtzCommand(pan=math.radians(-20.0), tilt=math.radians(10.0), zoom=500.0))
    request.wait, request.timeout_s = True, 20.0
    response = _answer(ros, probe, MovePtz, "ptz/move_absolute", request)
    assert response.success, response.message
    pan, tilt, zoom = cam.position()
    assert pan == pytest.approx(20.0, abs=0.5)  # VAPIX pan is clockwise-positive: -20° REP-103 is +20° VAPIX
    assert tilt == pytest.approx(10.0, abs=0.5)
    assert zoom == pytest.approx(500, abs=2)
    _camera_saw_only_valid_requests(cam)
