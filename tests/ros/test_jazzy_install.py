"""A ROS 2 Jazzy user's install, the standard way: rosdep, plain ``colcon build``, the overlay alone.

The workspace holds a fresh clone of this repository in ``src/`` (the working tree's tracked files copied over it, so
uncommitted edits are what is tested). Then, as on a Jazzy robot (``README.md``, "On a Jazzy robot"):

1. the real ``rosdep`` (from PyPI) crawls ``src/`` and resolves every key of every package it finds for
   ``ubuntu:noble`` / ``jazzy``, offline, against a snapshot of ros/rosdistro (``tests/data/rosdistro``: its
   ``rosdep/base.yaml``, ``rosdep/python.yaml`` and ``jazzy/distribution.yaml``) plus the project's own rosdep
   source (``axis_ptz_ros2/rosdep.yaml``, the one line the README tells the user to add);
2. plain ``colcon build`` (no ``--base-paths``, no ``--paths``) finds and builds exactly ``axis_ptz_ros2`` and
   ``axis_ptz_interfaces`` (never the stand-in message packages under ``interfaces/``, which would shadow Jazzy's);
3. from the overlay alone (its ``setup.bash`` on top of the ROS prefix; no bootstrap paths, the module imported from
   ``install/``) the executables, launch files, parameter files and URDF are where ``ros2 run``, ``ros2 launch`` and
   ``FindPackageShare`` look (ament index, ``lib/<pkg>``, ``share/<pkg>``), and the simulated camera and the camera
   driver started from it deliver images over DDS.

Here the "ROS prefix" is the bootstrap's venv (ROS 2 Jazzy from PyPI wheels): what differs from a real robot is only
where rclpy comes from. ``ros2``/``launch`` are not installable here; the launch files are checked by
``tests/ros/test_launch_files.py``.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from sensor_msgs.msg import CompressedImage

from axis_ptz_ros2.nodes.common import STREAM_QOS
from tests.ros.processes import node_process
from tests.support.harness import RosHarness

pytestmark = [pytest.mark.ros, pytest.mark.timeout(1500)]

ROOT = Path(__file__).resolve().parents[2]
VENV = Path(sys.prefix)
ROSDISTRO = ROOT / "tests" / "data" / "rosdistro"
PACKAGES = {"axis_ptz_ros2", "axis_ptz_interfaces"}


def fresh_clone(dest: Path) -> Path:
    """``git clone`` of this repository with the working tree's tracked files (edits included) copied over it."""
    subprocess.run(["git", "clone", "-q", str(ROOT), str(dest)], check=True)
    files = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-z"], check=True, capture_output=True).stdout
    for rel in filter(None, files.decode().split("\0")):
        src, dst = ROOT / rel, dest / rel
        if not src.exists() and not src.is_symlink():  # deleted in the working tree
            if dst.exists() or dst.is_symlink():
                dst.unlink()
            continue
        dst.parent.mkdir(parents=True, exist_ok=True)
        if dst.is_symlink() or dst.exists():
            dst.unlink()
        if src.is_symlink():
            dst.symlink_to(os.readlink(src))
        else:
            shutil.copy2(src, dst)
    return dest


@pytest.fixture(scope="module")
def workspace(tmp_path_factory: pytest.TempPathFactory) -> Path:
    ws = tmp_path_factory.mktemp("jazzy_ws")
    fresh_clone(ws / "src" / "axis_ptz_ros2")
    return ws


def rosdep_env(ws: Path, *, with_project_source: bool) -> dict[str, str]:
    """rosdep offline: the rosdistro snapshot as index and sources, a private ROS_HOME, ``rosdep update`` run."""
    home = ws.parent / ("rosdep_home_ours" if with_project_source else "rosdep_home_plain")
    sources = home / "sources.list.d"
    sources.mkdir(parents=True, exist_ok=True)
    lines = [f"yaml file://{ROSDISTRO}/rosdep/base.yaml", f"yaml file://{ROSDISTRO}/rosdep/python.yaml"]
    if with_project_source:  # the one line the README tells a Jazzy user to add
        lines.append(f"yaml file://{ws}/src/axis_ptz_ros2/axis_ptz_ros2/rosdep.yaml")
    (sources / "20-default.list").write_text("\n".join(lines) + "\n")
    env = dict(os.environ)
    env.update(
        ROSDISTRO_INDEX_URL=f"file://{ROSDISTRO}/index-v4.yaml",
        ROSDEP_SOURCE_PATH=str(sources),
        ROS_HOME=str(home),
        ROS_DISTRO="jazzy",
        PATH=f"{VENV / 'bin'}:{env.get('PATH', '')}",
    )
    r = subprocess.run(
        ["rosdep", "update", "--rosdistro", "jazzy"], env=env, capture_output=True, text=True, timeout=300
    )
    assert r.returncode == 0, r.stdout + r.stderr
    return env


