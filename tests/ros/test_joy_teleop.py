"""The real ``axis_joy_teleop`` program (with the shipped game-pad parameter file) driving the PTZ node and the
simulated camera over real DDS; a test thread plays the joystick by publishing ``sensor_msgs/Joy``.

Ground truth is the SIMULATOR's head position. The PTZ node runs with ``velocity_timeout`` = 10 s, so its own
watchdog cannot be what stops the head within the few seconds these tests allow: a stop seen here is the
teleop's (dead-man released, Joy silent).
"""

from __future__ import annotations

import contextlib
import math
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from rclpy.parameter import Parameter
from sensor_msgs.msg import Joy
from std_srvs.srv import Trigger

from axis_ptz_interfaces.msg import PtzCommand, PtzVelocity
from axis_ptz_interfaces.srv import MovePtz, Preset
from axis_ptz_ros2.nodes.common import COMMAND_QOS
from axis_ptz_ros2.nodes.ptz_node import PtzNode
from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.sim.ptz import vapix_to_ros
from axis_ptz_ros2.sim.world import load_world
from tests.ros.processes import node_process

pytestmark = [pytest.mark.ros, pytest.mark.timeout(180)]

ROOT = Path(__file__).resolve().parents[2]
PROGRAM = str(Path(sys.executable).with_name("axis_joy_teleop"))
PARAMS = ROOT / "config" / "joy_gamepad.params.yaml"
# game_controller_node layout (config/joy_gamepad.params.yaml): axes 0/1 left stick, 3 right stick y;
# buttons 0 A (preset "1"), 3 Y (home), 9 LB (dead-man), 10 RB (zoom in)
DEADMAN, HOME, PRESET_1, ZOOM_IN = 9, 3, 0, 10


@pytest.fixture(scope="module")
def cam() -> Iterator[SimulatedCamera]:
    c = SimulatedCamera(load_world(), port=0).start()
    try:
        yield c
    finally:
        c.stop()


def sim_pose(cam: SimulatedCamera) -> tuple[float, float, float]:
    """Simulator truth: REP-103 pan, tilt in DEGREES (its own conversion), zoom units."""
    p, t, z = cam.position()
    pr, tr = vapix_to_ros(p, t)
    return math.degrees(pr), math.degrees(tr), z


class Joystick:
    """Publishes the current Joy state at 20 Hz from a thread (like joy's autorepeat), until silenced."""

    def __init__(self, node: Any) -> None:
        self.pub = node.create_publisher(Joy, "joy", 10)
        self.axes = [0.0] * 6
        self.buttons = [0] * 15
        self.sending = True
        self.sent = 0  # messages published with the current state (since the last set())
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def set(self, axes: dict[int, float] | None = None, buttons: dict[int, int] | None = None) -> None:
        with self._lock:
            self.axes = [0.0] * 6
            self.buttons = [0] * 15
            for i, v in (axes or {}).items():
                self.axes[i] = v
            for i, v in (buttons or {}).items():
                self.buttons[i] = v
            self.sent = 0

    def published(self, n: int) -> bool:
        """True once ``n`` messages with the current state have been published."""
        with self._lock:
            return self.sent >= n

    def _run(self) -> None:
        while not self._stop.wait(0.05):
            if not self.sending:
                continue
            with self._lock:  # published under the lock: ``sent`` counts messages of exactly this state
                self.pub.publish(Joy(axes=list(self.axes), buttons=list(self.buttons)))
                self.sent += 1

    def close(self) -> None:
        self._stop.set()
        self._t.join(2)


@contextlib.contextmanager
def teleop(*ros_args: str) -> Iterator[subprocess.Popen[bytes]]:
    with node_process([PROGRAM, "--ros-args", "--params-file", str(PARAMS), *ros_args]) as proc:
        yield proc


