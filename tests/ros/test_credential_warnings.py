"""Credentials in the wrong place are refused loudly, and never echoed (issue 25): ``-p password:=…`` was silently
ignored (and stays visible in the process list), and a password file readable by everyone was accepted without a
word. The real executable, against the simulated camera with Digest."""

from __future__ import annotations

import os
import shutil
import signal
from pathlib import Path

import pytest

from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.sim.scene import load_world
from tests.ros.processes import node_process
from tests.support.waiting import wait_until

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]
PASSWORD = "Cr3d-Never-Logged"


def _run(args: list[str], until: str, timeout: float = 60.0) -> str:
    out = b""
    with node_process(args) as proc:
        assert proc.stdout is not None
        os.set_blocking(proc.stdout.fileno(), False)
        stdout = proc.stdout

        def seen_or_ended() -> bool:
            nonlocal out
            out += stdout.read() or b""
            return until.encode() in out or proc.poll() is not None

        wait_until(seen_or_ended, timeout, 0.05, scaled=False, raises=False)
        proc.send_signal(signal.SIGINT)
        proc.wait(10)
        out += proc.stdout.read() or b""
    return out.decode(errors="replace")


@pytest.fixture(scope="module")
def cam():
    c = SimulatedCamera(load_world(), port=0, auth="digest", password=PASSWORD).start()
    try:
        yield c
    finally:
        c.stop()


def test_a_password_parameter_is_refused_loudly_and_not_echoed(cam: SimulatedCamera, tmp_path: Path) -> None:
    secret_file = tmp_path / "camera.secret"
    secret_file.write_text(f"root:{PASSWORD}\n", encoding="utf-8")
    secret_file.chmod(0o600)
    exe = shutil.which("axis_ptz")
    assert exe, "axis_ptz not installed (./scripts/bootstrap)"
    args = [
        exe,
        "--ros-args",
        "-p",
        f"port:={cam.port}",
        "-p",
        f"password:={PASSWORD}x",
        "-p",
        f"password_file:={secret_file}",
    ]
    log = _run(args, "PTZ node up")
    assert "parameter(s) password ignored" in log, log[-2000:]
    assert PASSWORD not in log
    assert "PTZ node up" in log  # the file's credentials worked; the node runs
    assert "can be read by others" not in log  # mode 600 is fine


def test_a_password_file_others_can_read_is_warned_about(cam: SimulatedCamera, tmp_path: Path) -> None:
    secret_file = tmp_path / "camera.secret"
    secret_file.write_text(f"root:{PASSWORD}\n", encoding="utf-8")
    secret_file.chmod(0o644)
    exe = shutil.which("axis_ptz")
    assert exe
    log = _run([exe, "--ros-args", "-p", f"port:={cam.port}", "-p", f"password_file:={secret_file}"], "PTZ node up")
    assert f"the credentials file {secret_file} can be read by others (mode 644)" in log, log[-2000:]
    assert PASSWORD not in log
    assert "PTZ node up" in log
