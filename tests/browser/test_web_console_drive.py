"""The console in real headless Chromium with the real PTZ node and the simulated camera in one process.

Drive-safe zoom: the PTZ node (``drive_*`` parameters) caps the zoom while the robot moves (odometry from a
probe); the page must say "zoom capped while driving" exactly while the simulated head is held at the cap,
and drop it when the operator's zoom comes back. Truth is the simulator's own zoom, not the console's report.
The nodes live in their own namespace, so nothing here mixes with the demo of test_web_console_browser.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("rclpy")

from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from axis_ptz_interfaces.msg import PtzCommand  # noqa: E402
from axis_ptz_interfaces.srv import MovePtz  # noqa: E402
from axis_ptz_ros2.nodes.ptz_node import PtzNode  # noqa: E402
from axis_ptz_ros2.nodes.web_console import WebConsole  # noqa: E402
from axis_ptz_ros2.sim.camera import SimulatedCamera  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402

from .test_web_console_browser import shot, wait_js  # noqa: E402

pytestmark = pytest.mark.browser

NS = "/drive_test"
CAP = 4000.0
NAN = float("nan")


@pytest.fixture
def ros() -> Iterator[RosHarness]:
    h = RosHarness()
    try:
        yield h
    finally:
        h.close()


class Driver:
    """Publishes the robot's odometry at 10 Hz (a moving robot keeps publishing) until stopped."""

    def __init__(self, ros: RosHarness) -> None:
        self.node = ros.probe("fake_robot_odometry")
        self.pub = self.node.create_publisher(Odometry, f"{NS}/odom", 10)
        self.speed = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(0.1):
            m = Odometry()
            m.twist.twist.linear.x = self.speed
            self.pub.publish(m)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)


def test_page_says_zoom_capped_while_driving(ros: RosHarness, browser: Any) -> None:
    cam = SimulatedCamera(port=0).start()
    driver = None
    try:
        ptz = ros.add(
            PtzNode(
                context=ros.context,
                namespace=NS,
                parameter_overrides=[
                    Parameter("port", value=cam.port),
                    Parameter("drive_topic", value="odom"),
                    Parameter("drive_zoom_cap", value=CAP),
                    Parameter("drive_hold_time", value=0.5),
                ],
            )
        )
        console = ros.add(
            WebConsole(
                context=ros.context,
                namespace=NS,
                parameter_overrides=[Parameter("port", value=0), Parameter("service_timeout", value=10.0)],
            )
        )
        ros.wait_for(lambda: ptz.poller.latest is not None, 10.0)
        driver = Driver(ros)
        ros.wait_for(lambda: driver.pub.get_subscription_count() > 0, 10.0)
        # the operator zooms in to 8000 (above the cap) while the robot stands
        client = driver.node.create_client(MovePtz, f"{NS}/ptz/move_absolute")
        req = MovePtz.Request(command=PtzCommand(pan=NAN, tilt=NAN, zoom=8000.0, speed=NAN), wait=True, timeout_s=10.0)
        assert ros.call(client, req, timeout=15.0).success
        assert cam.position()[2] == pytest.approx(8000.0)

        ctx = browser.new_context(viewport={"width": 1280, "height": 800})
        page = ctx.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(console.url, wait_until="domcontentloaded")  # no camera stream here: "load" never fires
        wait_js(page, "document.getElementById('r-zoom').textContent.startsWith('8000')", 30)
        assert page.locator("#cap").is_hidden()

        # the robot drives: the head comes down to the cap and the page says so
        driver.speed = 1.0
        ros.wait_for(lambda: cam.position()[2] == pytest.approx(CAP) and not cam.state.moving(), 10.0)
        wait_js(page, "!document.getElementById('cap').hidden", 30)
        cap_text = page.locator("#cap").text_content() or ""
        assert "zoom capped while driving" in cap_text
        assert "4000" in cap_text
        assert "8000 asked" in cap_text  # the operator's zoom, restored later
        assert page.locator("#cap").is_visible()
        assert "capped" in (page.locator("#r-zoom").text_content() or "")
        state = console.state()["ptz"]
        assert state["zoom_capped"] is True
        assert state["zoom_cap"] == CAP
        assert state["requested_zoom"] == 8000.0
        shot(page, "zoom_capped")

        # the robot stops: after the hold time the operator's zoom comes back and the notice goes
        driver.speed = 0.0
        ros.wait_for(lambda: cam.position()[2] == pytest.approx(8000.0) and not cam.state.moving(), 10.0)
        wait_js(page, "document.getElementById('cap').hidden", 30)
        assert "capped" not in (page.locator("#r-zoom").text_content() or "")
        ctx.close()
        assert not errors, f"JavaScript errors on the page: {errors}"
    finally:
        if driver is not None:
            driver.close()
        cam.stop()


def test_sign_in_form_in_a_real_browser(ros: RosHarness, browser: Any, tmp_path: Any) -> None:
    """The token page as an operator uses it: a wrong token is refused, the right one signs in (cookie)."""
    token_file = tmp_path / "token"
    token_file.write_text("operator-token-1\n")
    console = ros.add(
        WebConsole(
            context=ros.context,
            namespace="/sign_in_test",
            parameter_overrides=[Parameter("port", value=0), Parameter("token_file", value=str(token_file))],
        )
    )
    ctx = browser.new_context(viewport={"width": 1280, "height": 800})
    page = ctx.new_page()
    try:
        page.goto(console.url, wait_until="domcontentloaded")
        assert page.title() == "Axis PTZ console: sign in"
        page.fill("#token", "a-wrong-guess")
        page.click("button[type=submit]")
        page.wait_for_load_state("domcontentloaded")
        assert "Wrong token." in (page.locator("[role=alert]").text_content() or "")
        page.fill("#token", "operator-token-1")
        page.click("button[type=submit]")
        page.wait_for_load_state("domcontentloaded")
        assert page.title() == "Axis PTZ console"
        # the cookie carries on: the page's own state poll is accepted
        wait_js(page, "document.getElementById('link').textContent === 'connected'", 30)
        cookie = next(c for c in ctx.cookies() if c["name"] == "axis_token")
        assert cookie["httpOnly"]
        assert cookie["sameSite"] == "Strict"
        assert "operator-token-1" not in page.content()
    finally:
        ctx.close()