def rosdep(env: dict[str, str], ws: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["rosdep", *args], cwd=ws, env=env, capture_output=True, text=True, timeout=300)


def test_rosdep_finds_both_packages_and_resolves_every_key_on_noble(workspace: Path) -> None:
    from catkin_pkg.packages import find_packages  # noqa: PLC0415 - rosdep's own crawler

    found = {p.name for p in find_packages(str(workspace / "src")).values()}
    assert found == PACKAGES, f"rosdep's crawl finds {sorted(found)}"
    env = rosdep_env(workspace, with_project_source=True)
    keys = rosdep(env, workspace, "keys", "--from-paths", "src", "--ignore-src", "--rosdistro", "jazzy")
    assert keys.returncode == 0, keys.stderr
    names = set(keys.stdout.split())
    assert {"rclpy", "sensor_msgs", "python3-opencv", "python3-httpx", "python3-av-pip", "tf2_msgs"} <= names
    assert not names & PACKAGES, "--ignore-src: our own packages are not keys"
    unresolved = {}
    for key in sorted(names):
        r = rosdep(env, workspace, "resolve", key, "--os=ubuntu:noble", "--rosdistro", "jazzy")
        if r.returncode != 0:
            unresolved[key] = (r.stdout + r.stderr).strip()[-300:]
    assert not unresolved, f"{len(unresolved)} keys do not resolve on ubuntu:noble: {unresolved}"
    # what `rosdep install` would do on noble (simulated: nothing is installed), with exit 0
    sim = rosdep(
        env, workspace, "install", "-s", "-y", "--from-paths", "src", "--ignore-src", "--os=ubuntu:noble",
        "--rosdistro", "jazzy",
    )  # fmt: skip
    assert sim.returncode == 0, sim.stdout + sim.stderr
    assert "apt-get install -y ros-jazzy-rclpy" in sim.stdout, sim.stdout  # (PyAV's pip line: only if missing here)


def test_without_the_project_source_only_pyav_is_missing(workspace: Path) -> None:
    """Why the README's one line is needed: ROS's database has no PyAV key (and nothing else is missing)."""
    env = rosdep_env(workspace, with_project_source=False)
    keys = rosdep(env, workspace, "keys", "--from-paths", "src", "--ignore-src", "--rosdistro", "jazzy")
    missing = {
        k
        for k in keys.stdout.split()
        if rosdep(env, workspace, "resolve", k, "--os=ubuntu:noble", "--rosdistro", "jazzy").returncode != 0
    }
    assert missing == {"python3-av-pip"}


@pytest.fixture(scope="module")
def overlay(workspace: Path) -> Iterator[Path]:
    """Plain ``colcon build`` in the workspace (the ROS prefix: the bootstrap's venv); yields ``install/``."""
    colcon = shutil.which("colcon", path=str(VENV / "bin"))
    assert colcon, "colcon is installed by scripts/bootstrap"
    env = dict(os.environ)
    env.update(
        AMENT_PREFIX_PATH=str(VENV),
        CMAKE_PREFIX_PATH=str(VENV),
        PATH=f"{VENV / 'bin'}:{env.get('PATH', '')}",
    )
    listed = subprocess.run([colcon, "list", "--names-only"], cwd=workspace, env=env, capture_output=True, text=True)
    assert listed.returncode == 0, listed.stderr
    assert set(listed.stdout.split()) == PACKAGES, f"plain colcon finds {listed.stdout.split()}"
    cmd = [colcon, "build", "--cmake-args", f"-DPython3_EXECUTABLE={sys.executable}", "-DBUILD_TESTING=OFF"]
    r = subprocess.run(cmd, cwd=workspace, env=env, capture_output=True, text=True, timeout=1200)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "Finished <<< axis_ptz_interfaces" in r.stdout, r.stdout
    assert "Finished <<< axis_ptz_ros2" in r.stdout, r.stdout
    assert sorted(p.name for p in (workspace / "install").iterdir() if p.is_dir()) == sorted(PACKAGES)
    return workspace / "install"


def overlay_env(install: Path) -> dict[str, str]:
    """The environment ``source install/setup.bash`` gives, on top of the ROS prefix only (no repository paths)."""
    base = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "AMENT_PREFIX_PATH", "COLCON_PREFIX_PATH")}
    base.update(AMENT_PREFIX_PATH=str(VENV), PATH=f"{VENV / 'bin'}:{base.get('PATH', '')}")
    r = subprocess.run(
        ["bash", "-c", f"source {install}/setup.bash && env -0"],
        env=base, capture_output=True, check=True, timeout=60, cwd=install.parent,
    )  # fmt: skip
    env = dict(line.split("=", 1) for line in r.stdout.decode().split("\0") if "=" in line)
    assert str(ROOT) not in env.get("PYTHONPATH", ""), env.get("PYTHONPATH")
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    return env


