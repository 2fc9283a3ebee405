"""A missing test tier fails the run under AXIS_REQUIRE_ALL_TIERS=1 (scripts/test, CI) and stays a skip without.

pytest runs in a subprocess with a dependency hidden: a shim package first on PYTHONPATH whose import raises
ModuleNotFoundError, exactly what an absent ROS install, unbuilt interfaces or a missing Playwright look like.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.unit


def _hide(tmp_path: Path, *packages: str) -> Path:
    shim = tmp_path / "shim"
    for name in packages:
        (shim / name).mkdir(parents=True)
        hidden = f"raise ModuleNotFoundError('{name} hidden by test_tier_guard', name='{name}')\n"
        (shim / name / "__init__.py").write_text(hidden)
    return shim


def _pytest(args: list[str], shim: Path, require: bool, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(shim), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env.pop("AXIS_REQUIRE_ALL_TIERS", None)
    if require:
        env["AXIS_REQUIRE_ALL_TIERS"] = "1"
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-q", "-rA", *args]
    return subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=240, check=False)


def test_shim_really_hides_rclpy(tmp_path: Path) -> None:
    shim = _hide(tmp_path, "rclpy")
    env = dict(os.environ, PYTHONPATH=str(shim))
    r = subprocess.run([sys.executable, "-c", "import rclpy"], env=env, capture_output=True, text=True, check=False)
    assert r.returncode != 0
    assert "rclpy hidden by test_tier_guard" in r.stderr


def test_missing_rclpy_fails_the_ros_tier_when_required(tmp_path: Path) -> None:
    r = _pytest(["tests/ros"], _hide(tmp_path, "rclpy"), require=True)
    out = r.stdout + r.stderr
    assert r.returncode != 0, out
    assert "skipped at collection while AXIS_REQUIRE_ALL_TIERS=1" in out, out
    assert "rclpy hidden by test_tier_guard" in out, out
    assert "passed" not in out.splitlines()[-1], out


def test_missing_rclpy_is_a_skip_when_not_required(tmp_path: Path) -> None:
    r = _pytest(["tests/ros", "tests/unit/test_keymap.py"], _hide(tmp_path, "rclpy"), require=False)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out
    last = out.strip().splitlines()[-1]
    assert "passed" in last, out
    assert "skipped" in last, out
    assert "failed" not in last, out
    assert "error" not in last, out
    assert "the ROS tier needs 'rclpy' (rclpy hidden by test_tier_guard)" in out, out


def test_missing_interfaces_fail_the_ros_tier_when_required(tmp_path: Path) -> None:
    r = _pytest(["tests/ros/test_readme_params.py"], _hide(tmp_path, "axis_ptz_interfaces"), require=True)
    out = r.stdout + r.stderr
    assert r.returncode != 0, out
    assert "axis_ptz_interfaces" in out, out
    assert "AXIS_REQUIRE_ALL_TIERS=1" in out, out


def test_missing_playwright_fails_the_browser_tier_when_required(tmp_path: Path) -> None:
    r = _pytest(["tests/browser", "-x"], _hide(tmp_path, "playwright"), require=True)
    out = r.stdout + r.stderr
    assert r.returncode != 0, out
    assert "skipped while AXIS_REQUIRE_ALL_TIERS=1" in out, out
    assert "playwright" in out, out


def _copy_conftest(tests: Path) -> None:
    """The suite's conftest.py into ``tests``, with what it imports of ``tests/`` (the wait helper)."""
    (tests / "support").mkdir(parents=True, exist_ok=True)
    (tests / "__init__.py").write_text("")
    (tests / "support" / "__init__.py").write_text("")
    (tests / "support" / "waiting.py").write_text((ROOT / "tests" / "support" / "waiting.py").read_text())
    (tests / "conftest.py").write_text((ROOT / "tests" / "conftest.py").read_text())


def test_a_module_that_collects_nothing_fails_when_required(tmp_path: Path) -> None:
    """Generic rule for any tier (a new one too): each requested test module must yield a test; and the
    collection-skip rule holds for a module-level importorskip of any dependency."""
    tests = tmp_path / "tests"
    (tests / "tier_a").mkdir(parents=True)
    (tests / "tier_b").mkdir()
    _copy_conftest(tests)
    (tests / "tier_a" / "test_fine.py").write_text("def test_ok():\n    assert 1 + 1 == 2\n")
    (tests / "tier_a" / "test_empty.py").write_text("if False:\n    def test_never():\n        pass\n")
    (tests / "tier_b" / "test_needs.py").write_text(
        "import pytest\npytest.importorskip('no_such_module_xyz')\n\ndef test_x():\n    assert True is True\n"
    )
    shim = _hide(tmp_path, "unused")
    r = _pytest(["tests/tier_a"], shim, require=True, cwd=tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode == 1, out
    assert "tests/tier_a/test_empty.py: collected no test (tier 'tier_a' incomplete)" in out, out
    assert "1 passed" in out, out
    r = _pytest(["tests/tier_a"], shim, require=False, cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    r = _pytest(["tests"], shim, require=True, cwd=tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode != 0, out
    assert "no_such_module_xyz" in out, out
    assert "tests collected per tier: tier_a 1" in out, out


def test_applies_to_deselects_cases_that_do_not_apply(tmp_path: Path) -> None:
    """A case that does not apply is not generated (deselected), so it neither skips nor fails the run."""
    tests = tmp_path / "tests"
    (tests / "tier_a").mkdir(parents=True)
    _copy_conftest(tests)
    (tests / "tier_a" / "test_p.py").write_text(
        "import pytest\n\n"
        "@pytest.fixture(params=['old', 'new'])\ndef cam(request):\n    return request.param\n\n"
        "@pytest.mark.applies_to(cam=['new'])\ndef test_only_new(cam):\n    assert cam == 'new'\n\n"
        "def test_both(cam):\n    assert cam in ('old', 'new')\n"
    )
    r = _pytest(["tests"], _hide(tmp_path, "unused"), require=True, cwd=tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out
    assert "3 passed, 1 deselected" in out, out
