"""axis_stream passing a camera's own RTSP H.264 through (issue 21 item 1), over real DDS, against the simulated
current-Axis persona (q6075: RTSP H.264 with Digest, plain HTTP here).

PyAV (FFmpeg's h264 decoder, nobody's code here) decodes what arrives on ``image_raw/ffmpeg``; the simulator
marks each frame's capture time in an SEI, which the node's header stamps (on this host's clock, which is the
simulator's) must follow within the stream's latency; ``Renew-Stream`` is counted on the simulator's sessions.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import av
import pytest

pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from ffmpeg_image_transport_msgs.msg import FFMPEGPacket  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from axis_ptz_ros2.media import annexb  # noqa: E402
from axis_ptz_ros2.media.annexb import NalType  # noqa: E402
from axis_ptz_ros2.nodes.link_monitor import LinkMonitorNode  # noqa: E402
from axis_ptz_ros2.nodes.stream_node import StreamNode  # noqa: E402
from axis_ptz_ros2.sim import SimulatedCamera  # noqa: E402
from axis_ptz_ros2.sim.rtsp.session import RtspSession  # noqa: E402
from tests.ros.test_stream_h264 import FAST, H264Recorder, Packet, set_params, subscribe  # noqa: E402
from tests.support.adapter_watch import wait_for_climb  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402
from tests.support.idr import idr_granted_at_once  # noqa: E402
from tests.support.stream_node import make_stream_node  # noqa: E402
from tests.support.waiting import wait_until  # noqa: E402

pytestmark = pytest.mark.ros

PASSWORD = "pass-through-Pa55"
SIZE = (640, 360)


@pytest.fixture(scope="module")
def sim() -> Iterator[SimulatedCamera]:
    cam = SimulatedCamera(model="q6075", https=False, auth="digest", password=PASSWORD).start()
    try:
        yield cam
    finally:
        cam.stop()


@pytest.fixture
def camera(sim: SimulatedCamera) -> SimulatedCamera:
    wait_until(lambda: not sim.rebooting, 10.0, 0.05, scaled=False, raises=False)
    sim.teleport(0.0, 0.0, 1.0)
    sim.reset_counts()
    return sim


@pytest.fixture
def cred(tmp_path: Path) -> str:
    path = tmp_path / "cred"
    path.write_text(f"root:{PASSWORD}\n", encoding="utf-8")
    return str(path)


@pytest.fixture
def renews(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    """Times of the ``Renew-Stream`` requests the simulator's sessions honoured."""
    seen: list[float] = []
    original = RtspSession.renew

    def renew(self: RtspSession) -> None:
        seen.append(time.monotonic())
        original(self)

    monkeypatch.setattr(RtspSession, "renew", renew)
    return seen


def make_node(ros: RosHarness, camera: SimulatedCamera, cred: str, **params: object) -> StreamNode:
    """The shared stream node (tests/support/stream_node.py) on this camera's RTSP, with its password, asking for
    H.264 at SIZE and 15 fps."""
    assert camera.rtsp is not None
    values: dict[str, object] = {
        "rtsp_port": camera.rtsp.port,
        "password_file": cred,
        "codec": "h264",
        "resolution": f"{SIZE[0]}x{SIZE[1]}",
        "fps": 15,
        # the simulator's encoder, the node and DDS share this one process: a 0.4 s stall limit read the GIL's
        # pauses as a lost stream (reconnects, a second session) in ~40 % of runs; 1.5 s is still fast recovery
        "stall_timeout": 1.5,
        **params,
    }
    return make_stream_node(ros, camera, **values)


def _diag_values(diags: list[DiagnosticArray], suffix: str) -> dict[str, str]:
    statuses = [s for d in list(diags) for s in d.status if s.name.endswith(suffix)]
    return {kv.key: kv.value for kv in statuses[-1].values} if statuses else {}


def decodes_one_picture_each(packets: list[Packet]) -> int:
    """Decode from the first IDR on: every message must give exactly one picture of SIZE; returns how many."""
    ctx = av.CodecContext.create("h264", "r")
    n = 0
    started = False
    for p in packets:
        started = started or p.key
        if not started:
            continue
        frames = ctx.decode(av.Packet(p.data))
        assert len(frames) == 1, f"pts {p.pts}: {len(frames)} pictures from one message"
        assert (frames[0].width, frames[0].height) == SIZE
        n += 1
    return n


