"""PtzNode against the simulated camera over real DDS and loopback HTTP.

Every check reads the SIMULATOR's own ground truth (``cam.position()``, its renderer, its request log), never
the node's state, so a sign, unit or frame error in the driver cannot cancel out.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import cv2
import numpy as np
import pytest
import yaml

pytest.importorskip("rclpy")

from action_msgs.msg import GoalStatus  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import PointStamped, Twist  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.action import ActionClient  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from axis_ptz_interfaces.action import PtzMove  # noqa: E402
from axis_ptz_interfaces.msg import PtzCommand, PtzState, PtzVelocity  # noqa: E402
from axis_ptz_interfaces.srv import AreaZoom, CenterOnPixel, ListPresets, LookAt, MovePtz, Preset, SetZoom  # noqa: E402
from axis_ptz_ros2.config import MountConfig, save_mount  # noqa: E402
from axis_ptz_ros2.geometry import pan_tilt_to_direction  # noqa: E402
from axis_ptz_ros2.nodes.common import COMMAND_QOS, STREAM_QOS  # noqa: E402
from axis_ptz_ros2.nodes.ptz_node import PtzNode  # noqa: E402
from axis_ptz_ros2.sim.camera import SimulatedCamera  # noqa: E402
from axis_ptz_ros2.sim.faults import FaultConfig  # noqa: E402
from axis_ptz_ros2.sim.ptz import Speeds, vapix_to_ros  # noqa: E402
from axis_ptz_ros2.sim.world import PtzLimits, TargetSpec, load_world  # noqa: E402
from axis_ptz_ros2.transforms import Transform  # noqa: E402
from tests.support.waiting import wait_until

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]

NAN = float("nan")
W, H = 704, 576
SPEED = 300.0  # deg/s, fast sim head (tests stay short)
MAST_Z = 3.0  # the test world's PTZ sits on a 3 m mast so targets 40 deg below the horizon are above ground
UP_COLOR = (255, 0, 255)  # BGR magenta
DOWN_COLOR = (255, 255, 0)  # BGR cyan


def _point_at(centre: np.ndarray, pan_deg: float, elev_deg: float, rng: float) -> tuple[float, float, float]:
    d = pan_tilt_to_direction(math.radians(pan_deg), math.radians(elev_deg))
    p = centre + rng * d
    return float(p[0]), float(p[1]), float(p[2])


def _world() -> Any:
    base = load_world()
    T = base.T_base_ptz
    mast = Transform(T.R, np.array([T.t[0], T.t[1], MAST_Z]))
    centre = mast.apply(np.array([0.0, 0.0, base.kinematics.h_tilt]))
    targets = (
        TargetSpec("up_marker", "marker", _point_at(centre, 12.0, 40.0, 4.0), (0.3, 0.3), color=UP_COLOR),
        TargetSpec("down_marker", "marker", _point_at(centre, -15.0, -40.0, 3.0), (0.3, 0.3), color=DOWN_COLOR),
        TargetSpec("side_marker", "marker", (float(T.t[0]), float(T.t[1]) + 3.0, MAST_Z), (0.4, 0.4)),
    )
    limits = PtzLimits(-170.0, 170.0, -90.0, 90.0, 1, 9999)
    return dataclasses.replace(base, T_base_ptz=mast, limits=limits, targets=targets)


@pytest.fixture(scope="module")
def cam() -> Iterator[SimulatedCamera]:
    c = SimulatedCamera(_world(), port=0, speeds=Speeds(SPEED, SPEED, 0.5, 0.5)).start()
    try:
        yield c
    finally:
        c.stop()


@pytest.fixture(scope="module")
def config_files(cam: SimulatedCamera, tmp_path_factory: pytest.TempPathFactory) -> tuple[str, str]:
    d = tmp_path_factory.mktemp("ptz_cfg")
    model = yaml.safe_load(Path("config/axis214.yaml").read_text(encoding="utf-8"))
    kin = cam.world.kinematics
    model["head"] = {"h_tilt": kin.h_tilt, "d_opt": list(kin.d_opt)}
    model["max_speed"] = {"pan_dps": SPEED, "tilt_dps": SPEED}
    model_path = d / "model.yaml"
    model_path.write_text(yaml.safe_dump(model), encoding="utf-8")
    mount_path = d / "mount.yaml"
    save_mount(MountConfig(transform=cam.world.T_base_ptz), mount_path)  # the sim's TRUE mount
    return str(model_path), str(mount_path)


def make_node(ros: Any, cam: SimulatedCamera, config_files: tuple[str, str], *extra: Parameter) -> PtzNode:
    """A PtzNode on the test camera (reset to a known state) with ``extra`` parameter overrides."""
    cam.set_faults(FaultConfig())
    cam.teleport(0.0, 0.0, 1)
    cam.state.speed = 100  # VAPIX speed is a persistent setting (an earlier test may have slowed the sim itself)
    cam.reset_counts()
    model, mount = config_files
    overrides = [
        Parameter("port", value=cam.port),
        Parameter("camera_model", value=model),
        Parameter("mount_file", value=mount),
        Parameter("state_timeout", value=0.5),
        Parameter("arrival_tolerance", value=0.001),
        *extra,
    ]
    n = ros.add(PtzNode(context=ros.context, parameter_overrides=overrides))
    ros.wait_for(lambda: n.poller.latest is not None, 10.0)
    return n


@pytest.fixture
def node(ros: Any, cam: SimulatedCamera, config_files: tuple[str, str]) -> PtzNode:
    return make_node(ros, cam, config_files)


# ------------------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------------------
def sim_pose(cam: SimulatedCamera) -> tuple[float, float, float]:
    """The simulator's true pose in REP-103 radians (its OWN conversion) and zoom units."""
    p, t, z = cam.position()
    pr, tr = vapix_to_ros(p, t)
    return pr, tr, z


def wait_sim_still(cam: SimulatedCamera, timeout: float = 10.0) -> tuple[float, float, float]:
    wait_until(lambda: not cam.state.moving(), timeout, what="the simulated head to stop moving")
    return sim_pose(cam)


def motion_requests(cam: SimulatedCamera) -> list[Any]:
    return [e for e in cam.request_counts.ptz_log if "query=" not in e.query]


def pantilt_velocity(entry: Any) -> tuple[float, float] | None:
    """The ``continuouspantiltmove`` speeds of a logged PTZ request (None: the request has none)."""
    for k, v in parse_qsl(entry.query, keep_blank_values=True):
        if k.lower() == "continuouspantiltmove":
            pan, tilt = v.split(",")
            return float(pan), float(tilt)
    return None


def is_velocity_stop(entry: Any) -> bool:
    return pantilt_velocity(entry) == (0.0, 0.0)


def velocity_start_and_stop(cam: SimulatedCamera) -> tuple[Any | None, Any | None]:
    """From the sim's request log: the first non-zero continuous pan/tilt move and the first stop after it."""
    start = stop = None
    for e in motion_requests(cam):
        v = pantilt_velocity(e)
        if v is None:
            continue
        if start is None and v != (0.0, 0.0):
            start = e
        elif start is not None and v == (0.0, 0.0):
            stop = e
            break
    return start, stop


