"""axis_stream over real DDS against the simulated camera (in-process, port 0).

Every parameter change goes through ``/axis_stream/set_parameters`` (what ``ros2 param set`` calls) and is
checked on the frames themselves (decoded size, measured rate, JPEG size); refusals are checked on the
simulator's request counters. Short timeouts/back-offs via parameters keep the file fast.
"""

from __future__ import annotations

import statistics
import threading
import time
from dataclasses import dataclass, field
from urllib.parse import parse_qsl

import cv2
import numpy as np
import pytest

pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rcl_interfaces.srv import GetParameters, SetParameters  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import CameraInfo, CompressedImage  # noqa: E402

from axis_ptz_interfaces.msg import PtzState, VideoParams  # noqa: E402
from axis_ptz_interfaces.srv import SetVideoParams  # noqa: E402
from axis_ptz_ros2.nodes.common import LATCHED_QOS, STREAM_QOS  # noqa: E402
from axis_ptz_ros2.nodes.stream_node import StreamNode  # noqa: E402
from axis_ptz_ros2.sim import FaultConfig, SimulatedCamera  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402
from tests.support.models import AXIS_214_ZOOM  # noqa: E402
from tests.support.sim import FAST_STREAM_PARAMS  # noqa: E402
from tests.support.stamps import sim_stamp  # noqa: E402
from tests.support.stream_node import make_stream_node  # noqa: E402
from tests.support.waiting import unchanged_for

pytestmark = pytest.mark.ros

FAST = FAST_STREAM_PARAMS


# the simulated camera: `sim` (one per module) and `camera` (reset per test) come from tests/ros/conftest.py


@dataclass
class Frame:
    t_rx: float  # monotonic at reception
    data: bytes
    seq: int
    t_sent: int


@dataclass
class Recorder:
    frames: list[Frame] = field(default_factory=list)
    infos: list[CameraInfo] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def on_image(self, msg: CompressedImage) -> None:
        data = bytes(msg.data)
        st = sim_stamp(data) or (-1, -1)
        with self.lock:
            self.frames.append(Frame(time.monotonic(), data, st[0], st[1]))

    def on_info(self, msg: CameraInfo) -> None:
        with self.lock:
            self.infos.append(msg)

    def since(self, t: float) -> list[Frame]:
        with self.lock:
            return [f for f in self.frames if f.t_rx >= t]

    def count(self) -> int:
        with self.lock:
            return len(self.frames)


def subscribe(ros: RosHarness, probe, info: bool = True) -> tuple[Recorder, list]:
    rec = Recorder()
    subs = [probe.create_subscription(CompressedImage, "image_raw/compressed", rec.on_image, STREAM_QOS)]
    if info:
        subs.append(probe.create_subscription(CameraInfo, "camera_info", rec.on_info, STREAM_QOS))
    return rec, subs


def decoded_size(data: bytes) -> tuple[int, int]:
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    assert img is not None, "frame does not decode"
    return img.shape[1], img.shape[0]


def rate(frames: list[Frame]) -> float:
    if len(frames) < 2:
        return 0.0
    return (len(frames) - 1) / (frames[-1].t_rx - frames[0].t_rx)


def connections(frames: list[Frame]) -> list[list[Frame]]:
    """Frames split by camera connection (the simulator's ``seq`` restarts with each connection)."""
    runs: list[list[Frame]] = []
    for f in (f for f in frames if f.t_sent > 0):
        if not runs or f.seq <= runs[-1][-1].seq:
            runs.append([])
        runs[-1].append(f)
    return runs


def camera_rate(frames: list[Frame]) -> float:
    """Frame rate the camera sent at: Σ Δseq / Σ Δt_sent within each connection. The camera's own counter and
    send stamps: a depth-1 subscriber missing a frame on a busy machine, or a reconnect gap, do not blur it."""
    runs = [r for r in connections(frames) if len(r) >= 2]
    n = sum(r[-1].seq - r[0].seq for r in runs)
    dt = sum((r[-1].t_sent - r[0].t_sent) / 1e9 for r in runs)
    return n / dt if dt > 0 else 0.0


