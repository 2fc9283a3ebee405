"""axis_stream in H.264 mode over real DDS against the simulated camera (in-process, port 0).

A probe decodes ``image_raw/ffmpeg`` with PyAV (FFmpeg's h264 decoder, nobody's code here) and compares the
pictures with the simulator's own compression-0 JPEG of the same view; parameter changes go through the node's
SetParameters service (what ``ros2 param set`` calls); refusals are checked on the simulator's request log.
"""

from __future__ import annotations

import statistics
import threading
import time
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import parse_qsl

import av
import av.error
import cv2
import numpy as np
import pytest

pytest.importorskip("rclpy")

from ffmpeg_image_transport_msgs.msg import FFMPEGPacket  # noqa: E402
from foxglove_msgs.msg import CompressedVideo  # noqa: E402
from rcl_interfaces.srv import SetParameters, SetParametersAtomically  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import CompressedImage, Image  # noqa: E402

from axis_ptz_interfaces.msg import LinkFeedback  # noqa: E402
from axis_ptz_ros2.media import annexb  # noqa: E402
from axis_ptz_ros2.media.annexb import NalType  # noqa: E402
from axis_ptz_ros2.nodes.common import FEEDBACK_QOS, STREAM_QOS, VIDEO_QOS  # noqa: E402
from axis_ptz_ros2.nodes.link_monitor import LinkMonitorNode  # noqa: E402
from axis_ptz_ros2.nodes.republish import RepublishNode  # noqa: E402
from axis_ptz_ros2.nodes.stream_node import StreamNode  # noqa: E402
from axis_ptz_ros2.sim import SimulatedCamera  # noqa: E402
from axis_ptz_ros2.sim.persona import AXIS_214_PICTURE  # noqa: E402
from axis_ptz_ros2.streaming.h264 import FFMPEG_ENCODING  # noqa: E402
from tests.support.adapter_watch import wait_for_climb  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402
from tests.support.idr import idr_granted_at_once  # noqa: E402
from tests.support.picture import psnr_db  # noqa: E402
from tests.support.sim import FAST_STREAM_PARAMS  # noqa: E402

pytestmark = pytest.mark.ros

FAST = FAST_STREAM_PARAMS
H264 = {"codec": "h264", "resolution": "704x576", "fps": 15}


@dataclass
class Packet:
    t_rx: float
    data: bytes
    pts: int
    key: bool
    width: int
    height: int
    encoding: str
    stamp_ns: int
    frame_id: str
    rx_ns: int = 0  # wall clock at receipt


@dataclass
class H264Recorder:
    """FFMPEGPacket and CompressedVideo messages as received."""

    packets: list[Packet] = field(default_factory=list)
    foxglove: list[tuple[int, bytes, str, str]] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def on_packet(self, msg: FFMPEGPacket) -> None:
        p = Packet(
            time.monotonic(),
            bytes(msg.data),
            int(msg.pts),
            bool(msg.flags & 1),
            int(msg.width),
            int(msg.height),
            str(msg.encoding),
            msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec,
            str(msg.header.frame_id),
            time.time_ns(),
        )
        with self.lock:
            self.packets.append(p)

    def on_foxglove(self, msg: CompressedVideo) -> None:
        stamp = msg.timestamp.sec * 1_000_000_000 + msg.timestamp.nanosec
        with self.lock:
            self.foxglove.append((stamp, bytes(msg.data), str(msg.format), str(msg.frame_id)))

    def since(self, t: float) -> list[Packet]:
        with self.lock:
            return [p for p in self.packets if p.t_rx >= t]

    def count(self) -> int:
        with self.lock:
            return len(self.packets)


def make_node(ros: RosHarness, camera: SimulatedCamera, **params: object) -> StreamNode:
    values = {"port": camera.port, **FAST, **params}
    overrides = [Parameter(k, value=v) for k, v in values.items()]
    return ros.add(StreamNode(context=ros.context, parameter_overrides=overrides))


def subscribe(probe, foxglove: bool = False) -> tuple[H264Recorder, list]:  # noqa: ANN001
    rec = H264Recorder()
    subs = [probe.create_subscription(FFMPEGPacket, "image_raw/ffmpeg", rec.on_packet, STREAM_QOS)]
    if foxglove:
        subs.append(probe.create_subscription(CompressedVideo, "image_raw/foxglove", rec.on_foxglove, STREAM_QOS))
    return rec, subs


def set_params(ros: RosHarness, probe, **values: object):  # noqa: ANN001, ANN201
    client = probe.create_client(SetParameters, "/axis_stream/set_parameters")
    req = SetParameters.Request()
    req.parameters = [Parameter(k, value=v).to_parameter_msg() for k, v in values.items()]
    return ros.call(client, req).results


