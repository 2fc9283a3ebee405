"""The still on a link, over real DDS against the simulated camera: the live video goes on while the stream node
waits for a reader's acknowledgement of a still, and the weak-link profile (``config/fastdds_weak_link.xml``) paces
the still's writer (with ``RMW_FASTRTPS_PUBLICATION_MODE=AUTO``) or, without AUTO, leaves the node running without
stills and saying why."""

from __future__ import annotations

import contextlib
import math
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("rclpy")

from rclpy.node import Node  # noqa: E402
from sensor_msgs.msg import CompressedImage  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from axis_ptz_ros2.nodes.common import LATCHED_QOS, STREAM_QOS  # noqa: E402
from axis_ptz_ros2.nodes.stream_still import UNAVAILABLE  # noqa: E402
from axis_ptz_ros2.streaming.still import BUSY  # noqa: E402
from tests.ros.processes import node_process  # noqa: E402
from tests.support.fastdds_profile import PROFILE, flow_controllers, pace  # noqa: E402
from tests.support.stream_node import make_stream_node  # noqa: E402

pytestmark = pytest.mark.ros

BIN = Path(sys.executable).parent

#: a reader of still/compressed in a process of its own, which the test then stops (SIGSTOP): it never acknowledges
SILENT_READER = textwrap.dedent(
    """
    import time, rclpy
    from rclpy.node import Node
    from sensor_msgs.msg import CompressedImage
    from axis_ptz_ros2.nodes.common import LATCHED_QOS
    rclpy.init()
    node = Node("silent_still_reader")
    node.create_subscription(CompressedImage, "still/compressed", lambda _m: None, LATCHED_QOS)
    print("ready", flush=True)
    while True:
        rclpy.spin_once(node, timeout_sec=0.1)
    """
)


class Counter:
    """Messages of one topic, counted with their arrival time."""

    def __init__(self) -> None:
        self.times: list[float] = []
        self._lock = threading.Lock()

    def on(self, _msg: object) -> None:
        with self._lock:
            self.times.append(time.monotonic())

    def between(self, t0: float, t1: float) -> int:
        with self._lock:
            return sum(1 for t in self.times if t0 <= t < t1)


def test_live_video_goes_on_while_a_reader_has_not_acknowledged_the_still(ros, camera):
    """A reader that never acknowledges (its process stopped) keeps the node waiting for the still's crossing (a
    second request is refused meanwhile). The wait must not hold the GIL: rclpy's ``wait_for_all_acked`` does while
    it waits, and in 0.2 s waits the node's frame path (and this in-process probe) ran at a few per cent."""
    node = make_stream_node(ros, camera, fps=10, resolution="352x288", compression=50, lazy=False)
    probe = ros.probe()
    live = Counter()
    probe.create_subscription(CompressedImage, "image_raw/compressed", live.on, STREAM_QOS)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    with node_process([sys.executable, "-c", SILENT_READER], env=env) as reader:
        assert reader.stdout is not None
        assert reader.stdout.readline().strip() == b"ready"
        assert node._still.pub is not None
        ros.wait_for(lambda: node._still.pub.get_subscription_count() >= 1, timeout=10)
        ros.wait_for(lambda: len(live.times) >= 10, timeout=10)
        os.kill(reader.pid, signal.SIGSTOP)
        try:
            client = probe.create_client(Trigger, "still/capture")
            assert client.wait_for_service(timeout_sec=10)
            t0 = time.monotonic()
            fut = client.call_async(Trigger.Request())
            ros.wait_for(fut.done, timeout=10)
            assert fut.result().success, fut.result().message
            t1 = time.monotonic()
            before = live.between(t0 - 2.0, t0)
            assert before >= 10, f"{before} live frames in the 2 s before the request"
            # the next 10 live frames: at the rate before they take ~2 s x 10 / before; with the GIL held by the
            # wait, the 10 s the node waits for the stopped reader were not enough
            ros.wait_for(lambda: live.between(t1, math.inf) >= 10, timeout=8.0)
            took = sorted(t for t in list(live.times) if t >= t1)[9] - t1
            rate_before, rate_during = before / 2.0, 10 / took
            assert rate_during >= 0.6 * rate_before, (
                f"live {rate_during:.1f} fps while waiting, {rate_before:.1f} before"
            )
            second = client.call_async(Trigger.Request())
            ros.wait_for(second.done, timeout=10)
            assert (second.result().success, second.result().message) == (False, BUSY), "the wait had ended"
        finally:
            os.kill(reader.pid, signal.SIGCONT)


