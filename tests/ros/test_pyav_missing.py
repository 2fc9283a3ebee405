"""Without a usable PyAV (none, or Ubuntu 24.04's 11.0): one clear log line, no traceback, MJPEG goes on.

The real executables run as processes whose ``PYTHONPATH`` puts a stand-in ``av`` package first: one that fails to
import (PyAV missing) and one that says it is 11.0.0 (noble's ``python3-av``). The stream node is asked for H.264
by its parameters; the republisher and the link monitor are started on the H.264 topic. Each must say what PyAV it
needs and how to get it (``media/pyav.py``), print no traceback, and keep working: the stream node's MJPEG topic
carries new pictures, the republisher falls back to the MJPEG topic and publishes raw images, the link monitor
reports what arrives.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
from sensor_msgs.msg import CompressedImage, Image

from axis_ptz_ros2.nodes.common import STREAM_QOS
from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.sim.world import load_world
from tests.support.harness import RosHarness

pytestmark = [pytest.mark.ros, pytest.mark.timeout(180)]

BIN = Path(sys.executable).parent
STAND_INS = {
    "missing": "raise ImportError(\"No module named 'av'\")\n",
    "noble": '__version__ = "11.0.0"\n',
}


@pytest.fixture(scope="module")
def cam() -> Iterator[SimulatedCamera]:
    c = SimulatedCamera(load_world(), port=0).start()
    try:
        yield c
    finally:
        c.stop()


@pytest.fixture(params=sorted(STAND_INS))
def fake_av(request: pytest.FixtureRequest, tmp_path: Path) -> tuple[str, Path]:
    pkg = tmp_path / "av"
    pkg.mkdir()
    (pkg / "__init__.py").write_text(STAND_INS[request.param])
    return request.param, tmp_path


class Output:
    """A process's merged output, read on a thread (so a chatty process never blocks on a full pipe)."""

    def __init__(self, proc: subprocess.Popen[bytes]) -> None:
        self.text = ""
        self._lock = threading.Lock()
        assert proc.stdout is not None
        self._thread = threading.Thread(target=self._read, args=(proc,), daemon=True)
        self._thread.start()

    def _read(self, proc: subprocess.Popen[bytes]) -> None:
        assert proc.stdout is not None
        for line in iter(proc.stdout.readline, b""):
            with self._lock:
                self.text += line.decode(errors="replace")

    def snapshot(self) -> str:
        with self._lock:
            return self.text


@contextlib.contextmanager  # not tests.ros.processes.node_process: the output is read to its end, shutdown included
def started(exe: str, av_path: Path, *ros_args: str) -> Iterator[tuple[subprocess.Popen[bytes], Output]]:
    env = dict(os.environ, PYTHONPATH=f"{av_path}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    proc = subprocess.Popen(
        [str(BIN / exe), "--ros-args", *ros_args],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        stdin=subprocess.DEVNULL,
        env=env,
        start_new_session=True,
    )
    out = Output(proc)
    try:
        yield proc, out
    finally:
        if proc.poll() is None:
            proc.send_signal(2)
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)


def says_what_is_needed(text: str, kind: str) -> bool:
    found = "found 11.0.0" if kind == "noble" else "not installed"
    return "PyAV >= 18.0" in text and found in text and "pip install 'av>=18.0'" in text