def video_args(query: str) -> dict[str, str]:
    return {k: v for k, v in parse_qsl(query) if k in ("resolution", "fps", "compression")}


def decode_all(packets: list[Packet]) -> list[tuple[Packet, np.ndarray]]:
    """PyAV's h264 decoder from the first IDR on; (packet, BGR picture) for each that decodes."""
    ctx = av.CodecContext.create("h264", "r")
    out = []
    started = False
    for p in packets:
        started = started or p.key
        if not started:
            continue
        for frame in ctx.decode(av.Packet(p.data)):
            out.append((p, frame.to_ndarray(format="bgr24")))
    return out


# --------------------------------------------------------------------------------------------------------
def test_h264_frames_decode_at_full_size_and_quality(ros: RosHarness, camera: SimulatedCamera) -> None:
    node = make_node(ros, camera, **H264, h264_bitrate_kbps=1500)
    probe = ros.probe()
    rec, _ = subscribe(probe, foxglove=True)
    ros.wait_for(lambda: rec.count() >= 45, timeout=10)
    packets = rec.since(0.0)
    # the camera was asked for its best quality at the requested size and rate
    assert video_args(camera.request_counts.video_log[-1].query) == {
        "resolution": "704x576",
        "fps": "15",
        "compression": "0",
    }
    decoded = decode_all(packets)
    assert len(decoded) >= 30
    assert all(img.shape == (576, 704, 3) for _p, img in decoded)
    # the camera's own picture of this view before sensor noise and compression (issue 21's PSNR reference) ...
    clean = AXIS_214_PICTURE.soften(camera.renderer.render(0.0, 0.0, 1.0, 704, 576), 1.0)
    # ... and what it sends at compression 0 (one noisy frame of the view)
    jpeg0 = cv2.imdecode(np.frombuffer(camera.frame_jpeg(704, 576, 0), np.uint8), cv2.IMREAD_COLOR)
    scores = [psnr_db(img, clean) for _p, img in decoded[15:]]  # after the first second (still camera)
    vs_jpeg = [psnr_db(img, jpeg0) for _p, img in decoded[15:]]
    print(  # noqa: T201
        f"PSNR median {statistics.median(scores):.1f} dB (min {min(scores):.1f}) against the picture before noise, "
        f"{statistics.median(vs_jpeg):.1f} dB against a compression-0 JPEG, {len(scores)} frames"
    )
    assert statistics.median(scores) >= 35.0
    # age at the subscriber from the JPEG's arrival at the stream node (the SEI: the header's stamp), on loopback
    ages = [(p.rx_ns - (annexb.extract_capture_stamp(p.data) or p.rx_ns)) / 1e6 for p in packets]
    print(f"age camera -> subscriber: median {statistics.median(ages):.1f} ms, max {max(ages):.1f} ms")  # noqa: T201
    # one access unit per message, SPS/PPS with every IDR, flags bit 0 = IDR, pts strictly increasing
    for p in packets:
        types = annexb.nal_types(p.data)
        assert p.key == (NalType.IDR in types)
        if p.key:
            assert types.index(NalType.SPS) < types.index(NalType.PPS) < types.index(NalType.IDR)
        assert sum(t in (NalType.IDR, NalType.SLICE) for t in types) == 1
        assert (p.width, p.height, p.encoding, p.frame_id) == (704, 576, FFMPEG_ENCODING, "axis_ptz_optical_frame")
        # header stamp: the frame's capture time (arrival from the camera), never in the future
        assert 0 < p.stamp_ns <= time.time_ns()
        assert annexb.extract_capture_stamp(p.data) == p.stamp_ns  # the SEI holds the header's stamp (arrival)
    pts = [p.pts for p in packets]
    assert all(b > a for a, b in zip(pts, pts[1:], strict=False))
    # x264's periodic intra refresh in High profile (issue 39): IDRs only on demand (the new subscriber's two),
    # none periodic; the refresh waves' recovery points (SPS/PPS, recovery-point SEI) are not flagged key
    keys = [p for p in packets if p.key]
    stats = node._stage.stats
    assert 1 <= len(keys) <= stats.encoder_opens + stats.idr_requests, (len(keys), stats)
    assert annexb.find_sps(keys[0].data).profile_idc == 100  # type: ignore[union-attr]
    assert any(NalType.SPS in annexb.nal_types(p.data) and not p.key for p in packets)  # a wave began
    # the foxglove message carries the same bytes with the same stamp
    by_stamp = {p.stamp_ns: p.data for p in packets}
    with rec.lock:
        fox = list(rec.foxglove)
    matched = [(data, fmt, fid) for s, data, fmt, fid in fox if s in by_stamp]
    assert len(matched) >= 20
    for (data, fmt, fid), s in zip(matched, [s for s, *_ in fox if s in by_stamp], strict=True):
        assert data == by_stamp[s]
        assert fmt == "h264"
        assert fid == "axis_ptz_optical_frame"
    # one encoder for both messages; made again only for the picture rate the camera really delivers (a loaded
    # machine's simulator makes fewer than the 15/s asked, and the encoder follows it: a fresh-clone CI run did)
    stats = node._stage.stats
    assert stats.encoder_opens == 1 + stats.fps_reopens, stats