def steady_rate(frames: list[Frame]) -> float:
    """The camera's frame rate while it runs: 1 / the median send interval (Δt_sent / Δseq of consecutive received
    frames within a connection). A stall of this process (the in-process simulator shares its interpreter) leaves
    one long interval and the simulator then goes on at its pace: the median ignores it, ``camera_rate`` does not."""
    steps = [
        (b.t_sent - a.t_sent) / 1e9 / (b.seq - a.seq)
        for run in connections(frames)
        for a, b in zip(run, run[1:], strict=False)
        if b.seq > a.seq
    ]
    return 1.0 / statistics.median(steps) if steps else 0.0


def mean_size(frames: list[Frame]) -> float:
    return sum(len(f.data) for f in frames) / len(frames)


def camera_kbps(frames: list[Frame], fps: float) -> float:
    """Bitrate the camera sent: mean JPEG size x the camera's frame rate (from its own stamps) in kbit/s. The
    probe's arrival times do not enter: a delivery gap or the burst after it does not change it."""
    return mean_size(frames) * fps * 8 / 1000


def set_params(ros: RosHarness, probe, **values):
    """Exactly what ``ros2 param set`` does: the node's SetParameters service."""
    client = probe.create_client(SetParameters, "/axis_stream/set_parameters")
    req = SetParameters.Request()
    req.parameters = [Parameter(k, value=v).to_parameter_msg() for k, v in values.items()]
    return ros.call(client, req).results


def get_params(ros: RosHarness, probe, *names: str) -> list:
    client = probe.create_client(GetParameters, "/axis_stream/get_parameters")
    req = GetParameters.Request()
    req.names = list(names)
    return ros.query(client, req).values


def video_count(camera: SimulatedCamera) -> int:
    return camera.request_counts.endpoints.get("video", 0)


def video_args(query: str) -> dict[str, str]:
    """The video parameters of one ``video.cgi`` request of the simulator's log."""
    return {k: v for k, v in parse_qsl(query) if k in ("resolution", "fps", "compression")}


def quiet_point(ros: RosHarness, node: StreamNode, camera: SimulatedCamera) -> tuple[int, int]:
    """(video requests logged, reader reconnects) read at a moment with no reconnect in flight: streaming, a
    frame less than half the stall limit old, nothing changed while reading. A reconnect (stall watchdog or
    error) counts itself before it sends its request, so from here on, reading the log before the counter,
    new requests <= new reconnects unless the node restarted the stream on purpose."""

    def read() -> tuple[int, int] | None:
        s0 = node._reader.stats()
        n0 = len(camera.request_counts.video_log)
        s1 = node._reader.stats()
        n1 = len(camera.request_counts.video_log)
        limit = node._reader.config.stall_limit(s1.params.fps)
        fresh = s1.frame_age_s is not None and s1.frame_age_s < limit / 2  # a stalled stream's frame is older
        if n0 == n1 and s0.reconnects == s1.reconnects and s1.state.value == "streaming" and fresh:
            return n0, s1.reconnects
        return None

    return ros.wait_for(read, timeout=5)


def assert_no_new_request_but_reconnects(
    node: StreamNode, camera: SimulatedCamera, point: tuple[int, int], want: dict[str, str]
) -> None:
    """Since ``point`` (``quiet_point``): the camera was asked for nothing but ``want``, and only to reconnect
    (a stall of this loaded process trips the 0.4 s watchdog, which reconnects with the unchanged values)."""
    n0, r0 = point
    new = [video_args(e.query) for e in camera.request_counts.video_log[n0:]]  # the log first, then the counter
    reconnects = node._reader.stats().reconnects - r0
    assert all(a == want for a in new), f"the camera saw a request for other values than {want}: {new}"
    assert len(new) <= reconnects, f"{len(new)} new video requests but {reconnects} reconnects: a restart"


