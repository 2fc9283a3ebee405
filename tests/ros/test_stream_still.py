"""``still/capture`` → ``still/compressed`` of axis_stream over real DDS against the simulated camera (in-process).

The still is checked on what arrives (decoded size, the JPEG's quantisation tables against the simulator's own
compression-0 snapshot) and on the simulator's request log (``image.cgi`` at the full resolution, compression 0);
the answer's order against the publication, live video while a still is in flight, a refused second request, an
unreachable camera (stopped, or dropping packets) answered within the connect timeout, no password in a message.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from urllib.parse import parse_qsl

import cv2
import httpx
import numpy as np
import pytest

pytest.importorskip("rclpy")

from rcl_interfaces.srv import GetParameters  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import CompressedImage  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from axis_ptz_ros2.nodes.common import LATCHED_QOS, STREAM_QOS  # noqa: E402
from axis_ptz_ros2.nodes.runner import Spinner, executor_for  # noqa: E402
from axis_ptz_ros2.nodes.stream_node import StreamNode  # noqa: E402
from axis_ptz_ros2.sim import FaultConfig, SimulatedCamera  # noqa: E402
from axis_ptz_ros2.streaming.still import BUSY  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402
from tests.support.sim import FAST_STREAM_PARAMS  # noqa: E402
from tests.support.stream_node import make_stream_node  # noqa: E402

pytestmark = pytest.mark.ros

FULL = (704, 576)  # the simulated 214's largest size (Properties.Image.Resolution)


# the simulated camera: `sim` (one per module) and `camera` (reset per test) come from tests/ros/conftest.py


@dataclass
class Inbox:
    """Messages of one topic with their arrival (monotonic) time."""

    msgs: list[tuple[float, CompressedImage]] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def on(self, msg: CompressedImage) -> None:
        with self.lock:
            self.msgs.append((time.monotonic(), msg))

    def times(self) -> list[float]:
        with self.lock:
            return [t for t, _ in self.msgs]

    def count(self) -> int:
        with self.lock:
            return len(self.msgs)


def decoded(jpeg: bytes) -> np.ndarray:
    img = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
    assert img is not None, "does not decode"
    return img


def dqt(jpeg: bytes) -> bytes:
    """The JPEG's quantisation tables (every DQT segment, concatenated): what the compression chose."""
    out, i = [], 2
    while i + 4 <= len(jpeg) and jpeg[i] == 0xFF:
        marker, length = jpeg[i + 1], int.from_bytes(jpeg[i + 2 : i + 4], "big")
        if marker == 0xDB:
            out.append(jpeg[i + 4 : i + 2 + length])
        if marker == 0xDA:  # start of scan: the header is over
            break
        i += 2 + length
    return b"".join(out)


def sim_jpeg(camera: SimulatedCamera, compression: int) -> bytes:
    url = f"http://127.0.0.1:{camera.port}/axis-cgi/jpg/image.cgi?resolution={FULL[0]}x{FULL[1]}&compression={compression}"
    with httpx.Client(trust_env=False) as c:
        r = c.get(url, timeout=10)
    r.raise_for_status()
    return r.content


def image_requests(camera: SimulatedCamera) -> list[dict[str, str]]:
    """The simulator's log of ``image.cgi`` requests (no ``fps``: ``video.cgi`` always has one)."""
    args = [dict(parse_qsl(e.query)) for e in camera.request_counts.video_log]
    return [a for a in args if "fps" not in a]


def call_async(ros: RosHarness, client, t_box: list[float]):  # noqa: ANN001, ANN201
    """Send a Trigger request; ``t_box`` gets the monotonic time its answer arrived."""
    assert client.wait_for_service(timeout_sec=10)
    fut = client.call_async(Trigger.Request())
    fut.add_done_callback(lambda _f: t_box.append(time.monotonic()))
    return fut


