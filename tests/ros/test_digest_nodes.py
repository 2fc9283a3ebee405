"""Digest logins that last (issue 10), over real DDS: the PTZ node and the stream node against a simulated
camera whose Digest nonces expire after 1–2 s of real time, and across a camera restart (which forgets every
nonce). Not one command may fail; frames must resume; the re-challenges show on /diagnostics."""

from __future__ import annotations

import math
import threading
import time
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import CompressedImage  # noqa: E402

from axis_ptz_interfaces.msg import PtzCommand  # noqa: E402
from axis_ptz_interfaces.srv import MovePtz  # noqa: E402
from axis_ptz_ros2.nodes.common import STREAM_QOS  # noqa: E402
from axis_ptz_ros2.nodes.ptz_node import PtzNode  # noqa: E402
from axis_ptz_ros2.nodes.stream_node import StreamNode  # noqa: E402
from axis_ptz_ros2.sim.camera import SimulatedCamera  # noqa: E402
from axis_ptz_ros2.sim.ptz import Speeds, vapix_to_ros  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402
from tests.support.stamps import sim_stamp  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(180)]
PASSWORD = "digest-Pa55"
NAN = float("nan")


@pytest.fixture
def cred(tmp_path: Path) -> str:
    path = tmp_path / "cred"
    path.write_text(f"root:{PASSWORD}\n", encoding="utf-8")
    return str(path)


def _diag_values(diags: list[DiagnosticArray], suffix: str) -> dict[str, str]:
    statuses = [s for d in list(diags) for s in d.status if s.name.endswith(suffix)]
    return {kv.key: kv.value for kv in statuses[-1].values} if statuses else {}


def _restart(cam: SimulatedCamera) -> None:
    """Power-cycle: every connection dropped, every nonce forgotten, same port."""
    cam.stop()
    cam.start()


@pytest.mark.parametrize("lifetime", [1.0, 1.5, 2.0])
def test_ptz_node_digest_across_nonce_expiry_and_restart(ros: RosHarness, cred: str, lifetime: float) -> None:
    cam = SimulatedCamera(
        port=0, auth="digest", password=PASSWORD, nonce_lifetime_s=lifetime, speeds=Speeds(300.0, 300.0, 0.5, 0.5)
    ).start()
    try:
        overrides = [
            Parameter("port", value=cam.port),
            Parameter("password_file", value=cred),
            Parameter("state_timeout", value=1.0),
        ]
        node = ros.add(PtzNode(context=ros.context, parameter_overrides=overrides))
        ros.wait_for(lambda: node.poller.latest is not None, 15.0)
        probe = ros.probe()
        diags: list[DiagnosticArray] = []
        probe.create_subscription(DiagnosticArray, "/diagnostics", diags.append, 10)
        client = probe.create_client(MovePtz, "ptz/move_absolute")

        def command(i: int) -> None:
            pan = math.radians(-20.0 + 7.0 * (i % 6))
            req = MovePtz.Request(command=PtzCommand(pan=pan, tilt=NAN, zoom=NAN, speed=NAN), wait=False)
            res = ros.call(client, req, timeout=10.0)
            assert res.success, f"command {i} failed: {res.message}"

        # Commands spread over ~3 nonce lifetimes of real time; polling runs all along.
        t_end = time.monotonic() + 3.0 * lifetime + 0.5
        i = 0
        while time.monotonic() < t_end:
            command(i)
            i += 1
            time.sleep(lifetime / 3.0)  # spread over real time: nonces must age and expire between the commands
        ros.wait_for(lambda: cam.request_counts.status.get(401, 0) > 0, 5.0)
        stats = node.poller.stats
        assert stats.failed == 0, f"state polls failed: {stats.last_error}"

        _restart(cam)  # the camera forgets every nonce; the node's next signed request gets a plain 401
        for j in range(4):  # each command carried out before the next (none superseded in the node)
            command(i + j)
            want_j = math.radians(-20.0 + 7.0 * ((i + j) % 6))
            ros.wait_for(lambda w=want_j: abs(vapix_to_ros(*cam.position()[:2])[0] - w) < 1e-3, 5.0)
        ros.wait_for(lambda: int(_diag_values(diags, "PTZ").get("auth rechallenges", "0")) >= 3, 5.0)
        values = _diag_values(diags, "PTZ")
        assert values["commands_failed"] == "0"
        assert values["auth refusals"] == "0"
        # The PTZ head really moved to the last command (the camera's own ground truth).
        want = math.radians(-20.0 + 7.0 * ((i + 3) % 6))
        ros.wait_for(lambda: abs(vapix_to_ros(*cam.position()[:2])[0] - want) < 1e-3, 5.0)
    finally:
        cam.stop()


