"""Our RTSP client (vapix/rtsp_client.py) against two servers: the simulated q6075 (sim/rtsp) and GStreamer's
gst-rtsp-server from Debian's packages (tests/integration/rtsp_gst_server.py, nobody here wrote it).

It owns the playing session, so ``Renew-Stream`` reaches the stream it plays; FFmpeg's session (PyAV) cannot be
named, and a Renew-Stream on another session does not reach it (measured below)."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import av
import pytest

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.decoder import H264Decoder
from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.vapix.errors import AuthError, CameraTimeout, CameraUnreachable
from axis_ptz_ros2.vapix.rtsp import MediaStreamRequest, RtspControl, RtspStatusError, sprop_parameter_sets
from axis_ptz_ros2.vapix.rtsp_client import RtspClient
from tests.support.waiting import wait_until

pytestmark = pytest.mark.integration

PASSWORD = "client-secret!"
STREAM = MediaStreamRequest(resolution="640x360", fps=15, keyframe_interval=300, max_bitrate_kbps=1500)


@pytest.fixture(scope="module")
def cam() -> Iterator[SimulatedCamera]:
    with SimulatedCamera(model="q6075", https=False, password=PASSWORD) as c:
        yield c


def _client(cam: SimulatedCamera, stream: MediaStreamRequest = STREAM, **kw: object) -> RtspClient:
    assert cam.rtsp is not None
    args: dict[str, object] = {"username": "root", "password": PASSWORD, "open_timeout_s": 10.0, "read_timeout_s": 3.0}
    args.update(kw)
    return RtspClient("127.0.0.1", cam.rtsp.port, stream=stream, **args)  # type: ignore[arg-type]


def _read_many(c: RtspClient, n: int) -> None:
    for _ in range(n):
        c.read()


def test_plays_decodes_and_stamps_capture_time_from_the_sender_reports(cam: SimulatedCamera) -> None:
    dec = H264Decoder()
    with _client(cam) as c:
        assert c.session_id
        assert c.session_timeout_s == 60
        aus = [c.read() for _ in range(20)]
    assert aus[0].keyframe
    assert annexb.NalType.SPS in annexb.nal_types(aus[0].data)  # from the SDP: the camera sends none in band
    for au in aus:
        assert dec.decode(au.data) is not None
    assert dec.stats.decode_errors == 0
    offsets = []
    for au in aus:
        stamp = annexb.extract_capture_stamp(au.data)
        assert stamp is not None
        assert au.capture_ns is not None
        offsets.append(abs(au.capture_ns - stamp))
    assert max(offsets) < 2_000_000, offsets  # same clock both sides: RTP rounding only


def test_renew_stream_reaches_the_session_it_plays(cam: SimulatedCamera) -> None:
    with _client(cam) as c:
        for _ in range(5):
            c.read()
        assert c.renew_stream().status == 200
        keys = [c.read().keyframe for _ in range(5)]
    assert keys.count(True) == 1  # keyframe interval 300: only the renewed one


def test_a_renew_stream_on_another_session_does_not_reach_ffmpegs(cam: SimulatedCamera) -> None:
    """Why we wrote a client: FFmpeg's session id is not exposed, and Renew-Stream is per session."""
    assert cam.rtsp is not None
    url = STREAM.url("127.0.0.1", cam.rtsp.port, "root", PASSWORD)
    with av.open(url, options={"rtsp_transport": "tcp", "timeout": "4000000"}, timeout=(10, 5)) as container:
        assert not [a for a in dir(container) if "session" in a.lower()]
        packets = container.demux(video=0)
        next(packets)
        with _client(cam) as other:
            other.read()
            other.renew_stream()
            keys = [next(packets).is_keyframe for _ in range(8)]
            assert any(other.read().keyframe for _ in range(4))
    assert not any(keys)


def test_adjustable_stream_configuration(cam: SimulatedCamera) -> None:
    adjustable = MediaStreamRequest(resolution="640x360", fps=15, max_bitrate_kbps=1500, adjustable=True)
    with _client(cam, adjustable) as c:
        c.read()
        assert c.adjust_stream(fps=5, max_bitrate_kbps=500).status == 200
        c.read()
        t0 = time.monotonic()
        for _ in range(5):
            c.read()
        assert time.monotonic() - t0 > 0.6  # 5 frames at 5 fps
    with _client(cam) as c, pytest.raises(RtspStatusError) as info:
        c.adjust_stream(fps=5)
    assert info.value.status_code == 451


def test_wrong_password_and_unknown_path_are_typed_errors(cam: SimulatedCamera) -> None:
    with pytest.raises(AuthError) as info:
        _client(cam, password="not-it-at-all").open()
    assert "not-it-at-all" not in str(info.value)
    with pytest.raises(RtspStatusError) as status:
        _client(cam, path="/nothing/here").open()
    assert status.value.status_code == 404


