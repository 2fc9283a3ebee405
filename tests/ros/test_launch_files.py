"""Every launch file is valid Python that names only executables, node names and parameters that exist.

The ``launch`` package cannot be installed here (not on PyPI), so each file is imported under a recording
stand-in (``tests/ros/launch_standin.py``) and what it declares is checked against the project: executables
against the console scripts in pyproject.toml, parameters against the nodes' own ParamSpec lists, parameter
files (``/**/node_name: ros__parameters:``, the form that matches the node under any namespace) against the
node names each executable creates, includes against the included file's declared arguments. Every
combination of the boolean launch arguments is evaluated.
"""

from __future__ import annotations

import ast
import itertools
import tomllib
from pathlib import Path
from typing import Any

import pytest
import yaml

from axis_ptz_ros2.nodes import (
    joy_teleop,
    keyboard_teleop,
    laser_sim,
    link_monitor,
    panorama_sim,
    ptz_node,
    republish,
    stream_node,
    virtual_camera,
    visualizer,
    web_console,
)
from axis_ptz_ros2.sim import cli as sim_cli
from tests.ros import launch_standin as ls

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[2]
LAUNCH_FILES = sorted((ROOT / "axis_ptz_ros2" / "launch").glob("*.launch.py"))
PARAMS_FILES = sorted((ROOT / "config").glob("*.params.yaml"))
SCRIPTS = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"])

#: executable → {node name: its ParamSpec list} (the nodes each process creates, under their default names)
EXE_NODES: dict[str, dict[str, Any]] = {
    "axis_camera": {"axis_stream": stream_node.PARAMS, "axis_ptz": ptz_node.PARAMS},
    "axis_stream": {"axis_stream": stream_node.PARAMS},
    "axis_ptz": {"axis_ptz": ptz_node.PARAMS},
    "axis_web_console": {"axis_web_console": web_console.PARAMS},
    "axis_visualizer": {"axis_visualizer": visualizer.PARAMS},
    "axis_republish": {"axis_republish": republish.PARAMS},
    "axis_joy_teleop": {"axis_joy_teleop": joy_teleop.PARAMS},
    "axis_keyboard_teleop": {"axis_keyboard_teleop": keyboard_teleop.PARAMS},
    "axis_panorama_sim": {"axis_panorama_sim": panorama_sim.PARAMS},
    "axis_laser_sim": {"axis_laser_sim": laser_sim.PARAMS},
    "axis_link_monitor": {"axis_link_monitor": link_monitor.PARAMS},
    "axis_virtual_camera": {"axis_virtual_camera": virtual_camera.PARAMS, "axis_virtual_camera_ptz": ptz_node.PARAMS},
}
#: other packages' executables our launch files may start, with the parameters we may give them
EXTERNAL: dict[tuple[str, str], set[str]] = {
    ("robot_state_publisher", "robot_state_publisher"): {"robot_description", "publish_frequency", "frame_prefix"},
    ("joy", "game_controller_node"): {"device_id", "device_name", "deadzone", "autorepeat_rate", "sticky_buttons"},
    ("joy", "joy_node"): {"device_id", "device_name", "deadzone", "autorepeat_rate", "sticky_buttons"},
}


def names(specs: Any) -> set[str]:
    return {s.name for s in specs}


def test_the_expected_launch_and_params_files_exist():
    assert {p.name for p in LAUNCH_FILES} >= {"camera.launch.py", "operator.launch.py", "virtual_camera.launch.py"}
    assert {p.name for p in PARAMS_FILES} >= {
        "axis_camera.params.yaml",
        "operator_tools.params.yaml",
        "virtual_camera.params.yaml",
        "joy_gamepad.params.yaml",
    }
    # every executable we map is a console script, and every node-running console script is mapped
    assert set(EXE_NODES) <= SCRIPTS
    assert SCRIPTS - set(EXE_NODES) == {"axis_calibrate", "axis_camera_sim"}  # not ROS nodes