@pytest.fixture
def rig(ros: Any, cam: SimulatedCamera) -> Iterator[dict[str, Any]]:
    cam.teleport(0.0, 0.0, 1)
    ptz = ros.add(
        PtzNode(
            context=ros.context,
            parameter_overrides=[Parameter("port", value=cam.port), Parameter("velocity_timeout", value=10.0)],
        )
    )
    probe = ros.probe("joy_probe")
    velocities: list[PtzVelocity] = []
    probe.create_subscription(PtzVelocity, "ptz/cmd/velocity", velocities.append, COMMAND_QOS)
    stick = Joystick(probe)
    ros.wait_for(lambda: ptz.poller.latest is not None, 15.0)
    with teleop() as proc:
        # the teleop is up and matched both ways: it subscribes /joy, its velocity publisher reaches the PTZ node
        ros.wait_for(lambda: probe.count_subscribers("/joy") > 0 or proc.poll() is not None, 60.0, 0.1)
        assert proc.poll() is None, proc.stdout.read().decode(errors="replace") if proc.stdout else ""
        ros.wait_for(lambda: ptz.count_publishers("/ptz/cmd/velocity") >= 1, 30.0, 0.1)
        # the Joy publisher has matched the teleop's subscription (the joystick repeats its state at 20 Hz, so a
        # message the other side drops while it completes the match is sent again 50 ms later)
        ros.wait_for(lambda: stick.pub.get_subscription_count() > 0, 30.0, 0.1)
        try:
            yield {"ptz": ptz, "probe": probe, "stick": stick, "velocities": velocities, "proc": proc}
        finally:
            stick.close()


def wait_still(ros: Any, cam: SimulatedCamera, timeout: float) -> tuple[float, float, float]:
    """Wait until the simulated head has not moved for 0.5 s; return that pose."""
    last = {"pose": sim_pose(cam), "since": time.monotonic()}

    def still() -> bool:
        now = sim_pose(cam)
        if any(abs(a - b) > 1e-3 for a, b in zip(now, last["pose"], strict=True)):
            last["pose"], last["since"] = now, time.monotonic()
            return False
        return time.monotonic() - last["since"] >= 0.5

    ros.wait_for(still, timeout, 0.02)
    return last["pose"]


def test_stick_with_deadman_moves_the_head_and_releasing_the_deadman_stops_it(ros, cam, rig):
    stick, velocities = rig["stick"], rig["velocities"]
    # without the dead-man: nothing moves and nothing is commanded
    stick.set(axes={0: 1.0})
    time.sleep(1.0)  # a window for a (wrong) move without the dead-man: the thing under test is that none comes
    assert sim_pose(cam)[:2] == pytest.approx((0.0, 0.0), abs=1e-3)
    assert not [v for v in velocities if v.pan_rate or v.tilt_rate or v.zoom_rate]

    # dead-man + left stick left and up: the view turns LEFT (REP-103 +pan) and UP
    stick.set(axes={0: 1.0, 1: 0.6}, buttons={DEADMAN: 1})
    ros.wait_for(lambda: sim_pose(cam)[0] > 10.0 and sim_pose(cam)[1] > 3.0, 10.0, 0.02)
    assert cam.position()[0] < 0.0  # the camera's own VAPIX pan: negative = left on the 214
    moving = [v for v in velocities if v.pan_rate > 0.0]
    assert moving
    assert moving[-1].pan_rate == pytest.approx(1.2)  # full deflection = pan_speed of the file (rad/s)

    # release the dead-man, stick still pushed, Joy still flowing: the head stops (explicit stop, not the
    # PTZ node's 10 s watchdog) and stays stopped
    n = len(velocities)
    stick.set(axes={0: 1.0, 1: 0.6})
    ros.wait_for(lambda: any(v.pan_rate == 0.0 and v.tilt_rate == 0.0 for v in velocities[n:]), 5.0)
    pose = wait_still(ros, cam, 5.0)
    time.sleep(1.0)  # a window for a (wrong) restart while Joy keeps flowing: the thing under test is none comes
    assert sim_pose(cam) == pytest.approx(pose, abs=1e-3)
    assert rig["proc"].poll() is None


