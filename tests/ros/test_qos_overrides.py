"""Publisher QoS overrides the standard way: ``qos_overrides.<topic>.publisher.<policy>`` parameters (rclpy's
QoSOverridingOptions), set with ``parameter_overrides`` in-process and with ``--ros-args -p`` on a real
executable; the publisher's QoS as DDS discovery reports it changes. An invalid value stops the executable at
start-up with one line naming the parameter (exit 2, no traceback)."""

from __future__ import annotations

import re
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rclpy")

from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy  # noqa: E402

from axis_ptz_ros2.nodes.stream_node import StreamNode  # noqa: E402
from axis_ptz_ros2.sim import SimulatedCamera  # noqa: E402
from tests.ros.processes import node_process  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent


@pytest.fixture(scope="module")
def camera() -> Iterator[SimulatedCamera]:
    cam = SimulatedCamera(host="127.0.0.1", port=0).start()
    try:
        yield cam
    finally:
        cam.stop()


def qos_of(ros: Any, probe: Any, topic: str) -> Any:
    infos = ros.wait_for(lambda: probe.get_publishers_info_by_topic(topic), 10.0)
    assert len(infos) == 1, infos
    return infos[0].qos_profile


def test_override_changes_the_publisher_and_only_that_one(ros: Any, camera: SimulatedCamera) -> None:
    prefix = "qos_overrides./image_raw/compressed.publisher."
    overrides = [
        Parameter("port", value=camera.port),
        Parameter(prefix + "reliability", value="best_effort"),
        Parameter(prefix + "durability", value="transient_local"),
        Parameter(prefix + "history", value="keep_last"),
        Parameter(prefix + "depth", value=7),
    ]
    node = ros.add(StreamNode(context=ros.context, parameter_overrides=overrides))
    probe = ros.probe()
    image = qos_of(ros, probe, "/image_raw/compressed")
    assert image.reliability == ReliabilityPolicy.BEST_EFFORT
    assert image.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert image.history in (HistoryPolicy.KEEP_LAST, HistoryPolicy.UNKNOWN)  # discovery may not carry history
    # camera_info is created next from the same shared profile: it keeps the default
    info = qos_of(ros, probe, "/camera_info")
    assert info.reliability == ReliabilityPolicy.RELIABLE
    assert info.durability == DurabilityPolicy.VOLATILE
    assert node.get_parameter(prefix + "depth").value == 7
    # every publisher of ours on the node has its four override parameters, read-only
    pubs = [p for p in node.publishers if p.topic_name not in ("/parameter_events", "/rosout")]  # rclpy's own
    assert len(pubs) >= 4
    for pub in pubs:
        for policy in ("history", "depth", "reliability", "durability"):
            name = f"qos_overrides.{pub.topic_name}.publisher.{policy}"
            assert node.has_parameter(name), name
    result = node.set_parameters([Parameter(prefix + "depth", value=3)])[0]
    assert not result.successful  # read-only: QoS is fixed once the publisher exists


def test_every_publisher_goes_through_the_helper() -> None:
    """No node creates a publisher except through ``nodes.common.publisher`` (which adds the overrides)."""
    offenders = []
    for path in (ROOT / "axis_ptz_ros2" / "axis_ptz_ros2").rglob("*.py"):
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if re.search(r"\.create_publisher\(", line) and path.name != "common.py":
                offenders.append(f"{path.relative_to(ROOT)}:{i}: {line.strip()}")
    assert not offenders, "\n".join(offenders)


def test_ros_args_override_on_the_executable(ros: Any, camera: SimulatedCamera) -> None:
    argv = [str(BIN / "axis_stream"), "--ros-args", "-p", f"port:={camera.port}",
            "-p", "qos_overrides./video/params.publisher.durability:=volatile",
            "-p", "qos_overrides./video/params.publisher.reliability:=best_effort"]  # fmt: skip
    with node_process(argv):
        probe = ros.probe()
        info = qos_of(ros, probe, "/video/params")
        assert info.durability == DurabilityPolicy.VOLATILE  # latched by default
        assert info.reliability == ReliabilityPolicy.BEST_EFFORT


@pytest.mark.parametrize(
    ("exe", "arg", "name"),
    [
        (
            "axis_stream",
            "qos_overrides./camera_info.publisher.reliability:=sometimes",
            "qos_overrides./camera_info.publisher.reliability",
        ),
        ("axis_stream", "qos_overrides./camera_info.publisher.depth:=0", "qos_overrides./camera_info.publisher.depth"),
        (
            "axis_stream",
            "qos_overrides./camera_info.publisher.depth:=deep",
            "qos_overrides./camera_info.publisher.depth",
        ),
        (
            "axis_ptz",
            "qos_overrides./ptz/state.publisher.durability:=forever",
            "qos_overrides./ptz/state.publisher.durability",
        ),
        (
            "axis_panorama_sim",
            "qos_overrides./tf_static.publisher.history:=keep_some",
            "qos_overrides./tf_static.publisher.history",
        ),
    ],  # fmt: skip
    ids=["reliability", "depth-0", "depth-type", "ptz-durability", "tf_static-history"],
)
def test_invalid_override_is_a_clear_start_up_error(camera: SimulatedCamera, exe: str, arg: str, name: str) -> None:
    argv = [str(BIN / exe), "--ros-args", "-p", f"port:={camera.port}", "-p", arg]
    if exe == "axis_panorama_sim":
        argv = [str(BIN / exe), "--ros-args", "-p", arg]
    t0 = time.monotonic()
    proc = subprocess.run(argv, capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
    took = time.monotonic() - t0
    out = proc.stdout + proc.stderr
    assert proc.returncode == 2, out
    assert f"invalid QoS override {name}" in proc.stderr, out
    assert "Traceback" not in out
    assert took < 30, f"took {took:.1f} s to give up"


def test_invalid_override_in_a_params_file_is_a_clear_start_up_error(camera: SimulatedCamera, tmp_path: Path) -> None:
    """The same refusal when the override comes the way launch passes it: nested keys in a parameter file."""
    path = tmp_path / "bad_qos.yaml"
    path.write_text(
        f"/**/axis_stream:\n  ros__parameters:\n    port: {camera.port}\n    qos_overrides:\n"
        "      /camera_info:\n        publisher:\n          reliability: sometimes\n",
        encoding="utf-8",
    )
    argv = [str(BIN / "axis_stream"), "--ros-args", "--params-file", str(path)]
    proc = subprocess.run(argv, capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 2, out
    assert "invalid QoS override qos_overrides./camera_info.publisher.reliability" in proc.stderr, out
    assert "Traceback" not in out