def test_without_pyav_every_h264_tool_says_so_once_and_mjpeg_goes_on(
    ros: RosHarness, cam: SimulatedCamera, fake_av: tuple[str, Path]
) -> None:
    kind, av_path = fake_av
    probe = ros.probe()
    mjpeg: list[int] = []
    raw: list[int] = []
    probe.create_subscription(CompressedImage, "/image_raw/compressed", lambda m: mjpeg.append(len(m.data)), STREAM_QOS)
    probe.create_subscription(Image, "/image_raw", lambda m: raw.append(m.width), STREAM_QOS)
    stream_args = ("-p", "hostname:=127.0.0.1", "-p", f"port:={cam.port}", "-p", "codec:=h264")
    with (
        started("axis_stream", av_path, *stream_args) as (stream, stream_out),
        started("axis_republish", av_path, "-p", "input:=h264", "-p", "lazy:=false") as (repub, repub_out),
        started("axis_link_monitor", av_path, "-p", "codec:=h264") as (monitor, monitor_out),
    ):
        # an H.264 viewer makes the stream node transcode (it is asked for codec h264 by a subscriber)
        from ffmpeg_image_transport_msgs.msg import FFMPEGPacket  # noqa: PLC0415

        from axis_ptz_ros2.nodes.common import VIDEO_QOS  # noqa: PLC0415

        probe.create_subscription(FFMPEGPacket, "/image_raw/ffmpeg", lambda _m: None, VIDEO_QOS)
        ros.wait_for(lambda: len(mjpeg) >= 10 and len(raw) >= 3, timeout=90.0, period=0.05)
        ros.wait_for(lambda: says_what_is_needed(stream_out.snapshot(), kind), timeout=30.0, period=0.05)
        ros.wait_for(lambda: says_what_is_needed(repub_out.snapshot(), kind), timeout=30.0, period=0.05)
        ros.wait_for(lambda: says_what_is_needed(monitor_out.snapshot(), kind), timeout=30.0, period=0.05)
        before = len(mjpeg)
        ros.wait_for(lambda: len(mjpeg) >= before + 10, timeout=30.0, period=0.05)  # still new pictures
        for proc in (stream, repub, monitor):
            assert proc.poll() is None, "a node exited without PyAV"
    for name, out in (("axis_stream", stream_out), ("axis_republish", repub_out), ("axis_link_monitor", monitor_out)):
        text = out.snapshot()
        assert "Traceback" not in text, f"{name}:\n{text[-3000:]}"
        assert text.count("PyAV >= 18.0") == 1, f"{name} said it {text.count('PyAV >= 18.0')} times:\n{text[-3000:]}"


def test_without_pyav_codec_h264_falls_back_to_plain_mjpeg(
    ros: RosHarness, cam: SimulatedCamera, fake_av: tuple[str, Path]
) -> None:
    """Asked for H.264 that cannot be made (no pass-through on the 214, no PyAV to transcode): no MJPEG share. The
    MJPEG topic carries the main stream at the size asked for (the share's budget would take it down to its small
    sizes) and ``video/params`` tells what is in effect: MJPEG at the requested size and compression."""
    from ffmpeg_image_transport_msgs.msg import FFMPEGPacket  # noqa: PLC0415

    from axis_ptz_interfaces.msg import VideoParams  # noqa: PLC0415
    from axis_ptz_ros2.nodes.common import LATCHED_QOS, VIDEO_QOS  # noqa: PLC0415
    from axis_ptz_ros2.streaming.jpeg import jpeg_sof  # noqa: PLC0415

    kind, av_path = fake_av
    probe = ros.probe()
    sizes: list[tuple[int, int]] = []
    params: list[VideoParams] = []

    def on_jpeg(msg: CompressedImage) -> None:
        sof = jpeg_sof(bytes(msg.data))
        sizes.append((sof[0], sof[1]) if sof else (0, 0))

    probe.create_subscription(CompressedImage, "/image_raw/compressed", on_jpeg, STREAM_QOS)
    probe.create_subscription(VideoParams, "/video/params", params.append, LATCHED_QOS)
    probe.create_subscription(FFMPEGPacket, "/image_raw/ffmpeg", lambda _m: None, VIDEO_QOS)
    args = ("hostname:=127.0.0.1", f"port:={cam.port}", "codec:=h264", "resolution:=704x576", "compression:=30")
    with started("axis_stream", av_path, *(a for arg in args for a in ("-p", arg))) as (stream, out):
        ros.wait_for(lambda: says_what_is_needed(out.snapshot(), kind), timeout=60.0, period=0.05)
        ros.wait_for(lambda: len(sizes) >= 10, timeout=60.0, period=0.05)
        before = len(sizes)
        ros.wait_for(lambda: len(sizes) >= before + 30, timeout=60.0, period=0.05)  # long enough for a share to step
        assert stream.poll() is None, out.snapshot()[-3000:]
        late = set(sizes[before:])
        assert late == {(704, 576)}, f"MJPEG topic sizes {sorted(late)} (asked 704x576):\n{out.snapshot()[-3000:]}"
        ros.wait_for(lambda: bool(params), timeout=10.0, period=0.05)
        last = params[-1]
        in_effect = (last.codec, last.width, last.height, last.compression)
        assert in_effect == ("mjpeg", 704, 576, 30), f"video/params says {in_effect}"
    assert "Traceback" not in out.snapshot(), out.snapshot()[-3000:]