def test_joy_silence_stops_the_head(ros, cam, rig):
    stick = rig["stick"]
    stick.set(axes={0: -1.0}, buttons={DEADMAN: 1})  # turn right
    ros.wait_for(lambda: sim_pose(cam)[0] < -10.0, 10.0, 0.02)
    t0 = time.monotonic()
    stick.sending = False  # the joystick driver dies: no more Joy messages at all
    pose = wait_still(ros, cam, 6.0)  # well before the PTZ node's own 10 s velocity watchdog
    assert time.monotonic() - t0 < 8.0
    time.sleep(1.0)  # a window for a (wrong) restart without Joy: the thing under test is that none comes
    assert sim_pose(cam) == pytest.approx(pose, abs=1e-3)
    assert rig["proc"].poll() is None  # the teleop is alive and waiting
    # the joystick comes back: the held stick moves the head again
    stick.sending = True
    ros.wait_for(lambda: sim_pose(cam)[0] < pose[0] - 5.0, 10.0, 0.02)
    stick.set(buttons={})
    wait_still(ros, cam, 6.0)


def absolute(pan_deg: float, tilt_deg: float, zoom: float) -> MovePtz.Request:
    cmd = PtzCommand(pan=math.radians(pan_deg), tilt=math.radians(tilt_deg), zoom=zoom, speed=math.nan)
    return MovePtz.Request(command=cmd, wait=True)


def test_zoom_home_and_preset_buttons(ros, cam, rig):
    stick, probe = rig["stick"], rig["probe"]
    # right stick up = zoom in; then RB (zoom_in_button) also zooms in
    stick.set(axes={3: 1.0}, buttons={DEADMAN: 1})
    ros.wait_for(lambda: sim_pose(cam)[2] > 1000, 10.0, 0.02)
    stick.set(buttons={DEADMAN: 1})
    z = wait_still(ros, cam, 6.0)[2]
    stick.set(buttons={DEADMAN: 1, ZOOM_IN: 1})
    ros.wait_for(lambda: sim_pose(cam)[2] > z + 500, 10.0, 0.02)
    stick.set(buttons={DEADMAN: 1})
    wait_still(ros, cam, 6.0)

    # store preset "1" at a pose, move away, press A (with the dead-man): the head goes back to the preset
    move = probe.create_client(MovePtz, "ptz/move_absolute")
    r = ros.call(move, absolute(25.0, -5.0, 300.0))
    assert r.success, r.message
    preset = probe.create_client(Preset, "ptz/preset")
    r = ros.call(preset, Preset.Request(action="set", name="1", wait=True))
    assert r.success, r.message
    r = ros.call(move, absolute(-30.0, 10.0, 1.0))
    assert r.success, r.message
    stick.set(buttons={PRESET_1: 1})  # without the dead-man: ignored
    time.sleep(0.8)  # a window for a (wrong) preset goto: the thing under test is that none comes
    assert sim_pose(cam)[0] == pytest.approx(-30.0, abs=0.05)
    stick.set(buttons={DEADMAN: 1})  # A released first: the preset fires on its rising edge
    ros.wait_for(lambda: stick.published(2), 5.0)
    stick.set(buttons={DEADMAN: 1, PRESET_1: 1})
    ros.wait_for(lambda: sim_pose(cam) == pytest.approx((25.0, -5.0, 300), abs=0.05), 10.0, 0.02)

    # Y with the dead-man: home (pan 0, tilt 0, zoom 1)
    stick.set(buttons={DEADMAN: 1})
    ros.wait_for(lambda: stick.published(2), 5.0)
    stick.set(buttons={DEADMAN: 1, HOME: 1})
    ros.wait_for(lambda: sim_pose(cam) == pytest.approx((0.0, 0.0, 1), abs=0.05), 10.0, 0.02)
    assert ros.call(probe.create_client(Trigger, "ptz/home"), Trigger.Request()).success


def test_sigint_stops_a_moving_head(ros, cam, rig):
    """Ctrl-C while the head turns (stick held, Joy flowing): the teleop sends a stop on its way out."""
    stick, proc, velocities = rig["stick"], rig["proc"], rig["velocities"]
    stick.set(axes={0: 1.0}, buttons={DEADMAN: 1})
    ros.wait_for(lambda: sim_pose(cam)[0] > 5.0, 10.0, 0.02)
    n = len(velocities)
    proc.send_signal(signal.SIGINT)
    assert proc.wait(15) == 0
    # the exit stop (nothing else stops it: Joy still says "turn", the PTZ watchdog is 10 s)
    ros.wait_for(lambda: any(v.pan_rate == 0.0 for v in velocities[n:]), 5.0)
    wait_still(ros, cam, 6.0)