def test_lazy_no_encoder_without_h264_subscriber_mjpeg_unaffected(ros: RosHarness, camera: SimulatedCamera) -> None:
    node = make_node(ros, camera, **H264)
    probe = ros.probe()
    jpegs: list[bytes] = []
    probe.create_subscription(
        CompressedImage, "image_raw/compressed", lambda m: jpegs.append(bytes(m.data)), STREAM_QOS
    )
    ros.wait_for(lambda: len(jpegs) >= 10, timeout=5)
    assert node._stage.stats.encoder_opens == 0
    assert not node._stage.encoder_open
    assert node._stage.stats.frames == 0
    assert jpegs[-1][:2] == b"\xff\xd8"  # the camera's bytes, as in MJPEG mode
    rec, subs = subscribe(probe)
    ros.wait_for(lambda: rec.count() >= 5, timeout=5)
    assert node._stage.encoder_open
    n = len(jpegs)
    for s in subs:
        probe.destroy_subscription(s)
    ros.wait_for(lambda: not node._stage.encoder_open, timeout=3)  # the last H.264 subscriber left: no encoder
    ros.wait_for(lambda: len(jpegs) >= n + 10, timeout=5)  # MJPEG goes on
    assert not node._stage.encoder_open


def test_mjpeg_mode_never_encodes_and_switches_live(ros: RosHarness, camera: SimulatedCamera) -> None:
    node = make_node(ros, camera, resolution="352x288", fps=15)
    probe = ros.probe()
    rec, _ = subscribe(probe)
    ros.wait_for(lambda: node._pipeline.starts.subscribers == 1, timeout=5)
    time.sleep(1.0)  # a window for a (wrong) stream request or encoder: the thing under test is that none comes
    # codec mjpeg: an H.264 subscriber alone is nobody to stream for (lazy): no request, no encoder
    assert camera.request_counts.endpoints.get("video", 0) == 0
    assert rec.count() == 0
    assert node._stage.stats.encoder_opens == 0
    (res,) = set_params(ros, probe, codec="h264")
    assert res.successful, res.reason
    ros.wait_for(lambda: rec.count() >= 3, timeout=5)
    got = rec.since(0.0)
    assert got[0].key
    assert (got[0].width, got[0].height) == (352, 288)
    assert video_args(camera.request_counts.video_log[-1].query)["compression"] == "0"


def test_late_joiner_gets_an_idr_within_a_second(ros: RosHarness, camera: SimulatedCamera) -> None:
    node = make_node(ros, camera, **{**H264, "fps": 30}, h264_keyframe_interval=600)
    probe = ros.probe()
    first, _ = subscribe(probe)
    ros.wait_for(lambda: first.count() >= 40, timeout=10)
    requests = node._stage.stats.idr_requests
    late_probe = ros.probe("late")
    late, _ = subscribe(late_probe)
    ros.wait_for(lambda: late.count() >= 1, timeout=5)
    ros.wait_for(lambda: any(p.key for p in late.since(0.0)), timeout=2)
    got = late.since(0.0)
    first_key = next(p for p in got if p.key)
    assert first_key.t_rx - got[0].t_rx <= 1.0
    assert node._stage.stats.idr_requests > requests  # asked for on the new subscription, not only periodic
    assert decode_all(got)  # and it decodes from there


def test_bitrate_parameter_changes_the_message_sizes(ros: RosHarness, camera: SimulatedCamera) -> None:
    make_node(ros, camera, **H264, h264_bitrate_kbps=3000, h264_max_bitrate_kbps=3000)
    probe = ros.probe()
    rec, _ = subscribe(probe)
    ros.wait_for(lambda: rec.count() >= 30, timeout=10)
    big = [len(p.data) for p in rec.since(0.0)[10:] if not p.key]
    (res,) = set_params(ros, probe, h264_bitrate_kbps=300)
    assert res.successful, res.reason
    t = time.monotonic()
    ros.wait_for(lambda: len(rec.since(t)) >= 30, timeout=10)
    small = [len(p.data) for p in rec.since(t)[10:] if not p.key]  # the first may be encoded before the change
    # the access units follow the bitrate: ~12.5 kB a picture at 3000 kbit/s and 15 fps, ~1.25 kB at 300
    assert statistics.median(small) < 0.3 * statistics.median(big), (big, small)