def test_passes_the_cameras_h264_through(ros: RosHarness, camera: SimulatedCamera, cred: str) -> None:
    node = make_node(ros, camera, cred)
    probe = ros.probe()
    rec, _ = subscribe(probe, foxglove=True)
    diags: list[DiagnosticArray] = []
    probe.create_subscription(DiagnosticArray, "/diagnostics", diags.append, 10)
    ros.wait_for(lambda: rec.count() >= 40, timeout=15)
    packets = rec.since(0.0)
    # (best effort: the first messages can go out before the probe's side of the match; an IDR within a second)
    first_idr = next(i for i, p in enumerate(packets) if p.key)
    assert packets[first_idr].t_rx - packets[0].t_rx <= 1.0
    assert decodes_one_picture_each(packets) == len(packets) - first_idr
    for p in packets:
        assert (p.width, p.height) == SIZE
        types = annexb.nal_types(p.data)
        assert p.key == (NalType.IDR in types)
        if p.key:
            assert types.index(NalType.SPS) < types.index(NalType.PPS) < types.index(NalType.IDR)
        # header stamp = the capture time on this host's clock (streaming/clock_sync.py maps the camera's RTP
        # time through the arrival times; the simulator's clock is this host's and its SEI says when): never
        # before the capture (RTP's 11 µs rounding aside), at most the stream's latency after it
        sei = annexb.extract_capture_stamp(p.data)
        assert sei is not None
        assert -1_000_000 < p.stamp_ns - sei < 50_000_000, (p.pts, p.stamp_ns - sei)
    assert [p.pts for p in packets] == sorted({p.pts for p in packets})
    by_stamp = {p.stamp_ns: p.data for p in packets}
    with rec.lock:
        both = [(by_stamp[stamp], data) for stamp, data, _f, _id in rec.foxglove if stamp in by_stamp]
    assert len(both) >= 10, "image_raw/foxglove carries the same stream"
    assert all(a == b for a, b in both)
    # no transcoding: the stage never opened an encoder, and no MJPEG stream was asked for
    assert node._stage.stats.encoder_opens == 0  # noqa: SLF001
    assert node._rtsp.supported is True  # noqa: SLF001
    assert not camera.request_counts.video_log
    # the camera was asked for baseline, fixed GOP, mbr at the bitrate in force
    assert camera.rtsp is not None
    sessions = camera.rtsp.sessions
    assert len(sessions) == 1
    req = sessions[0].request
    assert (req.width, req.height, req.fps) == (*SIZE, 15)
    assert req.keyframe_interval == 15  # h264_keyframe_interval 30, capped at one second
    assert req.bitrate_kbps == 1000  # h264_bitrate_kbps (no budget)
    assert req.adjustable  # adjustablelivestream=1: the bitrate can change without a new session
    # /diagnostics says where the H.264 comes from
    values = ros.wait_for(
        lambda: _diag_values(diags, "MJPEG stream").get("h264 source") and _diag_values(diags, "MJPEG stream")
    )
    assert values["h264 source"] == "camera (RTSP)"
    assert int(values["rtsp access units"]) > 0
    # and between which bitrates the link moves it (the parameters' defaults here)
    assert (values["h264 bitrate start [kbit/s]"], values["h264 bitrate ceiling [kbit/s]"]) == ("1000", "1500")


def test_a_late_joiner_gets_an_idr_within_a_second(
    ros: RosHarness, camera: SimulatedCamera, cred: str, renews: list[float]
) -> None:
    node = make_node(ros, camera, cred, h264_keyframe_interval=300)  # periodic IDRs every second (capped at fps)
    probe = ros.probe()
    first, _ = subscribe(probe)
    ros.wait_for(lambda: first.count() >= 20, timeout=15)
    # outside the stage's on-demand rate limit, the first subscriber's start-point repeats over
    ros.wait_for(lambda: idr_granted_at_once(node._stage, node._pipeline.starts), timeout=10)
    before = len(renews)
    joiner_probe = ros.probe("late_joiner")
    late = H264Recorder()
    t0 = time.monotonic()
    joiner_probe.create_subscription(FFMPEGPacket, "image_raw/ffmpeg", late.on_packet, 10)
    ros.wait_for(lambda: any(p.key for p in late.since(0.0)), timeout=5)
    key = next(p for p in late.since(0.0) if p.key)
    assert key.t_rx - t0 <= 1.0, f"first IDR {key.t_rx - t0:.2f} s after joining"
    assert len(renews) > before, "the node asked the camera for an IDR (Renew-Stream)"
    print(f"late joiner: IDR after {key.t_rx - t0:.2f} s, Renew-Stream sent")  # noqa: T201


def test_a_bitrate_change_reaches_the_playing_stream_without_a_new_session(
    ros: RosHarness, camera: SimulatedCamera, cred: str
) -> None:
    node = make_node(ros, camera, cred)
    probe = ros.probe()
    rec, subs = subscribe(probe)
    ros.wait_for(lambda: rec.count() >= 10, timeout=15)
    assert camera.rtsp is not None
    (session,) = camera.rtsp.sessions
    assert all(r.successful for r in set_params(ros, probe, h264_bitrate_kbps=600))
    # the encoder's bitrate in effect (the session's pending value lives only until its next frame: a test that
    # polled it passed only when it looked inside that ~66 ms window)
    ros.wait_for(lambda: session.bitrate_kbps == 600, timeout=5)
    n = rec.count()
    ros.wait_for(lambda: rec.count() >= n + 10, timeout=5)
    assert camera.rtsp.sessions == [session]
    assert node._rtsp.stats.adjustments == 1  # noqa: SLF001
    # lazy: the last H.264 subscriber gone, the session is torn down
    for sub in subs:
        probe.destroy_subscription(sub)
    ros.wait_for(lambda: not camera.rtsp.sessions, timeout=5)


