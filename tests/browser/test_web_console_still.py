"""The console's Still button and key P in Chromium, against the real stream node and the simulated modern camera
(``q6075``: Digest over HTTPS, sizes up to 1920x1080).

Live video at 640x360; the still the page then shows must be the camera's full resolution (1920x1080, the largest of
its list), asked of the camera at compression 0 (the simulator's own request log), beside the live view, and the
live view must keep playing. The nodes live in their own namespace (nothing mixes with the other browser tests).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl

import pytest

pytest.importorskip("rclpy")

from rclpy.parameter import Parameter  # noqa: E402

from axis_ptz_ros2.nodes.web_console import WebConsole  # noqa: E402
from axis_ptz_ros2.sim.camera import SimulatedCamera  # noqa: E402
from tests.support.console_rig import start_console_rig  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402

from .test_web_console_browser import shot, wait_for, wait_js  # noqa: E402

pytestmark = [pytest.mark.browser, pytest.mark.timeout(300)]

NS = "/still_test"
PASSWORD = "still-secret"
FULL = (1920, 1080)


@pytest.fixture
def ros() -> Iterator[RosHarness]:
    h = RosHarness()
    try:
        yield h
    finally:
        h.close()


@pytest.fixture
def rig(ros: RosHarness, tmp_path: Path) -> Iterator[tuple[SimulatedCamera, WebConsole]]:
    cam = SimulatedCamera(model="q6075", port=0, password=PASSWORD).start()
    try:
        cred = tmp_path / "camera.cred"
        cred.write_text(f"root:{PASSWORD}\n", encoding="utf-8")
        cred.chmod(0o600)
        connection = [
            Parameter("port", value=cam.port),
            Parameter("use_https", value=True),
            Parameter("verify_tls", value=True),
            Parameter("ca_file", value=str(cam.ca_file)),
            Parameter("password_file", value=str(cred)),
        ]
        video = [Parameter("resolution", value="640x360"), Parameter("fps", value=6)]
        yield cam, start_console_rig(ros, NS, connection, video)
    finally:
        cam.stop()


def still_requests(cam: SimulatedCamera) -> list[dict[str, str]]:
    """``image.cgi`` requests of the simulator's log (``video.cgi`` ones carry ``fps``)."""
    return [a for a in (dict(parse_qsl(e.query)) for e in cam.request_counts.video_log) if "fps" not in a]


def test_still_button_and_key_show_the_full_resolution_still_beside_the_live_view(
    rig: tuple[SimulatedCamera, WebConsole], browser: Any
) -> None:
    cam, console = rig
    ctx = browser.new_context(viewport={"width": 1280, "height": 800})
    page = ctx.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    try:
        page.goto(console.url, wait_until="domcontentloaded")  # no panorama here: "load" never fires
        wait_js(page, "document.getElementById('ptz').naturalWidth === 640", 60)
        assert page.locator("#still-figure").is_hidden()  # no still yet
        wait_js(page, "fetch('/api/state').then(r => r.json()).then(s => s.services.still)", 20)

        page.locator("#still-take").click()
        message = page.locator("#message")
        wait_for(lambda: "1920x1080 px, compression 0" in (message.text_content() or ""), 60, "the answer", page)
        wait_js(page, "document.getElementById('still').naturalWidth === 1920", 20)
        assert page.evaluate("document.getElementById('still').naturalHeight") == FULL[1]
        assert page.locator("#still-figure").is_visible()
        assert "1920x1080" in (page.locator("#still-info").text_content() or "")
        # (Digest: each still opens a new connection, so its first request is answered with a challenge: logged too)
        asked = still_requests(cam)
        assert asked, "the camera was not asked for a still"
        assert all(a == {"resolution": "1920x1080", "compression": "0"} for a in asked), asked
        # beside the live view (the side panel), and the live view keeps its own size
        live = page.locator("#ptz").bounding_box()
        still = page.locator("#still").bounding_box()
        assert still["x"] >= live["x"] + live["width"] - 1, (live, still)
        assert page.evaluate("document.getElementById('ptz').naturalWidth") == 640
        assert page.evaluate("document.documentElement.scrollHeight") <= 800, "the page no longer fits one screen"
        shot(page, "still")

        # key P: the keyboard teleop's key takes another (the page shows the new one)
        src = page.evaluate("document.getElementById('still').src")
        page.locator("body").press("p")
        wait_js(page, f"document.getElementById('still').src !== {src!r}", 60)
        wait_js(page, "document.getElementById('still').naturalWidth === 1920", 20)
        assert len(still_requests(cam)) > len(asked)
    finally:
        ctx.close()
    assert not errors, f"JavaScript errors on the page: {errors}"
