"""Test-suite wide settings: DDS on loopback, and no silently skipped tier.

With ``AXIS_REQUIRE_ALL_TIERS=1`` (``scripts/test``, CI) nothing may quietly drop out of the run:

- a skipped test fails (setup, call or teardown);
- a skip while *collecting* fails: ``pytest.importorskip("rclpy")`` at the top of a module or of a tier's
  ``conftest.py`` skips the whole module or tier before any test exists, so the per-test rule never sees it;
- every test module the run was asked to collect must contribute at least one test (counted before ``-k`` /
  ``-m`` deselection), so a module that defines its tests conditionally cannot vanish either.

The terminal summary lists the tests collected per tier (the directories under ``tests/``).
Without the variable a skip stays a skip (a developer without a browser can still run the rest).
"""

from __future__ import annotations

import contextlib
import ctypes
import gc
import os
import signal
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.support.waiting import wait_until

# Before anything imports rclpy: keep discovery on this machine.
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.pop("ROS_LOCALHOST_ONLY", None)
# One DDS domain per test session (several sessions may run at once on a machine; they must not cross-talk).
os.environ["ROS_DOMAIN_ID"] = os.environ.get("AXIS_TEST_DOMAIN_ID", str(100 + os.getpid() % 100))

# Orphaned grandchildren (a node started by a launcher that died) are re-parented to this process instead of
# init, so the leak guard below can see and stop them: a node left running would publish on this session's
# DDS domain and corrupt every later test that uses the same names.
_PR_SET_CHILD_SUBREAPER = 36
# (not Linux: no subreaper, the guard then sees direct children only)
with contextlib.suppress(OSError, AttributeError):
    ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)

TESTS = Path(__file__).resolve().parent


class _GcPauses:
    """The cyclic garbage collector's pauses in this process (every thread waits for them: a node under test, the
    simulated camera and the DDS callbacks alike). A ``gen2`` collection walks every tracked object, so its pause
    grows with what the session has accumulated; a failed test's report shows the longest pauses during it, and
    the run's summary shows the worst (a timing-sensitive failure can then be told from a defect)."""

    def __init__(self) -> None:
        self.pauses: list[tuple[float, float, int]] = []  # (end, seconds, generation)
        self._start = 0.0

    def __call__(self, phase: str, info: dict[str, int]) -> None:
        now = time.perf_counter()
        if phase == "start":
            self._start = now
        elif self._start:
            self.pauses.append((now, now - self._start, info.get("generation", -1)))
            self._start = 0.0

    def since(self, t0: float) -> list[tuple[float, float, int]]:
        return [p for p in self.pauses if p[0] >= t0]

    @staticmethod
    def describe(pauses: list[tuple[float, float, int]]) -> str:
        if not pauses:
            return "no collection"
        worst = sorted(pauses, key=lambda p: p[1], reverse=True)
        total = sum(p[1] for p in pauses)
        long = sum(p[1] >= 0.1 for p in pauses)
        top = ", ".join(f"{1000 * s:.0f} ms (gen {g})" for _e, s, g in worst[:3])
        return f"{len(pauses)} collections, {1000 * total:.0f} ms in all, {long} of 100 ms or more; longest {top}"


_gc_pauses = _GcPauses()
gc.callbacks.append(_gc_pauses)
REQUIRE = "AXIS_REQUIRE_ALL_TIERS"
_collected: Counter[Path] = Counter()  # test module -> tests collected (before deselection)
_problems: list[str] = []


def _required() -> bool:
    return os.environ.get(REQUIRE) == "1"


def _skip_reason(longrepr: object) -> str:
    return str(longrepr[2]) if isinstance(longrepr, tuple) and len(longrepr) == 3 else str(longrepr)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):  # noqa: ANN001, ANN201
    """A skipped test is a failure while AXIS_REQUIRE_ALL_TIERS=1; a failed test's report shows the garbage
    collector's pauses during it."""
    outcome = yield
    report = outcome.get_result()
    if report.failed and call.when == "call":
        t0 = time.perf_counter() - call.duration - 0.01
        report.sections.append(("garbage collector pauses during the test", _GcPauses.describe(_gc_pauses.since(t0))))
    if _required() and report.skipped and not hasattr(report, "wasxfail"):
        report.outcome = "failed"
        reason = _skip_reason(report.longrepr)
        report.longrepr = f"skipped while {REQUIRE}=1 (every tier must run): {reason}"


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):  # noqa: ANN001, ANN201
    """A module or tier skipped at collection (importorskip at import) is a collection error while required."""
    outcome = yield
    report = outcome.get_result()
    if _required() and report.skipped:
        reason = _skip_reason(report.longrepr)
        report.outcome = "failed"
        report.longrepr = (
            f"{collector.nodeid or collector}: skipped at collection while {REQUIRE}=1 (a tier is missing): {reason}"
        )
        _problems.append(f"{collector.nodeid}: skipped at collection: {reason}")


