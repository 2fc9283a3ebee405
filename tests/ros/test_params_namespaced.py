"""The shipped parameter files work under any namespace (issue 23, item 1).

Each executable is started as ``ros2 launch`` starts a ``Node(namespace=..., name=...)``: ``--ros-args
--params-file FILE -r __ns:=/robot1`` plus ``-r __node:=NAME`` for the single-node executables (a name remap
renames every node of a process, so the two-node ``axis_camera`` gets none). Every value in the file is read
back over DDS from ``/robot1/<node>/get_parameters`` and must be the value in effect. The old ``node_name:``
form is shown to be ignored under a namespace (so these tests can fail), a renamed node reads its own
``/**/<new name>`` section, and the README's two-robot example (two namespaces, two parameter files, one
process each) gives each robot its own values, and each robot's images and camera_info name the optical frame
of its own, prefixed ``/tf`` chain.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml
from sensor_msgs.msg import CameraInfo, CompressedImage
from tf2_msgs.msg import TFMessage

from axis_ptz_ros2.nodes.common import STREAM_QOS
from axis_ptz_ros2.nodes.tf_publish import TF_QOS, TF_STATIC_QOS
from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.sim.world import load_world
from tests.ros.test_launch_files import ALL_NODES, EXE_NODES
from tests.ros.test_params_files import process, read_params, sections

pytestmark = [pytest.mark.ros, pytest.mark.timeout(300)]

ROOT = Path(__file__).resolve().parents[2]
NS = "/robot1"


@pytest.fixture(scope="module")
def cam() -> Any:
    c = SimulatedCamera(load_world(), port=0).start()
    try:
        yield c
    finally:
        c.stop()


def check_all(ros: Any, probe: Any, proc: Any, path: Path, ns: str, node: str, overrides: dict[str, Any]) -> int:
    """Every file value of ``node`` (or its override) is in effect at ``ns/node``; returns how many of them
    differ from the node's defaults (so the caller can be sure the file was not simply ignored)."""
    want = {**sections(path)[node], **overrides}
    got = read_params(ros, probe, proc, f"{ns.strip('/')}/{node}", list(want))
    for k, v in want.items():
        g = got[k]
        ok = g == pytest.approx(v) if isinstance(v, float) else g == v
        assert ok, f"{path.name} under {ns}: {node}.{k} = {g!r}, file {v!r}"
    defaults = {s.name: s.default for s in ALL_NODES[node]}
    return sum(1 for k, v in want.items() if k not in overrides and defaults[k] != v)


# (params file, executable, {node: overrides}) — the web console's port 0: the file's 8090 may be taken
CASES = [
    ("axis_camera.params.yaml", "axis_camera", {"axis_stream": {"port": None}, "axis_ptz": {"port": None}}),
    ("axis_camera.params.yaml", "axis_stream", {"axis_stream": {"port": None}}),
    ("axis_camera.params.yaml", "axis_ptz", {"axis_ptz": {"port": None}}),
    ("operator_tools.params.yaml", "axis_web_console", {"axis_web_console": {"port": 0}}),
    ("operator_tools.params.yaml", "axis_visualizer", {"axis_visualizer": {}}),
    ("operator_tools.params.yaml", "axis_republish", {"axis_republish": {}}),
    ("virtual_camera.params.yaml", "axis_virtual_camera", {"axis_virtual_camera": {}, "axis_virtual_camera_ptz": {}}),
    ("joy_gamepad.params.yaml", "axis_joy_teleop", {"axis_joy_teleop": {}}),
]


#: one value per node that differs from the node's default, added to a copy of the shipped file, so that a
#: section the node silently ignored could not pass for one whose values all happen to be defaults
MARKERS: dict[str, tuple[str, Any]] = {
    "axis_stream": ("fps", 7),
    "axis_ptz": ("state_rate", 7.0),
    "axis_web_console": ("service_timeout", 4.0),
    "axis_visualizer": ("rate", 4.0),
    "axis_republish": ("lazy", False),
    "axis_virtual_camera": ("rate", 10.0),
    "axis_virtual_camera_ptz": ("state_rate", 10.0),
    "axis_joy_teleop": ("rate", 9.0),
}


def test_the_cases_cover_every_shipped_params_file_and_node():
    covered = {(f, n) for f, _, nodes in CASES for n in nodes}
    shipped = {(p.name, n) for p in (ROOT / "config").glob("*.params.yaml") for n in sections(p)}
    assert shipped <= covered, sorted(shipped - covered)
    for node, (name, value) in MARKERS.items():
        default = next(s.default for s in ALL_NODES[node] if s.name == name)
        assert value != default, f"marker {node}.{name} = its default"


def with_markers(src: Path, dst: Path) -> Path:
    """A copy of ``src`` with each section's marker value set (every other shipped value kept as it is)."""
    doc = yaml.safe_load(src.read_text(encoding="utf-8"))
    for key, body in doc.items():
        name, value = MARKERS[key.removeprefix("/**/")]
        body["ros__parameters"][name] = value
    dst.write_text(yaml.safe_dump(doc), encoding="utf-8")
    return dst