def test_resolution_change_mid_stream_starts_with_an_idr_of_the_new_size(
    ros: RosHarness, camera: SimulatedCamera
) -> None:
    node = make_node(ros, camera, **H264)
    probe = ros.probe()
    rec, _ = subscribe(probe)
    ros.wait_for(lambda: rec.count() >= 10, timeout=10)
    (res,) = set_params(ros, probe, resolution="352x288")
    assert res.successful, res.reason
    ros.wait_for(lambda: sum(p.width == 352 for p in rec.since(0.0)) >= 5, timeout=10)
    packets = rec.since(0.0)
    first_small = next(p for p in packets if p.width == 352)
    before = packets[packets.index(first_small) - 1]
    if first_small.pts == before.pts + 1:  # nothing lost in between: the new size's first access unit is an IDR
        assert first_small.key
    else:  # its IDR was replaced in the keep-last history before delivery (a loaded host): judge the next one,
        # asked for as a viewer that lost one does (IDRs come only on demand)
        assert before.width == 704, "a lost access unit, but the last one received before it was not the old size"
        node._stage.request_idr()
        ros.wait_for(lambda: any(p.width == 352 and p.key for p in rec.since(0.0)), timeout=10)
        packets = rec.since(0.0)
        first_small = next(p for p in packets if p.width == 352 and p.key)
    sps = annexb.find_sps(first_small.data)
    assert sps is not None
    assert (sps.width, sps.height) == (352, 288)
    assert all(p.width == 352 for p in packets[packets.index(first_small) :])  # no old-size frame after it
    kept = packets[: packets.index(before) + 1] + packets[packets.index(first_small) :]  # all, unless one was lost
    sizes = [img.shape[:2] for _p, img in decode_all(kept)]  # one decoder across the change
    assert (576, 704) in sizes
    assert sizes[-1] == (288, 352)


def test_invalid_codec_values_refused_with_reason_never_sent(ros: RosHarness, camera: SimulatedCamera) -> None:
    node = make_node(ros, camera, **H264)
    probe = ros.probe()
    rec, _ = subscribe(probe)
    ros.wait_for(lambda: rec.count() >= 5, timeout=5)
    n0 = len(camera.request_counts.video_log)
    (res,) = set_params(ros, probe, codec="h265")
    assert not res.successful
    assert "mjpeg, h264" in res.reason
    for name, bad in (("h264_bitrate_kbps", 10), ("h264_bitrate_kbps", 10**6), ("h264_keyframe_interval", 0)):
        (res,) = set_params(ros, probe, **{name: bad})
        assert not res.successful, f"{name}={bad} accepted"
        assert res.reason
    (res,) = set_params(ros, probe, h264_preset="placebo")
    assert not res.successful
    assert "superfast" in res.reason
    t = time.monotonic()
    ros.wait_for(lambda: len(rec.since(t)) >= 5, timeout=5)  # not interrupted
    valid = {"resolution": "704x576", "fps": "15", "compression": "0"}
    new = [video_args(e.query) for e in camera.request_counts.video_log[n0:]]
    assert all(a == valid for a in new), new  # the camera saw nothing of the refused values
    assert node.get_parameter("codec").value == "h264"


def test_camera_reboot_resumes_with_an_idr_and_no_old_frame(ros: RosHarness, camera: SimulatedCamera) -> None:
    make_node(ros, camera, **H264)
    probe = ros.probe()
    rec, _ = subscribe(probe)
    ros.wait_for(lambda: rec.count() >= 10, timeout=10)
    camera.reboot(1.0)
    ros.wait_for(lambda: camera.rebooting, timeout=2)
    ros.wait_for(lambda: not camera.rebooting, timeout=5)
    back, back_wall = time.monotonic(), time.time_ns()
    ros.wait_for(lambda: rec.since(back), timeout=1.5)
    ros.wait_for(lambda: len(rec.since(back)) >= 5, timeout=3)
    after = rec.since(back)
    resumed = after[0].t_rx - back
    assert after[0].key, "the first access unit after the camera came back is not an IDR"
    for p in after:
        cam_ns = annexb.extract_capture_stamp(p.data)
        assert cam_ns is not None
        assert cam_ns > back_wall - 200_000_000, "a frame from before the reboot"
    pts = [p.pts for p in rec.since(0.0)]
    assert all(b > a for a, b in zip(pts, pts[1:], strict=False))
    assert decode_all(after)
    print(f"frames resumed {resumed:.2f} s after the camera was back")  # noqa: T201