def assert_never_repeated(frames: list[Frame]) -> None:
    """Each frame published once: send times strictly increasing, seq increasing within a connection."""
    ts = [f.t_sent for f in frames]
    assert all(b > a for a, b in zip(ts, ts[1:], strict=False)), "a frame was repeated or reordered"
    # the simulator numbers frames per connection: within a run seq goes up by one; a new run starts low
    runs = 1
    for a, b in zip(frames, frames[1:], strict=False):
        if b.seq <= a.seq:
            runs += 1
            assert b.seq <= 5, f"seq went back from {a.seq} to {b.seq} without a new connection"
    assert runs >= 2


# --------------------------------------------------------------------------------------------------------
def test_lazy_no_request_until_subscribed_and_stops_after_last_unsubscribes(ros, camera):
    node = make_stream_node(ros, camera, fps=15)
    probe = ros.probe()
    time.sleep(0.6)  # a window for a (wrong) stream request with nobody subscribed: the thing under test is none
    assert camera.request_counts.endpoints.get("video", 0) == 0, "streamed with nobody subscribed"
    assert node._reader.stats().state.value == "idle-lazy"
    rec, subs = subscribe(ros, probe, info=False)
    ros.wait_for(lambda: rec.count() >= 3, timeout=5)  # (how promptly is a speed figure: bench_stream)
    # one stream; a reconnect by the stall watchdog (a stalled machine, 0.4 s at 15 fps) is the only other kind,
    # and a stall noticed as the last subscriber leaves ends in idle, not in a reconnect: at most one per stall
    assert 1 <= video_count(camera) <= 1 + node._reader.stats().stalls
    # camera_info alone also keeps it streaming
    info_rec = Recorder()
    info_sub = probe.create_subscription(CameraInfo, "camera_info", info_rec.on_info, STREAM_QOS)
    probe.destroy_subscription(subs[0])
    ros.wait_for(lambda: node._image_pub.get_subscription_count() == 0, timeout=5)
    n = len(info_rec.infos)
    ros.wait_for(lambda: len(info_rec.infos) >= n + 5, timeout=5)
    assert node._reader.stats().state.value != "idle-lazy"
    probe.destroy_subscription(info_sub)
    ros.wait_for(lambda: node._reader.stats().state.value == "idle-lazy", timeout=3)
    # the camera notices the closed socket on its next write or two: then it sends nothing more (at 15 fps a
    # streaming camera never goes 0.5 s without a frame)
    ros.wait_for(unchanged_for(lambda: camera.frames_sent, 0.5), timeout=5, period=0.05)
    assert 1 <= video_count(camera) <= 1 + node._reader.stats().stalls, "one stream for image and camera_info"