@pytest.mark.parametrize(("file", "exe", "nodes"), CASES, ids=lambda c: c if isinstance(c, str) else "")
def test_every_parameter_takes_effect_under_a_namespace_and_a_node_name_remap(ros, cam, tmp_path, file, exe, nodes):
    path = with_markers(ROOT / "config" / file, tmp_path / file)
    probe = ros.probe(f"ns_probe_{exe}")
    overrides = {n: {k: (cam.port if v is None else v) for k, v in o.items()} for n, o in nodes.items()}
    args = ["--params-file", str(path), "-r", f"__ns:={NS}"]
    if len(EXE_NODES[exe]) == 1:
        args += ["-r", f"__node:={next(iter(EXE_NODES[exe]))}"]  # what launch_ros passes for Node(name=...)
    for k, v in {k: v for o in overrides.values() for k, v in o.items()}.items():
        args += ["-p", f"{k}:={v}"]
    with process(exe, *args) as proc:
        for node, o in overrides.items():
            assert check_all(ros, probe, proc, path, NS, node, o) >= 1, f"{file}: {node} kept its defaults"


def renamed(src: Path, dst: Path, old: str, new: str, **values: Any) -> Path:
    doc = yaml.safe_load(src.read_text(encoding="utf-8"))
    body = doc[f"/**/{old}"]
    body["ros__parameters"].update(values)
    dst.write_text(yaml.safe_dump({f"/**/{new}": body}), encoding="utf-8")
    return dst


def test_a_renamed_node_reads_its_own_section(ros, cam, tmp_path):
    """Two cameras on one robot: ``-r __node:=front_stream`` reads ``/**/front_stream``."""
    path = renamed(
        ROOT / "config" / "axis_camera.params.yaml",
        tmp_path / "front.params.yaml",
        "axis_stream",
        "front_stream",
        fps=7,
        port=cam.port,
    )
    probe = ros.probe("ns_probe_renamed")
    with process("axis_stream", "--params-file", str(path), "-r", f"__ns:={NS}", "-r", "__node:=front_stream") as p:
        want = sections(path)["front_stream"]
        got = read_params(ros, probe, p, f"{NS.strip('/')}/front_stream", list(want))
    assert got == pytest.approx(want)
    assert got["fps"] == 7


def test_the_old_node_name_form_is_ignored_under_a_namespace(ros, cam, tmp_path):
    """Why the shipped files use ``/**/``: a bare ``axis_stream:`` section does not match ``/robot1/axis_stream``
    (rcl matches the fully qualified name), so the node silently keeps its defaults — the bug of issue 23."""
    old = tmp_path / "old.params.yaml"
    old.write_text(f"axis_stream:\n  ros__parameters:\n    fps: 7\n    port: {cam.port}\n", encoding="utf-8")
    probe = ros.probe("ns_probe_old")
    with process("axis_stream", "--params-file", str(old), "-r", f"__ns:={NS}") as p:
        got = read_params(ros, probe, p, f"{NS.strip('/')}/axis_stream", ["fps", "port"])
    default_fps = next(s.default for s in ALL_NODES["axis_stream"] if s.name == "fps")
    assert got == {"fps": default_fps, "port": 80}


def test_two_robots_two_params_files_as_in_the_readme(ros, cam, tmp_path):
    """The README's example: robot1 and robot2, each with its own copy of axis_camera.params.yaml."""
    src = ROOT / "config" / "axis_camera.params.yaml"
    files = {}
    for ns, fps in (("robot1", 5), ("robot2", 12)):
        doc = yaml.safe_load(src.read_text(encoding="utf-8"))
        for key in doc:
            doc[key]["ros__parameters"].update(port=cam.port)
        doc["/**/axis_stream"]["ros__parameters"].update(fps=fps, frame_prefix=f"{ns}/", camera_name=f"{ns}_axis")
        doc["/**/axis_ptz"]["ros__parameters"]["frame_prefix"] = f"{ns}/"
        files[ns] = tmp_path / f"{ns}.params.yaml"
        files[ns].write_text(yaml.safe_dump(doc), encoding="utf-8")
    probe = ros.probe("ns_probe_two")
    with (
        process("axis_camera", "--params-file", str(files["robot1"]), "-r", "__ns:=/robot1") as p1,
        process("axis_camera", "--params-file", str(files["robot2"]), "-r", "__ns:=/robot2") as p2,
    ):
        for ns, p, fps in (("robot1", p1, 5), ("robot2", p2, 12)):
            assert read_params(ros, probe, p, f"{ns}/axis_stream", ["fps", "port"]) == {"fps": fps, "port": cam.port}
            assert read_params(ros, probe, p, f"{ns}/axis_ptz", ["frame_prefix"]) == {"frame_prefix": f"{ns}/"}
            assert read_params(ros, probe, p, f"{ns}/axis_stream", ["camera_name"]) == {"camera_name": f"{ns}_axis"}
        # each robot's images and camera_info name a frame of its own /tf chain (one /tf shared by both robots)
        frames: dict[str, set[str]] = {}
        tf_children: set[str] = set()
        for ns in ("robot1", "robot2"):
            for msg_type, topic in ((CompressedImage, "image_raw/compressed"), (CameraInfo, "camera_info")):
                probe.create_subscription(
                    msg_type,
                    f"/{ns}/{topic}",
                    lambda m, ns=ns: frames.setdefault(ns, set()).add(m.header.frame_id),
                    STREAM_QOS,
                )
        for topic, qos in (("/tf", TF_QOS), ("/tf_static", TF_STATIC_QOS)):
            probe.create_subscription(
                TFMessage, topic, lambda m: tf_children.update(t.child_frame_id for t in m.transforms), qos
            )
        want = {ns: f"{ns}/axis_ptz_optical_frame" for ns in ("robot1", "robot2")}
        ros.wait_for(lambda: all(f in tf_children for f in want.values()) and len(frames) == 2, timeout=30.0)
        assert frames == {ns: {f} for ns, f in want.items()}, f"image/camera_info frames {frames}"
        assert {f for f in tf_children if "/" not in f} == set(), f"unprefixed /tf frames: {sorted(tf_children)}"