# --------------------------------------------------------------------------------------------------------
def test_still_is_the_full_resolution_at_compression_0_and_published_before_the_answer(ros, camera):
    node = make_stream_node(ros, camera, fps=10, resolution="352x288", compression=50, lazy=False)
    probe = ros.probe()
    live, still = Inbox(), Inbox()
    probe.create_subscription(CompressedImage, "image_raw/compressed", live.on, STREAM_QOS)
    probe.create_subscription(CompressedImage, "still/compressed", still.on, LATCHED_QOS)
    ros.wait_for(lambda: live.count() >= 3 and node._video.resolutions_known, timeout=5)
    published: list[float] = []
    pub = node._still.pub
    real_publish = pub.publish
    pub.publish = lambda msg: (published.append(time.monotonic()), real_publish(msg))[1]  # when it went out

    client = probe.create_client(Trigger, "still/capture")
    answered: list[float] = []
    t0 = time.monotonic()
    wall0 = time.time_ns()
    fut = call_async(ros, client, answered)
    ros.wait_for(fut.done, timeout=10)
    res = fut.result()
    assert res.success, res.message
    ros.wait_for(lambda: still.count() == 1, timeout=5)
    t_still, msg = still.msgs[0]
    data = bytes(msg.data)

    # the camera was asked for its best JPEG: the largest listed size, compression 0, nothing else
    assert image_requests(camera) == [{"resolution": f"{FULL[0]}x{FULL[1]}", "compression": "0"}]
    img = decoded(data)
    assert (img.shape[1], img.shape[0]) == FULL
    # compression 0's quantisation tables (the simulator's own snapshot), not those of the live stream's 50
    best, live_like = dqt(sim_jpeg(camera, 0)), dqt(sim_jpeg(camera, 50))
    assert best != live_like
    assert dqt(data) == best
    live_sizes = {decoded(bytes(m.data)).shape[:2] for _, m in live.msgs}
    assert live_sizes == {(288, 352)}, "the live stream kept its own size"

    # the answer says what was sent, and came after the still had been published
    assert f"{FULL[0]}x{FULL[1]}" in res.message, res.message
    assert f"{len(data)} bytes" in res.message, res.message
    assert "compression 0" in res.message
    assert len(published) == 1
    assert published[0] < answered[0]
    # stamped like the live images: when the JPEG arrived, on this host's clock; the live images' frame
    assert msg.header.frame_id == live.msgs[-1][1].header.frame_id != ""
    stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
    assert wall0 <= stamp_ns <= time.time_ns()
    assert msg.format == live.msgs[-1][1].format
    print(f"still: {len(data)} bytes, request->subscriber {1000 * (t_still - t0):.0f} ms")  # noqa: T201

    # latched: a subscriber that comes later gets the last still at once
    late = Inbox()
    probe.create_subscription(CompressedImage, "still/compressed", late.on, LATCHED_QOS)
    ros.wait_for(lambda: late.count() == 1, timeout=5)
    assert bytes(late.msgs[0][1].data) == data


def test_live_goes_on_and_a_second_request_is_refused_while_a_still_is_in_flight(ros, camera):
    # every reply of the camera comes 0.8 s late: the still is in flight at least that long
    camera.set_faults(FaultConfig(latency_ms=800))
    node = make_stream_node(ros, camera, fps=10, resolution="352x288", compression=50, lazy=False, stall_timeout=3.0)
    probe = ros.probe()
    live = Inbox()
    probe.create_subscription(CompressedImage, "image_raw/compressed", live.on, STREAM_QOS)
    ros.wait_for(lambda: live.count() >= 3 and node._video.resolutions_known, timeout=10)
    client = probe.create_client(Trigger, "still/capture")
    get = probe.create_client(GetParameters, "/axis_stream/get_parameters")
    assert get.wait_for_service(timeout_sec=10)

    first_at: list[float] = []
    t0 = time.monotonic()
    first = call_async(ros, client, first_at)
    ros.wait_for(lambda: node._still.taker.busy, timeout=2)
    second_at: list[float] = []
    second = call_async(ros, client, second_at)
    ros.wait_for(second.done, timeout=5)
    assert not first.done(), "the second answer came after the first: it was queued"
    assert second.result().success is False
    assert second.result().message == BUSY
    # the executor is free meanwhile: another service of the node answers
    req = GetParameters.Request(names=["fps"])
    params = probe_call(ros, get, req)
    assert params.values[0].integer_value == 10
    assert not first.done()

    ros.wait_for(lambda: first_at, timeout=10)  # the done callback runs on a later spin than the future completes
    assert first.result().success, first.result().message
    in_flight = [t for t in live.times() if t0 <= t <= first_at[0]]
    took = first_at[0] - t0
    assert took >= 0.8
    # live frames kept coming while the still was in flight (10 fps; a stall of this loaded machine allowed for)
    assert len(in_flight) >= 3, f"{len(in_flight)} live frames in {took:.2f} s"
    assert node._still.taker.taken == 1


def probe_call(ros: RosHarness, client, req):  # noqa: ANN001, ANN201
    fut = client.call_async(req)
    ros.wait_for(fut.done, timeout=5)
    return fut.result()


def test_stopped_camera_answers_false_at_once_without_the_password(ros, tmp_path):
    cam = SimulatedCamera(host="127.0.0.1", port=0, auth="basic", user="root", password="secret-XYZ-42").start()
    try:
        cred = tmp_path / "cred"
        cred.write_text("root:secret-XYZ-42\n")
        cred.chmod(0o600)
        make_stream_node(ros, cam, password_file=str(cred), lazy=True, connect_timeout=0.5)
    finally:
        cam.stop()
    probe = ros.probe()
    client = probe.create_client(Trigger, "still/capture")
    at: list[float] = []
    t0 = time.monotonic()
    fut = call_async(ros, client, at)
    ros.wait_for(lambda: at, timeout=5)  # the done callback runs on a later spin than the future completes
    res = fut.result()
    assert res.success is False
    assert "unreachable" in res.message, res.message
    assert "secret-XYZ-42" not in res.message
    assert "root:" not in res.message
    assert at[0] - t0 < 0.5 + 1.0, f"answered after {at[0] - t0:.2f} s"
    # and it can be asked again (the failure released it)
    fut = call_async(ros, client, at)
    ros.wait_for(fut.done, timeout=5)
    assert fut.result().success is False
    assert fut.result().message != BUSY


