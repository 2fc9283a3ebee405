"""The kinematic chain the PTZ node publishes (``geometry.PtzKinematics`` after the mount) equals the forward
kinematics of the xacro-generated URDF computed by an independent library (yourdfpy, not our reader), at
several joint states, within 1e-6 m and 1e-6 rad — for the shipped configuration and for one where every term
of the chain is non-zero (tilted mount, encoder offsets, ceiling/ccw convention, off-axis optical centre)."""

from __future__ import annotations

import io
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from axis_ptz_ros2.config import load_camera_model, load_mount
from axis_ptz_ros2.transforms import Transform
from tests.support.urdf_fk import write_unusual_configuration

yourdfpy = pytest.importorskip("yourdfpy", reason="scripts/bootstrap installs yourdfpy")

pytestmark = pytest.mark.unit

ROOT = Path(__file__).resolve().parents[2]
# joint states (REP-103 rad): zero, both signs, near the limits, and odd values
JOINT_STATES = [(0.0, 0.0), (0.7, 0.2), (-2.5, -0.45), (2.9, 1.5), (-0.3, 0.9), (1.234567, -0.1), (3.0, -0.5)]
POS_TOL_M = 1e-6
ROT_TOL_RAD = 1e-6


def expand(tmp: Path, camera_model: Path | None = None, mount: Path | None = None) -> str:
    """scripts/gen_urdf.py's URDF (the xacro expanded by xacro) for these files (None: the shipped ones)."""
    out = tmp / "head.urdf"
    args = [sys.executable, str(ROOT / "scripts" / "gen_urdf.py"), "--out", str(out)]
    args += ["--camera-model", str(camera_model)] if camera_model else []
    args += ["--mount", str(mount)] if mount else []
    subprocess.run(args, check=True, capture_output=True, timeout=120)
    return out.read_text(encoding="utf-8")


def load(urdf_text: str) -> yourdfpy.URDF:
    return yourdfpy.URDF.load(io.StringIO(urdf_text), load_meshes=False, build_collision_scene_graph=False)


def assert_same(a: np.ndarray, b: Transform, what: str) -> None:
    """Translation within POS_TOL_M, rotation (angle of the relative rotation) within ROT_TOL_RAD."""
    dt = float(np.linalg.norm(a[:3, 3] - b.t))
    angle = float(Rotation.from_matrix(a[:3, :3].T @ b.R).magnitude())
    assert dt <= POS_TOL_M, f"{what}: |dt| {dt:.3g} m"
    assert angle <= ROT_TOL_RAD, f"{what}: rotation {angle:.3g} rad"


def check(robot: yourdfpy.URDF, model_path: Path | None, mount_path: Path | None) -> int:
    model, mount = load_camera_model(model_path), load_mount(mount_path)
    head = model.head
    checked = 0
    for pan, tilt in JOINT_STATES:
        robot.update_cfg({"axis_ptz_pan_joint": pan, "axis_ptz_tilt_joint": tilt})
        where = f"pan {pan}, tilt {tilt}"
        # /tf_static: the mount
        assert_same(robot.get_transform("axis_ptz_base", "base_link"), mount.transform, f"mount, {where}")
        # the head: body frame (x along the optical axis) and optical frame in ptz_base, and from base_link
        assert_same(
            robot.get_transform("axis_ptz_camera_link", "axis_ptz_base"),
            head.head_to_ptz_base(pan, tilt),
            f"camera_link, {where}",
        )
        assert_same(
            robot.get_transform("axis_ptz_optical_frame", "axis_ptz_base"),
            head.optical_in_ptz_base(pan, tilt),
            f"optical in ptz_base, {where}",
        )
        assert_same(
            robot.get_transform("axis_ptz_optical_frame", "base_link"),
            mount.transform @ head.optical_in_ptz_base(pan, tilt),
            f"optical in base_link, {where}",
        )
        checked += 4
    return checked


def test_the_library_reads_transforms_as_we_think():
    """yourdfpy's get_transform(to, from) is the pose of ``to`` in ``from``: a known one-joint robot."""
    robot = load(
        '<robot name="t"><link name="a"/><link name="b"/>'
        '<joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
        '<origin xyz="1 2 3" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="1" effort="1"/>'
        "</joint></robot>"
    )
    robot.update_cfg({"j": 0.5})
    T = robot.get_transform("b", "a")
    assert np.allclose(T[:3, 3], [1.0, 2.0, 3.0])
    assert np.allclose(T[:3, :3], Rotation.from_euler("z", 0.5).as_matrix())


def test_shipped_configuration_chain_equals_the_urdf_by_an_independent_library(tmp_path):
    text = expand(tmp_path)
    assert text == (ROOT / "axis_ptz_ros2" / "urdf" / "axis_214.urdf").read_text(encoding="utf-8")  # the committed one
    robot = load(text)
    assert set(robot.actuated_joint_names) == {"axis_ptz_pan_joint", "axis_ptz_tilt_joint"}
    assert check(robot, None, None) == 4 * len(JOINT_STATES)


def test_unusual_configuration_chain_equals_the_urdf_by_an_independent_library(tmp_path):
    model, mount = write_unusual_configuration(tmp_path, (-175.0, 175.0, -90.0, 90.0))
    robot = load(expand(tmp_path, model, mount))
    check(robot, model, mount)


def test_the_check_notices_a_wrong_chain(tmp_path):
    """A 1 mm error in the head geometry is caught (so the tolerance is meaningful)."""
    raw = yaml.safe_load((ROOT / "config" / "axis214.yaml").read_text())
    raw["head"] = {"h_tilt": raw["head"]["h_tilt"] + 0.001, "d_opt": raw["head"].get("d_opt", [0.03, 0.0, 0.0])}
    model = tmp_path / "model.yaml"
    model.write_text(yaml.safe_dump(raw))
    robot = load(expand(tmp_path, model))  # the URDF of a head 1 mm taller ...
    with pytest.raises(AssertionError, match="camera_link"):
        check(robot, None, None)  # ... against the shipped kinematics
