"""The whole suite on the simulated camera, for a first look and for end-to-end tests.

Starts, as child processes on this machine only (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, servers on
127.0.0.1): the simulated camera (``axis_camera_sim --model <model>`` on a free port: the Axis 214 by default,
``--model q6075`` for a modern 1080p dome over HTTPS with Digest, its certificate as the driver's CA and a
random password handed over in a private file), the camera driver (``axis_camera``:
stream + PTZ in one process, or ``--split``: ``axis_stream`` + ``axis_ptz``), the simulated panorama camera
and laser, the visualizer and the web console. Prints the console URL once live video flows through it, runs
until Ctrl-C / SIGTERM (or ``--duration`` seconds), then stops everything: SIGINT to every child, a grace
period, then SIGKILL for whatever is left.

    ./scripts/demo                 # http://127.0.0.1:8090
    ./scripts/demo --port 0 --duration 30
    ./scripts/demo --model q6075   # the modern camera: the same driver, nothing configured for it
"""

from __future__ import annotations

import argparse
import contextlib
import http.client
import importlib.util
import os
import re
import secrets
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from axis_ptz_ros2.vapix.models import FPS_RANGE

#: executable → module holding its ``main`` (checked before starting, for a clear message).
EXECUTABLES = {
    "axis_camera_sim": "axis_ptz_ros2.sim.cli",
    "axis_camera": "axis_ptz_ros2.nodes.camera_main",
    "axis_stream": "axis_ptz_ros2.nodes.stream_node",
    "axis_ptz": "axis_ptz_ros2.nodes.ptz_node",
    "axis_panorama_sim": "axis_ptz_ros2.nodes.panorama_sim",
    "axis_laser_sim": "axis_ptz_ros2.nodes.laser_sim",
    "axis_visualizer": "axis_ptz_ros2.nodes.visualizer",
    "axis_web_console": "axis_ptz_ros2.nodes.web_console",
}
SIM_URL = re.compile(r"at (https?://127\.0\.0\.1:(\d+))/ \(auth=(\w+)(?:; CA certificate ([^;)]+))?[;)]")


class DemoError(RuntimeError):
    """The demo could not start (missing executable, a child died, no video in time)."""


def _log(msg: str) -> None:
    print(f"[demo] {msg}", file=sys.stderr, flush=True)  # noqa: T201 - a CLI


def find_executable(name: str) -> str:
    """Path of a console script of this project; :class:`DemoError` naming what is missing otherwise."""
    module = EXECUTABLES[name]
    try:
        spec = importlib.util.find_spec(module)
    except ModuleNotFoundError:
        spec = None
    if spec is None:
        raise DemoError(f"{name}: module {module} is not there (not implemented yet?)")
    here = Path(sys.executable).parent / name
    path = str(here) if here.exists() else shutil.which(name)
    if not path:
        raise DemoError(f"{name}: console script not found (run ./scripts/bootstrap to install it)")
    return path


def ros_args(params: dict[str, Any]) -> list[str]:
    """``--ros-args -p name:=value …``."""
    out = ["--ros-args"]
    for k, v in params.items():
        if isinstance(v, bool):
            v = "true" if v else "false"
        out += ["-p", f"{k}:={v}"]
    return out


@dataclass
class Child:
    """One child process with its log file."""

    name: str
    proc: subprocess.Popen[bytes]
    log_path: Path
    log_file: IO[bytes]

    def tail(self, lines: int = 15) -> str:
        """The last lines of its output."""
        try:
            text = self.log_path.read_text(encoding="utf-8", errors="replace")
        except OSError:
            return ""
        return "\n".join(text.splitlines()[-lines:])


@dataclass
class DemoConfig:
    """What to start (see the CLI flags)."""

    console_port: int = 8090
    fps: int = 10
    resolution: str = ""  # '' = the largest the camera lists
    model: str = "axis214"  # simulated camera persona (axis_camera_sim --model)
    split: bool = False
    panorama_width: int = 2048
    log_dir: Path | None = None
    stop_timeout: float = 8.0
    extra_env: dict[str, str] = field(default_factory=dict)