def wait_velocity_stop(ros: Any, cam: SimulatedCamera, timeout: float) -> tuple[Any, Any]:
    """Wait until the sim's log holds a continuous move and the stop after it; both log entries."""
    ros.wait_for(lambda: velocity_start_and_stop(cam)[1] is not None, timeout)
    start, stop = velocity_start_and_stop(cam)
    assert start is not None
    assert stop is not None
    return start, stop


def connect(ros: Any, pub: Any) -> Any:
    """Wait until the node's subscription and ``pub`` have matched each other (both sides)."""
    return ros.wait_matched(pub, 10.0)


def cmd(pan: float = NAN, tilt: float = NAN, zoom: float = NAN, speed: float = NAN) -> PtzCommand:
    return PtzCommand(pan=pan, tilt=tilt, zoom=zoom, speed=speed)


def move(ros: Any, probe: Any, service: str, command: PtzCommand, wait: bool = True) -> Any:
    client = probe.create_client(MovePtz, service)
    return ros.call(client, MovePtz.Request(command=command, wait=wait, timeout_s=10.0), timeout=15.0)


def snapshot(cam: SimulatedCamera) -> np.ndarray:
    jpeg = cam.frame_jpeg(W, H, 0)
    return cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)


def find_marker(img: np.ndarray, bgr: tuple[int, int, int]) -> tuple[float, float, float, float] | None:
    """Bounding box (u0, v0, u1, v1) of the pixels of a solid marker colour."""
    diff = np.abs(img.astype(np.int32) - np.array(bgr, np.int32)).sum(axis=2)
    ys, xs = np.nonzero(diff < 90)
    if len(xs) < 20:
        return None
    return float(xs.min()), float(ys.min()), float(xs.max()), float(ys.max())


def centre_of(box: tuple[float, float, float, float]) -> tuple[float, float]:
    return (box[0] + box[2]) / 2.0, (box[1] + box[3]) / 2.0


def marker_centroid(img: np.ndarray, bgr: tuple[int, int, int]) -> tuple[float, float]:
    """Centroid of the marker's pixels: unlike the bounding box, not moved by a few noisy pixels at the edge of a
    softened marker (the simulated 214's picture has the PAL chain's blur and sensor noise)."""
    diff = np.abs(img.astype(np.int32) - np.array(bgr, np.int32)).sum(axis=2)
    ys, xs = np.nonzero(diff < 90)
    return float(xs.mean()), float(ys.mean())


# ------------------------------------------------------------------------------------------------------
# tests
# ------------------------------------------------------------------------------------------------------
def test_absolute_relative_service_and_topic_land_on_the_sim(ros: Any, node: PtzNode, cam: SimulatedCamera) -> None:
    probe = ros.probe()
    pub_abs = connect(ros, probe.create_publisher(PtzCommand, "ptz/cmd/absolute", COMMAND_QOS))
    pub_rel = connect(ros, probe.create_publisher(PtzCommand, "ptz/cmd/relative", COMMAND_QOS))
    resp = move(ros, probe, "ptz/move_absolute", cmd(math.radians(30.0), math.radians(10.0), 3000.0))
    assert resp.success, resp.message
    p, t, z = sim_pose(cam)
    # +30 deg REP-103 pan = LEFT = VAPIX -30 (the sim's own convention)
    assert cam.position()[0] == pytest.approx(-30.0, abs=1e-3)
    assert (p, t, z) == pytest.approx((math.radians(30.0), math.radians(10.0), 3000.0), abs=1e-4)
    assert resp.state.pan == pytest.approx(p, abs=1e-4)

    resp = move(ros, probe, "ptz/move_relative", cmd(math.radians(-5.0), math.radians(2.5), -1000.0))
    assert resp.success, resp.message
    assert sim_pose(cam) == pytest.approx((math.radians(25.0), math.radians(12.5), 2000.0), abs=1e-4)

    # NaN axes stay where they are
    resp = move(ros, probe, "ptz/move_absolute", cmd(tilt=math.radians(-20.0)))
    assert resp.success, resp.message
    assert sim_pose(cam) == pytest.approx((math.radians(25.0), math.radians(-20.0), 2000.0), abs=1e-4)

    pub_abs.publish(cmd(math.radians(-60.0), math.radians(5.0), 1.0))
    want = (math.radians(-60.0), math.radians(5.0), 1.0)
    ros.wait_for(lambda: sim_pose(cam) == pytest.approx(want, abs=1e-4), 5.0)
    pub_rel.publish(cmd(pan=math.radians(10.0)))
    want = (math.radians(-50.0), math.radians(5.0), 1.0)
    ros.wait_for(lambda: sim_pose(cam) == pytest.approx(want, abs=1e-4), 5.0)


def test_out_of_limits_refused_and_never_sent(ros: Any, node: PtzNode, cam: SimulatedCamera) -> None:
    probe = ros.probe()
    cam.reset_counts()
    for command, service in (
        (cmd(pan=math.radians(175.0)), "ptz/move_absolute"),
        (cmd(tilt=math.radians(95.0)), "ptz/move_absolute"),
        (cmd(zoom=12000.0), "ptz/move_absolute"),
        (cmd(pan=math.radians(-171.0)), "ptz/move_relative"),
    ):
        resp = move(ros, probe, service, command)
        assert not resp.success
        assert "limits" in resp.message, resp.message
    pub = connect(ros, probe.create_publisher(PtzCommand, "ptz/cmd/absolute", COMMAND_QOS))
    refused0 = node.commander.stats.refused
    pub.publish(cmd(pan=math.radians(-200.0)))
    ros.wait_for(lambda: node.commander.stats.refused > refused0, 5.0)  # the node took it and refused it
    assert "limits" in node.commander.stats.last_refusal, node.commander.stats.last_refusal
    assert motion_requests(cam) == []  # the camera never saw a command
    assert cam.position() == pytest.approx((0.0, 0.0, 1.0))
    # a command right at the limit is accepted
    resp = move(ros, probe, "ptz/move_absolute", cmd(pan=math.radians(-170.0)))
    assert resp.success, resp.message
    assert cam.position()[0] == pytest.approx(170.0, abs=1e-3)


