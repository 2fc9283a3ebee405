"""The URDF of the head on its mount: urdf/axis_214.urdf is the xacro expanded by ``xacro`` (in sync with the
configuration), and its forward kinematics (a small URDF reader in tests/support) equal to the project's single
kinematics function — for the committed URDF and for the xacro expanded by the real ``xacro`` program, with a
non-trivial mount, encoder offsets and a ceiling mount."""

from __future__ import annotations

import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from axis_ptz_ros2.config import MountConfig, load_camera_model, load_mount, save_mount
from axis_ptz_ros2.transforms import Transform
from tests.support.urdf_fk import forward_kinematics, parse_urdf, write_unusual_configuration

pytestmark = pytest.mark.unit

ROOT = Path(__file__).resolve().parents[2]
URDF = ROOT / "axis_ptz_ros2" / "urdf" / "axis_214.urdf"
XACRO = ROOT / "axis_ptz_ros2" / "urdf" / "axis_214.urdf.xacro"
POSES = [(0.0, 0.0), (0.7, 0.2), (-2.5, -0.45), (2.9, 1.5), (-0.3, 0.9), (1.2, -0.1)]
OPT = "axis_ptz_optical_frame"


def xacro_exe() -> str:
    exe = shutil.which("xacro", path=str(Path(sys.executable).parent))
    assert exe, "xacro is installed by scripts/bootstrap"
    return exe


def run_xacro(*args: str, cwd: Path) -> str:
    r = subprocess.run([xacro_exe(), *args], capture_output=True, text=True, cwd=cwd, timeout=60)
    assert r.returncode == 0, r.stderr
    return r.stdout


def close(a: Transform, b: Transform, tol: float = 1e-8) -> bool:
    return bool(np.allclose(a.matrix(), b.matrix(), atol=tol))


def reference(model_path: Path | None, mount_path: Path | None, pan: float, tilt: float) -> Transform:
    """The PTZ node's transform: mount · PtzKinematics.optical_in_ptz_base(joint pan, joint tilt)."""
    model = load_camera_model(model_path)
    mount = load_mount(mount_path)
    return mount.transform @ model.head.optical_in_ptz_base(pan, tilt)


def test_generated_urdf_is_up_to_date():
    r = subprocess.run([sys.executable, str(ROOT / "scripts" / "gen_urdf.py"), "--check"], capture_output=True)
    assert r.returncode == 0, r.stdout.decode()


def test_drift_check_fails_when_the_config_changes(tmp_path):
    mount = tmp_path / "mount.yaml"
    save_mount(MountConfig(transform=Transform.from_xyz_rpy(0.1, 0.0, 0.5, 0.0, 0.0, 0.3)), mount)
    r = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "gen_urdf.py"), "--check", "--mount", str(mount)], capture_output=True
    )
    assert r.returncode == 1
    assert b"out of date" in r.stdout


def test_names_match_the_ptz_node_and_the_joint_states():
    joints = parse_urdf(URDF.read_text())
    assert joints["axis_ptz_pan_joint"].kind == "revolute"
    assert joints["axis_ptz_tilt_joint"].kind == "revolute"
    assert joints["axis_ptz_mount_joint"].parent == "base_link"
    assert joints["axis_ptz_mount_joint"].child == "axis_ptz_base"
    assert joints["axis_ptz_pan_joint"].parent == "axis_ptz_base"
    assert joints["axis_ptz_optical_joint"].child == OPT


def test_generated_urdf_forward_kinematics_equals_the_kinematics_function():
    joints = parse_urdf(URDF.read_text())
    for pan, tilt in POSES:
        T = forward_kinematics(joints, "base_link", OPT, {"axis_ptz_pan_joint": pan, "axis_ptz_tilt_joint": tilt})
        assert close(T, reference(None, None, pan, tilt), 1e-7), (pan, tilt)


def test_limits_come_from_the_camera_model():
    model = load_camera_model()
    joints = parse_urdf(URDF.read_text())
    pmin, pmax, tmin, tmax = model.convention.limits_to_ros(
        model.limits.min_pan_deg, model.limits.max_pan_deg, model.limits.min_tilt_deg, model.limits.max_tilt_deg
    )
    pan, tilt = joints["axis_ptz_pan_joint"], joints["axis_ptz_tilt_joint"]
    assert (pan.lower, pan.upper) == pytest.approx((pmin, pmax), abs=1e-8)
    assert (tilt.lower, tilt.upper) == pytest.approx((tmin, tmax), abs=1e-8)
    assert pan.velocity == pytest.approx(math.radians(model.max_pan_speed_dps), abs=1e-8)
    assert tilt.velocity == pytest.approx(math.radians(model.max_tilt_speed_dps), abs=1e-8)