def test_parameters_change_the_frames_live(ros, camera):
    # stall_timeout 1.0: the default watchdog
    node = make_stream_node(ros, camera, fps=20, resolution="704x576", compression=0, stall_timeout=1.0)
    probe = ros.probe()
    params_seen: list[VideoParams] = []
    probe.create_subscription(VideoParams, "video/params", params_seen.append, LATCHED_QOS)
    rec, _ = subscribe(ros, probe)
    ros.wait_for(lambda: rec.count() >= 10, timeout=5)
    assert decoded_size(rec.frames[-1].data) == (704, 576)
    size_c0 = len(rec.frames[-1].data)
    ros.wait_for(lambda: params_seen and params_seen[-1].source == "startup", timeout=3)

    # resolution
    (res,) = set_params(ros, probe, resolution="352x288")
    assert res.successful, res.reason
    t = time.monotonic()
    ros.wait_for(lambda: len(rec.since(t)) >= 3 and decoded_size(rec.since(t)[-1].data) == (352, 288), timeout=3)
    ros.wait_for(lambda: params_seen[-1].resolution == "352x288", timeout=2)
    assert params_seen[-1].source == "parameter"
    assert (params_seen[-1].width, params_seen[-1].height) == (352, 288)

    def infos_follow() -> bool:  # the newest image's camera_info may still be on its way: wait for it
        with rec.lock:
            later = [i for i in rec.infos if i.header.stamp.sec > 0][-3:]
        return len(later) == 3 and all((i.width, i.height) == (352, 288) for i in later)

    ros.wait_for(infos_follow, timeout=3)

    # fps: measured rate follows
    connects = node._reader.stats().connects
    (res,) = set_params(ros, probe, fps=5)
    assert res.successful, res.reason
    # the reader reconnected at 5 fps and a frame of the new stream is through: what follows is the new rate
    ros.wait_for(lambda: node._reader.stats().connects > connects and node._reader.stats().params.fps == 5, 5)
    frames = node._reader.stats().frames
    ros.wait_for(lambda: node._reader.stats().frames > frames, 5)
    t = time.monotonic()
    ros.wait_for(lambda: len(rec.since(t)) >= 8, timeout=8)
    rate_at_5 = steady_rate(rec.since(t))
    # the camera was asked for 5 fps and sends no faster. Rates here are the camera's median send interval, not
    # frames / time: now and then a stall of this process (the in-process simulator, the node and the probe share
    # one interpreter) holds the simulator's sender for up to ~1 s, seen on a quiet machine too, and the camera
    # does not burst to catch up, so a mean over the run mixes the stall into the rate
    assert video_args(camera.request_counts.video_log[-1].query)["fps"] == "5"
    assert 2.5 < rate_at_5 <= 5.0 * 1.25, rate_at_5

    # compression: JPEG size follows (same resolution, same view)
    assert all(r.successful for r in set_params(ros, probe, resolution="704x576", fps=20))
    (res,) = set_params(ros, probe, compression=90)
    assert res.successful, res.reason
    t = time.monotonic()
    ros.wait_for(lambda: len(rec.since(t)) >= 32, timeout=10)
    f = rec.since(t)[-1]
    assert decoded_size(f.data) == (704, 576)
    assert len(f.data) < 0.5 * size_c0
    # fps=20 again: the camera was asked for it, and it delivers clearly more than at 5 fps (this in-process
    # simulator shares one interpreter with the node and the probes, so its top rate depends on the load; the
    # out-of-process rate is measured by bench/bench_stream.py)
    assert "fps=20" in camera.request_counts.video_log[-1].query.split("&")
    # (a fresh-clone run measured frames / time at 5.04 fps here, at fps=20)
    assert steady_rate(rec.since(t)) > 1.25 * rate_at_5
    values = get_params(ros, probe, "fps", "resolution", "compression")
    assert (values[0].integer_value, values[1].string_value, values[2].integer_value) == (20, "704x576", 90)


def test_invalid_values_refused_with_reason_and_never_sent(ros, camera):
    node = make_stream_node(ros, camera, fps=10, resolution="352x288", compression=30)
    probe = ros.probe()
    rec, _ = subscribe(ros, probe)
    ros.wait_for(lambda: rec.count() >= 5, timeout=5)
    before = quiet_point(ros, node, camera)
    cases = {
        "resolution": ["640x480", "banana", "0x0"],
        "fps": [0, 31],
        "compression": [-1, 101],
    }
    for name, bad_values in cases.items():
        for bad in bad_values:
            (res,) = set_params(ros, probe, **{name: bad})
            assert not res.successful, f"{name}={bad!r} accepted"
            assert res.reason, f"{name}={bad!r} refused without a reason"
    (res,) = set_params(ros, probe, hostname="10.0.0.1")  # read-only connection setting
    assert not res.successful
    (res,) = set_params(ros, probe, resolution="640x480")
    assert "640x480" in res.reason
    assert "352x288" in res.reason  # the reason lists what the camera supports
    t = time.monotonic()
    ros.wait_for(lambda: len(rec.since(t)) >= 3, timeout=5)  # not interrupted by a refused value
    after = rec.since(t)
    assert all(decoded_size(f.data) == (352, 288) for f in after[-2:])
    valid = {"resolution": "352x288", "fps": "10", "compression": "30"}
    assert_no_new_request_but_reconnects(node, camera, before, valid)
    values = get_params(ros, probe, "fps", "resolution", "compression")
    assert (values[0].integer_value, values[1].string_value, values[2].integer_value) == (10, "352x288", 30)