ALL_NODES: dict[str, Any] = {n: specs for nodes in EXE_NODES.values() for n, specs in nodes.items()}


def node_of_section(key: str) -> str:
    """The node a parameter-file section addresses: ``/**/axis_stream`` → ``axis_stream``; ``/**`` stays.

    Only the namespace-independent forms are accepted: a bare ``axis_stream:`` matches the node only when it
    runs without a namespace (rcl compares the fully qualified name), so a namespaced launch ignores it."""
    if key == "/**":
        return key
    assert key.startswith("/**/"), f"section {key!r}: use '/**/{key.lstrip('/')}' so it applies under any namespace"
    return key.removeprefix("/**/")


def check_params_file(path: Path, exe: str) -> None:
    """A ``ros__parameters`` file given to ``exe``: it configures at least one of ``exe``'s nodes, and every
    section names a node of this package with parameters that node has (a file may serve several processes:
    each node reads only its own section)."""
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    assert isinstance(doc, dict), f"{path.name}: not a mapping"
    assert doc, f"{path.name}: empty"
    nodes = EXE_NODES[exe]
    doc = {node_of_section(k): v for k, v in doc.items()}
    assert set(doc) & (set(nodes) | {"/**"}), f"{path.name}: no section for {exe}'s nodes {sorted(nodes)}"
    for node_name, body in doc.items():
        assert set(body) == {"ros__parameters"}, f"{path.name}: {node_name}: only ros__parameters expected"
        if node_name == "/**":
            known = set().union(*(names(s) for s in nodes.values()))
        else:
            assert node_name in ALL_NODES, f"{path.name}: no node of this package is called {node_name!r}"
            known = names(ALL_NODES[node_name])
        unknown = set(body["ros__parameters"]) - known
        assert not unknown, f"{path.name}: {node_name} has no parameters {sorted(unknown)}"


def check_launch(path: Path, args_in: dict[str, str], seen: list[tuple[str, str]]) -> None:
    ld = ls.load_launch_file(path)
    declared = ls.declared_arguments(ld)
    unknown_in = set(args_in) - set(declared)
    assert not unknown_in, f"{path.name}: no launch arguments {sorted(unknown_in)}"
    args = {**declared, **args_in}
    for a in ls.actions(ld):
        if not ls.condition_true(a, args):
            continue
        if isinstance(a, ls.IncludeLaunchDescription):
            src = a.args[0]
            assert isinstance(src, ls.PythonLaunchDescriptionSource)
            inc = Path(ls.resolve(src.args[0], args))
            assert inc.exists(), f"{path.name}: includes {inc}, which does not exist"
            assert inc.parent == ls.share_dir() / "launch", f"{path.name}: includes {inc}, not an installed launch file"
            inc = inc.resolve()
            passed = {k: ls.resolve(v, args) for k, v in a.kwargs.get("launch_arguments", [])}
            check_launch(inc, passed, seen)
        elif isinstance(a, ls.Node):
            pkg, exe = a.kwargs["package"], a.kwargs["executable"]
            seen.append((pkg, exe))
            ls.resolve(a.kwargs.get("namespace", ""), args)  # resolvable
            params = a.kwargs.get("parameters", [])
            if pkg != "axis_ptz_ros2":
                assert (pkg, exe) in EXTERNAL, f"{path.name}: unknown external executable {pkg}/{exe}"
                for p in params:
                    assert isinstance(p, dict)
                    assert set(p) <= EXTERNAL[(pkg, exe)], f"{path.name}: {pkg}/{exe} has no {set(p)}"
                    for v in p.values():
                        ls.resolve(v, args) if not isinstance(v, int | float) else None
                continue
            assert exe in SCRIPTS, f"{path.name}: {exe} is not a console script of this package"
            if exe == "axis_camera_sim":  # no ROS node: its arguments must parse (launch's --ros-args ignored)
                assert not params, f"{path.name}: parameters for {exe}, which has none"
                argv = [ls.resolve(v, args) for v in a.kwargs.get("arguments", [])]
                sim_cli.build_parser().parse_args(sim_cli.without_ros_args([*argv, "--ros-args", "-r", "__ns:=/x"]))
                continue
            assert exe in EXE_NODES, f"{path.name}: {exe} is not a ROS node executable"
            if "name" in a.kwargs:
                # a name remap renames EVERY node of the process: only for single-node executables
                assert len(EXE_NODES[exe]) == 1, f"{path.name}: name= on {exe}, which runs several nodes"
            known = set().union(*(names(s) for s in EXE_NODES[exe].values()))
            for p in params:
                if isinstance(p, dict):
                    unknown = set(p) - known
                    assert not unknown, f"{path.name}: {exe} has no parameters {sorted(unknown)}"
                    for v in p.values():
                        ls.resolve(v, args)
                else:
                    f = Path(ls.resolve(p, args))
                    assert f.exists(), f"{path.name}: parameter file {f} does not exist"
                    assert f.parent == ls.share_dir() / "config", f"{path.name}: {f} is not an installed config file"
                    f = f.resolve()
                    check_params_file(f, exe)


