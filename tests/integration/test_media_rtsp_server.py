"""RtspReader and RtspControl against a real RTSP server on loopback (GStreamer's gst-rtsp-server, Digest auth).

The server sends SPS/PPS only in its SDP, like an Axis camera by default: every IDR the reader hands out must
carry them anyway, and decode. Needs Debian's python3-gi, gir1.2-gst-rtsp-server-1.0 and the GStreamer plugins
(x264enc: gstreamer1.0-plugins-ugly).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.decoder import H264Decoder
from axis_ptz_ros2.vapix.errors import AuthError, CameraTimeout
from axis_ptz_ros2.vapix.rtsp import (
    MediaStreamRequest,
    RtspControl,
    RtspStatusError,
    sprop_parameter_sets,
)
from tests.support.pyav_rtsp import RtspReader

pytestmark = pytest.mark.integration

SERVER = Path(__file__).with_name("rtsp_gst_server.py")
USER, PASSWORD = "operator", "s3cret-rtsp!"
SYSTEM_PYTHON = "/usr/bin/python3"


def _have_gst_rtsp() -> bool:
    probe = "import gi; gi.require_version('GstRtspServer', '1.0'); from gi.repository import GstRtspServer"
    ok = subprocess.run([SYSTEM_PYTHON, "-c", probe], capture_output=True, check=False).returncode == 0
    inspect = subprocess.run(["gst-inspect-1.0", "x264enc"], capture_output=True, check=False) if ok else None
    return ok and inspect is not None and inspect.returncode == 0


if not _have_gst_rtsp():
    pytest.skip(
        "GStreamer's RTSP server is not installed (apt-get install python3-gi gir1.2-gst-rtsp-server-1.0 "
        "gstreamer1.0-plugins-ugly gstreamer1.0-tools)",
        allow_module_level=True,
    )


@pytest.fixture(scope="module")
def server() -> Iterator[tuple[subprocess.Popen[str], int]]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "VIRTUAL_ENV"))}
    proc = subprocess.Popen(
        [SYSTEM_PYTHON, str(SERVER), USER, PASSWORD],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        env=env,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    assert line.startswith("PORT "), f"server did not start: {line!r}"
    try:
        yield proc, int(line.split()[1])
    finally:
        proc.send_signal(signal.SIGCONT)
        proc.terminate()
        proc.wait(timeout=10)


def url(port: int, password: str = PASSWORD) -> str:
    return MediaStreamRequest(resolution="352x288", fps=30).url("127.0.0.1", port, USER, password)


def test_reader_plays_h264_with_digest_and_every_idr_carries_sps_pps(
    server: tuple[subprocess.Popen[str], int],
) -> None:
    _, port = server
    dec = H264Decoder()
    aus = []
    t0 = time.monotonic()
    with RtspReader(url(port), open_timeout_s=10, read_timeout_s=5, secrets=(PASSWORD,)) as reader:
        for au in reader.access_units():
            aus.append(au)
            pic = dec.decode(au.data)
            if au.keyframe:
                types = annexb.nal_types(au.data)
                assert annexb.NalType.SPS in types
                assert annexb.NalType.PPS in types
                sps = annexb.find_sps(au.data)
                assert sps is not None
                assert (sps.width, sps.height) == (352, 288)
                assert pic is not None
            if len(aus) >= 75 or time.monotonic() - t0 > 20:
                break
    assert len(aus) >= 75
    assert sum(au.keyframe for au in aus) >= 2  # key-int-max=30
    assert dec.stats.pictures >= 60
    assert dec.stats.decode_errors == 0
    pts = [au.pts for au in aus]
    assert pts == sorted(set(pts))  # one access unit per pts
    stamped = [au.capture_ns for au in aus if au.capture_ns is not None]
    assert stamped, "no capture time from the RTCP sender reports"
    assert abs(stamped[-1] - time.time_ns()) < 2e9


def test_wrong_password_is_an_auth_error_without_the_password(server: tuple[subprocess.Popen[str], int]) -> None:
    _, port = server
    with pytest.raises(AuthError) as info:
        RtspReader(url(port, "wrong-pass"), open_timeout_s=10, secrets=("wrong-pass",)).open()
    assert "wrong-pass" not in str(info.value)
    assert USER not in str(info.value)


def test_stalled_server_times_out_instead_of_hanging(server: tuple[subprocess.Popen[str], int]) -> None:
    proc, port = server
    reader = RtspReader(url(port), open_timeout_s=10, read_timeout_s=2, secrets=(PASSWORD,))
    reader.open()
    try:
        it = reader.access_units()
        next(it)
        proc.send_signal(signal.SIGSTOP)
        t0 = time.monotonic()
        with pytest.raises(CameraTimeout):
            for _ in it:
                pass
        assert time.monotonic() - t0 < 10
    finally:
        proc.send_signal(signal.SIGCONT)
        reader.close()


def test_control_connection_signs_with_digest(server: tuple[subprocess.Popen[str], int]) -> None:
    _, port = server
    ctl = RtspControl(
        "127.0.0.1", port, username=USER, password=PASSWORD, stream=MediaStreamRequest(resolution="352x288")
    )
    try:
        assert "SET_PARAMETER" in ctl.options().headers.get("public", "")
        sdp = ctl.describe()  # DESCRIBE needs the credentials: 401, then the Digest-signed retry
        params = sprop_parameter_sets(sdp)
        assert params is not None
        assert (params.info.width, params.info.height) == (352, 288)
        assert sprop_parameter_sets(ctl.describe()) == params  # pre-emptively signed, kept-alive connection
        with pytest.raises(RtspStatusError) as status:
            ctl.renew_stream("no-such-session")  # SET_PARAMETER needs the playing session's id
        assert status.value.status_code == 454
    finally:
        ctl.close()
    bad = RtspControl(
        "127.0.0.1", port, username=USER, password="nope-nope", stream=MediaStreamRequest(resolution="352x288")
    )
    try:
        with pytest.raises(AuthError) as info:
            bad.describe()
        assert "nope-nope" not in str(info.value)
    finally:
        bad.close()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(pytest.main([__file__, "-q"]))
