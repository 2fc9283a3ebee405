"""The real ``axis_keyboard_teleop`` program in a pseudo-terminal, against the simulated camera, the PTZ node
and the stream node over real DDS.

Checks read ground truth: the SIMULATOR's head position (its own sign mapping), the stream node's parameters
and its latched ``video/params``; and the pty's terminal attributes before and after the program ran.
"""

from __future__ import annotations

import contextlib
import math
import os
import select
import signal
import subprocess
import sys
import termios
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from rclpy.parameter import Parameter

from axis_ptz_interfaces.msg import PtzVelocity, VideoParams
from axis_ptz_ros2.nodes.common import COMMAND_QOS, LATCHED_QOS
from axis_ptz_ros2.nodes.ptz_node import PtzNode
from axis_ptz_ros2.nodes.stream_node import StreamNode
from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.sim.ptz import Speeds, vapix_to_ros
from axis_ptz_ros2.sim.world import load_world
from tests.support.waiting import unchanged_for

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]

PROGRAM = str(Path(sys.executable).with_name("axis_keyboard_teleop"))


@pytest.fixture(scope="module")
def cam() -> Iterator[SimulatedCamera]:
    c = SimulatedCamera(load_world(), port=0, speeds=Speeds(300.0, 300.0, 0.5, 0.5)).start()
    try:
        yield c
    finally:
        c.stop()


class Pty:
    """The teleop program on the slave side of a pseudo-terminal; the test types on the master side."""

    def __init__(self, extra_args: tuple[str, ...] = ()) -> None:
        self.master, self.slave = os.openpty()
        self.attrs_before = termios.tcgetattr(self.slave)
        env = dict(os.environ)
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"  # ROS_DOMAIN_ID: the test session's (conftest)
        env["PYTHONUNBUFFERED"] = "1"
        self.proc = subprocess.Popen(
            [PROGRAM, *extra_args],
            stdin=self.slave,
            stdout=self.slave,
            stderr=self.slave,
            env=env,
            start_new_session=True,
            close_fds=True,
        )
        self.output = ""

    def read(self, period: float = 0.05) -> str:
        while True:
            ready, _, _ = select.select([self.master], [], [], period)
            if not ready:
                return self.output
            try:
                chunk = os.read(self.master, 65536)
            except OSError:
                return self.output
            if not chunk:
                return self.output
            self.output += chunk.decode("utf-8", errors="replace")

    def wait_output(self, text: str, timeout: float = 15.0, since: int = 0) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if text in self.read()[since:]:
                return
        raise AssertionError(f"{text!r} not in the program's output:\n{self.output[-2000:]}")

    def type(self, keys: str) -> int:
        """Type keys; returns the output position before them (for ``wait_output(since=...)``)."""
        mark = len(self.read())
        os.write(self.master, keys.encode())
        return mark

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(5)
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):
                os.close(fd)


@pytest.fixture
def stack(ros: Any, cam: SimulatedCamera) -> dict[str, Any]:
    cam.teleport(0.0, 0.0, 1)
    ptz = ros.add(
        PtzNode(
            context=ros.context,
            parameter_overrides=[Parameter("port", value=cam.port), Parameter("arrival_tolerance", value=0.001)],
        )
    )
    stream = ros.add(StreamNode(context=ros.context, parameter_overrides=[Parameter("port", value=cam.port)]))
    probe = ros.probe("teleop_probe")
    seen: dict[str, list[Any]] = {"video": [], "velocity": []}
    probe.create_subscription(VideoParams, "video/params", seen["video"].append, LATCHED_QOS)
    probe.create_subscription(PtzVelocity, "ptz/cmd/velocity", seen["velocity"].append, COMMAND_QOS)
    ros.wait_for(lambda: ptz.poller.latest is not None, 10.0)
    return {"ptz": ptz, "stream": stream, "seen": seen, "probe": probe}


def _sim_pose_deg(cam: SimulatedCamera) -> tuple[float, float, float]:
    """The simulator's true pose in REP-103 DEGREES (its own conversion) and zoom units."""
    p, t, z = cam.position()
    pr, tr = vapix_to_ros(p, t)
    return math.degrees(pr), math.degrees(tr), z


def _wait_pose(ros: Any, cam: SimulatedCamera, pan: float, tilt: float, zoom: float, tol: float = 0.05) -> None:
    def ok() -> bool:
        p, t, z = _sim_pose_deg(cam)
        return abs(p - pan) < tol and abs(t - tilt) < tol and abs(z - zoom) < 1.5

    try:
        ros.wait_for(ok, timeout=10.0, period=0.05)
    except AssertionError:
        log = cam.request_counts.as_dict()
        raise AssertionError(f"sim at {_sim_pose_deg(cam)}, expected {(pan, tilt, zoom)}; {log}") from None


