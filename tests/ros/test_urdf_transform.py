"""robot_state_publisher's view equals the PTZ node's: forward kinematics of the URDF (the xacro expanded by the
real ``xacro`` program), fed with the ``joint_states`` the running PTZ node publishes,
gives the ``ptz/transform`` it publishes with the same stamp — for several poses of the simulated camera, with a
tilted mount, encoder offsets and an off-axis optical centre."""

from __future__ import annotations

import math
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from geometry_msgs.msg import TransformStamped
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from axis_ptz_interfaces.msg import PtzCommand
from axis_ptz_interfaces.srv import MovePtz
from axis_ptz_ros2.config import MountConfig, save_mount
from axis_ptz_ros2.nodes.common import STREAM_QOS, transform_from_msg
from axis_ptz_ros2.nodes.ptz_node import PtzNode
from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.sim.world import load_world
from axis_ptz_ros2.transforms import Transform
from tests.support.urdf_fk import forward_kinematics, parse_urdf

pytestmark = [pytest.mark.ros, pytest.mark.timeout(180)]

ROOT = Path(__file__).resolve().parents[2]
POSES_DEG = [(0.0, 0.0), (35.0, 10.0), (-120.0, -20.0), (150.0, 60.0)]


def test_urdf_forward_kinematics_equals_ptz_transform_over_dds(ros, tmp_path):
    mount_path = tmp_path / "mount.yaml"
    save_mount(
        MountConfig(
            transform=Transform.from_xyz_rpy(-0.2, 0.05, 0.48, 0.03, -0.06, 0.4), pan_offset=0.015, tilt_offset=-0.02
        ),
        mount_path,
    )
    raw = yaml.safe_load((ROOT / "config" / "axis214.yaml").read_text())
    raw["head"] = {"h_tilt": 0.0687, "d_opt": [0.03, 0.005, -0.004]}
    model_path = tmp_path / "model.yaml"
    model_path.write_text(yaml.safe_dump(raw))

    xacro = shutil.which("xacro", path=str(Path(sys.executable).parent))
    assert xacro, "xacro is installed by scripts/bootstrap"
    expanded = subprocess.run(
        [
            xacro,
            str(ROOT / "axis_ptz_ros2" / "urdf" / "axis_214.urdf.xacro"),
            f"mount_file:={mount_path}",
            f"camera_model:={model_path}",
        ],
        capture_output=True,
        text=True,
        check=True,
        cwd=tmp_path,
    ).stdout
    urdfs = {"xacro": parse_urdf(expanded)}

    cam = SimulatedCamera(load_world(), port=0).start()
    try:
        ptz = ros.add(
            PtzNode(
                context=ros.context,
                parameter_overrides=[
                    Parameter("port", value=cam.port),
                    Parameter("mount_file", value=str(mount_path)),
                    Parameter("camera_model", value=str(model_path)),
                ],
            )
        )
        probe = ros.probe("urdf_probe")
        joints: dict[tuple[int, int], JointState] = {}
        transforms: dict[tuple[int, int], TransformStamped] = {}

        def key(stamp: Any) -> tuple[int, int]:
            return int(stamp.sec), int(stamp.nanosec)

        probe.create_subscription(
            JointState, "joint_states", lambda m: joints.__setitem__(key(m.header.stamp), m), STREAM_QOS
        )
        probe.create_subscription(
            TransformStamped, "ptz/transform", lambda m: transforms.__setitem__(key(m.header.stamp), m), STREAM_QOS
        )
        move = probe.create_client(MovePtz, "ptz/move_absolute")
        ros.wait_for(lambda: ptz.poller.latest is not None, 15.0)
        for pan_deg, tilt_deg in POSES_DEG:
            cmd = PtzCommand(pan=math.radians(pan_deg), tilt=math.radians(tilt_deg), zoom=math.nan, speed=math.nan)
            r = ros.call(move, MovePtz.Request(command=cmd, wait=True), timeout=30.0)
            assert r.success, r.message
            joints.clear()
            transforms.clear()
            # a joint state and a transform with the same stamp (the same camera reading)
            common = ros.wait_for(lambda: sorted(set(joints) & set(transforms)), 10.0)
            js, tf = joints[common[-1]], transforms[common[-1]]
            assert list(js.name) == ["axis_ptz_pan_joint", "axis_ptz_tilt_joint"]
            assert tf.header.frame_id == "base_link"
            assert tf.child_frame_id == "axis_ptz_optical_frame"
            assert js.position[0] == pytest.approx(math.radians(pan_deg), abs=0.003)
            published = transform_from_msg(tf)
            for label, urdf in urdfs.items():
                T = forward_kinematics(
                    urdf, "base_link", "axis_ptz_optical_frame", dict(zip(js.name, js.position, strict=True))
                )
                assert np.allclose(T.matrix(), published.matrix(), atol=1e-6), (label, pan_deg, tilt_deg)
    finally:
        cam.stop()