def test_velocity_moves_then_stops_by_itself(ros: Any, node: PtzNode, cam: SimulatedCamera) -> None:
    probe = ros.probe()
    pub = connect(ros, probe.create_publisher(PtzVelocity, "ptz/cmd/velocity", COMMAND_QOS))
    cam.reset_counts()
    rate = math.radians(30.0)  # rad/s, left
    t0 = time.monotonic()
    pub.publish(PtzVelocity(pan_rate=rate, tilt_rate=-rate / 2.0, zoom_rate=0.0))
    # nothing else is published: the node itself must send the stop (the sim's log has both requests)
    start, stop = wait_velocity_stop(ros, cam, 5.0)
    p, t, _ = wait_sim_still(cam)
    moved_for = stop.t_mono - start.t_mono  # the sim moved from one request to the other
    # The watchdog counts velocity_timeout (0.5 s) from when the node took the command, after t0: the stop
    # cannot come earlier. The upper bound only allows for executor stalls (a tick is 0.05 s) on a loaded
    # machine; a watchdog that ignored the timeout or never ticked would not meet it.
    assert stop.t_mono - t0 >= 0.5, stop.t_mono - t0
    assert moved_for < 2.0, moved_for
    assert p > 0.0  # REP-103 left = the sim's +yaw
    # The sim integrates the commanded velocity exactly from one request to the next; the log stamps are taken
    # just before each request is applied (same thread), so only scheduling jitter separates them.
    assert p == pytest.approx(rate * moved_for, rel=0.05)
    assert t == pytest.approx(-p / 2.0, rel=0.05)
    time.sleep(0.3)  # a window for a (wrong) second stop or move: the thing under test is that the head stays put
    assert sim_pose(cam) == pytest.approx((p, t, 1.0), abs=1e-6)


@pytest.mark.parametrize(("name", "color", "tilt_sign"), [("up_marker", UP_COLOR, 1), ("down_marker", DOWN_COLOR, -1)])
def test_center_on_rendered_target_at_steep_tilt(
    ros: Any, node: PtzNode, cam: SimulatedCamera, name: str, color: tuple[int, int, int], tilt_sign: int
) -> None:
    # start 7 deg beside and 5 deg nearer the horizon than the target (which is at 40 deg elevation)
    pan0 = (-12.0 + 7.0) if tilt_sign > 0 else (15.0 - 7.0)  # VAPIX degrees (+ = right)
    tilt0 = 35.0 * tilt_sign
    cam.teleport(pan0, tilt0, 1)
    ros.wait_for(
        lambda: node.poller.latest is not None and abs(node.poller.latest.reading.tilt - math.radians(tilt0)) < 1e-4,
        3.0,
    )
    box = find_marker(snapshot(cam), color)
    assert box is not None, f"{name} not visible"
    assert box[0] > 0
    assert box[2] < W - 1
    assert box[1] > 0
    assert box[3] < H - 1
    u, v = marker_centroid(snapshot(cam), color)
    assert math.hypot(u - (W - 1) / 2, v - (H - 1) / 2) > 40.0  # really off-centre to start with
    probe = ros.probe()
    client = probe.create_client(CenterOnPixel, "ptz/center")
    req = CenterOnPixel.Request(wait=True, timeout_s=10.0)
    req.target.u, req.target.v, req.target.image_width, req.target.image_height = u, v, W, H
    resp = ros.call(client, req, timeout=15.0)
    assert resp.success, resp.message
    wait_sim_still(cam)
    img = snapshot(cam)
    assert find_marker(img, color) is not None
    u2, v2 = marker_centroid(img, color)
    err = math.hypot(u2 - (W - 1) / 2, v2 - (H - 1) / 2)
    assert err < 3.0, (u2, v2, err)
    assert abs(cam.position()[1]) == pytest.approx(40.0, abs=1.0)  # truly centred at a steep tilt


def test_area_zoom_fills_the_view_with_the_box(ros: Any, node: PtzNode, cam: SimulatedCamera) -> None:
    cam.teleport(-12.0 + 3.0, 38.0, 1)
    # the pose the area zoom starts from is the commander's reading (what ptz/area_zoom reads): wait for it there
    ros.wait_for(lambda: (r := node.commander.reading()) is not None and abs(r.tilt - math.radians(38)) < 1e-3)
    box = find_marker(snapshot(cam), UP_COLOR)
    assert box is not None
    probe = ros.probe()
    client = probe.create_client(AreaZoom, "ptz/area_zoom")
    req = AreaZoom.Request(
        u_min=box[0], v_min=box[1], u_max=box[2], v_max=box[3], image_width=W, image_height=H, wait=True, timeout_s=10.0
    )
    resp = ros.call(client, req, timeout=15.0)
    assert resp.success, resp.message
    wait_sim_still(cam)
    box2 = find_marker(snapshot(cam), UP_COLOR)
    assert box2 is not None
    u2, v2 = centre_of(box2)
    assert math.hypot(u2 - (W - 1) / 2, v2 - (H - 1) / 2) < 4.0
    # the box's larger relative side now fills its image dimension (pixel-edge quantisation of the box: ~2 %)
    fill = max((box2[2] - box2[0] + 1) / W, (box2[3] - box2[1] + 1) / H)
    assert fill == pytest.approx(1.0, abs=0.05), (box, box2)
    assert cam.position()[2] > 1000


def test_set_zoom_by_units_magnification_and_hfov(ros: Any, node: PtzNode, cam: SimulatedCamera) -> None:
    probe = ros.probe()
    client = probe.create_client(SetZoom, "ptz/set_zoom")
    zm = cam.world.zoom_model  # the sim's own optics

    def call(**kw: float) -> Any:
        req = SetZoom.Request(zoom=NAN, magnification=NAN, hfov=NAN, wait=True, timeout_s=10.0)
        for k, v in kw.items():
            setattr(req, k, v)
        return ros.call(client, req, timeout=15.0)

    assert call(zoom=4321.0).success
    assert cam.position()[2] == pytest.approx(4321.0)
    resp = call(magnification=5.0)
    assert resp.success, resp.message
    assert zm.magnification(cam.position()[2]) == pytest.approx(5.0, abs=0.01)
    assert resp.state.magnification == pytest.approx(5.0, abs=0.01)
    resp = call(hfov=math.radians(10.0))
    assert resp.success, resp.message
    assert math.degrees(zm.hfov(cam.position()[2])) == pytest.approx(10.0, abs=0.02)
    assert not call(magnification=40.0).success
    assert not call(zoom=100.0, hfov=0.3).success


def test_home_and_presets(ros: Any, node: PtzNode, cam: SimulatedCamera) -> None:
    probe = ros.probe()
    preset = probe.create_client(Preset, "ptz/preset")
    listing = probe.create_client(ListPresets, "ptz/list_presets")
    home = probe.create_client(Trigger, "ptz/home")
    assert move(ros, probe, "ptz/move_absolute", cmd(math.radians(-45.0), math.radians(20.0), 2500.0)).success
    r = ros.call(preset, Preset.Request(action="set", name="door", wait=False))
    assert r.success, r.message
    assert ros.call(home, Trigger.Request()).success
    assert wait_sim_still(cam) == pytest.approx((0.0, 0.0, 1.0), abs=1e-6)
    r = ros.call(preset, Preset.Request(action="goto", name="door", wait=True, timeout_s=10.0), timeout=15.0)
    assert r.success, r.message
    assert cam.position() == pytest.approx((45.0, 20.0, 2500.0), abs=1e-3)
    names = ros.call(listing, ListPresets.Request())
    assert names.success
    assert "door" in names.names
    assert ros.call(preset, Preset.Request(action="remove", name="door")).success
    assert "door" not in ros.call(listing, ListPresets.Request()).names
    r = ros.call(preset, Preset.Request(action="goto", name="door", wait=True))
    assert not r.success
    assert "door" in r.message
    assert not ros.call(preset, Preset.Request(action="jump", name="x")).success