def test_service_sets_several_atomically(ros, camera):
    node = make_stream_node(ros, camera, fps=10, resolution="704x576", compression=30)
    probe = ros.probe()
    rec, _ = subscribe(ros, probe)
    ros.wait_for(lambda: rec.count() >= 3, timeout=5)
    client = probe.create_client(SetVideoParams, "video/set_params")
    before = quiet_point(ros, node, camera)
    bad = ros.call(client, SetVideoParams.Request(fps=5, resolution="123x45", compression=80))
    assert not bad.success
    assert "123x45" in bad.message
    assert (bad.params.fps, bad.params.resolution, bad.params.compression) == (10, "704x576", 30)
    assert_no_new_request_but_reconnects(
        node, camera, before, {"resolution": "704x576", "fps": "10", "compression": "30"}
    )
    ok = ros.call(client, SetVideoParams.Request(fps=5, resolution="176x144", compression=80))
    assert ok.success, ok.message
    assert (ok.params.fps, ok.params.resolution, ok.params.compression) == (5, "176x144", 80)
    assert ok.params.source == "service"
    values = get_params(ros, probe, "fps", "resolution", "compression")
    assert (values[0].integer_value, values[1].string_value, values[2].integer_value) == (5, "176x144", 80)
    t = time.monotonic()

    def small() -> list[Frame]:
        return [f for f in rec.since(t) if decoded_size(f.data) == (176, 144)]

    ros.wait_for(lambda: len(small()) >= 7, timeout=5)
    assert decoded_size(rec.since(t)[-1].data) == (176, 144)
    # asked for all three at once; the camera's own stamps: no faster than asked, and (a stall of this process
    # makes the in-process simulator skip frames) not far below
    assert video_args(camera.request_counts.video_log[-1].query) == {
        "resolution": "176x144",
        "fps": "5",
        "compression": "80",
    }
    assert 2.5 < steady_rate(small()) <= 5.0 * 1.25
    keep = ros.call(client, SetVideoParams.Request(fps=0, resolution="", compression=-1))
    assert keep.success
    assert (keep.params.fps, keep.params.resolution, keep.params.compression) == (5, "176x144", 80)


def test_recovers_after_reboot_stall_and_garbage(ros, camera):
    node = make_stream_node(ros, camera, fps=20, resolution="176x144")
    probe = ros.probe()
    rec, _ = subscribe(ros, probe, info=False)
    ros.wait_for(lambda: rec.count() >= 5, timeout=5)

    # reboot: connections dropped, refused for 1 s, back on the same port
    camera.reboot(1.0)
    ros.wait_for(lambda: camera.rebooting, timeout=2)
    ros.wait_for(lambda: not camera.rebooting, timeout=5)
    back = time.monotonic()
    ros.wait_for(lambda: rec.since(back), timeout=3)  # (how soon is a speed figure: bench_stream's recovery)
    assert rec.since(back)[0].seq <= 5, "the first frame after the reboot is not from a new connection"

    # stall: the socket stays open but nothing comes; the watchdog reconnects
    camera.set_faults(stall_after_frames=3, stall_seconds=30.0)
    t = time.monotonic()
    ros.wait_for(lambda: node._reader.stats().stalls >= 2, timeout=5)
    camera.set_faults(FaultConfig())
    t = time.monotonic()
    ros.wait_for(lambda: len(rec.since(t)) >= 5, timeout=3)

    # garbage between parts and truncated frames: dropped and counted, the rest decodes
    camera.set_faults(garbage_between_parts=True, truncate_every=3)
    on_ns = time.time_ns()
    t = time.monotonic()
    ros.wait_for(lambda: len(rec.since(t)) >= 12, timeout=4)
    off_ns = time.time_ns()
    camera.set_faults(FaultConfig())
    s = node._reader.stats()
    assert s.parser.dropped_truncated >= 2
    assert s.parser.garbage_bytes > 0
    for f in rec.since(t):
        assert decoded_size(f.data) == (176, 144)
        # every third frame the camera sent while the fault was on was cut (one in flight when it was set, or
        # sent after it was cleared, is whole: a CI run failed on such a seq=6)
        if on_ns < f.t_sent < off_ns:
            assert f.seq % 3 != 0 or f.seq == -1, "a truncated frame was published"
    assert_never_repeated(rec.frames)
    assert s.reconnects >= 3


