"""A real-Jazzy user's path: `colcon build` both packages from a clone, then run an installed executable.

colcon comes from PyPI here (the bootstrap installs it); the ROS prefix is the venv. This is the check that
package.xml, setup.py/setup.cfg, resource/ and the rosidl CMake package work for `colcon build` + `ros2 run`.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

# hang guard above the build's own 600 s subprocess timeout (the build alone took > 300 s on a loaded 2-core machine)
pytestmark = [pytest.mark.integration, pytest.mark.timeout(900)]

ROOT = Path(__file__).resolve().parents[2]
VENV = Path(sys.prefix)


@pytest.mark.timeout(1200)  # a deadline: a CMake build on a loaded 2-core machine has taken over 300 s
def test_colcon_builds_both_packages_and_installs_runnable_executables(tmp_path):
    colcon = shutil.which("colcon", path=str(VENV / "bin"))
    assert colcon, "colcon is installed by scripts/bootstrap"
    src = tmp_path / "src" / "axis_ptz_ros2"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(src)], check=True)
    # the working tree's current files (uncommitted edits included) are what we test
    for rel in ("package.xml", "setup.py", "setup.cfg", "pyproject.toml"):
        shutil.copy(ROOT / rel, src / rel)
    for folder in ("config", "launch", "urdf"):
        shutil.rmtree(src / folder, ignore_errors=True)
        shutil.copytree(ROOT / folder, src / folder)
    env = dict(os.environ)
    env.update(
        AMENT_PREFIX_PATH=str(VENV),
        CMAKE_PREFIX_PATH=str(VENV),
        PATH=f"{VENV / 'bin'}:{env.get('PATH', '')}",
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
    )
    cmd = [
        colcon,
        "build",
        "--base-paths",
        "src/axis_ptz_ros2",
        "src/axis_ptz_ros2/axis_ptz_interfaces",
        "--cmake-args",
        f"-DPython3_EXECUTABLE={sys.executable}",
        "-DBUILD_TESTING=OFF",
    ]
    r = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "Finished <<< axis_ptz_interfaces" in r.stdout
    assert "Finished <<< axis_ptz_ros2" in r.stdout
    inst = tmp_path / "install"
    share = inst / "axis_ptz_ros2" / "share"
    # what `ros2 run axis_ptz_ros2 <exe>` and ament_index need
    assert (share / "ament_index" / "resource_index" / "packages" / "axis_ptz_ros2").exists()
    assert (share / "axis_ptz_ros2" / "package.xml").exists()
    for name in ("axis214.yaml", "mount.yaml", "robot.yaml", "sim_world.yaml"):
        assert (share / "axis_ptz_ros2" / "config" / name).exists(), name
    # launch files, parameter files and the URDF where `ros2 launch` and FindPackageShare look for them
    installed = {p.relative_to(share / "axis_ptz_ros2").as_posix() for p in (share / "axis_ptz_ros2").rglob("*")}
    expected = {f"config/{p.name}" for p in (ROOT / "config").glob("*.yaml")}
    expected |= {f"launch/{p.name}" for p in (ROOT / "axis_ptz_ros2" / "launch").glob("*.launch.py")}
    expected |= {
        f"urdf/{p.name}" for p in (ROOT / "axis_ptz_ros2" / "urdf").iterdir() if p.suffix in (".urdf", ".xacro")
    }
    assert {"launch/camera.launch.py", "config/axis_camera.params.yaml", "urdf/axis_214.urdf.xacro"} <= expected
    assert expected <= installed, sorted(expected - installed)
    libexec = inst / "axis_ptz_ros2" / "lib" / "axis_ptz_ros2"
    exes = {p.name for p in libexec.iterdir()}
    for exe in (
        "axis_camera",
        "axis_stream",
        "axis_ptz",
        "axis_keyboard_teleop",
        "axis_web_console",
        "axis_visualizer",
        "axis_republish",
        "axis_virtual_camera",
        "axis_calibrate",
        "axis_camera_sim",
        "axis_joy_teleop",
    ):
        assert exe in exes, exe
    # the interface package's generated Python module is installed too
    msgs = list((inst / "axis_ptz_interfaces").rglob("axis_ptz_interfaces/msg/_ptz_state.py"))
    assert msgs, "generated axis_ptz_interfaces Python module missing from the colcon install"
    # an installed executable runs (outside the repo, so it must find its installed files)
    run = subprocess.run(
        [str(libexec / "axis_calibrate"), "--help"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60
    )
    assert run.returncode == 0, run.stderr
    assert "solve" in run.stdout