class Demo:
    """The running suite: :meth:`start`, :meth:`wait_ready`, :meth:`stop` (also a context manager)."""

    def __init__(self, config: DemoConfig | None = None) -> None:
        self.config = config or DemoConfig()
        self.children: list[Child] = []
        self.sim_url = ""
        self.console_url = ""
        self._own_dir = self.config.log_dir is None
        self.log_dir = self.config.log_dir or Path(tempfile.mkdtemp(prefix="axis_demo_"))
        self.log_dir.mkdir(parents=True, exist_ok=True)
        env = dict(os.environ)
        env.update(self.config.extra_env)
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"  # DDS stays on this machine
        env.pop("ROS_LOCALHOST_ONLY", None)
        env.pop("ROS_STATIC_PEERS", None)
        env["PYTHONUNBUFFERED"] = "1"
        self.env = env

    # -- processes ------------------------------------------------------------------------------------
    def _spawn(self, name: str, exe: str, args: list[str]) -> Child:
        log_path = self.log_dir / f"{name}.log"
        f = open(log_path, "wb")  # noqa: SIM115 - closed in stop()
        proc = subprocess.Popen(  # noqa: S603 - our own console scripts
            [exe, *args],
            stdout=f,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            env=self.env,
            start_new_session=True,  # the terminal's Ctrl-C goes to the demo, which stops children in order
        )
        child = Child(name, proc, log_path, f)
        self.children.append(child)
        return child

    def _check_alive(self) -> None:
        for c in self.children:
            code = c.proc.poll()
            if code is not None:
                raise DemoError(f"{c.name} exited with code {code}; its last output:\n{c.tail()}")

    def start(self) -> Demo:
        """Start every process (the simulator first, to learn its port); raises :class:`DemoError`."""
        cfg = self.config
        # resolve everything first: fail before starting anything when a piece is missing
        camera = ["axis_stream", "axis_ptz"] if cfg.split else ["axis_camera"]
        names = ["axis_camera_sim", *camera, "axis_panorama_sim", "axis_laser_sim", "axis_visualizer"]
        names.append("axis_web_console")
        missing, exes = [], {}
        for n in names:
            try:
                exes[n] = find_executable(n)
            except DemoError as err:
                missing.append(str(err))
        if missing and not cfg.split and any(m.startswith("axis_camera:") for m in missing):
            _log("axis_camera is not available; using axis_stream + axis_ptz instead")
            return self._restart_split()
        if missing:
            raise DemoError("cannot start the demo:\n  " + "\n  ".join(missing))

        password = secrets.token_urlsafe(12)
        self.env["AXIS_SIM_PASSWORD"] = password  # the simulator's; never on a command line
        sim = self._spawn("axis_camera_sim", exes["axis_camera_sim"], ["--port", "0", "--model", cfg.model])
        self.sim_url, auth, ca_file = self._wait_sim_url(sim, 30.0)
        port = int(self.sim_url.rsplit(":", 1)[1])
        video: dict[str, Any] = {"fps": cfg.fps}
        if cfg.resolution:
            video["resolution"] = cfg.resolution
        connection: dict[str, Any] = {"hostname": "127.0.0.1", "port": port}
        if self.sim_url.startswith("https://"):
            connection.update(use_https=True, verify_tls=True, ca_file=ca_file)
        if auth != "none":
            cred = self.log_dir / "camera.cred"
            cred.touch(mode=0o600)
            cred.write_text(f"root:{password}\n", encoding="utf-8")
            connection["password_file"] = str(cred)
        if cfg.split:
            self._spawn("axis_stream", exes["axis_stream"], ros_args({**connection, **video}))
            self._spawn("axis_ptz", exes["axis_ptz"], ros_args(connection))
        else:
            self._spawn("axis_camera", exes["axis_camera"], ros_args({**connection, **video}))
        self._spawn("axis_panorama_sim", exes["axis_panorama_sim"], ros_args({"width": cfg.panorama_width}))
        self._spawn("axis_laser_sim", exes["axis_laser_sim"], [])
        self._spawn("axis_visualizer", exes["axis_visualizer"], [])
        url_file = self.log_dir / "console_url"
        url_file.unlink(missing_ok=True)
        self._spawn(
            "axis_web_console",
            exes["axis_web_console"],
            ros_args({"port": cfg.console_port, "url_file": str(url_file)}),
        )
        self._url_file = url_file
        return self

    def _restart_split(self) -> Demo:
        self.config.split = True
        return self.start()

    def _wait_sim_url(self, sim: Child, timeout: float) -> tuple[str, str, str]:
        """(base URL, auth mode, CA certificate path or '') from the simulator's start-up line."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            m = SIM_URL.search(sim.log_path.read_text(encoding="utf-8", errors="replace"))
            if m:
                return m.group(1), m.group(3), m.group(4) or ""
            self._check_alive()
            time.sleep(0.05)
        raise DemoError(f"the simulator did not report its URL within {timeout:g} s:\n{sim.tail()}")

    # -- readiness ------------------------------------------------------------------------------------
    def wait_ready(self, timeout: float = 60.0, frames: int = 2) -> str:
        """Wait until the console serves live PTZ video (``frames`` MJPEG parts); return its URL."""
        deadline = time.monotonic() + timeout
        while not self.console_url:
            self._check_alive()
            if self._url_file.exists():
                self.console_url = self._url_file.read_text(encoding="utf-8").strip()
                break
            if time.monotonic() > deadline:
                raise DemoError("the web console did not start in time")
            time.sleep(0.1)
        last = ""
        while time.monotonic() < deadline:
            self._check_alive()
            try:
                n = count_mjpeg_frames(self.console_url, "/video/ptz.mjpg", frames, deadline - time.monotonic())
                if n >= frames:
                    return self.console_url
                last = f"only {n} frame(s)"
            except OSError as err:
                last = str(err)
            time.sleep(0.5)
        raise DemoError(f"no live video at {self.console_url} within {timeout:g} s ({last})")

    # -- stop -----------------------------------------------------------------------------------------
    def stop(self) -> dict[str, int | None]:
        """SIGINT every child (console first, simulator last), wait, SIGKILL the rest; exit codes by name."""
        for c in reversed(self.children):
            if c.proc.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(c.proc.pid, signal.SIGINT)
        deadline = time.monotonic() + self.config.stop_timeout
        codes: dict[str, int | None] = {}
        for c in reversed(self.children):
            try:
                codes[c.name] = c.proc.wait(max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                _log(f"{c.name} did not stop within {self.config.stop_timeout:g} s after SIGINT: killing it")
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(c.proc.pid, signal.SIGKILL)
                c.proc.wait(5.0)
                codes[c.name] = None
            c.log_file.close()
        self.children.clear()
        return codes

    def __enter__(self) -> Demo:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def count_mjpeg_frames(base_url: str, path: str, frames: int, timeout: float) -> int:
    """Read up to ``frames`` JPEG parts of an MJPEG stream on loopback; return how many arrived."""
    m = re.match(r"http://([^/:]+):(\d+)", base_url)
    if not m:
        raise OSError(f"not a console URL: {base_url!r}")
    conn = http.client.HTTPConnection(m.group(1), int(m.group(2)), timeout=max(0.5, timeout))
    try:
        conn.request("GET", path)
        resp = conn.getresponse()
        if resp.status != 200:
            return 0
        n = 0
        deadline = time.monotonic() + timeout
        while n < frames and time.monotonic() < deadline:
            line = resp.fp.readline()
            if not line:
                break
            if line.lower().startswith(b"content-length:"):
                length = int(line.split(b":", 1)[1])
                resp.fp.readline()  # blank line
                data = resp.fp.read(length)
                if data[:2] == b"\xff\xd8":
                    n += 1
        return n
    finally:
        conn.close()


def build_parser() -> argparse.ArgumentParser:
    """The CLI."""
    p = argparse.ArgumentParser(prog="demo", description=__doc__.split("\n\n")[0])
    p.add_argument("--port", type=int, default=8090, help="web console port (0 = pick a free one)")
    p.add_argument("--duration", type=float, default=0.0, help="stop after this many seconds (0 = until Ctrl-C)")
    p.add_argument("--fps", type=int, default=10, help=f"PTZ stream frame rate ({FPS_RANGE[0]}..{FPS_RANGE[1]})")
    p.add_argument("--resolution", default="", help="PTZ stream resolution ('' = the largest the camera lists)")
    p.add_argument("--model", default="axis214", help="simulated camera: axis214 (default) or q6075 (modern dome)")
    p.add_argument("--split", action="store_true", help="run axis_stream + axis_ptz instead of axis_camera")
    p.add_argument("--log-dir", type=Path, default=None, help="keep the children's logs here")
    p.add_argument("--ready-timeout", type=float, default=60.0, help="seconds to wait for live video")
    return p


def main(argv: list[str] | None = None) -> int:
    """``python -m scripts.demo`` (from the repository root; ``./scripts/demo`` bootstraps first)."""
    args = build_parser().parse_args(argv)
    stop = threading.Event()

    def on_signal(signum: int, _frame: Any) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    demo = Demo(
        DemoConfig(
            console_port=args.port,
            fps=args.fps,
            resolution=args.resolution,
            model=args.model,
            split=args.split,
            log_dir=args.log_dir,
        )
    )
    code = 0
    try:
        demo.start()
        _log(f"logs in {demo.log_dir}; simulator at {demo.sim_url}")
        url = demo.wait_ready(args.ready_timeout)
        print(f"Axis PTZ console: {url}", flush=True)  # noqa: T201 - a CLI
        _log("Ctrl-C to stop" + (f" (stopping by itself after {args.duration:g} s)" if args.duration else ""))
        deadline = time.monotonic() + args.duration if args.duration > 0 else None
        while not stop.is_set():
            if deadline is not None and time.monotonic() >= deadline:
                break
            demo._check_alive()  # noqa: SLF001 - same module
            stop.wait(0.5)
    except DemoError as err:
        _log(f"error: {err}")
        code = 1
    finally:
        codes = demo.stop()
        unclean = {n: c for n, c in codes.items() if c not in (0, -signal.SIGINT)}
        if unclean:
            _log(f"not stopped cleanly: {unclean}")
            code = code or 3
        elif codes:
            _log("all processes stopped cleanly")
    return code


if __name__ == "__main__":
    sys.exit(main())