def bool_args(path: Path) -> list[str]:
    ld = ls.load_launch_file(path)
    return [k for k, v in ls.declared_arguments(ld).items() if isinstance(v, str) and v in ("true", "false")]


@pytest.mark.parametrize("path", LAUNCH_FILES, ids=lambda p: p.name)
def test_launch_file_names_only_existing_executables_nodes_and_parameters(path):
    ast.parse(path.read_text(encoding="utf-8"), filename=str(path))  # plain valid Python
    flags = bool_args(path)
    started: set[tuple[str, str]] = set()
    for combo in itertools.product(("true", "false"), repeat=len(flags)):
        seen: list[tuple[str, str]] = []
        check_launch(path, dict(zip(flags, combo, strict=True)), seen)
        started |= set(seen)
    assert started, f"{path.name} starts nothing"


def test_camera_launch_hands_the_head_frames_to_robot_state_publisher_exclusively():
    """robot_state_publisher:=true starts it AND turns the PTZ node's own /tf off (one parent per frame)."""
    path = ROOT / "axis_ptz_ros2" / "launch" / "camera.launch.py"
    for flag, rsp_expected, publish_tf in (("true", True, "False"), ("false", False, "True")):
        ld = ls.load_launch_file(path)
        args = {**ls.declared_arguments(ld), "robot_state_publisher": flag}
        nodes = [a for a in ls.actions(ld) if isinstance(a, ls.Node) and ls.condition_true(a, args)]
        exes = [n.kwargs["executable"] for n in nodes]
        assert ("robot_state_publisher" in exes) is rsp_expected
        if rsp_expected:  # declared first: a missing package then fails launch before axis_camera runs (no orphan)
            assert exes.index("robot_state_publisher") < exes.index("axis_camera"), exes
        cam = next(n for n in nodes if n.kwargs["executable"] == "axis_camera")
        d = next(p for p in cam.kwargs["parameters"] if isinstance(p, dict))
        assert ls.resolve(d["publish_tf"], args) == publish_tf


