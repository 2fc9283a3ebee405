"""Off-host discovery (issue 11): the real ``axis_camera`` executable in the robot's namespace, an rclpy
subscriber in the operator's, default environment (no discovery range set): images, joint states and
``ptz/state`` arrive across the veth."""

from __future__ import annotations

from tests.netns.conftest import TwoHosts, host_env, wait_for


def test_camera_is_discoverable_from_another_host(two_hosts: TwoHosts) -> None:
    two_hosts.start_robot()
    probe = two_hosts.probe()
    wait_for(lambda: len(probe.of("image")) >= 5, 90, "images at the operator", two_hosts)
    wait_for(lambda: len(probe.of("joint_states")) >= 5, 30, "joint_states at the operator", two_hosts)
    wait_for(lambda: len(probe.of("ptz/state")) >= 5, 30, "ptz/state at the operator", two_hosts)
    wait_for(lambda: probe.of("video/params"), 30, "video/params at the operator", two_hosts)

    images = probe.of("image")
    assert all(r["w"] == 704 and r["h"] == 576 for r in images), "frames are the camera's JPEGs (SOF size)"
    assert all(r["seq"] >= 0 for r in images), "every frame carries the simulated camera's stamp"
    sent = [r["sim"] for r in images]  # the simulator's send stamps
    assert sent == sorted(set(sent)), "no frame delivered twice or out of order"
    assert {"axis_ptz_pan_joint", "axis_ptz_tilt_joint"} <= set(probe.of("joint_states")[-1]["names"])

    # The frames really crossed the veth (no shared-memory short cut between the "hosts"): the operator's end
    # received at least as many bytes as the JPEGs it was handed.
    received = two_hosts.link.counters("operator")["rx_bytes"]
    assert received >= sum(r["bytes"] for r in images), (received, sum(r["bytes"] for r in images))


def test_localhost_discovery_range_does_not_cross_hosts(two_hosts: TwoHosts) -> None:
    """Control: with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST on both sides (what our own scripts set) a
    subscriber on the robot gets frames while the operator's gets none: the test above passes because of
    discovery over the link."""
    local = host_env(ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    two_hosts.start_robot(env=local)
    remote = two_hosts.probe("operator", env=local)
    onboard = two_hosts.probe("robot", env=local)
    wait_for(lambda: len(onboard.of("image")) >= 60, 90, "images at a subscriber on the robot", two_hosts)
    wait_for(lambda: remote.of("ready"), 30, "the operator's probe to start", two_hosts)
    assert remote.of("image") == [], "LOCALHOST discovery crossed the link"
    assert remote.of("ptz/state") == [], "LOCALHOST discovery crossed the link"
