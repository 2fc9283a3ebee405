"""One RTSP session of the simulated camera: the live H.264 stream of the camera's view (ROS-free).

Each frame: the capture time taken (``time.time_ns()``), the view at the session's size as the MJPEG side makes
it (rendered, softened and with sensor noise by the persona's camera model), encoded by
:class:`~axis_ptz_ros2.media.encoder.H264Encoder` (libx264, Constrained Baseline, no B-frames), the SPS/PPS
removed when they are the SDP's (an Axis camera sends them only in the SDP by default),
the capture time put in an SEI (:func:`~axis_ptz_ros2.media.annexb.insert_capture_stamp`), then RTP on the 90 kHz
clock tied to the wall clock (RTP time = ``rtp0 + (t − t0)·90 kHz``), so the RTCP sender reports (one before the
first frame, then every second) give a client the capture time of every frame.

Faults (:class:`~axis_ptz_ros2.sim.faults.FaultConfig`, per session): ``stall_after_frames`` /
``stall_seconds`` (nothing sent, connection open), ``drop_after_frames`` (the connection closes mid access unit),
``clock_offset_s`` (the sender reports' wall clock is off the true time by that much, as a camera without NTP; the RTP
clock and the SEI capture stamp are unchanged).
"""

from __future__ import annotations

import contextlib
import secrets
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import cv2
import numpy as np
import numpy.typing as npt

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.errors import EncoderError
from axis_ptz_ros2.sim.rtsp.media import MediaRequest
from axis_ptz_ros2.sim.rtsp.rtp import CLOCK_RATE, H264Packetizer, interleave, sender_report
from axis_ptz_ros2.sim.view import CameraView

if TYPE_CHECKING:  # PyAV: imported when a session first encodes (the simulator runs MJPEG-only without it)
    from axis_ptz_ros2.media.encoder import H264Encoder

SR_INTERVAL_S = 1.0  #: seconds between RTCP sender reports (RFC 3550 allows ~5 s; 1 s lets clients sync fast)


class StreamClosedError(Exception):
    """The connection carrying the session's RTP cannot be written to any more."""


