"""The one way nodes hold parameters (:mod:`axis_ptz_ros2.nodes.live_params`, issue 38 item 2).

Over real DDS, through the nodes' own parameter services (what ``ros2 param set`` / ``ros2 param get`` call): a
proposed change is judged as a whole; a refused one leaves the snapshot, the node's state and ``param get``
untouched; an accepted one swaps the snapshot, reaches the node's ``on_change`` once with the names that were set,
and ``param get`` then tells what the node uses. One test per node family (PTZ, stream, virtual camera, teleop,
visualizer, republish); the PTZ node's stream size is runtime state that never rewrites its parameters.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rclpy")

import yaml  # noqa: E402
from rcl_interfaces.msg import SetParametersResult  # noqa: E402
from rcl_interfaces.srv import GetParameters, SetParametersAtomically  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter, parameter_value_to_python  # noqa: E402

from axis_ptz_interfaces.msg import VideoParams  # noqa: E402
from axis_ptz_ros2.nodes.common import LATCHED_QOS, ParamSpec  # noqa: E402
from axis_ptz_ros2.nodes.live_params import LiveParams, Params  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]


# ------------------------------------------------------------------------------------------------------
# helpers: the parameter services, as the ros2 CLI calls them
# ------------------------------------------------------------------------------------------------------
class Remote:
    """``ros2 param set`` (atomically) and ``ros2 param get`` against one node, from a probe node."""

    def __init__(self, ros: RosHarness, probe: Node, node: Node) -> None:
        name = node.get_fully_qualified_name()
        self.ros = ros
        self._set = probe.create_client(SetParametersAtomically, f"{name}/set_parameters_atomically")
        self._get = probe.create_client(GetParameters, f"{name}/get_parameters")

    def set(self, **values: Any) -> SetParametersResult:
        req = SetParametersAtomically.Request()
        req.parameters = [Parameter(k, value=v).to_parameter_msg() for k, v in values.items()]
        return self.ros.call(self._set, req).result

    def get(self, *names: str) -> dict[str, Any]:
        req = GetParameters.Request()
        req.names = list(names)
        values = self.ros.query(self._get, req).values
        return {n: _plain(parameter_value_to_python(v)) for n, v in zip(names, values, strict=True)}


def _plain(value: Any) -> Any:  # noqa: ANN401
    return tuple(value) if isinstance(value, list) else value


def assert_get_tells_the_snapshot(remote: Remote, live: LiveParams, *names: str) -> None:
    """What ``ros2 param get`` returns is the snapshot the node reads."""
    assert remote.get(*names) == {n: live.params[n] for n in names}


# ------------------------------------------------------------------------------------------------------
# the listener itself
# ------------------------------------------------------------------------------------------------------
SPECS = (
    ParamSpec("low", 1, "lower bound", int_range=(0, 100)),
    ParamSpec("high", 10, "upper bound", int_range=(0, 100)),
    ParamSpec("mode", "a", "a mode", choices=("a", "b")),
    ParamSpec("names", ["x", "y"], "a list"),
    ParamSpec("fixed", 3.0, "read-only", read_only=True),
)


class ListenerNode(Node):
    """A node whose state follows its listener: ``span`` is built only in on_change."""

    def __init__(self, context: Any) -> None:  # noqa: ANN401
        super().__init__("live_params_probe_node", context=context)
        self.changes: list[frozenset[str]] = []
        self.validated: list[tuple[Params, frozenset[str]]] = []
        self.live = LiveParams(self, SPECS, validate=self._validate, on_change=self._on_change)
        self.span = (self.live.params["low"], self.live.params["high"])

    def _validate(self, candidate: Params, names: frozenset[str]) -> str | None:
        self.validated.append((candidate, names))
        if candidate["low"] > candidate["high"]:
            return f"low ({candidate['low']}) must not exceed high ({candidate['high']})"
        return None

    def _on_change(self, names: frozenset[str]) -> None:
        self.changes.append(names)
        self.span = (self.live.params["low"], self.live.params["high"])


def test_a_refused_set_leaves_the_snapshot_the_state_and_param_get_untouched(ros: RosHarness) -> None:
    node = ros.add(ListenerNode(ros.context))
    remote = Remote(ros, ros.probe(), node)
    before = node.live.params
    res = remote.set(low=50)  # 50 > high 10: the whole candidate is judged
    assert not res.successful
    assert res.reason == "low (50) must not exceed high (10)"
    assert node.live.params is before  # nothing swapped
    assert node.span == (1, 10)
    assert node.changes == []
    assert remote.get("low", "high") == {"low": 1, "high": 10}
    # the candidate the validator saw had the change; the snapshot never did
    candidate, names = node.validated[-1]
    assert (candidate["low"], names) == (50, frozenset({"low"}))
    # choices refused with ParamSpec.check's reason; read-only and range by rclpy: all leave everything as it was
    res = remote.set(mode="c")
    assert (res.successful, res.reason) == (False, "mode='c' is not one of a, b")
    assert not remote.set(fixed=4.0).successful
    assert not remote.set(high=101).successful
    assert node.live.params is before
    assert node.changes == []
    assert_get_tells_the_snapshot(remote, node.live, "low", "high", "mode", "names", "fixed")


def test_a_multi_parameter_set_is_validated_together_and_on_change_gets_the_names(ros: RosHarness) -> None:
    node = ros.add(ListenerNode(ros.context))
    remote = Remote(ros, ros.probe(), node)
    assert not remote.set(low=50).successful  # alone: refused
    res = remote.set(low=50, high=60)  # together: a valid whole
    assert res.successful, res.reason
    assert node.changes == [frozenset({"low", "high"})]  # one call for the whole set
    assert node.span == (50, 60)
    assert_get_tells_the_snapshot(remote, node.live, "low", "high")
    # a list parameter: the snapshot holds a tuple (nothing mutable is shared)
    assert remote.set(names=["p", "q", "r"]).successful
    assert node.live.params["names"] == ("p", "q", "r")
    assert node.changes[-1] == frozenset({"names"})
    assert_get_tells_the_snapshot(remote, node.live, "names")


def test_parameters_of_others_do_not_reach_the_validator_or_on_change(ros: RosHarness) -> None:
    node = ros.add(ListenerNode(ros.context))
    n_validated = len(node.validated)
    node.declare_parameter("someone_elses", 1)  # e.g. rclpy's qos_overrides.* declared by a publisher
    assert node.set_parameters([Parameter("someone_elses", value=2)])[0].successful
    assert len(node.validated) == n_validated
    assert node.changes == []
    res = node.set_parameters_atomically([Parameter("someone_elses", value=3), Parameter("low", value=2)])
    assert res.successful
    assert node.changes == [frozenset({"low"})]


def test_the_snapshot_is_read_only() -> None:
    p = Params({"a": [1, 2], "b": 3})
    assert p["a"] == (1, 2)
    with pytest.raises(AttributeError):
        p.b = 4  # type: ignore[attr-defined]
    with pytest.raises(TypeError):
        p["b"] = 4  # type: ignore[index]
    assert p.replace({"b": 4})["b"] == 4
    assert p["b"] == 3
    with pytest.raises(KeyError, match="unknown parameter"):
        p.replace({"c": 1})


# ------------------------------------------------------------------------------------------------------
# node families: `ros2 param get` tells what the node uses, after a refused and an accepted set
# ------------------------------------------------------------------------------------------------------
def _virtual_backend() -> tuple[Any, Any]:
    from axis_ptz_ros2.config import camera_model_from_dict, default_config_path
    from axis_ptz_ros2.virtual.backend import VirtualPtzBackend, dynamics_from_model, limits_from_model
    from axis_ptz_ros2.virtual.camera import view_model_dict

    raw = yaml.safe_load(default_config_path("virtual_camera.yaml").read_text(encoding="utf-8")) or {}
    raw = view_model_dict(raw, 640, 480)
    model = camera_model_from_dict(raw)
    backend = VirtualPtzBackend(limits_from_model(model), model.zoom, dynamics_from_model(model, raw.get("dynamics")))
    return backend, model


def test_ptz_node_param_get_tells_what_it_uses_and_the_stream_size_is_runtime_state(ros: RosHarness) -> None:
    from axis_ptz_ros2.nodes.ptz_node import PtzNode

    backend, model = _virtual_backend()
    node = ros.add(PtzNode(backend=backend, model=model, context=ros.context))
    probe = ros.probe()
    remote = Remote(ros, probe, node)
    live = node.live_params
    tol = node.commander.tol
    assert not remote.set(velocity_timeout=100.0).successful  # out of range
    assert not remote.set(drive_topic_type="twist").successful  # read-only
    assert node.commander.tol is tol
    assert_get_tells_the_snapshot(remote, live, "velocity_timeout", "arrival_tolerance")
    assert remote.set(velocity_timeout=0.3, arrival_tolerance=0.02).successful
    assert remote.get("velocity_timeout", "arrival_tolerance") == {"velocity_timeout": 0.3, "arrival_tolerance": 0.02}
    assert (node.commander.tol.velocity_timeout_s, node.commander.tol.pan_tilt_rad) == (0.3, 0.02)

    # the stream size: the parameters until video/params tells one; never written back into them
    assert node.image_size() == (704, 576)
    pub = ros.wait_matched(probe.create_publisher(VideoParams, "video/params", LATCHED_QOS))
    pub.publish(VideoParams(width=1280, height=720))
    ros.wait_for(lambda: node.image_size() == (1280, 720))
    assert remote.get("image_width", "image_height") == {"image_width": 704, "image_height": 576}
    assert_get_tells_the_snapshot(remote, live, "image_width", "image_height", "follow_video_params")
    assert not remote.set(image_width=0).successful  # range: nothing changes
    assert node.image_size() == (1280, 720)
    assert remote.set(follow_video_params=False).successful  # now the parameters are the size in use
    assert node.image_size() == (704, 576)
    assert remote.set(image_width=800, image_height=600).successful
    assert node.image_size() == (800, 600) == tuple(remote.get("image_width", "image_height").values())
    assert remote.set(follow_video_params=True).successful  # the size video/params told is still known
    assert node.image_size() == (1280, 720)


def test_virtual_camera_param_get_tells_what_it_uses(ros: RosHarness, tmp_path: Path) -> None:
    from axis_ptz_ros2.nodes.virtual_camera import VirtualCameraNode

    node = ros.add(VirtualCameraNode(context=ros.context))
    ptz = ros.add(node.ptz)
    probe = ros.probe()
    remote, ptz_remote = Remote(ros, probe, node), Remote(ros, probe, ptz)
    # the PTZ node's view size is the render's: the rule the virtual camera added to the PTZ node's listener
    res = ptz_remote.set(image_width=1280, wait_timeout=20.0)  # refused as a whole: wait_timeout stays too
    assert not res.successful
    assert res.reason == "image_width is fixed by the virtual camera (its width/height parameters)"
    assert ptz_remote.get("image_width", "wait_timeout") == {"image_width": 640, "wait_timeout": 15.0}
    assert ptz.image_size() == (640, 480)
    assert ptz_remote.set(wait_timeout=20.0).successful
    assert_get_tells_the_snapshot(ptz_remote, ptz.live_params, "wait_timeout", "image_width", "image_height")
    # its own live parameters
    assert not remote.set(jpeg_quality=0).successful
    assert not remote.set(width=320).successful  # read-only
    assert_get_tells_the_snapshot(remote, node.live_params, "jpeg_quality", "min_rate", "width")
    assert remote.set(jpeg_quality=55, min_rate=2.0).successful
    assert remote.get("jpeg_quality", "min_rate") == {"jpeg_quality": 55, "min_rate": 2.0}
    assert_get_tells_the_snapshot(remote, node.live_params, "jpeg_quality", "min_rate")


def test_stream_node_param_get_tells_what_it_uses(ros: RosHarness) -> None:
    from axis_ptz_ros2.nodes.stream_node import StreamNode
    from axis_ptz_ros2.sim.camera import SimulatedCamera
    from tests.support.sim import FAST_STREAM_PARAMS

    cam = SimulatedCamera(host="127.0.0.1", port=0).start()
    try:
        values = {"port": cam.port, **FAST_STREAM_PARAMS, "fps": 10}
        node = ros.add(
            StreamNode(context=ros.context, parameter_overrides=[Parameter(k, value=v) for k, v in values.items()])
        )
        probe = ros.probe()
        remote = Remote(ros, probe, node)
        announced: list[VideoParams] = []
        probe.create_subscription(VideoParams, "video/params", announced.append, LATCHED_QOS)
        ros.wait_for(lambda: announced)
        settings = node._video.settings  # noqa: SLF001 - what the video pipeline was handed
        res = remote.set(fps=12, resolution="banana")  # one bad value refuses the whole set
        assert not res.successful
        assert "banana" in res.reason
        assert node._video.settings is settings  # noqa: SLF001
        assert remote.get("fps", "resolution") == {"fps": 10, "resolution": ""}
        assert not remote.set(hostname="10.0.0.1").successful  # read-only
        res = remote.set(fps=12, compression=40)
        assert res.successful, res.reason
        assert remote.get("fps", "compression") == {"fps": 12, "compression": 40}
        assert (node._video.settings.fps, node._video.settings.compression) == (12, 40)  # noqa: SLF001
        ros.wait_for(lambda: announced[-1].fps == 12 and announced[-1].compression == 40)
        assert_get_tells_the_snapshot(remote, node.live_params, "fps", "compression", "lazy", "zoom", "codec")
    finally:
        cam.stop()


def test_joy_teleop_param_get_tells_what_it_uses(ros: RosHarness) -> None:
    from axis_ptz_ros2.nodes.joy_teleop import JoyTeleopNode

    node = ros.add(JoyTeleopNode(context=ros.context))
    remote = Remote(ros, ros.probe(), node)
    joy_map = node.teleop.joy_map
    names = node.live_params.params["preset_names"]
    n = len(names)
    buttons = list(range(4, 4 + n + 1))
    res = remote.set(preset_buttons=buttons, pan_axis=2)  # more buttons than names: the whole set refused
    assert not res.successful
    assert "one name per button" in res.reason
    assert node.teleop.joy_map is joy_map
    assert_get_tells_the_snapshot(remote, node.live_params, "preset_buttons", "preset_names", "pan_axis")
    res = remote.set(preset_buttons=buttons, preset_names=[*names, "extra"], pan_axis=2)  # valid together
    assert res.successful, res.reason
    assert node.teleop.joy_map.pan_axis == 2
    assert node.teleop.joy_map.preset_names == (*names, "extra")
    assert_get_tells_the_snapshot(remote, node.live_params, "preset_buttons", "preset_names", "pan_axis")


def test_visualizer_param_get_tells_what_it_uses(ros: RosHarness) -> None:
    from axis_ptz_ros2.nodes.visualizer import Visualizer

    node = ros.add(Visualizer(context=ros.context))
    remote = Remote(ros, ros.probe(), node)
    settings = node.settings()
    assert not remote.set(depth=0.0, marker_radius=9).successful  # depth out of range: nothing applied
    assert node.settings() is settings
    assert remote.get("depth", "marker_radius") == {"depth": settings.depth, "marker_radius": settings.marker_radius}
    assert remote.set(depth=12.5, marker_radius=9, jpeg_quality=70).successful
    assert (node.settings().depth, node.settings().marker_radius) == (12.5, 9)
    assert_get_tells_the_snapshot(remote, node.live_params, "depth", "marker_radius", "jpeg_quality")


def test_republish_lazy_is_live(ros: RosHarness) -> None:
    from axis_ptz_ros2.nodes.republish import RepublishNode

    # input jpeg: no stream node here to announce its codec (auto would wait for video/params)
    node = ros.add(RepublishNode(context=ros.context, parameter_overrides=[Parameter("input", value="jpeg")]))
    remote = Remote(ros, ros.probe(), node)
    assert not node.subscribed  # lazy, nobody watches image_raw
    assert not remote.set(input="h264").successful  # read-only
    assert remote.set(lazy=False).successful
    assert node.subscribed  # subscribed at once (on_change), not at the next housekeeping tick
    assert remote.get("lazy", "input") == {"lazy": False, "input": "jpeg"}
    assert remote.set(lazy=True).successful
    assert not node.subscribed


def test_web_console_param_get_tells_what_it_uses(ros: RosHarness) -> None:
    from axis_ptz_ros2.nodes.web_console import WebConsole

    overrides = [Parameter("port", value=0), Parameter("bind", value="127.0.0.1")]
    node = ros.add(WebConsole(context=ros.context, parameter_overrides=overrides))
    remote = Remote(ros, ros.probe(), node)
    mouse = node.state()["mouse"]
    assert not remote.set(look_zoom=0.5, shift_zoom_delta=100.0).successful  # look_zoom out of range
    assert node.state()["mouse"] == mouse
    assert remote.set(look_zoom=3.0, shift_zoom_delta=100.0, service_timeout=7.0).successful
    assert node.state()["mouse"] == {**mouse, "look_zoom": 3.0, "shift_zoom_delta": 100.0}
    assert_get_tells_the_snapshot(remote, node.live_params, "look_zoom", "shift_zoom_delta", "service_timeout")


def test_keyboard_teleop_and_sims_param_get_tells_what_they_use(ros: RosHarness) -> None:
    import io

    from axis_ptz_ros2.nodes.keyboard_teleop import KeyboardTeleop
    from axis_ptz_ros2.nodes.laser_sim import LaserSim
    from axis_ptz_ros2.nodes.panorama_sim import PanoramaSim

    probe = ros.probe()
    teleop = ros.add(KeyboardTeleop(io.StringIO(), context=ros.context))
    pano = ros.add(PanoramaSim(context=ros.context, parameter_overrides=[Parameter("width", value=64)]))
    laser = ros.add(LaserSim(context=ros.context))
    cases = (  # node, a refused set, an accepted set
        (teleop, {"service_timeout": 0.0}, {"service_timeout": 7.0}),
        (pano, {"jpeg_quality": 0, "overlay": False}, {"jpeg_quality": 40, "overlay": False}),
        (laser, {"range_noise": 2.0}, {"range_noise": 0.01}),
    )
    for node, refused, accepted in cases:
        live = node._live  # noqa: SLF001 - the snapshot the node reads at each use
        remote = Remote(ros, probe, node)
        before = live.params
        assert not remote.set(**refused).successful, refused
        assert live.params is before
        assert_get_tells_the_snapshot(remote, live, *accepted)
        assert remote.set(**accepted).successful, accepted
        assert remote.get(*accepted) == accepted
        assert_get_tells_the_snapshot(remote, live, *accepted)
    # the panorama without the overlay is the static render, as the snapshot says
    assert (pano.frame(1_000_000_000) == pano._base).all()  # noqa: SLF001