def test_a_clear_link_raises_the_cameras_bitrate_past_the_start_on_the_playing_stream(
    ros: RosHarness, camera: SimulatedCamera, cred: str
) -> None:
    """Pass-through: the operator's monitor reporting a clear link raises the camera's own bitrate (its encoder's,
    in the playing session) past h264_bitrate_kbps up to h264_max_bitrate_kbps, live, without a new session (the
    ceiling three climbs above the start: see the transcoding twin in test_stream_h264.py)."""
    node = make_node(ros, camera, cred, h264_bitrate_kbps=400, h264_max_bitrate_kbps=600)
    probe = ros.probe()
    rec, _ = subscribe(probe)
    ros.wait_for(lambda: rec.count() >= 10, timeout=15)
    assert camera.rtsp is not None
    (session,) = camera.rtsp.sessions
    assert session.request.bitrate_kbps == 400  # no feedback: the start
    ros.add(LinkMonitorNode(context=ros.context, parameter_overrides=[Parameter("codec", value="h264")]))
    seen: list[int] = []

    def at_ceiling() -> bool:
        seen.append(session.bitrate_kbps)
        return seen[-1] == 600

    wait_for_climb(ros, node, at_ceiling, timeout=30)
    assert max(seen) == 600, sorted(set(seen))  # never past the ceiling
    assert len(set(seen)) >= 3, sorted(set(seen))  # climbed in steps
    assert camera.rtsp.sessions == [session]
    assert node._rtsp.stats.adjustments >= 1  # noqa: SLF001


def test_a_resolution_change_reconnects_at_the_new_size(ros: RosHarness, camera: SimulatedCamera, cred: str) -> None:
    make_node(ros, camera, cred)
    probe = ros.probe()
    rec, _ = subscribe(probe)
    ros.wait_for(lambda: rec.count() >= 10, timeout=15)
    assert all(r.successful for r in set_params(ros, probe, resolution="1280x720"))
    t = time.monotonic()
    ros.wait_for(lambda: any(p.key and p.width == 1280 for p in rec.since(t)), timeout=5)
    new = rec.since(t)
    first = next(i for i, p in enumerate(new) if p.width == 1280)
    assert new[first].key, "the new size starts at an IDR (new SPS/PPS)"
    assert all(p.width == 1280 for p in new[first:])
    ros.wait_for(lambda: len(rec.since(t)) >= first + 10, timeout=5)
    ctx = av.CodecContext.create("h264", "r")
    sizes = {(f.width, f.height) for p in rec.since(t)[first:] for f in ctx.decode(av.Packet(p.data))}
    assert sizes == {(1280, 720)}


def test_frames_resume_after_a_reboot_without_an_old_frame(ros: RosHarness, camera: SimulatedCamera, cred: str) -> None:
    node = make_node(ros, camera, cred)
    probe = ros.probe()
    rec, _ = subscribe(probe)
    ros.wait_for(lambda: rec.count() >= 15, timeout=15)
    camera.reboot(2.0, blackhole=True)
    t_reboot = time.monotonic()
    ros.wait_for(lambda: not camera.rebooting, timeout=20)
    t_back = time.monotonic()
    ros.wait_for(lambda: rec.since(t_back), timeout=5)
    resumed = rec.since(t_back)[0]
    before = [p for p in rec.since(0.0) if p.t_rx < t_reboot]
    after = rec.since(t_back)
    print(f"frames resumed {resumed.t_rx - t_back:.2f} s after the camera was back")  # noqa: T201
    assert resumed.t_rx - t_back <= 1.5
    assert resumed.key, "the first frame after the reboot is an IDR"
    newest_before = max(p.stamp_ns for p in before)
    between = [p for p in rec.since(t_reboot) if p.t_rx < t_back]
    assert all(p.stamp_ns > newest_before for p in between + after), "an old frame was republished"
    assert len({p.pts for p in rec.since(0.0)}) == rec.count()
    assert node._rtsp.stats.reconnects >= 1  # noqa: SLF001
    ros.wait_for(lambda: len(rec.since(t_back)) >= 10, timeout=5)
    resumed_packets = rec.since(t_back)  # one snapshot: more arrive while it decodes
    assert decodes_one_picture_each(resumed_packets) == len(resumed_packets)


def test_a_camera_without_h264_is_transcoded(ros: RosHarness, cred: str) -> None:
    cam = SimulatedCamera(port=0).start()  # the 214: MJPEG only
    try:
        node = ros.add(
            StreamNode(
                context=ros.context,
                parameter_overrides=[
                    Parameter(k, value=v)
                    for k, v in {"port": cam.port, "codec": "h264", "resolution": "704x576", "fps": 15, **FAST}.items()
                ],
            )
        )
        rec, _ = subscribe(ros.probe())
        ros.wait_for(lambda: rec.count() >= 5, timeout=15)
        assert node._rtsp.supported is False  # noqa: SLF001
        assert node._stage.stats.encoder_opens >= 1  # noqa: SLF001
        assert cam.request_counts.video_log
    finally:
        cam.stop()