def test_look_at_a_3d_target_with_parallax(ros: Any, node: PtzNode, cam: SimulatedCamera) -> None:
    target = cam.renderer.scene.target("side_marker").center if hasattr(cam.renderer, "scene") else None
    if target is None:
        target = np.array(cam.world.targets[2].center)
    probe = ros.probe()
    client = probe.create_client(LookAt, "ptz/look_at")
    req = LookAt.Request(zoom=NAN, wait=True, timeout_s=10.0)
    req.target.header.frame_id = "base_link"
    req.target.point.x, req.target.point.y, req.target.point.z = (float(v) for v in target)
    resp = ros.call(client, req, timeout=15.0)
    assert resp.success, resp.message
    T = cam.renderer.camera_pose(*cam.position()[:2])  # TRUE optical frame in base_link
    axis = T.R[:, 2]
    to_target = np.asarray(target) - T.t
    err = math.degrees(math.acos(float(np.clip(axis @ to_target / np.linalg.norm(to_target), -1, 1))))
    assert err < 0.15, err
    # a point in the PTZ base frame too, via the topic
    pub = connect(ros, probe.create_publisher(PointStamped, "ptz/cmd/look_at", COMMAND_QOS))
    msg = PointStamped()
    msg.header.frame_id = "axis_ptz_base"
    msg.point.x, msg.point.y, msg.point.z = 5.0, -5.0, 0.0687 + 5.0 * math.sqrt(2.0)
    pub.publish(msg)
    ros.wait_for(lambda: cam.position()[:2] == pytest.approx((45.0, 45.0), abs=0.05), 5.0)
    # an unknown frame is refused
    req.target.header.frame_id = "map"
    assert not ros.call(client, req).success


def test_state_joint_states_and_transform(ros: Any, node: PtzNode, cam: SimulatedCamera) -> None:
    probe = ros.probe()
    states: list[PtzState] = []
    joints: list[JointState] = []
    probe.create_subscription(PtzState, "ptz/state", states.append, STREAM_QOS)
    probe.create_subscription(JointState, "joint_states", joints.append, STREAM_QOS)
    assert move(ros, probe, "ptz/move_absolute", cmd(math.radians(20.0), math.radians(-10.0), 5000.0)).success
    # no rate is asserted here (timing under load belongs to bench/bench_ptz.py): state keeps coming, each
    # message newer than the one before
    n0 = len(states)
    ros.wait_for(lambda: len(states) >= n0 + 3, 10.0)
    stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in states[n0:]]
    assert stamps == sorted(stamps)
    assert len(set(stamps)) == len(stamps)
    s = states[-1]
    assert (s.pan, s.tilt, s.zoom) == pytest.approx((math.radians(20.0), math.radians(-10.0), 5000.0), abs=1e-4)
    assert not s.moving
    assert s.hfov == pytest.approx(cam.world.zoom_model.hfov(5000.0), rel=1e-6)
    assert s.pan_max == pytest.approx(math.radians(170.0))
    assert s.tilt_min == pytest.approx(math.radians(-90.0))
    j = joints[-1]
    assert list(j.name) == ["axis_ptz_pan_joint", "axis_ptz_tilt_joint"]
    assert list(j.position) == pytest.approx([math.radians(20.0), math.radians(-10.0)], abs=1e-4)


def test_burst_of_relative_commands_coalesces(ros: Any, node: PtzNode, cam: SimulatedCamera) -> None:
    latency = 0.1  # s per request, like a real 214 over a robot's link
    cam.set_faults(latency_ms=latency * 1000.0)
    probe = ros.probe()
    pub = connect(ros, probe.create_publisher(PtzCommand, "ptz/cmd/relative", COMMAND_QOS))
    cam.reset_counts()
    step = math.radians(0.1)
    gen0 = node.commander.generation
    for _ in range(300):
        pub.publish(cmd(pan=step))
        time.sleep(1.0 / 30.0)  # pace the commands as a 30 Hz joystick does: the load is the thing under test
    # the moment the node has taken the last command (every command counts one generation) ...
    ros.wait_for(lambda: node.commander.generation == gen0 + 300, 20.0)
    n_at_last = len(motion_requests(cam))
    want_vapix = -300 * 0.1  # 30 deg left
    ros.wait_for(lambda: abs(cam.position()[0] - want_vapix) < 1e-3, 10.0)
    reqs = motion_requests(cam)
    # ... at most the request then in flight and the last command's own request follow: no backlog, and the
    # burst was coalesced (no wall-clock bound: that figure is measured by bench/bench_ptz.py)
    assert len(reqs) - n_at_last <= 2, [e.query for e in reqs[n_at_last:]]
    assert len(reqs) < 300
    assert "pan=-30" in reqs[-1].query, reqs[-1].query
    cam.set_faults(FaultConfig())


def test_state_survives_errors_stall_and_reboot(ros: Any, node: PtzNode, cam: SimulatedCamera) -> None:
    probe = ros.probe()
    states: list[tuple[float, PtzState]] = []
    diags: list[DiagnosticArray] = []
    probe.create_subscription(PtzState, "ptz/state", lambda m: states.append((time.monotonic(), m)), STREAM_QOS)
    probe.create_subscription(DiagnosticArray, "/diagnostics", diags.append, 10)
    ros.wait_for(lambda: len(states) > 3)

    def resumes_at(pan_deg: float, timeout: float = 5.0) -> None:
        t = time.monotonic()
        ros.wait_for(
            lambda: (
                states and states[-1][0] > t and states[-1][1].pan == pytest.approx(math.radians(-pan_deg), abs=1e-4)
            ),
            timeout,
        )

    for code in (500, 503):
        failed0 = node.poller.stats.failed
        cam.set_faults(http_error=code)
        ros.wait_for(lambda f=failed0: node.poller.stats.failed >= f + 2, 5.0)  # the node is blind
        cam.teleport(10.0 + code / 100.0, 0.0, 1)  # the head moved while we were blind
        cam.set_faults(FaultConfig())
        resumes_at(10.0 + code / 100.0)
    # a stall: every reply 1.5 s late (> state_timeout 0.5 s)
    failed0 = node.poller.stats.failed
    cam.set_faults(latency_ms=1500.0)
    ros.wait_for(lambda: node.poller.stats.failed > failed0, 5.0)  # a poll timed out
    cam.teleport(-33.0, 0.0, 1)
    cam.set_faults(FaultConfig())
    resumes_at(-33.0, 8.0)
    failed = node.poller.stats.failed
    assert failed >= 3
    ros.wait_for(
        lambda: any(kv.key == "polls_failed" and int(kv.value) > 0 for d in diags for s in d.status for kv in s.values),
        3.0,
    )
    # a reboot: refused connections for 3 s, then back at home. The poller notices: its failure count grows
    # (``failed`` never decreases, unlike consecutive_failures, so a finished failure streak is not missed)
    failed_before_reboot = node.poller.stats.failed
    cam.reboot(3.0)
    ros.wait_for(lambda: node.poller.stats.failed > failed_before_reboot, 5.0)
    ros.wait_for(lambda: not cam.rebooting, 5.0)
    resumes_at(0.0, 8.0)
    # and commands work again
    assert move(ros, probe, "ptz/move_absolute", cmd(pan=math.radians(5.0))).success
    assert cam.position()[0] == pytest.approx(-5.0, abs=1e-3)