@pytest.fixture
def unusual(tmp_path: Path) -> tuple[Path, Path]:
    """A rolled/pitched/yawed mount with encoder offsets, and a ceiling-mounted ccw camera with an offset
    optical centre: every term of the chain is non-zero."""
    return write_unusual_configuration(tmp_path, (-120.0, 150.0, -80.0, 10.0))


def test_unusual_configuration_generated_and_xacro_agree_with_the_kinematics(unusual, tmp_path):
    model_path, mount_path = unusual
    model = load_camera_model(model_path)
    out = tmp_path / "generated.urdf"
    gen = [sys.executable, str(ROOT / "scripts" / "gen_urdf.py"), "--camera-model", str(model_path)]
    subprocess.run([*gen, "--mount", str(mount_path), "--out", str(out)], check=True, capture_output=True)
    generated = parse_urdf(out.read_text())
    expanded = parse_urdf(
        run_xacro(str(XACRO), f"camera_model:={model_path}", f"mount_file:={mount_path}", cwd=tmp_path)
    )
    for joints in (generated, expanded):
        for pan, tilt in POSES:
            pos = {"axis_ptz_pan_joint": pan, "axis_ptz_tilt_joint": tilt}
            T = forward_kinematics(joints, "base_link", OPT, pos)
            assert close(T, reference(model_path, mount_path, pan, tilt), 1e-7), (pan, tilt)
        # limits in joint coordinates: the head's limits through the ceiling/ccw convention, plus the offsets
        pmin, pmax, tmin, tmax = model.convention.limits_to_ros(-120.0, 150.0, -80.0, 10.0)
        assert joints["axis_ptz_pan_joint"].lower == pytest.approx(pmin + 0.02, abs=1e-7)
        assert joints["axis_ptz_pan_joint"].upper == pytest.approx(pmax + 0.02, abs=1e-7)
        assert joints["axis_ptz_tilt_joint"].lower == pytest.approx(tmin - 0.01, abs=1e-7)
        assert joints["axis_ptz_tilt_joint"].upper == pytest.approx(tmax - 0.01, abs=1e-7)


def test_xacro_defaults_read_the_repository_config_from_any_directory(tmp_path):
    joints = parse_urdf(run_xacro(str(XACRO), cwd=tmp_path))
    committed = parse_urdf(URDF.read_text())
    assert set(joints) == set(committed)
    for pan, tilt in POSES:
        pos = {"axis_ptz_pan_joint": pan, "axis_ptz_tilt_joint": tilt}
        a = forward_kinematics(joints, "base_link", OPT, pos)
        assert close(a, forward_kinematics(committed, "base_link", OPT, pos), 1e-7)


def test_xacro_macro_included_in_a_robot_with_a_prefix(tmp_path):
    robot = tmp_path / "robot.urdf.xacro"
    robot.write_text(
        '<?xml version="1.0"?>\n<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">\n'
        '  <xacro:arg name="standalone" default="false"/>\n'
        f'  <xacro:include filename="{XACRO}"/>\n'
        '  <link name="r1/base_link"/>\n'
        '  <xacro:axis_214_ptz parent="base_link" prefix="r1/"/>\n'
        "</robot>\n"
    )
    joints = parse_urdf(run_xacro(str(robot), cwd=tmp_path))
    assert "r1/axis_ptz_pan_joint" in joints
    assert joints["r1/axis_ptz_mount_joint"].parent == "r1/base_link"
    T = forward_kinematics(
        joints, "r1/base_link", "r1/" + OPT, {"r1/axis_ptz_pan_joint": 0.4, "r1/axis_ptz_tilt_joint": 0.3}
    )
    assert close(T, reference(None, None, 0.4, 0.3), 1e-7)


def test_urdf_reader_rejects_broken_input():
    with pytest.raises(ValueError, match="not a URDF"):
        parse_urdf("<notrobot/>")
    with pytest.raises(ValueError, match="parent"):
        parse_urdf('<robot><joint name="j" type="fixed"><child link="a"/></joint></robot>')
    joints = parse_urdf(URDF.read_text())
    with pytest.raises(ValueError, match="no joint chain"):
        forward_kinematics(joints, "base_link", "nowhere", {})


def test_the_committed_urdf_is_the_xacro_output_not_a_hand_written_copy():
    """One description (issue 24): the committed file says it is generated, and the package has no URDF writer."""
    text = URDF.read_text()
    assert "GENERATED by scripts/gen_urdf.py" in text
    assert "xacro" in text
    assert not (ROOT / "axis_ptz_ros2" / "axis_ptz_ros2" / "urdf.py").exists()