def test_a_stall_is_a_timeout_a_drop_or_reboot_a_lost_connection(cam: SimulatedCamera) -> None:
    cam.set_faults(stall_after_frames=3, stall_seconds=5.0)
    try:
        with _client(cam, read_timeout_s=1.0) as c:
            for _ in range(3):
                c.read()
            t0 = time.monotonic()
            with pytest.raises(CameraTimeout):
                _read_many(c, 10)
            assert time.monotonic() - t0 < 2.5
    finally:
        cam.set_faults(stall_after_frames=0, stall_seconds=0.0)
    cam.set_faults(drop_after_frames=4)
    try:
        with _client(cam) as c:
            for _ in range(3):
                c.read()
            with pytest.raises(CameraUnreachable):  # the 4th frame is cut mid access unit: never handed out
                c.read()
            assert c.dropped + c.refused <= 1
    finally:
        cam.set_faults(drop_after_frames=0)
    with _client(cam) as c:
        c.read()
        cam.reboot(0.5)
        with pytest.raises(CameraUnreachable):
            _read_many(c, 100)
    wait_until(lambda: not cam.rebooting, timeout=10, interval=0.1, raises=False)


# ---- GStreamer's RTSP server ----------------------------------------------------------------------------------
SERVER = Path(__file__).with_name("rtsp_gst_server.py")
SYSTEM_PYTHON = "/usr/bin/python3"


def _have_gst_rtsp() -> bool:
    probe = "import gi; gi.require_version('GstRtspServer', '1.0'); from gi.repository import GstRtspServer"
    ok = subprocess.run([SYSTEM_PYTHON, "-c", probe], capture_output=True, check=False).returncode == 0
    inspect = subprocess.run(["gst-inspect-1.0", "x264enc"], capture_output=True, check=False) if ok else None
    return ok and inspect is not None and inspect.returncode == 0


@pytest.fixture(scope="module")
def gst() -> Iterator[int]:
    if not _have_gst_rtsp():
        pytest.skip("GStreamer's RTSP server is not installed (scripts/bootstrap --browser installs it)")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "VIRTUAL_ENV"))}
    proc = subprocess.Popen(
        [SYSTEM_PYTHON, str(SERVER), "operator", PASSWORD],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        env=env,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    assert line.startswith("PORT "), f"server did not start: {line!r}"
    try:
        yield int(line.split()[1])
    finally:
        proc.send_signal(signal.SIGCONT)
        proc.terminate()
        proc.wait(timeout=10)


def test_plays_gstreamers_server_with_digest(gst: int) -> None:
    dec = H264Decoder()
    stream = MediaStreamRequest(resolution="352x288", fps=30)
    with RtspClient("127.0.0.1", gst, stream=stream, username="operator", password=PASSWORD, open_timeout_s=10) as c:
        assert c.session_id
        aus = [c.read(5.0) for _ in range(45)]
        try:
            status = c.renew_stream().status  # GStreamer does not know Renew-Stream …
        except RtspStatusError as err:
            status = err.status_code
        print(f"GStreamer answers Renew-Stream on the playing session with {status}")
        assert status != 454  # … but the session is found: it is the one we play
        aus += [c.read(5.0) for _ in range(5)]  # still playing after the SET_PARAMETER
        deadline = time.monotonic() + 10  # gst-rtsp-server's first sender report comes after a few seconds
        while aus[-1].capture_ns is None and time.monotonic() < deadline:
            aus.append(c.read(5.0))
    keys = [au for au in aus if au.keyframe]
    assert keys, "no IDR in 50 frames (key-int-max=30)"
    for au in keys:
        assert annexb.NalType.SPS in annexb.nal_types(au.data)  # GStreamer sends them only in the SDP here
    decoded = [dec.decode(au.data) for au in aus[aus.index(keys[0]) :]]
    assert all(pic is not None for pic in decoded)
    assert decoded[0] is not None
    assert decoded[0].image.shape[:2] == (288, 352)
    stamped = [au.capture_ns for au in aus if au.capture_ns is not None]
    assert stamped, "no capture time: no RTCP sender report"
    assert abs(stamped[-1] - time.time_ns()) < 2e9


def test_rtsp_control_renews_the_session_our_client_plays_from_another_connection(cam: SimulatedCamera) -> None:
    """RtspControl signs Digest over the absolute URL (the simulator checks it) and names a session by id."""
    assert cam.rtsp is not None
    ctl = RtspControl("127.0.0.1", cam.rtsp.port, username="root", password=PASSWORD, stream=STREAM)
    try:
        assert sprop_parameter_sets(ctl.describe()) is not None
        with _client(cam) as c:
            for _ in range(3):
                c.read()
            assert c.session_id is not None
            assert ctl.renew_stream(c.session_id).status == 200
            assert any(c.read().keyframe for _ in range(4))
        with pytest.raises(RtspStatusError) as info:
            ctl.renew_stream("NO-SUCH-SESSION")
        assert info.value.status_code == 454
    finally:
        ctl.close()


def test_a_packet_dropping_reboot_is_a_read_timeout_then_the_camera_plays_again(cam: SimulatedCamera) -> None:
    with _client(cam, read_timeout_s=1.0) as c:
        c.read()
        cam.reboot(2.0, blackhole=True)
        t0 = time.monotonic()
        with pytest.raises(CameraTimeout):  # the connection goes mute, not closed
            _read_many(c, 100)
        assert time.monotonic() - t0 < 2.0
    wait_until(lambda: not cam.rebooting, timeout=15, interval=0.1, what="the camera back from its reboot")
    with _client(cam) as c:
        assert c.read().keyframe