def test_settings_snapshots_are_built_from_dynamic_parameter_specs() -> None:
    """One source for defaults: every field of the ROS-free settings (Tolerances, DriveSafeConfig) is filled
    by a parameter whose default is the field's, and each of those parameters is dynamic (the node rebuilds the
    snapshot on a change; a read-only one would never reach it)."""
    import dataclasses

    from axis_ptz_ros2.nodes import ptz_node
    from axis_ptz_ros2.nodes.common import snapshot
    from axis_ptz_ros2.ptz.drive_safe import DriveSafeConfig
    from axis_ptz_ros2.ptz.orders import Tolerances

    defaults = {s.name: s.default for s in ptz_node.PARAMS}
    for cls in (Tolerances, DriveSafeConfig):
        specs = [s for s in ptz_node.PARAMS if s.config is cls]
        assert sorted(s.field for s in specs) == sorted(f.name for f in dataclasses.fields(cls))
        assert all(s.name in ptz_node._DYNAMIC and s.float_range is not None for s in specs)
        assert snapshot(cls, ptz_node.PARAMS, defaults) == cls()
    changed = dict(defaults, drive_zoom_cap=2500.0, arrival_tolerance=0.01)
    assert snapshot(DriveSafeConfig, ptz_node.PARAMS, changed).zoom_cap == 2500.0
    assert snapshot(Tolerances, ptz_node.PARAMS, changed).pan_tilt_rad == 0.01
    assert {"image_width", "image_height", "follow_video_params", "wait_timeout"} <= ptz_node._DYNAMIC
    assert not {"state_rate", "timeout", "hostname"} & ptz_node._DYNAMIC


def test_goal_kinds_match_the_action() -> None:
    from axis_ptz_ros2.ptz.requests import GoalKind

    assert {k.name: k.value for k in GoalKind} == {k.name: getattr(PtzMove.Goal, k.name) for k in GoalKind}


def test_parameters_dynamic_and_read_only(ros: Any, cam: SimulatedCamera, config_files: tuple[str, str]) -> None:
    # started with a long velocity timeout (5 s) so that the runtime change to 0.2 s is unmistakable
    node = make_node(ros, cam, config_files, Parameter("velocity_timeout", value=5.0))
    res = node.set_parameters([Parameter("velocity_timeout", value=0.2)])
    assert res[0].successful
    assert not node.set_parameters([Parameter("hostname", value="10.0.0.1")])[0].successful  # read-only
    assert not node.set_parameters([Parameter("velocity_timeout", value=100.0)])[0].successful  # range
    probe = ros.probe()
    pub = connect(ros, probe.create_publisher(PtzVelocity, "ptz/cmd/velocity", COMMAND_QOS))
    cam.reset_counts()
    t0 = time.monotonic()
    pub.publish(PtzVelocity(pan_rate=-0.5, tilt_rate=0.0, zoom_rate=0.0))
    start, stop = wait_velocity_stop(ros, cam, 8.0)  # (the 5 s timeout would stop it too: bounds below)
    # the node's own stop, from the sim's log: not before the new 0.2 s (counted from when the node took the
    # command, after t0), and far sooner than the initial 5 s (the bound only allows for a loaded machine)
    assert stop.t_mono - t0 >= 0.2, stop.t_mono - t0
    assert stop.t_mono - start.t_mono < 2.5, stop.t_mono - start.t_mono
    wait_sim_still(cam)
    assert cam.position()[0] > 0.0  # REP-103 negative pan rate = right = VAPIX +


# ------------------------------------------------------------------------------------------------------
# commands that never fight (issue 11)
# ------------------------------------------------------------------------------------------------------
def assert_not_stopped_by_the_watchdog(cam: SimulatedCamera, timeout: float, arrived: float) -> None:
    """The sim's log since the velocity command: the next command (the first one after it that is not a
    continuous move) went out while velocity mode was on (no stop before it), the head was still on its way
    ``timeout`` after the velocity command (so a watchdog that still counted would have fired part-way), and no
    stop came after it."""
    log = motion_requests(cam)
    start, _ = velocity_start_and_stop(cam)
    assert start is not None, [e.query for e in log]
    issued = next((e for e in log if e.t_mono >= start.t_mono and pantilt_velocity(e) is None), None)
    assert issued is not None, [e.query for e in log]
    stops = [e for e in log if is_velocity_stop(e)]
    # the precondition of the test: velocity mode was still on when the command was issued
    assert not [e for e in stops if e.t_mono < issued.t_mono], [e.query for e in log]
    assert arrived - start.t_mono > timeout + 0.2, arrived - start.t_mono
    assert not [e for e in stops if e.t_mono >= issued.t_mono], [e.query for e in log]