@contextlib.contextmanager
def stream_process(ros, camera, mode: str) -> Iterator[tuple[subprocess.Popen[bytes], Node, Counter]]:  # noqa: ANN001
    """``axis_stream`` as a process with the weak-link profile and ``RMW_FASTRTPS_PUBLICATION_MODE=mode``, streaming
    352x288 at 10 fps to a probe: (the process, the probe, the live images' counter) once 5 have arrived."""
    argv = [str(BIN / "axis_stream"), "--ros-args", "-p", f"port:={camera.port}", "-p", "fps:=10",
            "-p", "resolution:=352x288", "-p", "lazy:=false"]  # fmt: skip
    env = dict(os.environ, FASTRTPS_DEFAULT_PROFILES_FILE=str(PROFILE), RMW_FASTRTPS_PUBLICATION_MODE=mode)
    with node_process(argv, env=env) as proc:
        probe = ros.probe()
        live = Counter()
        probe.create_subscription(CompressedImage, "image_raw/compressed", live.on, STREAM_QOS)
        ros.wait_for(lambda: len(live.times) >= 5, timeout=20)
        yield proc, probe, live


def call_still(ros, probe: Node) -> Trigger.Response:  # noqa: ANN001
    """``still/capture`` once; its answer."""
    client = probe.create_client(Trigger, "still/capture")
    assert client.wait_for_service(timeout_sec=10)
    fut = client.call_async(Trigger.Request())
    ros.wait_for(fut.done, timeout=10)
    return fut.result()


def test_weak_link_profile_paces_the_still_and_the_live_video_goes_on(ros, camera):
    """``axis_stream`` with the weak-link profile and AUTO: the still arrives whole, no sooner than its bytes at
    the profile's pace allow (unpaced it takes milliseconds on loopback), and live frames arrive while it crosses."""
    (controller,) = flow_controllers()
    nbytes, period_s = pace(controller)
    with stream_process(ros, camera, "AUTO") as (proc, probe, live):
        still = Counter()
        sizes: list[int] = []
        probe.create_subscription(
            CompressedImage, "still/compressed", lambda m: (sizes.append(len(m.data)), still.on(m)), LATCHED_QOS
        )
        t0 = time.monotonic()
        res = call_still(ros, probe)
        assert res.success, res.message
        ros.wait_for(lambda: len(still.times) == 1, timeout=20)
        took = still.times[0] - t0
        assert took >= 0.8 * sizes[0] * period_s / nbytes, f"{sizes[0]} bytes in {took:.2f} s: not paced"
        assert live.between(t0, still.times[0]) >= 1, "no live frame while the still crossed"
        assert proc.poll() is None


def test_weak_link_profile_without_auto_leaves_the_node_running_without_stills(ros, camera):
    """Without AUTO rmw_fastrtps makes the still's writer synchronous and Fast DDS refuses its flow controller: the
    node logs why, keeps streaming, and answers every still request with the reason."""
    with stream_process(ros, camera, "SYNCHRONOUS") as (proc, probe, live):
        res = call_still(ros, probe)
        assert not res.success
        assert res.message.startswith(UNAVAILABLE), res.message
        assert "RMW_FASTRTPS_PUBLICATION_MODE=AUTO" in res.message
        n = len(live.times)
        ros.wait_for(lambda: len(live.times) >= n + 3, timeout=10)
        assert proc.poll() is None
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=15)
    assert UNAVAILABLE.encode() in out, out.decode(errors="replace")[-2000:]