def test_auth_failure_reported_clearly_and_not_hammered(ros, tmp_path):
    cam = SimulatedCamera(host="127.0.0.1", port=0, auth="digest", user="root", password="right-pass").start()
    try:
        pw = tmp_path / "cred"
        pw.write_text("root:wrong-pass-XYZ\n")
        node = make_stream_node(ros, cam, password_file=str(pw), lazy=False, auth_retry=1.0)
        probe = ros.probe()
        diags: list[DiagnosticArray] = []
        probe.create_subscription(DiagnosticArray, "/diagnostics", diags.append, 10)
        ros.wait_for(lambda: any(ord(s.level) == 2 for d in diags for s in d.status), timeout=5)
        time.sleep(2.2)  # a measuring window (auth_retry 1 s): the thing under test is how often it tries in it
        counts = cam.request_counts
        status = [s for d in diags for s in d.status if s.name.endswith("MJPEG stream")][-1]
        assert ord(status.level) == 2
        assert "authentication failed" in status.message
        assert "401" in status.message
        text = status.message + " ".join(kv.value for kv in status.values)
        assert "wrong-pass-XYZ" not in text
        kv = {k.key: k.value for k in status.values}
        assert kv["state"] == "auth-failed"
        assert int(kv["auth failures"]) <= 4
        total = sum(counts.endpoints.values())
        assert total <= 12, f"camera hammered: {dict(counts.endpoints)}"  # ~3 attempts x (challenge + try)
        assert counts.status.get(401, 0) >= 2
        assert node._reader.stats().frames == 0
    finally:
        cam.stop()


def test_camera_info_matches_frames_and_follows_zoom(ros, camera):
    make_stream_node(ros, camera, fps=15, resolution="704x576", zoom=1.0)
    probe = ros.probe()
    rec, _ = subscribe(ros, probe)
    ros.wait_for(lambda: len(rec.infos) >= 5, timeout=5)
    with rec.lock:
        pairs = {(i.header.stamp.sec, i.header.stamp.nanosec): i for i in rec.infos}
    info = rec.infos[-1]
    assert (info.width, info.height) == (704, 576)
    assert info.header.frame_id == "axis_ptz_optical_frame"
    k_wide = AXIS_214_ZOOM.intrinsics(1.0, 704, 576)
    assert info.k[0] == pytest.approx(k_wide.fx)
    assert info.k[4] == pytest.approx(k_wide.fy)
    assert len(pairs) >= 3  # stamped per frame, not a frozen copy

    (res,) = set_params(ros, probe, resolution="352x288")
    assert res.successful
    ros.wait_for(lambda: rec.infos[-1].width == 352, timeout=3)
    half = rec.infos[-1]
    assert half.height == 288
    assert half.k[0] == pytest.approx(info.k[0] / 2, rel=1e-6)
    assert half.k[4] == pytest.approx(info.k[4] / 2, rel=1e-6)

    pub = probe.create_publisher(PtzState, "ptz/state", STREAM_QOS)
    state = PtzState(zoom=5000.0)
    want = AXIS_214_ZOOM.intrinsics(5000.0, 352, 288).fx
    ros.wait_for(lambda: (pub.publish(state), rec.infos[-1].k[0] == pytest.approx(want))[1], timeout=3)
    assert rec.infos[-1].k[0] > 5 * half.k[0]
    f = rec.frames[-1]
    assert decoded_size(f.data) == (rec.infos[-1].width, rec.infos[-1].height)


