"""scripts/demo end to end: the whole simulated suite comes up, the printed URL serves live MJPEG within a
minute, and everything stops cleanly (after --duration, and on SIGTERM) leaving nothing behind."""

from __future__ import annotations

import http.client
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from scripts.demo import count_mjpeg_frames
from tests.support.waiting import wait_until

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[2]
URL_LINE = re.compile(r"Axis PTZ console: (http://127\.0\.0\.1:(\d+))")


class Output:
    """Collects a process's output in a thread (so pipes never fill) and finds the console URL."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self.text = ""
        self._lock = threading.Lock()
        self._t = threading.Thread(target=self._read, args=(proc,), daemon=True)
        self._t.start()

    def _read(self, proc: subprocess.Popen[str]) -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            with self._lock:
                self.text += line

    def url(self, timeout: float) -> str:

        def found() -> re.Match[str] | None:
            with self._lock:
                return URL_LINE.search(self.text)

        if m := wait_until(found, timeout, 0.1, scaled=False, raises=False):
            return m.group(1)
        raise AssertionError(f"no console URL within {timeout:g} s; output:\n{self.text[-3000:]}")

    def join(self) -> str:
        self._t.join(10)
        return self.text


def env() -> dict[str, str]:
    e = dict(os.environ)
    e["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    return e


def log_dir(text: str) -> Path:
    m = re.search(r"logs in (\S+);", text)
    assert m, text
    return Path(m.group(1))


def stop(proc: subprocess.Popen[str]) -> None:
    """After a failed check: SIGTERM first, so the demo stops its children (each in its own session, so a
    SIGKILL of the demo alone would leave them running, and on this DDS domain for the tests after)."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def refused(url: str) -> bool:
    host, port = url.removeprefix("http://").split(":")
    conn = http.client.HTTPConnection(host, int(port), timeout=2)
    try:
        conn.request("GET", "/api/state")
        conn.getresponse().read()
        return False
    except OSError:
        return True
    finally:
        conn.close()


def test_scripts_demo_serves_live_video_and_stops_after_duration(tmp_path: Path) -> None:
    t0 = time.monotonic()
    proc = subprocess.Popen(
        [str(ROOT / "scripts" / "demo"), "--port", "0", "--duration", "40", "--log-dir", str(tmp_path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env(),
        cwd=ROOT,
    )
    out = Output(proc)
    try:
        url = out.url(60.0)
        assert time.monotonic() - t0 < 60.0
        # deadlines, not speed bounds (the demo's 40 s start when it serves live PTZ video; the panorama is
        # rendered after that and has taken 24 s on a loaded machine)
        assert count_mjpeg_frames(url, "/video/ptz.mjpg", 3, 20.0) == 3
        assert count_mjpeg_frames(url, "/video/panorama.mjpg", 1, 35.0) == 1
        code = proc.wait(90.0)
    finally:
        stop(proc)
    text = out.join()
    assert code == 0, text[-3000:]
    assert "all processes stopped cleanly" in text
    assert refused(url), "the console still answers after the demo ended"
    logs = sorted(p.name for p in tmp_path.glob("*.log"))
    assert "axis_web_console.log" in logs
    assert "axis_camera_sim.log" in logs


def test_demo_stops_everything_on_sigterm(tmp_path: Path) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "scripts.demo", "--port", "0", "--log-dir", str(tmp_path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env(),
        cwd=ROOT,
    )
    out = Output(proc)
    try:
        url = out.url(60.0)
        assert count_mjpeg_frames(url, "/video/ptz.mjpg", 2, 20.0) == 2
        sim_port = int(re.search(r"simulator at http://127\.0\.0\.1:(\d+)", out.text).group(1))  # type: ignore[union-attr]
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(30.0)
        stop_s = time.monotonic() - t0
    finally:
        stop(proc)
    text = out.join()
    assert code == 0, text[-3000:]
    assert "all processes stopped cleanly" in text
    assert stop_s < 15.0
    assert refused(url)
    assert refused(f"http://127.0.0.1:{sim_port}")
    assert log_dir(text) == tmp_path
