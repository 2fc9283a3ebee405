"""The driver against both simulated cameras: the Axis 214 (VAPIX 2, PAL, anonymous HTTP) and a modern 1080p dome
(``q6075``: VAPIX 3, square pixels, endless pan, Digest over HTTPS with certificate checking on).

Nodes get only the connection (host, port, https, CA, credentials file): no resolution, no camera model, no
limits. Everything else they must learn from the camera. Checks read the simulator's ground truth (its own
sign mapping, its request log) and the frames themselves.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

pytest.importorskip("rclpy")

from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import CameraInfo, CompressedImage  # noqa: E402

from axis_ptz_interfaces.msg import PtzCommand, PtzState, VideoParams  # noqa: E402
from axis_ptz_interfaces.srv import MovePtz  # noqa: E402
from axis_ptz_ros2.nodes import common  # noqa: E402
from axis_ptz_ros2.nodes.common import LATCHED_QOS, STREAM_QOS  # noqa: E402
from axis_ptz_ros2.nodes.ptz_node import PtzNode  # noqa: E402
from axis_ptz_ros2.nodes.stream_node import StreamNode  # noqa: E402
from axis_ptz_ros2.sim.camera import SimulatedCamera  # noqa: E402
from axis_ptz_ros2.sim.ptz import Speeds, vapix_to_ros  # noqa: E402
from tests.support.waiting import wait_until

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]

NAN = float("nan")
PASSWORD = "modern-secret"
FAST = {"backoff_initial": 0.05, "backoff_max": 0.3, "stall_timeout": 0.6, "auth_retry": 1.0, "read_timeout": 2.0}


@pytest.fixture(scope="module", params=["axis214", "q6075"])
def cam(request: pytest.FixtureRequest) -> Iterator[SimulatedCamera]:
    """Each persona as the camera would ship: the 214 anonymous over HTTP, the modern one Digest over HTTPS."""
    c = SimulatedCamera(model=request.param, port=0, password=PASSWORD, speeds=Speeds(200.0, 200.0, 0.5, 0.5))
    c.start()
    try:
        yield c
    finally:
        c.stop()


@pytest.fixture(scope="module")
def connection(cam: SimulatedCamera, tmp_path_factory: pytest.TempPathFactory) -> list[Parameter]:
    """Only how to reach the camera; the CA is the camera's own generated certificate (checking stays on)."""
    params = {"port": cam.port}
    if cam.https:
        params.update(use_https=True, verify_tls=True, ca_file=str(cam.ca_file))
    if cam.auth != "none":
        f = Path(tmp_path_factory.mktemp("cred")) / "camera.cred"
        f.write_text(f"root:{PASSWORD}\n", encoding="utf-8")
        f.chmod(0o600)
        params["password_file"] = str(f)
    return [Parameter(k, value=v) for k, v in params.items()]


def _largest(cam: SimulatedCamera) -> tuple[int, int]:
    return max(cam.persona.resolutions.values(), key=lambda s: (s[0] * s[1], s[0]))


def _wait_still(cam: SimulatedCamera, timeout: float = 10.0) -> None:
    wait_until(lambda: not cam.state.moving(), timeout, scaled=False, raises=False)
    assert not cam.state.moving(), "simulated head still moving"