def test_bandwidth_budget_holds_the_bitrate(ros, camera):
    # stall_timeout 1.0: the default watchdog
    node = make_stream_node(ros, camera, fps=20, resolution="704x576", compression=0, stall_timeout=1.0)
    probe = ros.probe()
    params_seen: list[VideoParams] = []
    probe.create_subscription(VideoParams, "video/params", params_seen.append, LATCHED_QOS)
    rec, _ = subscribe(ros, probe, info=False)
    ros.wait_for(lambda: rec.count() >= 10, timeout=5)
    t = time.monotonic()
    ros.wait_for(lambda: len(rec.since(t)) >= 15, timeout=5)  # the full rate, from frames (a stall only lowers it)
    full = rec.since(t)
    # what the camera sends at full settings, from its own data: mean JPEG size x its steady frame rate (the
    # median send interval: a stall of this process, which the in-process simulator shares, must not lower the
    # reference, or 40 % of it would need more than compression)
    full_kbps = camera_kbps(full, steady_rate(full))
    budget = int(full_kbps * 0.4)
    (res,) = set_params(ros, probe, max_bitrate_kbps=budget)
    assert res.successful
    ros.wait_for(lambda: params_seen and params_seen[-1].source == "bandwidth_budget", timeout=5)
    assert params_seen[-1].max_bitrate_kbps == budget

    # measure 2 s of one setting, from 1 s after the controller's last switch (a cautious first step may be
    # followed by a climb after its 3 s hysteresis; a stall of the machine restarts its judgement): wait on
    # that condition, not on a fixed sleep
    def settled() -> bool:
        last = len(params_seen)
        time.sleep(3.0)  # a 3 s window in which the setting must not change: the condition is a quiet window
        return len(params_seen) == last

    ros.wait_for(settled, timeout=30)
    t = time.monotonic() - 2.0
    got = rec.since(t)
    assert len(got) >= 3
    # what the camera sent at the chosen setting (the controller meters that): mean size x its average rate from
    # its own stamps; the probe's arrival times, with their delivery gaps and bursts, do not enter
    kbps = camera_kbps(got, camera_rate(got))
    print(f"budget {budget} kbit/s (full {full_kbps:.0f}): held {kbps:.0f} kbit/s with {params_seen[-1]}")
    assert kbps <= budget * 1.1, f"{kbps:.0f} kbit/s over the budget {budget}"
    last = params_seen[-1]
    assert (last.compression, last.fps, last.resolution) != (0, 20, "704x576")
    # not stuck far below: 40 % of the full bitrate is reachable by compression alone, so the controller must
    # keep the frame rate and the resolution (the delivered rate of this in-process simulator depends on the
    # load, so the choice is checked, not a lower bound on the measured bitrate; bench_stream measures that)
    steps = [(p.resolution, p.fps, p.compression, p.max_bitrate_kbps) for p in params_seen]
    if node._reader.stats().stalls == 0:
        assert (last.fps, last.resolution) == (20, "704x576"), f"stepped too far: {steps}"
    else:  # a stall of this process (the in-process simulator shares its GIL) ends in a burst of frames that the
        # meter reads as over the budget, one step more is then right by what was measured: keep the resolution
        assert last.resolution == "704x576", f"stepped too far after a stall: {steps}"
    # switched off: back to the request
    (res,) = set_params(ros, probe, max_bitrate_kbps=0)
    assert res.successful
    ros.wait_for(lambda: params_seen[-1].compression == 0 and params_seen[-1].fps == 20, timeout=3)


def test_video_params_carry_the_cameras_resolution_list(ros: RosHarness, camera: SimulatedCamera) -> None:
    """The latched video/params tells the teleops which sizes the camera offers (read from param.cgi)."""
    make_stream_node(ros, camera)
    probe = ros.probe("res_probe")
    got: list[VideoParams] = []
    probe.create_subscription(VideoParams, "video/params", got.append, LATCHED_QOS)
    rec, _ = subscribe(ros, probe)  # a subscriber makes the node contact the camera and read its list
    ros.wait_for(lambda: any(m.available_resolutions for m in got), timeout=10)
    last = [m for m in got if m.available_resolutions][-1]
    assert last.source == "startup", "learning the list changes no value, so the cause stays"
    # the 214 persona lists 4CIF,2CIFEXP,2CIF,CIF,QCIF (PAL): four distinct sizes, smallest first
    assert list(last.available_resolutions) == ["176x144", "352x288", "704x288", "704x576"]