def test_home_and_preset_right_after_velocity_are_not_stopped_by_the_watchdog(
    ros: Any, node: PtzNode, cam: SimulatedCamera
) -> None:
    # velocity_timeout 1.5 s: far longer than the gap from the velocity command to the home/preset request, so
    # velocity mode is certainly still on when that is issued. The head runs at VAPIX speed 15 (45 deg/s) for
    # those moves, so they take > 3 s: a watchdog that still thought velocity mode was on would stop them
    # part-way (and send a stop the sim logs).
    timeout = 1.5
    assert node.set_parameters([Parameter("velocity_timeout", value=timeout)])[0].successful
    probe = ros.probe()
    pub = connect(ros, probe.create_publisher(PtzVelocity, "ptz/cmd/velocity", COMMAND_QOS))
    home = probe.create_client(Trigger, "ptz/home")
    preset = probe.create_client(Preset, "ptz/preset")
    assert home.wait_for_service(timeout_sec=10.0)
    try:
        cam.teleport(150.0, 30.0, 5000)
        ros.wait_for(lambda: node.commander.reading() is not None and abs(node.commander.reading().zoom - 5000) < 1)
        cam.state.speed = 15  # the camera's own speed setting (the node does not send one for home/presets)
        cam.reset_counts()
        pub.publish(PtzVelocity(pan_rate=0.1, tilt_rate=0.0, zoom_rate=0.0))
        ros.wait_for(lambda: velocity_start_and_stop(cam)[0] is not None, 5.0)
        r = ros.call(home, Trigger.Request(), timeout=20.0)
        arrived = time.monotonic()
        assert r.success, r.message
        assert "arrived" in r.message
        assert cam.position() == pytest.approx((0.0, 0.0, 1.0), abs=1e-3)  # the sim's ground truth
        time.sleep(0.5)  # a window for a (wrong) stop or move after arrival: the thing under test is none comes
        assert cam.position() == pytest.approx((0.0, 0.0, 1.0), abs=1e-3)
        assert_not_stopped_by_the_watchdog(cam, timeout, arrived)
        # the same for a preset goto with wait
        cam.state.speed = 100
        assert move(ros, probe, "ptz/move_absolute", cmd(math.radians(-150.0), math.radians(-20.0), 3000.0)).success
        assert ros.call(preset, Preset.Request(action="set", name="far")).success
        assert move(ros, probe, "ptz/move_absolute", cmd(math.radians(10.0), 0.0, 1.0)).success
        cam.state.speed = 15
        cam.reset_counts()
        pub.publish(PtzVelocity(pan_rate=-0.1, tilt_rate=0.0, zoom_rate=0.0))
        ros.wait_for(lambda: velocity_start_and_stop(cam)[0] is not None, 5.0)
        r = ros.call(preset, Preset.Request(action="goto", name="far", wait=True, timeout_s=10.0), timeout=20.0)
        arrived = time.monotonic()
        assert r.success, r.message
        assert "arrived" in r.message
        assert cam.position() == pytest.approx((150.0, -20.0, 3000.0), abs=1e-3)
        time.sleep(0.5)  # a window for a (wrong) stop or move after arrival: the thing under test is none comes
        assert cam.position() == pytest.approx((150.0, -20.0, 3000.0), abs=1e-3)
        assert_not_stopped_by_the_watchdog(cam, timeout, arrived)
    finally:
        cam.state.speed = 100


def test_preset_goto_reports_where_the_head_stopped(ros: Any, node: PtzNode, cam: SimulatedCamera) -> None:
    probe = ros.probe()
    preset = probe.create_client(Preset, "ptz/preset")
    assert ros.call(preset, Preset.Request(action="set", name="start")).success  # at (0, 0, 1)
    cam.teleport(-120.0, 10.0, 1)
    ros.wait_for(lambda: abs(cam.position()[0] + 120.0) < 1e-6)
    assert node.commander.preset_pose("start") is not None  # stored by this node: its pose is known
    cam.state.speed = 10  # 30 deg/s: the move takes 4 s, so "part-way" does not depend on the test's timing
    fut = preset.call_async(Preset.Request(action="goto", name="start", wait=True, timeout_s=10.0))
    ros.wait_for(lambda: cam.state.moving(), 5.0)
    cam.teleport(*cam.position())  # another client stops the head part-way
    stopped = cam.position()
    assert stopped[0] < -10.0
    cam.state.speed = 100
    ros.wait_for(fut.done, 15.0)
    r = fut.result()
    assert not r.success, r.message
    assert "stopped at" in r.message, r.message
    where = re.search(r"stopped at pan (-?[\d.]+) deg, tilt (-?[\d.]+) deg", r.message)
    assert where is not None, r.message
    assert float(where.group(1)) == pytest.approx(-stopped[0], abs=0.01)  # where it stopped, REP-103 degrees
    assert float(where.group(2)) == pytest.approx(stopped[1], abs=0.01)
    # a preset the node never saw stored: arrival = the head settled there; its pose is learned
    r = ros.call(preset, Preset.Request(action="goto", name="Home", wait=True, timeout_s=10.0), timeout=15.0)
    assert r.success, r.message
    assert "not known" in r.message
    assert cam.position() == pytest.approx((0.0, 0.0, 1.0), abs=1e-3)
    assert node.commander.preset_pose("Home") is not None


def test_infinite_values_are_refused_never_sent(ros: Any, node: PtzNode, cam: SimulatedCamera) -> None:
    probe = ros.probe()
    assert move(ros, probe, "ptz/move_absolute", cmd(math.radians(10.0), 0.0, 1.0)).success
    pub_abs = connect(ros, probe.create_publisher(PtzCommand, "ptz/cmd/absolute", COMMAND_QOS))
    pub_vel = connect(ros, probe.create_publisher(PtzVelocity, "ptz/cmd/velocity", COMMAND_QOS))
    cam.reset_counts()
    refused0 = node.commander.stats.refused
    for service in ("ptz/move_absolute", "ptz/move_relative"):
        for c in (cmd(pan=math.inf), cmd(tilt=-math.inf), cmd(math.radians(5.0), 0.0, math.inf)):
            resp = move(ros, probe, service, c)
            assert not resp.success
            assert "inf" in resp.message, resp.message
    pub_abs.publish(cmd(pan=math.inf, tilt=math.radians(5.0)))
    pub_vel.publish(PtzVelocity(pan_rate=math.inf, tilt_rate=0.0, zoom_rate=0.0))
    pub_vel.publish(PtzVelocity(pan_rate=0.0, tilt_rate=-math.inf, zoom_rate=0.0))
    ros.wait_for(lambda: node.commander.stats.refused >= refused0 + 9, 5.0)
    time.sleep(0.3)  # a window for a (wrong) move or stop sent after the refusal: the thing under test is none comes
    assert motion_requests(cam) == []  # neither a move, nor a "keep this axis" move, nor a silent stop
    assert cam.position() == pytest.approx((-10.0, 0.0, 1.0), abs=1e-3)


def test_a_rejected_command_never_becomes_the_target(ros: Any, node: PtzNode, cam: SimulatedCamera) -> None:
    probe = ros.probe()
    assert move(ros, probe, "ptz/move_absolute", cmd(math.radians(20.0), 0.0, 1.0)).success
    cam.set_faults(http_error=500)  # the camera refuses the next command
    resp = move(ros, probe, "ptz/move_relative", cmd(pan=math.radians(10.0)), wait=False)
    assert not resp.success
    assert "camera error" in resp.message
    cam.set_faults(FaultConfig())
    assert node.target is not None
    assert node.target.pan == pytest.approx(math.radians(20.0))
    resp = move(ros, probe, "ptz/move_relative", cmd(pan=math.radians(5.0)))
    assert resp.success, resp.message
    # 20 + 5, not 20 + 10 + 5: the refused step was never added
    assert cam.position()[0] == pytest.approx(-25.0, abs=1e-3)


def _diag_values(diags: list[DiagnosticArray], node: PtzNode) -> list[tuple[int, str, dict[str, str]]]:
    out = []
    for d in diags:
        for st in d.status:
            if st.name.startswith(node.get_name()):
                out.append(
                    (
                        int.from_bytes(st.level, "little") if isinstance(st.level, bytes) else int(st.level),
                        st.message,
                        {kv.key: kv.value for kv in st.values},
                    )
                )
    return out