def test_stream_node_learns_size_aspect_and_model(ros: Any, cam: SimulatedCamera, connection: list[Parameter]):
    cam.teleport(0.0, 0.0, 1)
    overrides = connection + [Parameter(k, value=v) for k, v in FAST.items()]
    node = ros.add(StreamNode(context=ros.context, parameter_overrides=overrides))
    probe = ros.probe("persona_probe")
    images: list[CompressedImage] = []
    infos: list[CameraInfo] = []
    params: list[VideoParams] = []
    probe.create_subscription(CompressedImage, "image_raw/compressed", images.append, STREAM_QOS)
    probe.create_subscription(CameraInfo, "camera_info", infos.append, STREAM_QOS)
    probe.create_subscription(VideoParams, "video/params", params.append, LATCHED_QOS)
    w, h = _largest(cam)
    # resolution '' = the largest the camera lists: 704x576 on the 214, 1920x1080 on the modern dome
    ros.wait_for(lambda: infos and (infos[-1].width, infos[-1].height) == (w, h), timeout=20)
    ros.wait_for(lambda: len(images) >= 2, timeout=10)
    img = cv2.imdecode(np.frombuffer(bytes(images[-1].data), np.uint8), cv2.IMREAD_COLOR)
    assert (img.shape[1], img.shape[0]) == (w, h)
    info = infos[-1]
    fx, fy = info.k[0], info.k[4]
    if cam.persona.key == "axis214":
        assert node.camera_model.name == "AXIS 214 PTZ"  # noqa: SLF001 - selected by Brand.ProdNbr=214
        assert fy / fx == pytest.approx(12.0 / 11.0, rel=1e-6)  # PAL 704x576: non-square pixels
        assert fx == pytest.approx(352.0 / math.tan(math.radians(47.98) / 2), rel=1e-6)
    else:
        assert node.camera_model.name == "AXIS Q6075-E"  # noqa: SLF001 - selected by Brand.ProdNbr=Q6075-E
        assert fy == pytest.approx(fx, rel=1e-9)  # square pixels
        assert fx == pytest.approx(960.0 / math.tan(math.radians(63.7) / 2), rel=1e-6)
    # the camera's own resolution list reaches the teleops (latched video/params)
    listed = sorted(cam.persona.resolutions.values(), key=lambda s: (s[0] * s[1], s[0]))
    ros.wait_for(lambda: params and params[-1].available_resolutions[-1] == f"{w}x{h}", timeout=10)
    assert set(params[-1].available_resolutions) == {f"{a}x{b}" for a, b in listed}
    # a size of the other camera is refused with a reason and never sent
    other = "1280x720" if cam.persona.key == "axis214" else "704x576"
    res = node.set_parameters([Parameter("resolution", value=other)])[0]
    assert not res.successful
    assert other in res.reason
    assert not any(f"resolution={other}" in e.query for e in cam.request_counts.video_log)


def _move(ros: Any, probe: Any, client: Any, pan: float, tilt: float = NAN, zoom: float = NAN, wait: bool = True):
    req = MovePtz.Request()
    req.command = PtzCommand(pan=pan, tilt=tilt, zoom=zoom, speed=NAN)
    req.wait = wait
    req.timeout_s = 10.0
    fut = client.call_async(req)
    return ros.wait_for(lambda: fut.result() if fut.done() else None, timeout=15)


def test_ptz_node_learns_limits_and_pans_across_the_seam(ros: Any, cam: SimulatedCamera, connection: list[Parameter]):
    cam.teleport(170.0, 0.0, 1)  # VAPIX +170 = 170 deg to the right = REP-103 -170 deg
    node = ros.add(PtzNode(context=ros.context, parameter_overrides=connection))
    probe = ros.probe("persona_ptz_probe")
    states: list[PtzState] = []
    probe.create_subscription(PtzState, "ptz/state", states.append, STREAM_QOS)
    absolute = probe.create_client(MovePtz, "ptz/move_absolute")
    relative = probe.create_client(MovePtz, "ptz/move_relative")
    ros.wait_for(lambda: absolute.service_is_ready() and relative.service_is_ready(), timeout=10)
    ros.wait_for(lambda: node.poller.latest is not None and states, timeout=10)
    lim = cam.world.limits
    s = states[-1]
    assert (s.zoom_min, s.zoom_max) == (lim.min_zoom, lim.max_zoom)  # 1..9999 / 1..19999, as the camera says
    assert (math.degrees(s.tilt_min), math.degrees(s.tilt_max)) == pytest.approx((lim.min_tilt, lim.max_tilt))
    cam.reset_counts()
    # REP-103 +170 deg (VAPIX -170): 20 deg away across the seam, 340 deg the other way round.
    reply = _move(ros, probe, absolute, math.radians(170.0))
    if cam.persona.key == "axis214":  # end stops at +-170: 170 is reachable, but only the long way round
        assert reply.success, reply.message
        _wait_still(cam)
        assert cam.position()[0] == pytest.approx(-170.0, abs=0.01)
        beyond = _move(ros, probe, absolute, math.radians(175.0))
        assert not beyond.success
        assert "outside the limits" in beyond.message
        assert not any("pan=-175" in e.query for e in cam.request_counts.ptz_log)
        return
    assert reply.success, reply.message
    _wait_still(cam)
    assert cam.position()[0] == pytest.approx(-170.0, abs=0.01)
    sent = [e.query for e in cam.request_counts.ptz_log if "pan=" in e.query]
    assert sent, "no pan command reached the camera"
    assert all(-180.0 <= float(q.split("pan=")[1].split("&")[0]) <= 180.0 for q in sent)
    # relative moves wrap too: +30 deg from +170 lands on -160 (VAPIX +160), never refused at the seam
    rel = _move(ros, probe, relative, math.radians(30.0))
    assert rel.success, rel.message
    _wait_still(cam)
    assert cam.position()[0] == pytest.approx(160.0, abs=0.01)
    ros.wait_for(lambda: abs(math.degrees(states[-1].pan) + 160.0) < 0.5, timeout=5)  # REP-103 -160
    assert vapix_to_ros(*cam.position()[:2])[0] == pytest.approx(math.radians(-160.0), abs=1e-3)