def pytest_configure(config):  # noqa: ANN001, ANN201
    config.addinivalue_line(
        "markers",
        "applies_to(**params): run only for these values of a parametrised fixture or argument, e.g. "
        "applies_to(cam=['q6075']); other cases are deselected at collection (a case that does not apply is "
        "not generated, rather than skipped: a skip fails the run under AXIS_REQUIRE_ALL_TIERS=1)",
    )


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(session, config, items):  # noqa: ANN001, ANN201
    """Count tests per module before -k/-m deselect any; deselect the cases an applies_to marker excludes."""
    for item in items:
        _collected[Path(str(item.path)).resolve()] += 1
    keep, dropped = [], []
    for item in items:
        marker = item.get_closest_marker("applies_to")
        params = getattr(getattr(item, "callspec", None), "params", {})
        if marker is not None and any(k in params and params[k] not in v for k, v in marker.kwargs.items()):
            dropped.append(item)
        else:
            keep.append(item)
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        items[:] = keep


def _requested_modules(config: pytest.Config) -> set[Path]:
    """Every test module under the paths this run was asked to collect."""
    out: set[Path] = set()
    for arg in config.args:
        p = Path(arg.split("::")[0])
        p = (p if p.is_absolute() else Path(config.invocation_params.dir) / p).resolve()
        if p.is_dir():
            out.update(q.resolve() for q in p.rglob("test_*.py") if ".venv" not in q.parts)
        elif p.is_file() and p.name.startswith("test_") and p.suffix == ".py":
            out.add(p)
    return {p for p in out if TESTS in p.parents}


def _tier(path: Path) -> str:
    rel = path.relative_to(TESTS)
    return rel.parts[0] if len(rel.parts) > 1 else "(top level)"


def pytest_sessionfinish(session, exitstatus):  # noqa: ANN001, ANN201
    if not _required():
        return
    empty = sorted(m for m in _requested_modules(session.config) if _collected[m] == 0)
    for m in empty:
        _problems.append(f"{m.relative_to(TESTS.parent)}: collected no test (tier '{_tier(m)}' incomplete)")
    if empty and session.exitstatus == pytest.ExitCode.OK:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter, exitstatus, config):  # noqa: ANN001, ANN201
    tiers: Counter[str] = Counter()
    for module, n in _collected.items():
        if TESTS in module.parents:
            tiers[_tier(module)] += n
    if tiers:
        terminalreporter.write_line(
            "tests collected per tier: " + ", ".join(f"{t} {n}" for t, n in sorted(tiers.items()))
        )
    terminalreporter.write_line(
        f"garbage collector pauses in the pytest process: {_GcPauses.describe(_gc_pauses.pauses)}; "
        f"objects tracked at the end: {len(gc.get_objects())}"
    )
    if _problems:
        terminalreporter.section(f"missing tiers ({REQUIRE}=1)", red=True)
        for p in _problems:
            terminalreporter.write_line(p, red=True)


def _descendants(root: int) -> dict[int, str]:
    """Live (non-zombie) processes below ``root``: pid -> command line. (Exited orphans stay zombies of
    this process until it ends: reaping them here could steal an exit status a test's Popen waits for.)"""
    children: dict[int, list[int]] = {}
    info: dict[int, tuple[str, str]] = {}
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            stat = Path(entry.path, "stat").read_text()
            cmd = Path(entry.path, "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
        except OSError:
            continue
        rest = stat[stat.rindex(")") + 2 :].split()
        state, ppid = rest[0], int(rest[1])
        children.setdefault(ppid, []).append(int(entry.name))
        info[int(entry.name)] = (state, cmd)
    out: dict[int, str] = {}
    todo = list(children.get(root, []))
    while todo:
        pid = todo.pop()
        state, cmd = info.get(pid, ("X", ""))
        if state not in ("Z", "X"):
            out[pid] = cmd
        todo.extend(children.get(pid, []))
    return out


@pytest.fixture(autouse=True, scope="module")
def _no_leaked_processes() -> Iterator[None]:
    """Every process a test module starts must be gone when the module ends (grace: 5 s after its fixtures).

    A leftover is stopped (SIGTERM, then SIGKILL) and reported as an error of the module's last test."""
    before = set(_descendants(os.getpid()))
    yield

    def leftovers() -> dict[int, str]:
        return {p: c for p, c in _descendants(os.getpid()).items() if p not in before}

    wait_until(lambda: not leftovers(), 5.0, 0.2, scaled=False, raises=False)
    left = leftovers()
    if not left:
        return
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for pid in left:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, sig)
        wait_until(lambda: not any(p in _descendants(os.getpid()) for p in left), 3.0, 0.1, scaled=False, raises=False)
    pytest.fail(
        "processes left running by this test module (stopped now):\n"
        + "\n".join(f"  pid {p}: {c[:200]}" for p, c in sorted(left.items())),
        pytrace=False,
    )