def test_the_standin_catches_mistakes(tmp_path):
    """The checker itself fails on a wrong executable, parameter, node name in a file, or import."""
    bad_exe = tmp_path / "a.launch.py"
    bad_exe.write_text(
        "from launch import LaunchDescription\nfrom launch_ros.actions import Node\n"
        "def generate_launch_description():\n"
        "    return LaunchDescription([Node(package='axis_ptz_ros2', executable='axis_cam')])\n"
    )
    with pytest.raises(AssertionError, match="not a console script"):
        check_launch(bad_exe, {}, [])
    bad_param = tmp_path / "b.launch.py"
    bad_param.write_text(
        "from launch import LaunchDescription\nfrom launch_ros.actions import Node\n"
        "def generate_launch_description():\n"
        "    return LaunchDescription([Node(package='axis_ptz_ros2', executable='axis_ptz',"
        " parameters=[{'host': 'x'}])])\n"
    )
    with pytest.raises(AssertionError, match="no parameters"):
        check_launch(bad_param, {}, [])
    bad_import = tmp_path / "c.launch.py"
    bad_import.write_text("from launch.actions import TimerActionz\n")
    with pytest.raises(ImportError):
        ls.load_launch_file(bad_import)
    bad_kw = tmp_path / "d.launch.py"
    bad_kw.write_text(
        "from launch import LaunchDescription\nfrom launch_ros.actions import Node\n"
        "def generate_launch_description():\n"
        "    return LaunchDescription([Node(package='axis_ptz_ros2', node_executable='axis_ptz')])\n"
    )
    with pytest.raises(TypeError, match="node_executable"):
        ls.load_launch_file(bad_kw)
    wrong_node = tmp_path / "x.params.yaml"
    wrong_node.write_text("/**/axis_ptz:\n  ros__parameters:\n    state_rate: 3.0\n")
    with pytest.raises(AssertionError, match="no section for"):
        check_params_file(wrong_node, "axis_stream")
    wrong_node.write_text("/**/axis_stream:\n  ros__parameters:\n    fps: 3\n/**/axis_stram:\n  ros__parameters: {}\n")
    with pytest.raises(AssertionError, match="no node of this package"):
        check_params_file(wrong_node, "axis_stream")
    wrong_node.write_text("axis_stream:\n  ros__parameters:\n    fps: 3\n")  # ignored under a namespace
    with pytest.raises(AssertionError, match="under any namespace"):
        check_params_file(wrong_node, "axis_stream")
    wrong_param = tmp_path / "y.params.yaml"
    wrong_param.write_text("/**/axis_stream:\n  ros__parameters:\n    fsp: 3\n")
    with pytest.raises(AssertionError, match="no parameters"):
        check_params_file(wrong_param, "axis_camera")


@pytest.mark.parametrize("path", PARAMS_FILES, ids=lambda p: p.name)
def test_every_params_file_fits_some_executable(path):
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    for key in doc:
        node_name = node_of_section(key)
        exes = [exe for exe, nodes in EXE_NODES.items() if node_name in nodes]
        assert exes, f"{path.name}: no executable creates {node_name!r}"
        check_params_file(path, exes[0])


def test_camera_launch_with_the_simulated_camera_points_the_driver_at_it():
    """simulated_camera:=true starts axis_camera_sim and ONE axis_camera whose hostname/port are the simulator's
    (over the params file); false starts no simulator and leaves the params file's address alone."""
    path = ROOT / "axis_ptz_ros2" / "launch" / "camera.launch.py"
    for flag in ("true", "false"):
        ld = ls.load_launch_file(path)
        args = {**ls.declared_arguments(ld), "simulated_camera": flag}
        nodes = [a for a in ls.actions(ld) if isinstance(a, ls.Node) and ls.condition_true(a, args)]
        exes = [n.kwargs["executable"] for n in nodes]
        assert exes.count("axis_camera") == 1, exes
        assert ("axis_camera_sim" in exes) is (flag == "true"), exes
        cam = next(n for n in nodes if n.kwargs["executable"] == "axis_camera")
        overrides = {k: v for p in cam.kwargs["parameters"] if isinstance(p, dict) for k, v in p.items()}
        if flag == "true":
            sim = next(n for n in nodes if n.kwargs["executable"] == "axis_camera_sim")
            sim_args = sim_cli.build_parser().parse_args([ls.resolve(v, args) for v in sim.kwargs["arguments"]])
            assert overrides["hostname"] == sim_args.host
            assert sim_args.host == "127.0.0.1"
            assert overrides["port"] == sim_args.port
        else:
            assert "hostname" not in overrides
            assert "port" not in overrides