def test_keys_move_the_simulated_head_and_change_the_stream_and_the_terminal_is_restored(ros, cam, stack):
    ptz, stream, seen = stack["ptz"], stack["stream"], stack["seen"]
    pty = Pty()
    try:
        # Live status line once ptz/state and video/params are in.
        pty.wait_output("video: 704x576 at 15 fps, compression 30")
        pty.wait_output("pan   +0.00 deg")
        assert termios.tcgetattr(pty.slave) != pty.attrs_before  # raw mode while running
        # The PTZ node has discovered the teleop's relative-move publisher (volatile topic: a move sent
        # before that is lost).
        ros.wait_for(lambda: ptz.count_publishers("/ptz/cmd/relative") > 0)

        # Step 3, A: the view turns LEFT by 3 deg (REP-103 +3; VAPIX -3 on the 214, thesis "pan -x").
        pty.type("3a")
        _wait_pose(ros, cam, 3.0, 0.0, 1)
        assert cam.position()[0] == pytest.approx(-3.0, abs=0.05)  # the camera's own VAPIX pan
        # SHIFT+D: right by 5x = 15 deg; W: up 3 deg; E: zoom in 10*3 units; SHIFT+E: 100*3 more.
        pty.type("D")
        _wait_pose(ros, cam, -12.0, 0.0, 1)
        pty.type("w")
        _wait_pose(ros, cam, -12.0, 3.0, 1)
        pty.type("e")
        _wait_pose(ros, cam, -12.0, 3.0, 31)
        pty.type("E")
        _wait_pose(ros, cam, -12.0, 3.0, 331)
        # Step 1, S (down 1), Q (zoom out 10), arrow left (= A).
        pty.type("1s")
        _wait_pose(ros, cam, -12.0, 2.0, 331)
        pty.type("q")
        _wait_pose(ros, cam, -12.0, 2.0, 321)
        pty.type("\x1b[D")
        _wait_pose(ros, cam, -11.0, 2.0, 321)
        pty.wait_output("pan  -11.00 deg")  # status line follows ptz/state

        # Video keys: R fps +3, G lower resolution, T higher again, Y compression +10.
        def param(name: str) -> Any:
            return stream.get_parameter(name).value

        # (Each key is computed from the values the teleop last heard: wait until its status line shows them.)
        m = pty.type("r")
        ros.wait_for(lambda: param("fps") == 18)
        ros.wait_for(lambda: seen["video"] and seen["video"][-1].fps == 18)
        pty.wait_output("video: 704x576 at 18 fps, compression 30", since=m)
        m = pty.type("g")
        ros.wait_for(lambda: param("resolution") == "704x288")
        ros.wait_for(lambda: seen["video"][-1].resolution == "704x288")
        pty.wait_output("video: 704x288 at 18 fps, compression 30", since=m)
        m = pty.type("t")
        ros.wait_for(lambda: param("resolution") == "704x576")
        pty.wait_output("video: 704x576 at 18 fps, compression 30", since=m)
        m = pty.type("t")  # already the largest: a notice, no request
        pty.wait_output("resolution already at the top", since=m)
        m = pty.type("y")
        ros.wait_for(lambda: param("compression") == 40)
        ros.wait_for(lambda: seen["video"][-1].compression == 40 and seen["video"][-1].source == "service")
        pty.wait_output("video: 704x576 at 18 fps, compression 40", since=m)
        m = pty.type("F")
        ros.wait_for(lambda: param("fps") == 15)
        pty.wait_output("video: 704x576 at 15 fps, compression 40", since=m)
        m = pty.type("h")
        ros.wait_for(lambda: param("compression") == 30)
        pty.wait_output("video: 704x576 at 15 fps, compression 30 | step 1", since=m)

        # SPACE: home (the simulator's home is pan 0, tilt 0, zoom 1).
        pty.type(" ")
        _wait_pose(ros, cam, 0.0, 0.0, 1)

        # Help screen, then quit with Ctrl-C: a velocity stop is sent, the terminal is as before.
        m = pty.type("?")
        pty.wait_output("compression -10", since=m)
        n_stop = len(seen["velocity"])
        pty.type("\x03")
        assert pty.proc.wait(10) == 0
        ros.wait_for(lambda: len(seen["velocity"]) > n_stop)
        v = seen["velocity"][-1]
        assert (v.pan_rate, v.tilt_rate, v.zoom_rate) == (0.0, 0.0, 0.0)
        assert termios.tcgetattr(pty.slave) == pty.attrs_before
    finally:
        pty.close()


def test_sigterm_restores_the_terminal_and_stops(ros, stack):
    seen = stack["seen"]
    pty = Pty(("--ros-args", "-p", "step:=4"))
    try:
        pty.wait_output("step 4")
        assert termios.tcgetattr(pty.slave) != pty.attrs_before
        # The teleop's velocity publisher is discovered by our probe before we type (volatile topic).
        probe = stack["probe"]
        ros.wait_for(lambda: probe.count_publishers("/ptz/cmd/velocity") > 0)
        n = len(seen["velocity"])
        # Seeing its publisher does not mean it has matched our subscription yet (discovery runs on both
        # sides): type the explicit stop key until one arrives, then let any still in flight land.
        ros.wait_for(lambda: (pty.type("x"), len(seen["velocity"]) > n)[1], timeout=10, period=0.5)
        ros.wait_for(unchanged_for(lambda: len(seen["velocity"]), 1.0), timeout=10, period=0.05)
        m = len(seen["velocity"])
        pty.proc.send_signal(signal.SIGTERM)
        assert pty.proc.wait(10) == 128 + signal.SIGTERM
        assert termios.tcgetattr(pty.slave) == pty.attrs_before
        ros.wait_for(lambda: len(seen["velocity"]) > m)  # the stop it sends on the way out
    finally:
        pty.close()