def test_state_poller_restarts_itself_and_stale_state_is_an_error(
    ros: Any, node: PtzNode, cam: SimulatedCamera
) -> None:
    probe = ros.probe()
    states: list[PtzState] = []
    diags: list[DiagnosticArray] = []
    probe.create_subscription(PtzState, "ptz/state", states.append, STREAM_QOS)
    probe.create_subscription(DiagnosticArray, "/diagnostics", diags.append, 10)
    ros.wait_for(lambda: len(states) > 2, 10.0)
    # a bug inside one poll tick (not a camera error): the poller logs it, restarts and keeps publishing
    real_poll = node.poller.poll
    crashes = {"n": 0}

    def crashing_poll() -> Any:
        if crashes["n"] < 2:
            crashes["n"] += 1
            raise RuntimeError("injected poll bug")
        return real_poll()

    node.poller.poll = crashing_poll  # type: ignore[method-assign]
    ros.wait_for(lambda: crashes["n"] == 2, 5.0)
    n = len(states)
    cam.teleport(-40.0, 0.0, 1)
    ros.wait_for(lambda: len(states) > n and states[-1].pan == pytest.approx(math.radians(40.0), abs=1e-4), 10.0)
    ros.wait_for(lambda: any(v.get("poller_restarts", "0") not in ("0", "") for _, _, v in _diag_values(diags, node)))
    # a poll that never returns: state ages; diagnostics say ERROR "stale" with the age
    release = threading.Event()

    def hanging_poll() -> Any:
        release.wait(30.0)
        return real_poll()

    node.poller.poll = hanging_poll  # type: ignore[method-assign]
    try:
        ros.wait_for(lambda: any(lvl == 2 and "stale" in msg for lvl, msg, _ in _diag_values(diags, node)[-2:]), 15.0)
        lvl, msg, values = [x for x in _diag_values(diags, node) if "stale" in x[1]][-1]
        assert float(values["state_age_s"]) >= float(values["state_stale_after_s"])
    finally:
        node.poller.poll = real_poll  # type: ignore[method-assign]
        release.set()
    ros.wait_for(lambda: _diag_values(diags, node)[-1][0] == 0, 10.0)


# ------------------------------------------------------------------------------------------------------
# ptz/move action (issue 15)
# ------------------------------------------------------------------------------------------------------
class MoveClient:
    """rclpy's ActionClient driven from the test thread (the harness spins the executor)."""

    def __init__(self, ros: Any) -> None:
        self.ros = ros
        self.probe = ros.probe("action_probe")
        self.client = ActionClient(self.probe, PtzMove, "ptz/move")
        assert self.client.wait_for_server(timeout_sec=10.0)

    def send(self, goal: PtzMove.Goal, feedback: list[Any] | None = None) -> Any:
        cb = None if feedback is None else (lambda m: feedback.append(m.feedback))
        fut = self.client.send_goal_async(goal, feedback_callback=cb)
        self.ros.wait_for(fut.done, 10.0)
        handle = fut.result()
        assert handle.accepted
        return handle

    def result(self, handle: Any, timeout: float = 20.0) -> Any:
        fut = handle.get_result_async()
        self.ros.wait_for(fut.done, timeout)
        return fut.result()


@pytest.fixture
def mc(ros: Any, node: PtzNode) -> MoveClient:
    return MoveClient(ros)  # destroyed with its probe node by the harness


def absolute_goal(pan_deg: float, tilt_deg: float = 0.0, zoom: float = 1.0, speed: float = NAN) -> PtzMove.Goal:
    return PtzMove.Goal(
        kind=PtzMove.Goal.ABSOLUTE,
        command=cmd(math.radians(pan_deg), math.radians(tilt_deg), zoom, speed),
        timeout_s=15.0,
    )


def test_move_action_feedback_and_result_land_on_the_sim(
    ros: Any, node: PtzNode, cam: SimulatedCamera, mc: MoveClient
) -> None:
    feedback: list[Any] = []
    handle = mc.send(absolute_goal(40.0, 10.0, 2000.0, speed=0.2), feedback)  # 60 deg/s: ~0.7 s of motion
    res = mc.result(handle)
    assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message
    assert res.result.success
    truth = sim_pose(cam)
    assert truth == pytest.approx((math.radians(40.0), math.radians(10.0), 2000.0), abs=1e-4)
    assert (res.result.state.pan, res.result.state.tilt, res.result.state.zoom) == pytest.approx(truth, abs=1e-4)
    assert feedback, "no feedback while the head moved"
    assert any(f.pan_error > math.radians(1.0) for f in feedback)  # remaining error while on the way
    assert all(f.state.pan <= math.radians(40.0) + 1e-4 for f in feedback)
    # zoom by magnification, home, look-at and a relative goal
    goal = PtzMove.Goal(kind=PtzMove.Goal.ZOOM, command=cmd(), magnification=4.0, hfov=NAN, timeout_s=10.0)
    res = mc.result(mc.send(goal))
    assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message
    assert cam.world.zoom_model.magnification(cam.position()[2]) == pytest.approx(4.0, abs=0.01)
    goal = PtzMove.Goal(kind=PtzMove.Goal.RELATIVE, command=cmd(pan=math.radians(-10.0)), timeout_s=10.0)
    res = mc.result(mc.send(goal))
    assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message
    assert cam.position()[0] == pytest.approx(-30.0, abs=1e-3)
    res = mc.result(mc.send(PtzMove.Goal(kind=PtzMove.Goal.HOME, timeout_s=10.0)))
    assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message
    assert cam.position() == pytest.approx((0.0, 0.0, 1.0), abs=1e-3)
    goal = PtzMove.Goal(kind=PtzMove.Goal.LOOK_AT, command=cmd(), timeout_s=10.0)
    goal.point.header.frame_id = "axis_ptz_base"
    goal.point.point.x, goal.point.point.y, goal.point.point.z = 5.0, -5.0, 0.0687 + 5.0 * math.sqrt(2.0)
    res = mc.result(mc.send(goal))
    assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message
    assert cam.position()[:2] == pytest.approx((45.0, 45.0), abs=0.05)
    # an invalid goal ends aborted with the reason, and nothing is sent
    cam.reset_counts()
    res = mc.result(mc.send(absolute_goal(0.0, 0.0, 99999.0)))
    assert res.status == GoalStatus.STATUS_ABORTED
    assert "limits" in res.result.message
    res = mc.result(mc.send(PtzMove.Goal(kind=PtzMove.Goal.ABSOLUTE, command=cmd(pan=math.inf))))
    assert res.status == GoalStatus.STATUS_ABORTED
    assert "inf" in res.result.message
    assert motion_requests(cam) == []