def test_camera_dropping_packets_answers_false_within_the_connect_timeout(ros, camera):
    node = make_stream_node(ros, camera, lazy=True, connect_timeout=0.5)
    ros.wait_for(lambda: node._video.resolutions_known, timeout=5)
    probe = ros.probe()
    client = probe.create_client(Trigger, "still/capture")
    assert client.wait_for_service(timeout_sec=10)
    camera.reboot(2.0, blackhole=True)  # connects hang for 2 s, as for a camera off the network
    try:
        at: list[float] = []
        t0 = time.monotonic()
        fut = call_async(ros, client, at)
        ros.wait_for(lambda: at, timeout=5)  # the done callback runs on a later spin than the future completes
        res = fut.result()
        took = at[0] - t0
        assert res.success is False
        assert "did not answer in time" in res.message or "unreachable" in res.message, res.message
        assert 0.4 <= took < 0.5 + 1.0, f"answered after {took:.2f} s (connect timeout 0.5 s)"
    finally:
        ros.wait_for(lambda: not camera.rebooting, timeout=5)


def test_still_on_the_nodes_own_single_threaded_executor(tmp_path, camera):
    """The node as ``axis_stream`` spins it (``run_nodes``: :func:`executor_for`, single-threaded): the coroutine
    answer is resumed by the worker's wake-up, and the executor serves other callbacks meanwhile."""
    ros = RosHarness()  # the probe's context and executor
    try:
        values = {"port": camera.port, **FAST_STREAM_PARAMS, "lazy": True}
        node = StreamNode(context=ros.context, parameter_overrides=[Parameter(k, value=v) for k, v in values.items()])
        executor = executor_for(node, ros.context)
        assert type(executor).__name__ == "SingleThreadedExecutor"
        executor.add_node(node)
        spinner = Spinner(executor, "stream-node").start()
        try:
            probe = ros.probe()
            still = Inbox()
            probe.create_subscription(CompressedImage, "still/compressed", still.on, LATCHED_QOS)
            client = probe.create_client(Trigger, "still/capture")
            at: list[float] = []
            fut = call_async(ros, client, at)
            ros.wait_for(fut.done, timeout=10)
            assert fut.result().success, fut.result().message
            ros.wait_for(lambda: still.count() == 1, timeout=5)
            assert spinner.alive()
            assert spinner.error is None
        finally:
            spinner.stop()
            spinner.wait_idle(2.0)
            node.destroy_node()
    finally:
        ros.close()


def test_console_still_button_and_key_show_the_stream_nodes_still(ros, camera):
    """The console's API as the page uses it (Still button: ``POST /api/still``, key P: ``POST /api/key``) against
    the real stream node and the simulator: the still it then serves is the stream node's, byte for byte."""
    import http.client  # noqa: PLC0415 - only this test
    import json  # noqa: PLC0415

    from axis_ptz_ros2.nodes.web_console import WebConsole  # noqa: PLC0415

    make_stream_node(ros, camera, lazy=True)
    console = ros.add(
        WebConsole(context=ros.context, parameter_overrides=[Parameter("port", value=0)])  # (loopback, no token)
    )
    probe = ros.probe()
    still = Inbox()
    probe.create_subscription(CompressedImage, "still/compressed", still.on, LATCHED_QOS)

    def call(method: str, path: str, body: object = None) -> tuple[int, bytes]:
        conn = http.client.HTTPConnection("127.0.0.1", console.server.port, timeout=60)
        try:
            data = json.dumps(body).encode() if body is not None else None
            conn.request(method, path, body=data, headers={"Content-Type": "application/json"} if data else {})
            r = conn.getresponse()
            return r.status, r.read()
        finally:
            conn.close()

    assert call("GET", "/video/still.jpg")[0] == 404  # none taken yet
    ros.wait_for(lambda: json.loads(call("GET", "/api/state")[1])["services"]["still"], timeout=10)
    status, data = call("POST", "/api/still", {})
    ans = json.loads(data)
    assert status == 200, ans
    assert ans["ok"], ans
    assert "704x576 px, compression 0" in ans["message"]
    ros.wait_for(lambda: still.count() == 1, timeout=5)
    published = bytes(still.msgs[0][1].data)
    status, jpeg_bytes = call("GET", "/video/still.jpg")
    assert status == 200
    assert jpeg_bytes == published  # passed through as the stream node published it
    assert decoded(jpeg_bytes).shape[:2] == (FULL[1], FULL[0])
    st = json.loads(call("GET", "/api/state")[1])["still"]
    assert (st["seq"], st["width"], st["height"], st["bytes"]) == (ans["seq"], *FULL, len(published))

    # key P does the same (the keyboard teleop's key map, as the page sends it)
    status, data = call("POST", "/api/key", {"key": "p"})
    ans2 = json.loads(data)
    assert status == 200, ans2
    assert "704x576 px" in ans2["message"]
    ros.wait_for(lambda: json.loads(call("GET", "/api/state")[1])["still"]["seq"] == ans["seq"] + 1, timeout=5)
    ros.wait_for(lambda: still.count() == 2, timeout=5)
    assert len(image_requests(camera)) == 2