def test_namespace_remap_reaches_nodes_in_that_namespace(ros, cam):
    """``--ros-args -r __ns:=/robot1``: the program talks to /robot1/ptz/*, not to /ptz/*."""
    cam.teleport(0.0, 0.0, 1)
    ptz = ros.add(
        PtzNode(context=ros.context, namespace="robot1", parameter_overrides=[Parameter("port", value=cam.port)])
    )
    pty = Pty(("--ros-args", "-r", "__ns:=/robot1"))
    try:
        pty.wait_output("pan   +0.00 deg")
        # the PTZ node in /robot1 has discovered the teleop's relative-move publisher before the first key
        ros.wait_for(lambda: ptz.count_publishers("/robot1/ptz/cmd/relative") > 0)
        pty.type("5d")
        _wait_pose(ros, cam, -5.0, 0.0, 1)
        pty.type("\x11")  # Ctrl-Q
        assert pty.proc.wait(10) == 0
        assert termios.tcgetattr(pty.slave) == pty.attrs_before
    finally:
        pty.close()


def test_quality_keys_step_the_h264_bitrates_when_the_stream_is_h264(ros, cam):
    """``codec: h264``: the teleop learns the codec from video/params; Y/H step the H.264 bitrate without
    feedback and the ceiling together (video/set_params), the compression stays; the help says so."""
    overrides = {"port": cam.port, "codec": "h264", "h264_bitrate_kbps": 1000, "h264_max_bitrate_kbps": 1500}
    stream = ros.add(
        StreamNode(context=ros.context, parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
    )
    probe = ros.probe("teleop_h264_probe")
    seen: list[VideoParams] = []
    probe.create_subscription(VideoParams, "video/params", seen.append, LATCHED_QOS)

    def param(name: str) -> Any:
        return stream.get_parameter(name).value

    pty = Pty()
    try:
        pty.wait_output("H.264 1000 kbit/s (up to 1500 with feedback)")
        compression = param("compression")
        m = pty.type("h")
        ros.wait_for(lambda: (param("h264_bitrate_kbps"), param("h264_max_bitrate_kbps")) == (1500, 2000))
        ros.wait_for(lambda: seen and (seen[-1].h264_bitrate_kbps, seen[-1].h264_max_bitrate_kbps) == (1500, 2000))
        assert seen[-1].codec == "h264"
        pty.wait_output("H.264 1500 kbit/s (up to 2000 with feedback)", since=m)
        m = pty.type("y")
        ros.wait_for(lambda: (param("h264_bitrate_kbps"), param("h264_max_bitrate_kbps")) == (1000, 1500))
        pty.wait_output("H.264 1000 kbit/s (up to 1500 with feedback)", since=m)
        m = pty.type("Y")
        ros.wait_for(lambda: (param("h264_bitrate_kbps"), param("h264_max_bitrate_kbps")) == (700, 1000))
        pty.wait_output("H.264 700 kbit/s (up to 1000 with feedback)", since=m)
        assert param("compression") == compression  # the MJPEG key's parameter is left alone
        m = pty.type("?")
        pty.wait_output("the stream is h264: Y/H act on the H.264 bitrate", since=m)
        pty.wait_output("H.264: bitrate one step down", since=m)
        # the codec switched back to MJPEG: the same key steps the compression again
        assert stream.set_parameters([Parameter("codec", value="mjpeg")])[0].successful
        pty.wait_output("compression 30")
        m = pty.type("y")
        ros.wait_for(lambda: param("compression") == 40)
        assert (param("h264_bitrate_kbps"), param("h264_max_bitrate_kbps")) == (700, 1000)
        pty.type("\x03")
        assert pty.proc.wait(10) == 0
        assert termios.tcgetattr(pty.slave) == pty.attrs_before
    finally:
        pty.close()


def test_p_takes_a_full_quality_still_and_prints_the_answer(ros, stack):
    from sensor_msgs.msg import CompressedImage  # noqa: PLC0415 - only this test

    stills: list[CompressedImage] = []
    stack["probe"].create_subscription(CompressedImage, "still/compressed", stills.append, LATCHED_QOS)
    pty = Pty()
    try:
        pty.wait_output("video: 704x576")  # the teleop has discovered the stream node
        m = pty.type("?")
        pty.wait_output("take a full-quality still", since=m)  # the help names the key
        m = pty.type("p")
        pty.wait_output("still 704x576 px, compression 0, ", since=m)  # the node's answer, printed
        ros.wait_for(lambda: len(stills) == 1, timeout=5)
        assert f"{len(stills[0].data)} bytes" in pty.output[m:]
        pty.type("\x03")
        assert pty.proc.wait(10) == 0
    finally:
        pty.close()
