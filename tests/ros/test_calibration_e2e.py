"""End to end over real DDS: capture views from the simulated camera and laser, pick automatically, calibrate.

Simulated camera (in-process, loopback HTTP) + stream node + PTZ node running the NOMINAL mount
(config/mount.yaml — the tools never see the simulator's true mount) + laser sim node. ``axis_calibrate
capture`` commands the head through ``ptz/move_absolute``, records state, a frame and a laser snapshot per view
and picks the board dots automatically with the simulated-board picker plug-in (``--picker``,
``tests/support/sim_picker.py``); ``axis_calibrate solve`` recovers ``base_link → ptz_base``, which is checked
against the simulator's truth (``load_world().ptz_mount``, here ``T_base_ptz``).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import numpy as np
import pytest
import yaml

pytest.importorskip("rclpy")

from geometry_msgs.msg import TransformStamped  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import HistoryPolicy, ReliabilityPolicy  # noqa: E402

from axis_ptz_ros2.calibration.capture import (  # noqa: E402
    CaptureError,
    PoseCommand,
    cloud_path,
    parse_poses,
)
from axis_ptz_ros2.calibration.correspondences import load_correspondences  # noqa: E402
from axis_ptz_ros2.calibration.picking import picking_noise  # noqa: E402
from axis_ptz_ros2.calibration.problem import rotation_angle  # noqa: E402
from axis_ptz_ros2.config import default_config_path, load_mount, load_robot  # noqa: E402
from axis_ptz_ros2.nodes.calibration_capture import CaptureSession, _laser_qos  # noqa: E402
from axis_ptz_ros2.nodes.calibration_capture import main as cli_main  # noqa: E402
from axis_ptz_ros2.nodes.common import LATCHED_QOS, STREAM_QOS  # noqa: E402
from axis_ptz_ros2.nodes.laser_sim import LaserSim  # noqa: E402
from axis_ptz_ros2.nodes.ptz_node import PtzNode  # noqa: E402
from axis_ptz_ros2.nodes.stream_node import StreamNode  # noqa: E402
from axis_ptz_ros2.sim.camera import SimulatedCamera  # noqa: E402
from axis_ptz_ros2.sim.ptz import Speeds  # noqa: E402
from axis_ptz_ros2.sim.scene import Scene  # noqa: E402
from axis_ptz_ros2.sim.world import load_world  # noqa: E402
from axis_ptz_ros2.transforms import quaternion_to_matrix  # noqa: E402
from tests.support.sim_picker import scene_dot_features  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(150)]

WORLD = load_world()
SPEED = 300.0  # deg/s: a fast simulated head keeps the test short

#: REP-103 degrees and zoom units: views at 1x on two boards, on single boards, tilted up/down so the dots
#: fall on other parts of the image, and zoomed in on each board (aimed roughly, as an operator would).
POSES = "25,7,1;0,5,1;-38,1,1;25,20,1;25,-5,1;12.7,7.5,1200;38.4,9.3,1200;-38.5,0.8,1200"


@pytest.fixture(scope="module")
def cam() -> Iterator[SimulatedCamera]:
    c = SimulatedCamera(WORLD, port=0, speeds=Speeds(SPEED, SPEED, 0.5, 0.5)).start()
    try:
        yield c
    finally:
        c.stop()


@pytest.fixture(scope="module")
def model_file(cam: SimulatedCamera, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """config/axis214.yaml with the head geometry of the simulated 214 (a property of the camera model, known
    from its drawings; NOT the mount) and the fast simulated speeds."""
    model = yaml.safe_load(default_config_path("axis214.yaml").read_text(encoding="utf-8"))
    kin = cam.world.kinematics
    model["head"] = {"h_tilt": kin.h_tilt, "d_opt": list(kin.d_opt)}
    model["max_speed"] = {"pan_dps": SPEED, "tilt_dps": SPEED}
    p = tmp_path_factory.mktemp("calib_model") / "model.yaml"
    p.write_text(yaml.safe_dump(model), encoding="utf-8")
    return p


@pytest.fixture
def system(ros: Any, cam: SimulatedCamera, model_file: Path) -> dict[str, Any]:
    cam.teleport(0.0, 0.0, 1)
    nominal = default_config_path("mount.yaml")
    ptz = ros.add(
        PtzNode(
            context=ros.context,
            parameter_overrides=[
                Parameter("port", value=cam.port),
                Parameter("camera_model", value=str(model_file)),
                Parameter("mount_file", value=str(nominal)),  # the NOMINAL mount
                Parameter("arrival_tolerance", value=0.0005),
            ],
        )
    )
    ros.add(
        StreamNode(
            context=ros.context,
            parameter_overrides=[
                Parameter("port", value=cam.port),
                Parameter("camera_model", value=str(model_file)),
                Parameter("compression", value=20),
            ],
        )
    )
    ros.add(LaserSim(context=ros.context, parameter_overrides=[Parameter("rate", value=5.0)]))
    ros.wait_for(lambda: ptz.poller.latest is not None, 10.0)
    return {"nominal": nominal, "model": model_file}


def _errors(T) -> tuple[float, float]:
    truth = WORLD.T_base_ptz
    return float(np.linalg.norm(T.t - truth.t)), math.degrees(rotation_angle(T.R.T @ truth.R))


def test_laser_qos_reliable_is_latched_and_best_effort_keeps_the_newest_scan() -> None:
    assert _laser_qos("reliable") == LATCHED_QOS  # a latched scan at once
    be = _laser_qos("best_effort")
    assert (be.history, be.depth, be.reliability) == (HistoryPolicy.KEEP_LAST, 1, ReliabilityPolicy.BEST_EFFORT)
    assert be.durability == STREAM_QOS.durability
    with pytest.raises(ValueError, match="laser_qos"):
        _laser_qos("sensor_data")


def test_capture_pick_and_calibrate_recovers_the_true_mount(ros, cam, system, tmp_path, capsys):
    t_start = time.monotonic()
    out = tmp_path / "calib.yaml"
    nominal_t, nominal_r = _errors(load_mount(system["nominal"]).transform)
    assert nominal_t > 0.005  # the nominal mount really is off (else the test would prove nothing)
    assert nominal_r > 1.0

    rc = cli_main(
        [
            "capture",
            str(out),
            f"--poses={POSES}",
            "--picker=tests.support.sim_picker:SimBoardPicker",
            "--camera-model",
            str(system["model"]),
            "--mount",
            str(system["nominal"]),
            "--timeout",
            "20",
        ]
    )
    captured = capsys.readouterr().out
    print(captured)
    assert rc == 0, captured
    t_capture = time.monotonic() - t_start

    # The file: one view per pose, reported pan/tilt where the head was sent, images and clouds stored.
    cs = load_correspondences(out)
    assert len(cs.views) == 8
    assert cs.resolve_camera_model() == system["model"].resolve()
    for v, pose in zip(cs.views, parse_poses(POSES), strict=True):
        assert v.pan == pytest.approx(pose.pan, abs=1e-3)
        assert v.tilt == pytest.approx(pose.tilt, abs=1e-3)
        assert v.zoom == pytest.approx(pose.zoom, abs=3)
        assert (v.image_width, v.image_height) == (704, 576)
        assert (out.parent / v.image).stat().st_size > 10_000
        cloud = np.load(cloud_path(out, v))
        assert cloud.shape[1] == 4
        assert len(cloud) > 10_000
    # Laser snapshot is in base_link: the ground (z = 0 there, 0.4 m below the scanner) is at z ≈ 0.
    ground = cloud[(cloud[:, 2] < 0.05) & (np.hypot(cloud[:, 0], cloud[:, 1]) < 6.0)]
    assert len(ground) > 1000
    assert abs(float(np.median(ground[:, 2]))) < 1e-3
    n_points = [len(v.points) for v in cs.views]
    assert n_points[0] == 8  # front + left board
    assert sum(n_points) >= 40
    # Picked 3-D points vs the scene's truth (the measured picking noise).
    truth = {f.label: f.point for f in scene_dot_features(Scene(WORLD))}
    pts = [c for v in cs.views for c in v.points]
    noise = picking_noise([c.point for c in pts], [truth[c.label] for c in pts])
    print(
        f"3-D picking noise: RMS {noise.rms * 100:.2f} cm, per axis {noise.rms_per_axis * 100:.2f} cm, "
        f"max {noise.max * 100:.2f} cm"
    )
    assert noise.max < 0.02

    # Solve through the CLI and check against the simulator's TRUE mount.
    mount_out = tmp_path / "mount.yaml"
    rc = cli_main(["solve", str(out), "--out", str(mount_out), "--sigma-px", "0.5", "--sigma-3d", "0.005"])
    solved = capsys.readouterr().out
    print(solved)
    assert rc == 0, solved
    mount = load_mount(mount_out)
    dt, dr = _errors(mount.transform)
    print(
        f"recovered mount vs truth: {dt * 100:.2f} cm, {dr:.3f} deg (nominal was {nominal_t * 100:.2f} cm, "
        f"{nominal_r:.3f} deg); capture {t_capture:.1f} s, total {time.monotonic() - t_start:.1f} s"
    )
    assert dt < 0.02
    assert dr < 0.25
    assert dt < 0.5 * nominal_t  # better than the nominal mount in translation too (which is < 1 cm off)
    assert mount.covariance is not None
    assert (mount.parent_frame, mount.child_frame) == ("base_link", "axis_ptz_base")
    # A PTZ node started with the written mount file publishes it (latched ptz/mount).
    ros.add(
        PtzNode(
            context=ros.context,
            namespace="calibrated",
            parameter_overrides=[
                Parameter("port", value=cam.port),
                Parameter("camera_model", value=str(system["model"])),
                Parameter("mount_file", value=str(mount_out)),
            ],
        )
    )
    got: list[TransformStamped] = []
    ros.probe("mount_probe").create_subscription(TransformStamped, "/calibrated/ptz/mount", got.append, LATCHED_QOS)
    ros.wait_for(lambda: got, 10.0)
    q, t = got[0].transform.rotation, got[0].transform.translation
    np.testing.assert_allclose([t.x, t.y, t.z], mount.transform.t, atol=1e-6)
    np.testing.assert_allclose(quaternion_to_matrix(q.x, q.y, q.z, q.w), mount.transform.R, atol=1e-6)


def test_capture_refuses_bad_data_instead_of_recording_it(ros, system):
    probe = ros.probe("calib_probe")
    robot = load_robot()
    # A wrong laser frame name: the cloud (laser_link) cannot be put into base_link -> refused, not guessed.
    session = CaptureSession(probe, T_base_laser=robot.laser.pose, laser_frame="velodyne", timeout_s=10.0)
    session.wait_ready()
    with pytest.raises(CaptureError, match="frame 'laser_link'"):
        session.capture("bad_frame")
    session.close()
    # A pose outside the head's limits: the PTZ node refuses, the capture says why.
    session = CaptureSession(probe, T_base_laser=robot.laser.pose, timeout_s=10.0)
    session.wait_ready()
    with pytest.raises(CaptureError, match="failed"):
        session.move(PoseCommand(math.radians(179.0), math.radians(-80.0), 1.0))
    # A good view at the current pose.
    session.move(PoseCommand(math.radians(10.0), math.radians(4.0), 1.0))
    view = session.capture("ok")
    assert view.pan == pytest.approx(math.radians(10.0), abs=1e-3)
    assert view.tilt == pytest.approx(math.radians(4.0), abs=1e-3)
    assert view.image().shape == (576, 704, 3)
    session.close()