def test_link_feedback_lowers_the_encoders_bitrate(ros: RosHarness, camera: SimulatedCamera) -> None:
    """A consumer that receives a fraction of the frames: the budget goes to the encoder (smaller messages), the
    camera is not asked for anything else (compression 0 stays)."""
    node = make_node(ros, camera, **H264, h264_bitrate_kbps=1500)
    probe = ros.probe()
    rec, _ = subscribe(probe)
    ros.wait_for(lambda: rec.count() >= 45, timeout=10)  # 3 s: the meter's window is full
    t0 = time.monotonic()
    ros.wait_for(lambda: len(rec.since(t0)) >= 30, timeout=10)
    before = statistics.median(len(p.data) for p in rec.since(t0) if not p.key)
    n0 = len(camera.request_counts.video_log)
    pub = probe.create_publisher(LinkFeedback, "video/feedback", FEEDBACK_QOS)
    report = LinkFeedback(consumer="/operator", frames=10, fps=5.0, kbps=400.0, window_s=2.0)
    report.delay_p95_s, report.delay_min_s, report.gap_s = 0.02, 0.01, 0.1
    pub.publish(report)
    ros.wait_for(lambda: node._video.h264_settings().bitrate_kbps <= 0.8 * 400 + 1, timeout=3)
    t1 = time.monotonic() + 0.5
    ros.wait_for(lambda: len(rec.since(t1)) >= 30, timeout=10)
    after = statistics.median(len(p.data) for p in rec.since(t1) if not p.key)
    assert after < 0.6 * before, (before, after)
    assert node._video.current.compression == 0
    assert all(video_args(e.query)["compression"] == "0" for e in camera.request_counts.video_log[n0:])


def test_republisher_decodes_h264_to_image(ros: RosHarness, camera: SimulatedCamera) -> None:
    make_node(ros, camera, **H264)
    rep = ros.add(RepublishNode(context=ros.context, parameter_overrides=[Parameter("input", value="h264")]))
    probe = ros.probe()
    images: list[Image] = []
    probe.create_subscription(Image, "image_raw", images.append, STREAM_QOS)
    ros.wait_for(lambda: len(images) >= 5, timeout=10)
    img = images[-1]
    assert (img.width, img.height, img.encoding, img.step) == (704, 576, "bgr8", 704 * 3)
    assert rep.subscribed
    assert rep.decoded >= 5


def test_link_monitor_decodes_and_its_loss_report_brings_an_idr(ros: RosHarness, camera: SimulatedCamera) -> None:
    node = make_node(ros, camera, **{**H264, "fps": 30}, h264_keyframe_interval=600)
    monitor = ros.add(LinkMonitorNode(context=ros.context, parameter_overrides=[Parameter("codec", value="h264")]))
    probe = ros.probe()
    reports: list[LinkFeedback] = []
    probe.create_subscription(LinkFeedback, "video/feedback", reports.append, FEEDBACK_QOS)
    ros.wait_for(lambda: any(r.frames > 5 for r in reports), timeout=10)
    assert monitor.receiver is not None
    assert monitor.receiver.stats.pictures > 5
    assert reports[-1].header.frame_id.endswith("image_raw/ffmpeg")
    # a consumer that lost sync says so: the stream node sends an IDR at once, not at the next periodic one
    rec, _ = subscribe(probe)
    ros.wait_for(lambda: rec.count() >= 5, timeout=5)
    ros.wait_for(
        lambda: idr_granted_at_once(node._stage, node._pipeline.starts), timeout=10
    )  # past the new subscription's IDRs
    before = node._stage.stats.idr_requests
    pub = probe.create_publisher(LinkFeedback, "video/feedback", FEEDBACK_QOS)
    msg = LinkFeedback(consumer="/lossy", frames=10, fps=10.0, kbps=500.0, window_s=1.0, decode_errors=3)
    t = time.monotonic()
    pub.publish(msg)
    ros.wait_for(lambda: node._stage.stats.idr_requests > before, timeout=2)
    ros.wait_for(lambda: any(p.key for p in rec.since(t)), timeout=1)


