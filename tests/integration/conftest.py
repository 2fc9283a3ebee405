"""Integration tier fixtures: the simulated camera on loopback (port 0) and a raw HTTP client to it."""

import httpx
import pytest

from axis_ptz_ros2.sim.camera import SimulatedCamera


@pytest.fixture(scope="module")
def cam():
    """One simulated Axis 214 per test module."""
    with SimulatedCamera() as c:
        yield c


@pytest.fixture
def client(cam):
    """A plain httpx client to the simulator (protocol tests talk raw VAPIX, not through our client)."""
    with httpx.Client(base_url=cam.base_url, timeout=5.0) as c:
        yield c
