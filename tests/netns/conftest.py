"""Two-host tier: the robot and the operator in two network namespaces joined by a veth pair
(``tests.support.link``), every node a real executable in its own process, DDS with the default
discovery range (no ROS_AUTOMATIC_DISCOVERY_RANGE inside the namespaces: they are the two "hosts").

Needs root (``ip netns``); ``nftables`` is installed on first use. Without root the tests skip, which
``./scripts/test`` (AXIS_REQUIRE_ALL_TIERS=1) turns into a failure: the tier cannot vanish silently.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.netns.hosts import Probe, TwoHosts, host_env, wait_for
from tests.support import link as linkmod

__all__ = ["Probe", "TwoHosts", "host_env", "wait_for"]

pytestmark = pytest.mark.netns

ARTIFACTS = Path(__file__).resolve().parents[2] / "artifacts" / "netns"


@pytest.fixture
def two_hosts(request: pytest.FixtureRequest) -> Iterator[TwoHosts]:
    reason = linkmod.available()
    if reason:
        pytest.skip(f"two-host tier: {reason}")
    tag = "".join(c for c in request.node.name.removeprefix("test_") if c.isalnum())[:12] or "t"
    hosts = TwoHosts(tag, ARTIFACTS)
    try:
        yield hosts
    finally:
        hosts.close()
