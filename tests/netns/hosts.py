"""Robot and operator as two "hosts" (network namespaces over a :class:`~tests.support.link.Link`), with
the processes started on each: used by the two-host test tier (``tests/netns``) and ``bench/bench_link.py``. Test
and bench support, not shipped in the package: it clears the DDS discovery settings of the processes it starts.

Processes get the environment of a host of their own: the default DDS discovery range (nothing in our node
code restricts it), this session's ``ROS_DOMAIN_ID``, and ``/dev/shm`` per host. ROS-free (processes only).
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
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from tests.support import link as linkmod
from tests.support.waiting import wait_until

ROOT = Path(__file__).resolve().parents[2]  # the repository (tests/netns/hosts.py)


def host_env(**extra: str) -> dict[str, str]:
    """The environment of a process on one of the two "hosts": default DDS discovery, this session's domain. With a
    Fast DDS profile (``FASTRTPS_DEFAULT_PROFILES_FILE``) also ``RMW_FASTRTPS_PUBLICATION_MODE=AUTO``, as
    docs/weak-link.md says to export with it (the profile's paced still writer needs it)."""
    env = dict(os.environ)
    for k in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY", "ROS_STATIC_PEERS"):
        env.pop(k, None)
    env["PYTHONUNBUFFERED"] = "1"
    env["PATH"] = f"{Path(sys.executable).parent}:{env.get('PATH', '')}"
    if extra.get("FASTRTPS_DEFAULT_PROFILES_FILE"):
        env["RMW_FASTRTPS_PUBLICATION_MODE"] = "AUTO"
    env.update(extra)
    return env


class Probe:
    """``tests.support.link_probe`` in a namespace: its JSON lines collected by a thread."""

    def __init__(self, proc: subprocess.Popen[bytes]) -> None:
        """Start collecting ``proc``'s stdout."""
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
        """Records of ``kind`` received at or after ``since_ns`` (wall clock)."""
        with self._lock:
            return [r for r in self.records if r.get("t") == kind and r.get("rx", 0) >= since_ns]

    def send(self, cmd: dict[str, Any]) -> None:
        """A command line to the probe (see its docstring)."""
        assert self.proc.stdin is not None
        self.proc.stdin.write((json.dumps(cmd) + "\n").encode())
        self.proc.stdin.flush()


class TwoHosts:
    """A :class:`~tests.support.link.Link` and the processes started in it; everything stops at close.

    Each process's output goes to ``<logs>/<tag>-<name>.log``."""

    def __init__(self, tag: str, logs: Path, queue_ms: float = 100.0) -> None:
        """Create the link (raises :class:`~tests.support.link.LinkError` if it cannot)."""
        self.logs = logs
        logs.mkdir(parents=True, exist_ok=True)
        self.link = linkmod.Link(tag, queue_ms=queue_ms)
        self.procs: list[tuple[str, subprocess.Popen[bytes]]] = []
        self.tag = tag

    def start(
        self, side: str, name: str, argv: Sequence[str], env: dict[str, str] | None = None
    ) -> subprocess.Popen[bytes]:
        """Start ``argv`` on ``side`` (output to the log file)."""
        log = open(self.logs / f"{self.tag}-{name}.log", "wb")  # noqa: SIM115 - closed with the process
        proc = self.link.popen(side, argv, env=env or host_env(), stdout=log, stderr=subprocess.STDOUT, cwd=str(ROOT))
        log.close()
        self.procs.append((name, proc))
        return proc

    def probe(self, side: str = "operator", args: Sequence[str] = (), env: dict[str, str] | None = None) -> Probe:
        """``tests.support.link_probe`` on ``side``: the operator's measuring viewer."""
        argv = [sys.executable, "-m", "tests.support.link_probe", *args]
        err = open(self.logs / f"{self.tag}-probe-{side}-{len(self.procs)}.log", "wb")  # noqa: SIM115
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
        """AssertionError naming the first process that exited."""
        for name, p in self.procs:
            assert p.poll() is None, f"{name} exited with {p.returncode} (log in {self.logs})"

    def close(self) -> None:
        """SIGINT every process group, SIGKILL what is left after 5 s, then remove the link."""
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
    return wait_until(
        predicate, timeout, 0.05, what=what, scaled=False, tick=None if hosts is None else hosts.check_alive
    )