@pytest.mark.applies_to(cam=["q6075"])  # the 214 has end stops
def test_ptz_moves_take_the_short_way_on_the_modern_dome(ros: Any, cam: SimulatedCamera, connection: list[Parameter]):
    assert cam.state.pan_wraps
    cam.teleport(-175.0, 0.0, 1)  # REP-103 +175
    ros.add(PtzNode(context=ros.context, parameter_overrides=connection))
    probe = ros.probe("persona_seam_probe")
    absolute = probe.create_client(MovePtz, "ptz/move_absolute")
    ros.wait_for(absolute.service_is_ready, timeout=10)
    seen: list[float] = []
    reply_box: list[Any] = []
    req = MovePtz.Request()
    req.command = PtzCommand(pan=math.radians(-175.0), tilt=NAN, zoom=NAN, speed=NAN)  # VAPIX +175
    req.wait = False
    fut = absolute.call_async(req)

    def arrived() -> bool:  # sampling the pan all the way
        seen.append(cam.position()[0])
        if fut.done() and not reply_box:
            reply_box.append(fut.result())
        return bool(reply_box) and not cam.state.moving() and abs(cam.position()[0] - 175.0) < 0.01

    wait_until(arrived, 10.0, 0.005, scaled=False, raises=False)
    assert reply_box, "no answer from ptz/move_absolute"
    assert reply_box[0].success, reply_box[0].message
    assert cam.position()[0] == pytest.approx(175.0, abs=0.01)
    assert all(abs(p) >= 174.9 for p in seen), f"went the long way round: {min(map(abs, seen)):.1f} deg from 0"


@pytest.mark.applies_to(cam=["q6075"])  # the 214 is an HTTP camera
def test_verify_tls_false_warns_once(ros: Any, cam: SimulatedCamera, connection: list[Parameter], capfd):
    assert cam.https
    common._INSECURE_TLS_WARNED.clear()  # noqa: SLF001 - a fresh process
    insecure = [p for p in connection if p.name not in ("verify_tls", "ca_file")] + [
        Parameter("verify_tls", value=False)
    ]
    ros.add(StreamNode(context=ros.context, parameter_overrides=insecure))
    ros.add(PtzNode(context=ros.context, parameter_overrides=insecure))
    # both nodes made their camera configuration (and logged) in their constructors; the log line may still be
    # on its way through the logging backend
    err = ""

    def logged() -> bool:
        nonlocal err
        err += capfd.readouterr().err
        return "verify_tls is false" in err

    wait_until(logged, 5.0, 0.05, raises=False)
    assert err.count("verify_tls is false") == 1, err[-2000:]


