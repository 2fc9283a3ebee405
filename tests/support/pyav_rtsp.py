"""FFmpeg's RTSP client through PyAV, as an independent oracle for the tests (moved out of ``vapix/rtsp.py``: the
product plays RTSP with its own client, :class:`~axis_ptz_ros2.vapix.rtsp_client.RtspClient`).

:class:`RtspReader` plays a media URL with FFmpeg's RTSP client: RTP interleaved on the RTSP TCP connection, open and
read timeouts (without them ``demux()`` hangs on a stalled camera), packets sharing a pts merged into one access
unit, capture time from the RTCP sender reports (``start_time_realtime`` + pts, PyAV 18.1), SPS/PPS from the SDP
(``extradata``) prepended to every IDR that lacks them. Credentials go in the URL (FFmpeg's only way); that URL never
reaches a repr or an exception message (:func:`~axis_ptz_ros2.vapix.errors.redact`).
"""

from __future__ import annotations

import urllib.parse
from collections.abc import Iterator
from dataclasses import dataclass, field
from fractions import Fraction

import av
import av.error

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.errors import BitstreamError
from axis_ptz_ros2.vapix.errors import (
    AuthError,
    CameraTimeout,
    CameraUnreachable,
    InvalidArgument,
    ResponseParseError,
    redact,
)


# ---- access units out of FFmpeg's packets ------------------------------------------------------------------------
@dataclass(slots=True)
class AccessUnitMerger:
    """Packets that share a pts are one access unit (FFmpeg's parser can split an IDR when the server repeats
    SPS/PPS in band): hold the last one until a packet with another pts arrives."""

    _pts: int | None = None
    _parts: list[bytes] = field(default_factory=list)
    merged: int = 0  #: packets appended to an access unit already begun

    def push(self, pts: int | None, data: bytes) -> tuple[int | None, bytes] | None:
        """Add a packet; return the previous access unit (pts, Annex B) when this one starts a new one."""
        out = None
        if self._parts and pts != self._pts:
            out = (self._pts, b"".join(self._parts))
            self._parts = []
        elif self._parts:
            self.merged += 1
        self._pts = pts
        if data:
            self._parts.append(data)
        return out

    def flush(self) -> tuple[int | None, bytes] | None:
        """The held access unit, if any."""
        if not self._parts:
            return None
        out = (self._pts, b"".join(self._parts))
        self._parts = []
        return out


@dataclass(frozen=True, slots=True)
class RtspAccessUnit:
    """One access unit from the camera: Annex B (SPS/PPS in front of every IDR), its pts and capture time."""

    data: bytes
    keyframe: bool
    pts: int
    capture_ns: int | None  # camera wall clock (RTCP sender reports); None until the first report


