"""Test-suite wide settings: DDS on loopback, and no silently skipped tier."""

from __future__ import annotations

import os

import pytest

# Before anything imports rclpy: keep discovery on this machine.
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.pop("ROS_LOCALHOST_ONLY", None)
# One DDS domain per test session (several sessions may run at once on a machine; they must not cross-talk).
os.environ["ROS_DOMAIN_ID"] = os.environ.get("AXIS_TEST_DOMAIN_ID", str(100 + os.getpid() % 100))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):  # noqa: ANN001, ANN201
    """With AXIS_REQUIRE_ALL_TIERS=1 (scripts/test, CI) a skipped test is a failure, not a silent pass."""
    outcome = yield
    report = outcome.get_result()
    if os.environ.get("AXIS_REQUIRE_ALL_TIERS") == "1" and report.skipped and not hasattr(report, "wasxfail"):
        report.outcome = "failed"
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        report.longrepr = f"skipped while AXIS_REQUIRE_ALL_TIERS=1 (every tier must run): {reason}"
