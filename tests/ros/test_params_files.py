"""Every ``config/*.params.yaml`` loads with ``--ros-args --params-file FILE`` into the REAL executables.

Each executable runs as its own process against the simulated camera (the file's loopback address, the
simulator's port given with ``-p port:=N`` after the file, as a user overriding one value would), and the
parameters are read back over DDS with an ``rcl_interfaces/GetParameters`` client: every value in the file is
the value in effect. Where a value changes behaviour we can observe, we check that too (the stream node's
latched ``video/params`` carries the file's fps, resolution and compression, not the defaults).
"""

from __future__ import annotations

import contextlib
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml
from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import GetParameters

from axis_ptz_interfaces.msg import VideoParams
from axis_ptz_ros2.nodes.common import LATCHED_QOS
from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.sim.world import load_world
from tests.ros.processes import node_process
from tests.ros.test_launch_files import ALL_NODES, node_of_section

pytestmark = [pytest.mark.ros, pytest.mark.timeout(240)]

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent


@pytest.fixture(scope="module")
def cam() -> Iterator[SimulatedCamera]:
    c = SimulatedCamera(load_world(), port=0).start()
    try:
        yield c
    finally:
        c.stop()


@contextlib.contextmanager
def process(exe: str, *ros_args: str) -> Iterator[subprocess.Popen[bytes]]:
    with node_process([str(BIN / exe), "--ros-args", *ros_args]) as proc:
        yield proc


def value_of(v: Any) -> Any:
    t = v.type
    return {
        ParameterType.PARAMETER_BOOL: lambda: v.bool_value,
        ParameterType.PARAMETER_INTEGER: lambda: v.integer_value,
        ParameterType.PARAMETER_DOUBLE: lambda: v.double_value,
        ParameterType.PARAMETER_STRING: lambda: v.string_value,
        ParameterType.PARAMETER_INTEGER_ARRAY: lambda: list(v.integer_array_value),
        ParameterType.PARAMETER_STRING_ARRAY: lambda: list(v.string_array_value),
        ParameterType.PARAMETER_DOUBLE_ARRAY: lambda: list(v.double_array_value),
        ParameterType.PARAMETER_BOOL_ARRAY: lambda: list(v.bool_array_value),
    }.get(t, lambda: None)()


def read_params(ros: Any, probe: Any, proc: subprocess.Popen[bytes], node: str, names: list[str]) -> dict[str, Any]:
    client = probe.create_client(GetParameters, f"/{node}/get_parameters")
    try:
        ros.wait_for(lambda: client.service_is_ready() or proc.poll() is not None, timeout=60.0, period=0.1)
        if proc.poll() is not None:
            out = proc.stdout.read().decode(errors="replace") if proc.stdout else ""
            raise AssertionError(f"{node}: process exited with {proc.returncode}:\n{out[-3000:]}")
        resp = ros.query(client, GetParameters.Request(names=names), timeout=20.0)
    finally:
        probe.destroy_client(client)
    assert len(resp.values) == len(names)
    return {n: value_of(v) for n, v in zip(names, resp.values, strict=True)}


def sections(path: Path) -> dict[str, dict[str, Any]]:
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    return {node_of_section(key): body["ros__parameters"] for key, body in doc.items()}


def expect_loaded(
    ros: Any, probe: Any, proc: subprocess.Popen[bytes], path: Path, node: str, overrides: dict[str, Any]
) -> int:
    """Assert every file value of ``node`` (or the override) is in effect; return how many differ from the
    node's defaults (so a test can make sure the file was not simply ignored)."""
    want = {**sections(path)[node], **overrides}
    got = read_params(ros, probe, proc, node, list(want))
    for k, v in want.items():
        g = got[k]
        assert g == pytest.approx(v) if isinstance(v, float) else g == v, f"{path.name}: {node}.{k} = {g!r}, file {v!r}"
    defaults = {s.name: s.default for s in ALL_NODES[node]}
    return sum(1 for k, v in want.items() if k not in overrides and defaults[k] != v)


def test_axis_camera_params_file_in_the_one_process_driver(ros, cam):
    path = ROOT / "config" / "axis_camera.params.yaml"
    probe = ros.probe("params_probe")
    videos: list[VideoParams] = []
    probe.create_subscription(VideoParams, "video/params", videos.append, LATCHED_QOS)
    with process("axis_camera", "--params-file", str(path), "-p", f"port:={cam.port}") as proc:
        changed = expect_loaded(ros, probe, proc, path, "axis_stream", {"port": cam.port})
        changed += expect_loaded(ros, probe, proc, path, "axis_ptz", {"port": cam.port})
        assert changed >= 1, "the file sets nothing but defaults: this test could not tell it was loaded"
        # behaviour: the stream node publishes the file's video settings as those in effect
        file = sections(path)["axis_stream"]
        ros.wait_for(lambda: videos, timeout=30.0)
        v = videos[-1]
        assert (v.fps, v.resolution, v.compression) == (file["fps"], file["resolution"], file["compression"])
        assert file["fps"] != 15  # differs from the node's default, so the file demonstrably took effect


def test_axis_camera_params_file_in_the_split_driver(ros, cam):
    path = ROOT / "config" / "axis_camera.params.yaml"
    probe = ros.probe("params_probe_split")
    for exe, node in (("axis_stream", "axis_stream"), ("axis_ptz", "axis_ptz")):
        with process(exe, "--params-file", str(path), "-p", f"port:={cam.port}") as proc:
            expect_loaded(ros, probe, proc, path, node, {"port": cam.port})


def test_operator_tools_params_file(ros):
    path = ROOT / "config" / "operator_tools.params.yaml"
    probe = ros.probe("params_probe_tools")
    changed = 0
    for exe, node, extra in (
        ("axis_web_console", "axis_web_console", {"port": 0}),  # 0: any free port (the file's 8090 may be taken)
        ("axis_visualizer", "axis_visualizer", {}),
        ("axis_republish", "axis_republish", {}),
    ):
        args = ["--params-file", str(path)] + [a for k, v in extra.items() for a in ("-p", f"{k}:={v}")]
        with process(exe, *args) as proc:
            changed += expect_loaded(ros, probe, proc, path, node, extra)
    assert changed >= 1


def test_virtual_camera_params_file_reaches_both_nodes_of_the_process(ros):
    path = ROOT / "config" / "virtual_camera.params.yaml"
    probe = ros.probe("params_probe_virtual")
    with process("axis_virtual_camera", "--params-file", str(path)) as proc:
        expect_loaded(ros, probe, proc, path, "axis_virtual_camera", {})
        expect_loaded(ros, probe, proc, path, "axis_virtual_camera_ptz", {})


def test_joy_params_file(ros):
    path = ROOT / "config" / "joy_gamepad.params.yaml"
    probe = ros.probe("params_probe_joy")
    with process("axis_joy_teleop", "--params-file", str(path)) as proc:
        assert expect_loaded(ros, probe, proc, path, "axis_joy_teleop", {}) >= 3


def test_a_bad_value_in_a_params_file_is_refused_with_the_reason(tmp_path):
    """A file with a value out of range stops the node at start-up with a message naming the parameter."""
    bad = tmp_path / "bad.params.yaml"
    bad.write_text("axis_joy_teleop:\n  ros__parameters:\n    home_button: 9\n")  # 9 is also the dead-man button
    with process("axis_joy_teleop", "--params-file", str(bad)) as proc:
        assert proc.wait(60) != 0
        out = proc.stdout.read().decode(errors="replace") if proc.stdout else ""
    assert "dead-man button 9 cannot also be an action button" in out, out[-2000:]