class RtspSession:
    """A session: SETUP made it, PLAY starts its stream thread, TEARDOWN or a timeout ends it."""

    def __init__(
        self,
        cam: CameraView,
        request: MediaRequest,
        params: annexb.ParameterSets,
        timeout_s: float,
        send: Callable[[bytes], None],
        on_drop: Callable[[], None],
    ) -> None:
        """``send`` writes interleaved bytes to the connection (thread-safe); ``on_drop`` closes it."""
        self.id = secrets.token_hex(8).upper()
        self.cam = cam
        self.request = request
        self.params = params
        self.timeout_s = timeout_s
        self.channels = (0, 1)
        self.last_seen = time.monotonic()
        self.packetizer = H264Packetizer()
        self.frames = 0  #: access units sent
        self.idrs = 0  #: IDR access units sent
        self._send = send
        self._on_drop = on_drop
        self._fps = request.fps
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self._encoder: H264Encoder | None = None
        self._renew = False
        self._t0_ns = 0
        self._rtp0 = secrets.randbits(32)
        self._view_key: tuple[float, float, float] | None = None
        self._soft: npt.NDArray[np.uint8] | None = None
        self._noise: tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint8]] | None = None
        self._rng = np.random.default_rng()

    @property
    def playing(self) -> bool:
        """Whether the stream thread runs."""
        return self._thread is not None and self._thread.is_alive()

    def touch(self) -> None:
        """A keep-alive: the session lives another ``timeout_s``."""
        self.last_seen = time.monotonic()

    def expired(self) -> bool:
        """No keep-alive for longer than the timeout."""
        return time.monotonic() - self.last_seen > self.timeout_s

    def rtp_time(self, unix_ns: int) -> int:
        """The RTP timestamp of wall-clock time ``unix_ns`` (32 bits)."""
        return (self._rtp0 + (unix_ns - self._t0_ns) * CLOCK_RATE // 1_000_000_000) & 0xFFFFFFFF

    def prepare_play(self) -> tuple[int, int]:
        """Fix the clock origin for PLAY; the ``(seq, rtptime)`` of the first packet (for ``RTP-Info``)."""
        self._t0_ns = time.time_ns()
        return self.packetizer.seq, self.rtp_time(self._t0_ns)

    def play(self) -> None:
        """Start streaming (nothing if already playing)."""
        if self.playing:
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=f"rtsp-session-{self.id}", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """End the stream (returns at once; the thread ends after the frame it is on)."""
        self._stop.set()

    def renew(self) -> None:
        """``Renew-Stream: yes``: the next frame is an IDR."""
        with self._lock:
            self._renew = True

    def adjust(self, fps: int | None, max_bitrate_kbps: int | None) -> None:
        """``Adjustable-Stream-Configuration``: new frame rate and/or bitrate from the next frame on."""
        with self._lock:
            if fps is not None:
                self._fps = fps
            if max_bitrate_kbps is not None:
                self._bitrate_kbps = max_bitrate_kbps

    _bitrate_kbps: int | None = None  # a bitrate asked for and not yet applied (the stream loop takes it)

    @property
    def bitrate_kbps(self) -> int | None:
        """The bitrate (kbit/s) the session's encoder runs at now (None before its first frame)."""
        enc = self._encoder
        return None if enc is None else enc.settings.bitrate_kbps

    # ---- the stream ------------------------------------------------------------------------------------
    def _run(self) -> None:
        with contextlib.suppress(StreamClosedError):
            self._stream()

    def _stream(self) -> None:
        cam = self.cam
        req = self.request
        from axis_ptz_ros2.media.encoder import H264Encoder  # noqa: PLC0415 - PyAV, on first use

        self._encoder = enc = H264Encoder(req.h264_settings(), req.width, req.height)
        gen = cam.generation
        next_t = time.monotonic()
        last_sr = -1.0
        stalled = False
        while not self._stop.is_set() and not cam.stopping.is_set() and gen == cam.generation:
            if cam.blackholed:
                return
            with self._lock:
                renew, self._renew = self._renew, False
                fps, bitrate = self._fps, self._bitrate_kbps
                self._bitrate_kbps = None
            if renew:
                enc.request_idr()
            if bitrate is not None:
                enc.set_bitrate(bitrate)
            capture_ns = time.time_ns()
            image = self._picture()
            try:
                frame = enc.encode_bgr(image, capture_ns)
            except EncoderError:
                return  # an encoder fault ends the stream as a camera's would: the client sees the stall
            au = self._wire_access_unit(frame.data, frame.keyframe, capture_ns)
            now_ns = time.time_ns()
            if time.monotonic() - last_sr >= SR_INTERVAL_S:
                self._send_sr(now_ns)
                last_sr = time.monotonic()
            faults = cam.faults
            packets = self.packetizer.packetize(au, self.rtp_time(capture_ns))
            if faults.drop_after_frames and self.frames + 1 >= faults.drop_after_frames:
                self._send(b"".join(interleave(self.channels[0], p) for p in packets[: max(1, len(packets) // 2)]))
                self._on_drop()
                return
            self._send(b"".join(interleave(self.channels[0], p) for p in packets))
            self.frames += 1
            self.idrs += frame.keyframe
            if faults.stall_after_frames and self.frames == faults.stall_after_frames and not stalled:
                stalled = True
                if self._stop.wait(faults.stall_seconds):
                    return
                next_t = time.monotonic()
            next_t += 1.0 / fps
            delay = next_t - time.monotonic()
            if delay < -1.0 / fps:
                next_t = time.monotonic()  # fell behind (slow render, stall): do not burst
            elif delay > 0:
                self._stop.wait(delay)

    def _picture(self) -> npt.NDArray[np.uint8]:
        """The view as the sensor sees it, as on the MJPEG side (the persona's camera model: the optics' and
        video chain's softness once per view, a new draw of sensor noise per frame); rendered only on a move."""
        cam, req = self.cam, self.request
        pan, tilt, zoom = cam.position()
        key = (round(pan, 5), round(tilt, 5), round(zoom, 3))
        model = cam.persona.picture
        if key != self._view_key or self._soft is None:
            self._soft = model.soften(cam.renderer.render(pan, tilt, zoom, req.width, req.height), zoom)
            self._view_key = key
        if not model.noisy:
            return self._soft
        if self._noise is None:
            self._noise = model.noise_field(req.width, req.height)
        pos, neg = self._noise
        h, w = req.height, req.width
        dy = int(self._rng.integers(0, pos.shape[0] - h + 1))
        dx = int(self._rng.integers(0, pos.shape[1] - w + 1))
        noisy = cv2.subtract(cv2.add(self._soft, pos[dy : dy + h, dx : dx + w]), neg[dy : dy + h, dx : dx + w])
        return np.asarray(noisy, dtype=np.uint8)

    def _wire_access_unit(self, data: bytes, keyframe: bool, capture_ns: int) -> bytes:
        """What the camera sends for one frame: SPS/PPS dropped when the SDP has them, capture-time SEI added."""
        if keyframe:
            nals = annexb.split_nal_units(data)
            sdp_sets = (self.params.sps, self.params.pps)
            sps = [n for n in nals if n[0] & 0x1F == annexb.NalType.SPS]
            pps = [n for n in nals if n[0] & 0x1F == annexb.NalType.PPS]
            if sps == [sdp_sets[0]] and pps == [sdp_sets[1]]:
                keep = (annexb.NalType.SPS, annexb.NalType.PPS)
                data = annexb.join_nal_units(n for n in nals if n[0] & 0x1F not in keep)
            # else: the parameter sets changed (an encoder re-open): in-band, as a camera must
        return annexb.insert_capture_stamp(data, capture_ns)

    def _send_sr(self, now_ns: int) -> None:
        p = self.packetizer
        wall_ns = now_ns + round(self.cam.faults.clock_offset_s * 1e9)  # the camera's clock (clock_offset_s fault)
        rtcp = sender_report(p.ssrc, wall_ns, self.rtp_time(now_ns), p.packets, p.octets, f"axis-sim@{self.cam.mac}")
        self._send(interleave(self.channels[1], rtcp))
