"""mypy --strict covers every module of the package by default (issue 24: a module list had silently missed
``streaming/*``, ``camera_info``, ``urdf`` …); only the ROS node modules relax a few checks, never ``strict``."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.unit


def _mypy() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["mypy"]


def test_strict_is_the_default_for_every_module() -> None:
    assert _mypy().get("strict") is True


def test_no_override_turns_strict_off_and_relaxations_only_touch_ros_modules() -> None:
    relaxing = {"disallow_untyped_calls", "disallow_subclassing_any", "warn_return_any", "warn_unused_ignores"}
    for override in _mypy().get("overrides", []):
        assert override.get("strict", True) is True, override
        if relaxing & set(override):
            modules = override["module"] if isinstance(override["module"], list) else [override["module"]]
            assert all(m.startswith("axis_ptz_ros2.nodes") for m in modules), modules
