"""Two-host tier: the robot and the operator in two network namespaces joined by a veth pair
(``axis_ptz_ros2.sim.link``), every node a real executable in its own process, DDS with the default
discovery range (no ROS_AUTOMATIC_DISCOVERY_RANGE inside the namespaces: they are the two "hosts").

Needs root (``ip netns``); ``nftables`` is installed on first use. Without root the tests skip, which
``./scripts/test`` (AXIS_REQUIRE_ALL_TIERS=1) turns into a failure: the tier cannot vanish silently.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import pytest

from axis_ptz_ros2.sim import link as linkmod

pytestmark = pytest.mark.netns

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = ROOT / "artifacts" / "netns"


def host_env(**extra: str) -> dict[str, str]:
    """The environment of a process on one of the two "hosts": default DDS discovery, this session's domain."""
    env = dict(os.environ)
    for k in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY", "ROS_STATIC_PEERS"):
        env.pop(k, None)
    env["PYTHONUNBUFFERED"] = "1"
    env["PATH"] = f"{Path(sys.executable).parent}:{env.get('PATH', '')}"
    env.update(extra)
    return env


class Probe:
    """``axis_ptz_ros2.nodes.link_probe`` in a namespace: its JSON lines collected by a thread."""

    def __init__(self, proc: subprocess.Popen[bytes]) -> None:
        self.proc = proc
        self.records: list[dict[str, Any]] = []
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for raw in self.proc.stdout:
            try:
                rec = json.loads(raw)
            except ValueError:
                continue
            with self._lock:
                self.records.append(rec)

    def of(self, kind: str, since_ns: int = 0) -> list[dict[str, Any]]:
        with self._lock:
            return [r for r in self.records if r.get("t") == kind and r.get("rx", 0) >= since_ns]

    def send(self, cmd: dict[str, Any]) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write((json.dumps(cmd) + "\n").encode())
        self.proc.stdin.flush()


class TwoHosts:
    """A :class:`~axis_ptz_ros2.sim.link.Link` and the processes started in it; everything stops at close."""

    def __init__(self, tag: str) -> None:
        self.link = linkmod.Link(tag)
        self.procs: list[tuple[str, subprocess.Popen[bytes]]] = []
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        self.tag = tag

    def start(
        self, side: str, name: str, argv: Sequence[str], env: dict[str, str] | None = None
    ) -> subprocess.Popen[bytes]:
        log = open(ARTIFACTS / f"{self.tag}-{name}.log", "wb")  # noqa: SIM115 - closed with the process
        proc = self.link.popen(side, argv, env=env or host_env(), stdout=log, stderr=subprocess.STDOUT, cwd=str(ROOT))
        log.close()
        self.procs.append((name, proc))
        return proc

    def probe(self, side: str = "operator", args: Sequence[str] = (), env: dict[str, str] | None = None) -> Probe:
        argv = [sys.executable, "-m", "axis_ptz_ros2.nodes.link_probe", *args]
        err = open(ARTIFACTS / f"{self.tag}-probe-{side}-{len(self.procs)}.log", "wb")  # noqa: SIM115
        proc = self.link.popen(
            side, argv, env=env or host_env(), stdout=subprocess.PIPE, stdin=subprocess.PIPE, stderr=err, cwd=str(ROOT)
        )
        err.close()
        self.procs.append(("probe", proc))
        return Probe(proc)

    def start_robot(self, camera_args: Sequence[str] = (), env: dict[str, str] | None = None) -> None:
        """The simulated camera on the robot's loopback, and ``axis_camera`` talking to it."""
        self.start("robot", "sim", ["axis_camera_sim", "--port", "8080"], env)
        self.start(
            "robot",
            "axis_camera",
            ["axis_camera", "--ros-args", "-p", "hostname:=127.0.0.1", "-p", "port:=8080", *camera_args],
            env,
        )

    def check_alive(self) -> None:
        for name, p in self.procs:
            assert p.poll() is None, f"{name} exited with {p.returncode} (log in {ARTIFACTS})"

    def close(self) -> None:
        for _name, p in reversed(self.procs):
            if p.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGINT)
        deadline = time.monotonic() + 5.0
        for _name, p in reversed(self.procs):
            try:
                p.wait(timeout=max(deadline - time.monotonic(), 0.1))
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGKILL)
                p.wait(timeout=5.0)
        self.link.close()


def wait_for(predicate: Callable[[], Any], timeout: float, what: str, hosts: TwoHosts | None = None) -> Any:
    """Poll ``predicate`` until truthy (processes checked alive meanwhile); AssertionError naming ``what``."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        v = predicate()
        if v:
            return v
        if hosts is not None:
            hosts.check_alive()
        time.sleep(0.05)
    raise AssertionError(f"timed out after {timeout:.0f} s waiting for {what}")


@pytest.fixture
def two_hosts(request: pytest.FixtureRequest) -> Iterator[TwoHosts]:
    reason = linkmod.available()
    if reason:
        pytest.skip(f"two-host tier: {reason}")
    tag = "".join(c for c in request.node.name.removeprefix("test_") if c.isalnum())[:12] or "t"
    hosts = TwoHosts(tag)
    try:
        yield hosts
    finally:
        hosts.close()