@pytest.mark.parametrize("lifetime", [1.0, 2.0])
def test_stream_node_digest_reconnects_after_expiry_and_restart(ros: RosHarness, cred: str, lifetime: float) -> None:
    cam = SimulatedCamera(port=0, auth="digest", password=PASSWORD, nonce_lifetime_s=lifetime).start()
    try:
        params = {
            "port": cam.port,
            "password_file": cred,
            "lazy": False,
            "fps": 10,
            "resolution": "176x144",
            "backoff_initial": 0.05,
            "backoff_max": 0.3,
            "stall_timeout": 0.5,
            "auth_retry": 5.0,
        }
        node = ros.add(
            StreamNode(context=ros.context, parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
        )
        probe = ros.probe()
        lock = threading.Lock()
        frames: list[tuple[float, int]] = []

        def on_image(msg: CompressedImage) -> None:
            st = sim_stamp(bytes(msg.data))
            with lock:
                frames.append((time.monotonic(), st[1] if st else -1))

        probe.create_subscription(CompressedImage, "image_raw/compressed", on_image, STREAM_QOS)

        def frames_since(t: float) -> int:
            with lock:
                return sum(1 for f in frames if f[0] >= t)

        ros.wait_for(lambda: frames_since(0.0) >= 5, 15.0)
        # Each drop forces a new video request with credentials; the nonces expire in between.
        for _ in range(3):
            cam.authenticator.age_nonces(lifetime + 0.3)  # the simulator's clock past the lifetime: expiry
            cam.set_faults(drop_after_frames=2)
            t = time.monotonic()
            ros.wait_for(lambda t=t: frames_since(t) >= 2, 10.0)
            cam.set_faults(drop_after_frames=0)
        t = time.monotonic()
        _restart(cam)
        ros.wait_for(lambda: frames_since(t) >= 5, 10.0)
        stats: Any = node._reader.stats()  # noqa: SLF001
        assert stats.auth_failures == 0, stats.last_error
        with lock:
            stamps = [s for _, s in frames if s > 0]
        assert all(b > a for a, b in zip(stamps, stamps[1:], strict=False)), "an old frame was republished"
    finally:
        cam.stop()


def test_basic_only_camera_over_http_gets_no_password_and_says_why(ros: RosHarness, cred: str) -> None:
    """auth=auto against a camera offering only Basic over plain HTTP: never sent; /diagnostics explains."""
    cam = SimulatedCamera(port=0, auth="basic", password=PASSWORD).start()
    try:
        params = {"port": cam.port, "password_file": cred, "lazy": False, "auth_retry": 1.0}
        ros.add(StreamNode(context=ros.context, parameter_overrides=[Parameter(k, value=v) for k, v in params.items()]))
        probe = ros.probe()
        diags: list[DiagnosticArray] = []
        probe.create_subscription(DiagnosticArray, "/diagnostics", diags.append, 10)

        def refused() -> bool:
            values = _diag_values(diags, "MJPEG stream")
            return int(values.get("auth basic refused (plain HTTP)", "0")) >= 2

        ros.wait_for(refused, 10.0)
        status = [s for d in list(diags) for s in d.status if s.name.endswith("MJPEG stream")][-1]
        assert "offers only Basic" in status.message
        assert "auth: basic" in status.message
        assert PASSWORD not in status.message
        seen = cam.request_counts.auth
        assert seen.get("basic", 0) == 0, f"Basic credentials were sent over plain HTTP: {dict(seen)}"
        assert seen.get("none", 0) >= 2
    finally:
        cam.stop()


def test_ptz_node_says_at_start_up_that_a_camera_has_no_ptz_head(
    ros: RosHarness, capfd: pytest.CaptureFixture[str]
) -> None:
    cam = SimulatedCamera(port=0).start()
    try:
        cam.params["PTZ.ImageSource.I0.PTZEnabled"] = "false"  # a fixed camera with digital PTZ only
        overrides = [Parameter("port", value=cam.port), Parameter("state_timeout", value=1.0)]
        ros.add(PtzNode(context=ros.context, parameter_overrides=overrides))
        err = capfd.readouterr().err
        assert "no PTZ head" in err
        assert "PTZ.ImageSource.I0.PTZEnabled=false" in err
    finally:
        cam.stop()
