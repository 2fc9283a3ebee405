"""The console on the modern 16:9 camera (simulated ``q6075``: square pixels, Digest over HTTPS) in Chromium.

The real stream and PTZ nodes, told only how to reach the camera, learn it is a 16:9 camera; the page must lay the
live image out at 16:9 (never an assumed 4:3 / PAL box), still give it most of the screen, and a click on the
marker must bring that marker to the centre of the camera's own 1280x720 snapshot (the simulator's truth).
The nodes live in their own namespace, so nothing here mixes with the demo of test_web_console_browser.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

pytest.importorskip("rclpy")

from rclpy.parameter import Parameter  # noqa: E402

from axis_ptz_ros2.nodes.web_console import WebConsole  # noqa: E402
from axis_ptz_ros2.sim.camera import SimulatedCamera  # noqa: E402
from axis_ptz_ros2.sim.ptz import Speeds  # noqa: E402
from tests.support.console_rig import start_console_rig
from tests.support.harness import RosHarness  # noqa: E402

from .test_web_console_browser import LAYOUT_JS, green_blob, shot, wait_for, wait_js  # noqa: E402

pytestmark = [pytest.mark.browser, pytest.mark.timeout(300)]

NS = "/hd_test"
PASSWORD = "hd-secret"
W, H = 1280, 720  # asked for; the stream node may step down (bandwidth budget, consumer feedback): 16:9 stays


@pytest.fixture
def ros() -> Iterator[RosHarness]:
    h = RosHarness()
    try:
        yield h
    finally:
        h.close()


@pytest.fixture
def hd_console(ros: RosHarness, tmp_path: Path) -> Iterator[tuple[SimulatedCamera, WebConsole]]:
    cam = SimulatedCamera(model="q6075", port=0, password=PASSWORD, speeds=Speeds(200.0, 200.0, 0.5, 0.5)).start()
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
        video = [Parameter("resolution", value=f"{W}x{H}"), Parameter("fps", value=6)]
        console = start_console_rig(ros, NS, connection, video)
        yield cam, console
    finally:
        cam.stop()


def _snapshot(cam: SimulatedCamera, w: int = W, h: int = H) -> np.ndarray:
    img = cv2.imdecode(np.frombuffer(cam.frame_jpeg(w, h, 0), np.uint8), cv2.IMREAD_COLOR)
    assert img is not None
    return img


def _wait_still(cam: SimulatedCamera) -> None:
    wait_for(lambda: not cam.state.moving(), 20.0, "the simulated head to stop")
    time.sleep(0.5)  # let frames from the final pose reach the <img> (an MJPEG image tells the page nothing)


def test_hd_camera_layout_and_click_centre(hd_console: tuple[SimulatedCamera, WebConsole], browser: Any) -> None:
    cam, console = hd_console
    # a pose with the green marker off-centre (found in the camera's own frames, not assumed)
    blob = None
    for pan in (-80.0, -70.0, -90.0, -60.0, -100.0):
        cam.teleport(pan, 3.0, 1)
        blob = green_blob(_snapshot(cam))
        if blob is not None and abs(blob[0] - (W - 1) / 2) > 60:
            break
    assert blob is not None, "the green marker is not in view of the HD camera"

    for vw, vh in ((1280, 800), (1920, 1080)):
        ctx = browser.new_context(viewport={"width": vw, "height": vh})
        page = ctx.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda e, errs=errors: errs.append(str(e)))
        try:
            page.goto(console.url, wait_until="domcontentloaded")  # no panorama here: "load" never fires
            wait_js(page, "document.getElementById('ptz').naturalWidth > 0", 60)
            wait_js(page, "document.documentElement.style.getPropertyValue('--ptz-aspect') !== ''", 10)
            g = page.evaluate(LAYOUT_JS)
            p = g["ptz"]
            nw, nh = g["natural"]
            assert nw / nh == pytest.approx(16 / 9, rel=0.01), g  # a 16:9 size of the camera's list
            assert p["w"] / p["h"] == pytest.approx(16 / 9, rel=0.01), g
            assert p["w"] * p["h"] / (vw * vh) > 0.5, g
            assert g["doc_h"] <= vh, g
            assert g["home"]["x"] >= p["x"] + p["w"], g
            shot(page, f"hd_{vw}x{vh}")
            if (vw, vh) == (1920, 1080):
                continue
            # click on the marker: the camera brings it to the centre of its own frame
            _wait_still(cam)
            u, v, _ = green_blob(_snapshot(cam, nw, nh)) or (math.nan, math.nan, 0)
            assert not math.isnan(u)
            box = page.locator("#ptz").bounding_box()
            pose = cam.position()
            page.mouse.click(box["x"] + (u + 0.5) * box["width"] / nw, box["y"] + (v + 0.5) * box["height"] / nh)
            message = page.locator("#message")
            wait_for(lambda m=message: "centring" in (m.text_content() or ""), 10.0, "a confirmation")
            wait_for(lambda p=pose: cam.state.moving() or cam.position() != p, 10.0, "the head to move")
            _wait_still(cam)
            after = green_blob(_snapshot(cam, nw, nh))
            assert after is not None
            err = math.hypot(after[0] - (nw - 1) / 2, after[1] - (nh - 1) / 2)
            assert err < 4.0 * nw / 704, f"marker at ({after[0]:.1f}, {after[1]:.1f}) after the click: {err:.1f} px off"
        finally:
            ctx.close()
        assert not errors, f"JavaScript errors on the page: {errors}"
