"""ROS tier fixtures: nodes and probes over real DDS (Fast DDS, loopback only), one context per test.

Without rclpy or the built ``axis_ptz_interfaces`` every module of this tier is reported skipped at
collection (never imported); with AXIS_REQUIRE_ALL_TIERS=1 (scripts/test, CI) tests/conftest.py turns that
into a collection error (tests/unit/test_tier_guard.py proves both). A skip raised while a conftest is being
imported would crash pytest instead, hence the check here rather than ``pytest.importorskip``.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

try:
    import rclpy  # noqa: F401

    import axis_ptz_interfaces.msg  # noqa: F401
except ModuleNotFoundError as err:
    MISSING: str | None = f"the ROS tier needs {err.name!r} ({err}): ./scripts/bootstrap builds it"
else:
    MISSING = None

pytestmark = pytest.mark.ros


class _MissingTier(pytest.File):
    """Stands in for a test module of this tier when its dependencies are missing: a collection skip."""

    def collect(self):  # noqa: ANN201
        raise pytest.skip.Exception(MISSING or "", allow_module_level=True)


@pytest.hookimpl(tryfirst=True)
def pytest_pycollect_makemodule(module_path: Path, parent):  # noqa: ANN001, ANN201
    if MISSING is not None:
        return _MissingTier.from_parent(parent, path=module_path)
    return None


if MISSING is None:
    from axis_ptz_ros2.sim.camera import SimulatedCamera
    from tests.support.harness import RosHarness
    from tests.support.sim import reset_camera

    @pytest.fixture(scope="module")
    def sim() -> Iterator[SimulatedCamera]:
        """The simulated 214 (no auth), one per test module (a module may define its own: a persona, auth)."""
        cam = SimulatedCamera(host="127.0.0.1", port=0).start()
        try:
            yield cam
        finally:
            cam.stop()

    @pytest.fixture
    def camera(sim: SimulatedCamera) -> SimulatedCamera:
        """The module's simulated camera, reset to its start state for each test."""
        return reset_camera(sim)

    @pytest.fixture
    def ros() -> Iterator[RosHarness]:
        """A fresh ROS context per test."""
        h = RosHarness()
        try:
            yield h
        finally:
            h.close()