CHECK = r"""
import json, pathlib
from ament_index_python.packages import get_package_prefix, get_package_share_directory
import axis_ptz_ros2, axis_ptz_interfaces.msg
share = pathlib.Path(get_package_share_directory("axis_ptz_ros2"))
print(json.dumps({
    "module": axis_ptz_ros2.__file__,
    "interfaces": axis_ptz_interfaces.msg.__file__,
    "prefix": get_package_prefix("axis_ptz_ros2"),
    "share": str(share),
    "files": sorted(p.relative_to(share).as_posix() for p in share.rglob("*") if p.is_file()),
}))
"""


def test_the_overlay_alone_has_everything_ros2_run_and_launch_look_for(overlay: Path) -> None:
    import json  # noqa: PLC0415
    import tomllib  # noqa: PLC0415

    env = overlay_env(overlay)
    r = subprocess.run([sys.executable, "-c", CHECK], env=env, capture_output=True, text=True, cwd=overlay.parent)
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout)
    assert got["module"].startswith(str(overlay / "axis_ptz_ros2")), got["module"]  # not the repository's copy
    assert got["interfaces"].startswith(str(overlay / "axis_ptz_interfaces")), got["interfaces"]
    assert got["prefix"] == str(overlay / "axis_ptz_ros2")
    files = set(got["files"])
    want = {f"config/{p.name}" for p in (ROOT / "config").glob("*.yaml")}
    want |= {f"launch/{p.name}" for p in (ROOT / "axis_ptz_ros2" / "launch").glob("*.launch.py")}
    want |= {f"urdf/{p.name}" for p in (ROOT / "axis_ptz_ros2" / "urdf").iterdir()}
    want |= {"package.xml", "config/fastdds_weak_link.xml"}
    assert {"launch/camera.launch.py", "config/axis_camera.params.yaml", "urdf/axis_214.urdf.xacro"} <= want
    assert want <= files, sorted(want - files)
    # the URDF's xacro finds the camera model and mount beside it in share/ (../config), as on a robot
    xacro = (Path(got["share"]) / "urdf" / "axis_214.urdf.xacro").read_text()
    assert "../config/axis214.yaml" in xacro
    assert (Path(got["share"]) / "config" / "axis214.yaml").exists()
    # `ros2 run axis_ptz_ros2 <exe>` looks in lib/axis_ptz_ros2: every console script is there
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    lib = overlay / "axis_ptz_ros2" / "lib" / "axis_ptz_ros2"
    assert {p.name for p in lib.iterdir()} >= set(scripts)
    run = subprocess.run([str(lib / "axis_calibrate"), "--help"], env=env, capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert "solve" in run.stdout


def test_nodes_started_from_the_overlay_deliver_images(overlay: Path, ros: RosHarness) -> None:
    """``ros2 run axis_ptz_ros2 axis_camera_sim`` and ``ros2 run axis_ptz_ros2 axis_stream --ros-args
    --params-file <share>/config/axis_camera.params.yaml`` (what the launch file passes), from the overlay: images
    arrive over DDS at a subscriber in this process."""
    env = overlay_env(overlay)  # this session's ROS_DOMAIN_ID included
    lib = overlay / "axis_ptz_ros2" / "lib" / "axis_ptz_ros2"
    params = overlay / "axis_ptz_ros2" / "share" / "axis_ptz_ros2" / "config" / "axis_camera.params.yaml"
    with node_process([str(lib / "axis_camera_sim"), "--port", "0"], env=env, cwd=overlay.parent) as sim:
        assert sim.stdout is not None
        line = sim.stdout.readline().decode()  # "Simulated AXIS 214 PTZ at http://127.0.0.1:PORT/ ..."
        m = re.search(r"http://127\.0\.0\.1:(\d+)/", line)
        assert m, line
        argv = [str(lib / "axis_stream"), "--ros-args", "--params-file", str(params), "-p", f"port:={m.group(1)}"]
        with node_process(argv, env=env, cwd=overlay.parent) as stream:
            probe = ros.probe()
            got: list[int] = []
            probe.create_subscription(
                CompressedImage, "/image_raw/compressed", lambda msg: got.append(len(msg.data)), STREAM_QOS
            )
            ros.wait_for(lambda: len(got) >= 5 or stream.poll() is not None, timeout=90.0, period=0.05)
            assert stream.poll() is None, f"axis_stream from the overlay exited with {stream.returncode}"
            assert len(got) >= 5, got
            assert min(got) > 1000, got