def test_link_monitor_reports_a_loss_at_once_not_at_its_period(ros: RosHarness, camera: SimulatedCamera) -> None:
    """The stream node's own access units replayed to a monitor (report period 5 s) over DDS, one left out: the
    monitor reports the loss within a fraction of a second (the stream node answers with an IDR), not 5 s later."""
    make_node(ros, camera, **{**H264, "fps": 30}, h264_keyframe_interval=600)
    probe = ros.probe()
    rec, _ = subscribe(probe)
    ros.wait_for(lambda: sum(1 for p in rec.since(0) if p.key) >= 1 and len(rec.since(0)) >= 12, timeout=10)
    packets = rec.since(0)
    first = next(i for i, p in enumerate(packets) if p.key)
    packets = packets[first : first + 10]
    assert len(packets) == 10
    overrides = {"codec": "h264", "h264_topic": "lossy/ffmpeg", "feedback_topic": "lossy/feedback", "period": 5.0}
    monitor = ros.add(
        LinkMonitorNode(context=ros.context, parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
    )
    reports: list[tuple[float, LinkFeedback]] = []
    probe.create_subscription(
        LinkFeedback, "lossy/feedback", lambda m: reports.append((time.monotonic(), m)), FEEDBACK_QOS
    )
    pub = probe.create_publisher(FFMPEGPacket, "lossy/ffmpeg", VIDEO_QOS)
    ros.wait_for(lambda: pub.get_subscription_count() >= 1, timeout=10)

    receiver = monitor.receiver
    assert receiver is not None

    def send(p: Packet) -> None:  # one at a time, as a camera would
        n = receiver.stats.access_units
        msg = FFMPEGPacket(encoding=p.encoding, width=p.width, height=p.height, pts=p.pts, flags=int(p.key))
        msg.data = p.data
        pub.publish(msg)
        ros.wait_for(lambda: receiver.stats.access_units > n, timeout=5)

    for p in packets[:6]:
        send(p)
    assert receiver.stats.pictures >= 5  # (the first IDR's picture may come out with the next one)
    ros.wait_for(lambda: len(reports) >= 1, timeout=7)  # a periodic report: the next one is 5 s away
    assert all(m.decode_errors == 0 for _t, m in reports)
    t = time.monotonic()
    send(packets[7])  # packets[6] lost on the way
    ros.wait_for(lambda: any(m.decode_errors > 0 for _t, m in reports), timeout=2)
    first_loss = next(tr for tr, m in reports if m.decode_errors > 0)
    assert first_loss - t < 1.0, f"loss reported {first_loss - t:.2f} s after it (period 5 s)"
    assert receiver.stats.lost == 1
    # ``lost`` (the running count of access units that never arrived: the stream node's congestion signal) says
    # the same; the reports before it said 0
    assert all(m.lost == 0 for _t, m in reports if m.decode_errors == 0)
    assert next(m for _t, m in reports if m.decode_errors > 0).lost == 1


def test_link_monitor_reports_no_decode_errors_on_a_clean_stream(ros: RosHarness, camera: SimulatedCamera) -> None:
    """Loopback loses nothing: the monitor's decode_errors stay 0 once it has its first IDR (the field is not noise)."""
    make_node(ros, camera, **H264)
    ros.add(LinkMonitorNode(context=ros.context, parameter_overrides=[Parameter("codec", value="h264")]))
    probe = ros.probe()
    reports: list[LinkFeedback] = []
    probe.create_subscription(LinkFeedback, "video/feedback", reports.append, FEEDBACK_QOS)
    ros.wait_for(lambda: sum(r.frames > 10 for r in reports) >= 3, timeout=10)
    steady = [r for r in reports if r.frames > 10][-2:]
    assert all(r.decode_errors == 0 for r in steady), [r.decode_errors for r in steady]
    assert all(r.lost == 0 for r in reports), [r.lost for r in reports]


def test_a_clear_link_raises_the_bitrate_past_the_start_up_to_the_ceiling(
    ros: RosHarness, camera: SimulatedCamera
) -> None:
    """Without feedback the encoder stays at h264_bitrate_kbps (the safe default); with the operator's monitor
    reporting a clear link (loopback) the link adaptation raises it past that, up to h264_max_bitrate_kbps and no
    further, and the access units grow with it. (The climb's pace and its judgements are the adapter's unit tests'
    and the weak-link bench's: here the ceiling sits three climbs above the start, so a host that pauses now and
    then still gets there.)"""
    node = make_node(ros, camera, **H264, h264_bitrate_kbps=400, h264_max_bitrate_kbps=600)
    probe = ros.probe()
    rec, _ = subscribe(probe)
    targets: list[int] = []
    ros.wait_for(lambda: rec.count() >= 15, timeout=10)
    t0 = time.monotonic()
    while time.monotonic() - t0 < 3.0:  # 3 s of a plain subscriber: no feedback, the start applies
        targets.append(node._video.h264_settings().bitrate_kbps)
        time.sleep(0.1)  # sampling a 3 s window: the thing under test is that the target holds all along
    assert set(targets) == {400}
    assert node._stage._applied_kbps == 400
    before = rec.since(t0)
    kbps_before = sum(len(p.data) for p in before) * 8 / 1000 / (before[-1].t_rx - before[0].t_rx)
    ros.add(LinkMonitorNode(context=ros.context, parameter_overrides=[Parameter("codec", value="h264")]))
    seen: list[int] = []

    def at_ceiling() -> bool:
        seen.append(node._video.h264_settings().bitrate_kbps)
        return seen[-1] == 600

    wait_for_climb(ros, node, at_ceiling, timeout=30)
    assert max(seen) == 600, sorted(set(seen))  # never past the ceiling
    assert len(set(seen)) >= 3, sorted(set(seen))  # climbed in steps
    assert node._video.state().link_state == "clear"
    ros.wait_for(lambda: node._stage._applied_kbps == 600, timeout=3)  # the encoder targets it
    t1 = time.monotonic()
    ros.wait_for(lambda: len(rec.since(t1)) >= 45, timeout=10)
    after = rec.since(t1)
    kbps_after = sum(len(p.data) for p in after) * 8 / 1000 / (after[-1].t_rx - after[0].t_rx)
    print(f"kbit/s received: {kbps_before:.0f} without feedback, {kbps_after:.0f} with a clear link")  # noqa: T201
    assert kbps_after > 1.25 * kbps_before, (kbps_before, kbps_after)
    assert node._video.h264_settings().bitrate_kbps <= 600  # a clear link holds at the ceiling
    assert video_args(camera.request_counts.video_log[-1].query)["compression"] == "0"  # the camera's ask: as is


def _report_all_sent(pub: Any, node: StreamNode, consumer: str, **figures: Any) -> None:
    """A feedback report of ``consumer`` that received, over a 1 s window, every byte and picture the node sent,
    with the delay figures (and ``lost``) given."""
    sent = node._video._h264_meter.rate(time.monotonic())
    pub.publish(
        LinkFeedback(
            consumer=consumer,
            window_s=1.0,
            frames=max(int(sent.fps), 10),
            fps=sent.fps,
            kbps=sent.kbps,
            gap_s=0.02,
            **figures,
        )
    )


def _reporting_consumer(ros: RosHarness, camera: SimulatedCamera, max_kbps: int) -> tuple[StreamNode, Any, str]:
    """An H.264 stream node (start 400 kbit/s, ceiling ``max_kbps``) with a consumer whose image subscription the
    node has discovered and is streaming to: (node, its ``video/feedback`` publisher, its fully qualified name)."""
    node = make_node(ros, camera, **H264, h264_bitrate_kbps=400, h264_max_bitrate_kbps=max_kbps)
    probe = ros.probe()
    rec, _ = subscribe(probe)
    ros.wait_for(lambda: rec.count() >= 15, timeout=10)
    return node, probe.create_publisher(LinkFeedback, "video/feedback", FEEDBACK_QOS), probe.get_fully_qualified_name()


def test_access_units_lost_behind_a_queue_lower_the_bitrate_and_lost_without_one_hold_it(
    ros: RosHarness, camera: SimulatedCamera
) -> None:
    """A consumer whose running ``lost`` count grows (access units that never arrived: the writer dropped them from
    its history before their repair finished) while a queue stands (p95 250 ms over its minimum, under the 500 ms
    that is congestion by itself) is congested: the encoder's bitrate comes down at once. The same losses with no
    queue are the link's random loss: the bitrate is held (steady), not cut; a steady count lets it climb."""
    node, pub, consumer = _reporting_consumer(ros, camera, 600)

    def report(lost: int, queue_s: float = 0.01) -> None:
        _report_all_sent(pub, node, consumer, delay_p95_s=0.01 + queue_s, delay_min_s=0.01, lost=lost)

    seen: list[int] = []

    def climbed() -> bool:  # a report every 0.3 s (the wait's period)
        report(3)  # a steady count (its first value: the consumer's join) is no news
        seen.append(node._video.h264_settings().bitrate_kbps)
        return seen[-1] > 400

    ros.wait_for(climbed, timeout=20, period=0.3)
    assert node._video.state().link_state == "clear"
    high = node._video.h264_settings().bitrate_kbps
    report(5)  # two more lost, no queue: random loss
    ros.wait_for(lambda: node._video.state().link_state == "steady", timeout=3)
    assert node._video.h264_settings().bitrate_kbps == high  # held where it had climbed to: no cut
    report(7, queue_s=0.3)  # two more lost behind a queue
    ros.wait_for(lambda: node._video.h264_settings().bitrate_kbps < high, timeout=3)
    assert node._video.state().link_state == "congested"


def test_a_queue_seen_in_the_median_delay_lowers_the_bitrate_where_the_p95_alone_reads_steady(
    ros: RosHarness, camera: SimulatedCamera
) -> None:
    """``LinkFeedback.delay_p50_s`` reaches the adapter: with the p95 300 ms over its minimum (between the H.264
    thresholds: steady) a median 20 ms over it is the link's repairs (held), a median 150 ms over it is a queue
    (congested: the encoder's bitrate comes down)."""
    node, pub, consumer = _reporting_consumer(ros, camera, 400)

    def report(median_s: float) -> None:
        _report_all_sent(pub, node, consumer, delay_p95_s=1.31, delay_p50_s=1.01 + median_s, delay_min_s=1.01)

    start = node._video.h264_settings().bitrate_kbps

    def judged(state: str, median_s: float) -> bool:
        report(median_s)
        return node._video.state().link_state == state

    ros.wait_for(lambda: judged("steady", 0.02), timeout=5, period=0.3)
    assert node._video.h264_settings().bitrate_kbps == start
    ros.wait_for(lambda: judged("congested", 0.15), timeout=5, period=0.3)
    assert node._video.h264_settings().bitrate_kbps < start


def test_a_queue_seen_in_the_delay_floor_near_a_rate_that_congested_lowers_the_bitrate(
    ros: RosHarness, camera: SimulatedCamera
) -> None:
    """``LinkFeedback.delay_floor_s`` reaches the adapter: after a congestion, growing back near the rate that
    congested, a floor 30 ms over its minimum with the p95 and the median clear is the link's edge (congested: the
    bitrate comes down); the same report with the floor not measured (0) reads clear."""
    node, pub, consumer = _reporting_consumer(ros, camera, 400)

    def judged(state: str, queue_s: float, floor_s: float = 0.0) -> bool:
        _report_all_sent(
            pub,
            node,
            consumer,
            delay_p95_s=1.01 + queue_s,
            delay_p50_s=1.01 + min(queue_s, 0.02),
            delay_min_s=1.01,
            delay_floor_s=1.01 + floor_s if floor_s else 0.0,
        )
        return node._video.state().link_state == state

    start = node._video.h264_settings().bitrate_kbps
    ros.wait_for(lambda: judged("congested", 0.6), timeout=5, period=0.3)  # swamped: the rate that congested
    ros.wait_for(lambda: node._video.h264_settings().bitrate_kbps < start, timeout=3)
    eased = node._video.h264_settings().bitrate_kbps
    ros.wait_for(lambda: judged("clear", 0.06, 0.0), timeout=5, period=0.3)  # the floor not measured: clear
    assert node._video.h264_settings().bitrate_kbps >= eased
    ros.wait_for(lambda: judged("congested", 0.06, 0.03), timeout=5, period=0.3)  # after a clear one: the floor's
    # the next decrease once the first one's hold (2.5 s) has passed
    ros.wait_for(
        lambda: judged("congested", 0.06, 0.03) and node._video.h264_settings().bitrate_kbps < eased,
        timeout=8,
        period=0.3,
    )


def test_the_default_ceiling_lets_a_clear_link_raise_the_start_by_half_and_a_start_above_the_ceiling_is_no_raising(
    ros: RosHarness, camera: SimulatedCamera
) -> None:
    """The shipped default starts at 1000 kbit/s and lets a clear link raise it to 1500 (docs/weak-link.md, "The
    ceiling"); raising the start alone is accepted (the ceiling then means "never above the start"), and both can
    be set at once to let a clear link raise it further."""
    node = make_node(ros, camera, **H264)
    assert (node.get_parameter("h264_bitrate_kbps").value, node.get_parameter("h264_max_bitrate_kbps").value) == (
        1000,
        1500,
    )
    probe = ros.probe()
    (res,) = set_params(ros, probe, h264_bitrate_kbps=2000)
    assert res.successful, res.reason
    ros.wait_for(lambda: node._video.h264_settings().bitrate_kbps == 2000, timeout=3)
    (res,) = set_params(ros, probe, h264_max_bitrate_kbps=800)  # below the start: never above it
    assert res.successful, res.reason
    assert node._video.h264_settings().bitrate_kbps == 2000
    client = probe.create_client(SetParametersAtomically, "/axis_stream/set_parameters_atomically")
    req = SetParametersAtomically.Request()
    req.parameters = [
        Parameter(k, value=v).to_parameter_msg()
        for k, v in {"h264_bitrate_kbps": 2000, "h264_max_bitrate_kbps": 3000}.items()
    ]
    result = ros.call(client, req).result  # both at once: fine
    assert result.successful, result.reason
    assert (node.get_parameter("h264_bitrate_kbps").value, node.get_parameter("h264_max_bitrate_kbps").value) == (
        2000,
        3000,
    )