class RtspReader:
    """Play an RTSP H.264 stream with PyAV; iterate :meth:`access_units` (raises :class:`AxisPtzError` kinds).

    ``open_timeout_s``/``read_timeout_s`` bound every blocking call; a stalled camera raises
    :class:`CameraTimeout` instead of hanging.
    """

    def __init__(
        self,
        url: str,
        *,
        open_timeout_s: float = 5.0,
        read_timeout_s: float = 3.0,
        secrets: tuple[str | None, ...] = (),
    ) -> None:
        self._url = url
        self._open_timeout_s = open_timeout_s
        self._read_timeout_s = read_timeout_s
        self._secrets = secrets
        self._container: av.container.InputContainer | None = None
        self._params: annexb.ParameterSetTracker | None = None
        self._merger = AccessUnitMerger()

    def __repr__(self) -> str:
        return f"RtspReader({redact(self._url, self._secrets)!r})"

    def open(self) -> None:
        """Connect, DESCRIBE/SETUP/PLAY (FFmpeg), and take SPS/PPS from the SDP."""
        options = {
            "rtsp_transport": "tcp",
            "timeout": str(int(self._read_timeout_s * 1e6)),  # socket I/O timeout, µs
            "fflags": "nobuffer",
            "probesize": "32768",
            "analyzeduration": "500000",
        }
        try:
            container = av.open(self._url, options=options, timeout=(self._open_timeout_s, self._read_timeout_s))
        except av.error.HTTPUnauthorizedError as err:
            raise AuthError(f"RTSP {self._where()}: credentials refused (401)") from err
        except av.error.HTTPNotFoundError as err:
            raise CameraUnreachable(f"RTSP {self._where()}: no such stream (404)") from err
        except av.error.ExitError as err:  # FFmpeg's interrupt callback: the timeout fired
            raise CameraTimeout(f"RTSP {self._where()}: no answer within {self._open_timeout_s} s") from err
        except (av.error.FFmpegError, OSError) as err:
            raise CameraUnreachable(f"RTSP {self._where()}: {redact(str(err), self._secrets_all())}") from err
        if not container.streams.video:
            container.close()
            raise ResponseParseError(f"RTSP {self._where()}: the stream has no video")
        self._container = container
        self._params = annexb.ParameterSetTracker(self._sdp_parameter_sets())

    @property
    def merged_packets(self) -> int:
        """Packets merged into an access unit that had begun (split IDRs)."""
        return self._merger.merged

    def close(self) -> None:
        if self._container is not None:
            self._container.close()
            self._container = None

    def __enter__(self) -> RtspReader:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def access_units(self) -> Iterator[RtspAccessUnit]:
        """Access units as they arrive (equal-pts packets merged); ends when the stream ends."""
        container = self._container
        if container is None or self._params is None:
            raise InvalidArgument("RtspReader.access_units() before open()")
        stream = container.streams.video[0]
        tb = stream.time_base
        merger = self._merger = AccessUnitMerger()
        try:
            for packet in container.demux(stream):
                if packet.size == 0 and packet.pts is None:
                    continue  # demux's end-of-stream marker
                done = merger.push(packet.pts, bytes(packet))
                if done is not None:
                    au = self._finish(done, tb)
                    if au is not None:
                        yield au
        except av.error.ExitError as err:
            raise CameraTimeout(f"RTSP {self._where()}: no data within {self._read_timeout_s} s") from err
        except (av.error.FFmpegError, OSError) as err:
            raise CameraUnreachable(f"RTSP {self._where()}: {redact(str(err), self._secrets_all())}") from err
        last = merger.flush()
        if last is not None:
            au = self._finish(last, tb)
            if au is not None:
                yield au

    # ---- internals ---------------------------------------------------------------------------------------------
    def _finish(self, item: tuple[int | None, bytes], time_base: Fraction | None) -> RtspAccessUnit | None:
        pts, data = item
        assert self._params is not None
        assert self._container is not None
        try:
            data = self._params.process(data)
            key = annexb.is_idr(data)
        except BitstreamError:
            return None  # corrupt or undecodable access unit: dropped (the node counts it)
        capture_ns = None
        start_us = self._container.start_time_realtime
        if start_us is not None and start_us > 0 and pts is not None and time_base is not None:
            capture_ns = int(start_us) * 1000 + int(pts * time_base * 1_000_000_000)
        return RtspAccessUnit(data, key, pts if pts is not None else -1, capture_ns)

    def _sdp_parameter_sets(self) -> annexb.ParameterSets | None:
        assert self._container is not None
        extradata = self._container.streams.video[0].codec_context.extradata
        if not extradata:
            return None
        try:
            nals = annexb.split_nal_units(bytes(extradata))
            sps = next(n for n in nals if n[0] & 0x1F == annexb.NalType.SPS)
            pps = next(n for n in nals if n[0] & 0x1F == annexb.NalType.PPS)
            return annexb.ParameterSets(sps, pps)
        except (BitstreamError, StopIteration):
            return None

    def _secrets_all(self) -> tuple[str | None, ...]:
        return (*self._secrets, self._url)

    def _where(self) -> str:
        p = urllib.parse.urlsplit(self._url)
        return f"{p.hostname}:{p.port or 554}{p.path}"