def test_move_action_cancel_stops_the_head(ros: Any, node: PtzNode, cam: SimulatedCamera, mc: MoveClient) -> None:
    feedback: list[Any] = []
    handle = mc.send(absolute_goal(-90.0, speed=0.05), feedback)  # 15 deg/s: 6 s to get there
    ros.wait_for(lambda: len(feedback) >= 3 and cam.state.moving(), 10.0)
    cancel = handle.cancel_goal_async()
    ros.wait_for(cancel.done, 10.0)
    res = mc.result(handle)
    assert res.status == GoalStatus.STATUS_CANCELED, res.result.message
    assert "stopped at" in res.result.message
    assert not cam.state.moving()
    stopped = cam.position()
    assert 1.0 < stopped[0] < 89.0  # VAPIX +pan = right = REP-103 -90: stopped on the way
    time.sleep(0.5)  # a window for a (wrong) restart of the move: the thing under test is that none comes
    assert cam.position() == pytest.approx(stopped, abs=1e-6)  # and stays stopped
    assert res.result.state.pan == pytest.approx(-math.radians(stopped[0]), abs=1e-3), res.result.message


def test_move_action_newer_goal_preempts_the_older(
    ros: Any, node: PtzNode, cam: SimulatedCamera, mc: MoveClient
) -> None:
    fb: list[Any] = []
    first = mc.send(absolute_goal(80.0, speed=0.05), fb)
    ros.wait_for(lambda: len(fb) >= 2 and cam.state.moving(), 10.0)
    second = mc.send(absolute_goal(-20.0, 5.0, 1500.0, speed=1.0))
    res1 = mc.result(first)
    assert res1.status == GoalStatus.STATUS_ABORTED
    assert "pre-empted" in res1.result.message
    res2 = mc.result(second)
    assert res2.status == GoalStatus.STATUS_SUCCEEDED, res2.result.message
    assert cam.position() == pytest.approx((20.0, 5.0, 1500.0), abs=1e-3)  # the newer goal won
    assert move(ros, ros.probe(), "ptz/move_absolute", cmd(pan=math.radians(-21.0))).success
    assert cam.state.speed == 100  # the slow goal did not leave the camera's persistent speed setting slow
    # an invalid newer goal ends aborted with its reason and does not take the head from the running goal
    fb.clear()
    running = mc.send(absolute_goal(30.0, speed=0.1), fb)
    ros.wait_for(lambda: len(fb) >= 2, 10.0)
    bad = mc.result(mc.send(absolute_goal(0.0, 0.0, 99999.0)))
    assert bad.status == GoalStatus.STATUS_ABORTED
    assert "limits" in bad.result.message
    res = mc.result(running)
    assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message
    assert cam.position()[0] == pytest.approx(-30.0, abs=1e-3)
    # a topic command pre-empts a running goal as well (the head obeys the latest command)
    probe = ros.probe()
    pub = connect(ros, probe.create_publisher(PtzCommand, "ptz/cmd/absolute", COMMAND_QOS))
    fb.clear()
    third = mc.send(absolute_goal(80.0, speed=0.05), fb)
    ros.wait_for(lambda: len(fb) >= 2, 10.0)
    pub.publish(cmd(math.radians(10.0), 0.0, 1.0, 1.0))
    res3 = mc.result(third)
    assert res3.status == GoalStatus.STATUS_ABORTED
    assert "superseded" in res3.result.message
    ros.wait_for(lambda: cam.position() == pytest.approx((-10.0, 0.0, 1.0), abs=1e-3), 10.0)


# ------------------------------------------------------------------------------------------------------
# drive-safe zoom (issue 15)
# ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["odometry", "twist"])
def test_drive_safe_zoom_caps_while_moving_and_restores(
    ros: Any, cam: SimulatedCamera, config_files: tuple[str, str], kind: str
) -> None:
    cam.set_faults(FaultConfig())
    cam.teleport(0.0, 0.0, 1)
    cam.state.speed = 100
    model, mount = config_files
    overrides = [
        Parameter("port", value=cam.port),
        Parameter("camera_model", value=model),
        Parameter("mount_file", value=mount),
        Parameter("state_timeout", value=0.5),
        Parameter("drive_topic", value="odom" if kind == "odometry" else "cmd_vel"),
        Parameter("drive_topic_type", value=kind),
        Parameter("drive_zoom_cap", value=4000.0),
        Parameter("drive_hold_time", value=2.0),  # far above any executor stall between speed messages
    ]
    node = ros.add(PtzNode(context=ros.context, parameter_overrides=overrides))
    ros.wait_for(lambda: node.poller.latest is not None, 10.0)
    probe = ros.probe()
    states: list[PtzState] = []
    probe.create_subscription(PtzState, "ptz/state", states.append, STREAM_QOS)
    if kind == "odometry":
        pub = connect(ros, probe.create_publisher(Odometry, "odom", 10))
    else:
        pub = connect(ros, probe.create_publisher(Twist, "cmd_vel", 10))

    # the robot's speed streams at 20 Hz like real odometry; no message for drive_hold_time counts as stopped,
    # so single messages would race the hold against the test's own waits
    speed: list[tuple[float, float] | None] = [None]

    def publish_speed() -> None:
        if speed[0] is None:
            return
        linear, angular = speed[0]
        if kind == "odometry":
            m = Odometry()
            m.twist.twist.linear.x, m.twist.twist.angular.z = linear, angular
        else:
            m = Twist()
            m.linear.x, m.angular.z = linear, angular
        pub.publish(m)

    probe.create_timer(0.05, publish_speed)

    def drive(linear: float, angular: float) -> None:
        speed[0] = (linear, angular)

    assert move(ros, probe, "ptz/move_absolute", cmd(math.radians(10.0), 0.0, 8000.0)).success
    ros.wait_for(lambda: states and not states[-1].zoom_capped and states[-1].zoom_cap == 4000.0, 5.0)
    # driving (or turning on the spot with cmd_vel): the sim's zoom comes down to the cap
    fast = (1.0, 0.0) if kind == "odometry" else (0.0, 0.8)
    drive(*fast)
    ros.wait_for(lambda: cam.position()[2] == pytest.approx(4000.0) and not cam.state.moving(), 10.0)
    assert cam.position()[0] == pytest.approx(-10.0, abs=1e-3)  # pan untouched
    ros.wait_for(lambda: states[-1].zoom_capped and states[-1].requested_zoom == 8000.0, 5.0)
    # while driving, a zoom above the cap is held at the cap and remembered as the operator's zoom
    resp = move(ros, probe, "ptz/move_absolute", cmd(zoom=9000.0))
    assert resp.success, resp.message
    assert cam.position()[2] == pytest.approx(4000.0)
    ros.wait_for(lambda: states[-1].requested_zoom == 9000.0, 5.0)
    # slow below the thresholds: still capped during the hold, then the operator's zoom comes back
    drive(0.05, 0.05)
    ros.wait_for(lambda: cam.position()[2] == pytest.approx(9000.0) and not cam.state.moving(), 10.0)
    ros.wait_for(lambda: not states[-1].zoom_capped, 5.0)
    assert cam.position()[:2] == pytest.approx((-10.0, 0.0), abs=1e-3)