@pytest.mark.applies_to(cam=["q6075"])  # the 214 is an HTTP camera
def test_https_without_the_camera_certificate_fails_safely(ros: Any, cam: SimulatedCamera, connection: list[Parameter]):
    """Certificate checking against the system store: the self-signed camera is refused, the node keeps running
    and says why; nothing reaches the camera's CGIs."""
    assert cam.https
    cam.reset_counts()
    strict = [p for p in connection if p.name != "ca_file"] + [Parameter(k, value=v) for k, v in FAST.items()]
    node = ros.add(StreamNode(context=ros.context, parameter_overrides=strict + [Parameter("lazy", value=False)]))
    ros.wait_for(lambda: "certificate" in node._reader.stats().last_error.lower(), timeout=10)  # noqa: SLF001
    assert node._reader.stats().frames == 0  # noqa: SLF001
    assert sum(cam.request_counts.endpoints.values()) == 0


def test_demo_with_the_modern_camera_serves_1080p_through_the_console(tmp_path: Path):
    """``demo --model q6075``: the same executables, nothing configured for the camera but how to reach it; the
    web console shows the camera's own resolution list and relays its 1920x1080 frames."""
    import http.client
    import json

    from scripts.demo import Demo, DemoConfig

    with Demo(DemoConfig(console_port=0, fps=5, model="q6075", log_dir=tmp_path)) as demo:
        url = demo.wait_ready(90.0)
        assert demo.sim_url.startswith("https://")
        host, port = url.removeprefix("http://").split(":")
        state: dict[str, Any] = {}

        def shows_1080p() -> bool:
            nonlocal state
            conn = http.client.HTTPConnection(host, int(port), timeout=5)
            conn.request("GET", "/api/state")
            state = json.loads(conn.getresponse().read())
            conn.close()
            return "1920x1080" in json.dumps(state)

        wait_until(shows_1080p, 30.0, 0.5, scaled=False, raises=False)
        assert "1920x1080" in json.dumps(state), state
        assert "704x576" not in json.dumps(state.get("resolutions", state))
        logs = "".join(p.read_text(errors="replace") for p in tmp_path.glob("axis_camera*.log"))
        assert "AXIS Q6075-E" in logs
        assert "HTTPS with Digest auth" in logs
        assert "square pixels" in logs
        assert "verify_tls is false" not in logs  # the certificate is checked
        codes = demo.stop()
    assert all(c in (0, -2) for c in codes.values()), codes


def test_keyboard_teleop_drives_either_camera(ros: Any, cam: SimulatedCamera, connection: list[Parameter]):
    """The real ``axis_keyboard_teleop`` in a pty: A turns left, G walks down the camera's OWN resolution list."""
    from tests.ros.test_keyboard_teleop import Pty

    cam.teleport(0.0, 0.0, 1)
    ptz = ros.add(PtzNode(context=ros.context, parameter_overrides=connection))
    stream = ros.add(StreamNode(context=ros.context, parameter_overrides=connection))
    ros.wait_for(lambda: ptz.poller.latest is not None, 10.0)
    listed = sorted(set(cam.persona.resolutions.values()), key=lambda s: (s[0] * s[1], s[0]))
    top, below = (f"{w}x{h}" for w, h in (listed[-1], listed[-2]))
    pty = Pty()
    try:
        pty.wait_output(f"video: {top} at 15 fps, compression 30", timeout=30)
        pty.wait_output("pan   +0.00 deg")
        # the PTZ node has discovered the teleop's relative-move publisher (volatile: a move sent before is lost)
        ros.wait_for(lambda: ptz.count_publishers("/ptz/cmd/relative") > 0)
        pty.type("5a")  # left 5 deg: REP-103 +5, VAPIX -5 on both cameras
        ros.wait_for(lambda: abs(cam.position()[0] + 5.0) < 0.05 and not cam.state.moving(), timeout=10)
        m = pty.type("g")
        ros.wait_for(lambda: stream.get_parameter("resolution").value == below, timeout=10)
        pty.wait_output(f"video: {below} at 15 fps, compression 30", since=m, timeout=15)
        pty.type("\x03")
        assert pty.proc.wait(10) == 0
    finally:
        pty.close()
