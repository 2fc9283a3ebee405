"""RTP → H.264 access units (RFC 6184) and RTCP sender reports → capture time (RFC 3550), for our RTSP client.

ROS-free, stdlib only. :class:`H264Depacketizer` takes RTP packets as they come off the RTSP TCP connection and
gives complete access units (Annex B): single NAL unit packets, STAP-A aggregates and FU-A fragments; an access
unit ends at the marker bit or when the timestamp changes. Bad input never raises anything but
:class:`RtpPacketError` (a packet that is not RTP at all, or that the depacketiser cannot parse) and never grows
without bound: an access unit with a sequence gap, a fragment out of order or a corrupt NAL header is dropped
whole (:attr:`H264Depacketizer.dropped`; one that held IDR or parameter-set NAL units also counts in
:attr:`H264Depacketizer.dropped_idrs`: what follows cannot be decoded until the next IDR), and the next one
starts clean. :class:`SenderReportClock` maps RTP timestamps to the sender's wall clock from its last sender
report.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Final

from axis_ptz_ros2.vapix.errors import ResponseParseError

CLOCK_RATE: Final = 90_000
NTP_UNIX_OFFSET_S: Final = 2_208_988_800
MAX_ACCESS_UNIT_BYTES: Final = 8 << 20  #: a larger access unit is dropped (bounded buffers)
MAX_NAL_UNITS: Final = 1024
_START: Final = b"\x00\x00\x00\x01"
_STAP_A: Final = 24
_FU_A: Final = 28
_IDR: Final = 5  # IDR slice
_KEY_KINDS: Final = frozenset({_IDR, 7, 8})  # IDR slice, SPS, PPS
_UNIT_START_KINDS: Final = frozenset({6, 7, 8, 9})  # SEI, SPS, PPS, access unit delimiter


def starts_access_unit(payload: bytes) -> bool:
    """Whether an RTP payload begins an access unit: its first NAL unit (or first fragment's) is an access unit
    delimiter, SEI or parameter set, or a slice with ``first_mb_in_slice`` = 0 (its ue(v) is the single bit 1)."""
    if not payload:
        return False
    kind, body = payload[0] & 0x1F, payload[1:]
    if kind == _STAP_A:
        if len(payload) < 4:
            return False
        kind, body = payload[3] & 0x1F, payload[4:]
    elif kind == _FU_A:
        if len(payload) < 3 or not payload[1] & 0x80:  # not the start fragment
            return False
        kind, body = payload[1] & 0x1F, payload[2:]
    if kind in _UNIT_START_KINDS:
        return True
    return kind in (1, 5) and bool(body) and bool(body[0] & 0x80)


class RtpPacketError(ResponseParseError):
    """An RTP or RTCP packet that cannot be parsed (truncated, wrong version, unsupported payload)."""


@dataclass(frozen=True, slots=True)
class RtpPacket:
    """The parts of an RTP header we use, and the payload (padding and extension removed)."""

    marker: bool
    payload_type: int
    seq: int
    timestamp: int
    ssrc: int
    payload: bytes


def parse_rtp(packet: bytes) -> RtpPacket:
    """Parse one RTP packet (RFC 3550 §5.1); :class:`RtpPacketError` if it is not one."""
    if len(packet) < 12:
        raise RtpPacketError(f"RTP packet of {len(packet)} bytes (header is 12)")
    b0, b1, seq, ts, ssrc = struct.unpack_from("!BBHII", packet)
    if b0 >> 6 != 2:
        raise RtpPacketError(f"RTP version {b0 >> 6}, expected 2")
    pos = 12 + 4 * (b0 & 0x0F)
    end = len(packet)
    if b0 & 0x20:  # padding: the last byte counts it
        pad = packet[-1]
        if pad == 0 or pad > end - pos:
            raise RtpPacketError(f"RTP padding of {pad} bytes does not fit the packet")
        end -= pad
    if b0 & 0x10:  # header extension
        if pos + 4 > end:
            raise RtpPacketError("RTP header extension runs past the packet")
        pos += 4 + 4 * struct.unpack_from("!H", packet, pos + 2)[0]
    if pos >= end:
        raise RtpPacketError("RTP packet without payload")
    return RtpPacket(bool(b1 & 0x80), b1 & 0x7F, seq, ts, ssrc, packet[pos:end])


@dataclass(frozen=True, slots=True)
class RtpAccessUnit:
    """One access unit off RTP: Annex B bytes, whether it holds an IDR slice, its RTP time, and what the RTSP client
    learnt about its timing: capture time on the camera's wall clock (None before an RTCP sender report), arrival
    on the host's wall clock (:func:`time.time_ns` when its last packet came), and the latest sender report's RTP
    time and arrival (None before one).

    :class:`H264Depacketizer` fills the first three; :class:`~axis_ptz_ros2.vapix.rtsp_client.RtspClient` gives
    the whole record (SPS/PPS put in front of an IDR). Not :class:`axis_ptz_ros2.media.frame.EncodedFrame`: it
    carries the RTP timing that ``streaming/rtsp_source.py`` turns into one capture stamp when it converts it to an
    ``EncodedFrame``; the rest of the video path never sees RTP time.
    """

    data: bytes
    keyframe: bool
    rtp_timestamp: int
    capture_ns: int | None = None
    arrival_ns: int | None = None
    report_rtp: int | None = None  #: the RTP time of the latest RTCP sender report (None before one)
    report_arrival_ns: int | None = None  #: … and when it arrived (host clock)


class H264Depacketizer:
    """RTP packets of one H.264 stream in, complete access units out (see the module notes)."""

    def __init__(self, payload_type: int | None = None, first_seq: int | None = None) -> None:
        """``payload_type``: accept only this RTP payload type (None: any). ``first_seq``: the sequence number of
        the first packet (``RTP-Info: seq=`` of the PLAY reply); without it, packets lost before the first one
        that arrives cannot be noticed: the first access unit is taken only if its first packet starts one
        (:func:`starts_access_unit`: an AUD, SEI or parameter set, or the first slice of a picture), else dropped."""
        self.payload_type = payload_type
        self.dropped = 0  #: access units dropped (gap, out-of-order fragment, corrupt NAL header, too large)
        self.dropped_idrs = 0  #: … of which held (part of) an IDR or a parameter set
        self.errors = 0  #: packets refused with :class:`RtpPacketError`
        self._nals: list[bytes] = []
        self._kinds: set[int] = set()  # NAL unit types seen in the access unit in progress (also in fragments)
        self._fu: bytearray | None = None
        self._size = 0
        self._ts: int | None = None
        self._seq: int | None = None if first_seq is None else (first_seq - 1) & 0xFFFF
        self._bad = False
        self._unsure_start = first_seq is None

    def push(self, packet: bytes) -> list[RtpAccessUnit]:
        """Add one RTP packet; return the access units it completes (0, 1 or 2)."""
        try:
            rtp = parse_rtp(packet)
        except RtpPacketError:
            self.errors += 1
            self._bad = bool(self._nals or self._fu is not None) or self._bad
            raise
        if self.payload_type is not None and rtp.payload_type != self.payload_type:
            self.errors += 1
            raise RtpPacketError(f"RTP payload type {rtp.payload_type}, expected {self.payload_type}")
        out: list[RtpAccessUnit] = []
        # A lost, reordered or repeated packet: the access unit it falls in cannot be trusted. At a timestamp
        # change nobody can tell whether the missing packets were the old unit's end or the new one's start:
        # both are dropped (never half an access unit).
        gap = self._seq is not None and rtp.seq != (self._seq + 1) & 0xFFFF
        if self._ts is not None and rtp.timestamp != self._ts:
            self._bad = self._bad or gap
            done = self._finish()  # the previous access unit lost its marker packet: it ends here
            if done is not None:
                out.append(done)
        self._bad = self._bad or gap
        if self._unsure_start:  # the first packet of all, without RTP-Info: whole only if it starts a unit
            self._unsure_start = False
            self._bad = self._bad or not starts_access_unit(rtp.payload)
        self._seq = rtp.seq
        self._ts = rtp.timestamp
        self._payload(rtp.payload)
        if rtp.marker:
            done = self._finish()
            if done is not None:
                out.append(done)
        return out

    def flush(self) -> RtpAccessUnit | None:
        """The access unit in progress, if complete and sound (at the end of a stream)."""
        return self._finish()

    def _payload(self, payload: bytes) -> None:
        header = payload[0]
        kind = header & 0x1F
        self._kinds.add(payload[1] & 0x1F if kind == _FU_A and len(payload) > 1 else kind)
        if header & 0x80:  # forbidden_zero_bit
            self._bad = True
        elif 1 <= kind <= 23:
            self._end_fragment_missing()
            self._add(payload)
        elif kind == _STAP_A:
            self._end_fragment_missing()
            pos = 1
            while pos < len(payload):
                if pos + 2 > len(payload):
                    self._bad = True
                    return
                n = struct.unpack_from("!H", payload, pos)[0]
                if n == 0 or pos + 2 + n > len(payload):
                    self._bad = True
                    return
                self._kinds.add(payload[pos + 2] & 0x1F)
                self._add(payload[pos + 2 : pos + 2 + n])
                pos += 2 + n
        elif kind == _FU_A:
            if len(payload) < 3:
                self._bad = True
                return
            fu = payload[1]
            start, end = bool(fu & 0x80), bool(fu & 0x40)
            if start and end:
                self._bad = True  # RFC 6184 §5.8: both set is not allowed
            elif start:
                self._end_fragment_missing()
                self._fu = bytearray([(header & 0xE0) | (fu & 0x1F)])
                self._fu += payload[2:]
            elif self._fu is None:
                self._bad = True  # a middle or end fragment without its start
            else:
                self._fu += payload[2:]
                if end:
                    nal, self._fu = bytes(self._fu), None
                    self._add(nal)
            if self._fu is not None and len(self._fu) + self._size > MAX_ACCESS_UNIT_BYTES:
                self._bad, self._fu = True, None
        else:
            self._bad = True  # STAP-B, MTAP, FU-B, reserved: not sent in packetization-mode 1

    def _end_fragment_missing(self) -> None:
        if self._fu is not None:  # a fragmented NAL unit never got its end
            self._bad, self._fu = True, None

    def _add(self, nal: bytes) -> None:
        if not nal or nal[0] & 0x80 or not 1 <= nal[0] & 0x1F <= 23:
            self._bad = True
            return
        self._size += len(nal) + 4
        if self._size > MAX_ACCESS_UNIT_BYTES or len(self._nals) >= MAX_NAL_UNITS:
            self._bad = True
            return
        self._nals.append(nal)

    def _finish(self) -> RtpAccessUnit | None:
        nals, bad, ts, kinds = self._nals, self._bad or self._fu is not None, self._ts, self._kinds
        self._nals, self._fu, self._size, self._bad, self._ts, self._kinds = [], None, 0, False, None, set()
        if bad or not nals or ts is None:
            if bad:
                self.dropped += 1
                self.dropped_idrs += bool(kinds & _KEY_KINDS)
            return None
        return RtpAccessUnit(b"".join(_START + n for n in nals), _IDR in kinds, ts)


@dataclass(frozen=True, slots=True)
class SenderReport:
    """The clock pair of an RTCP sender report."""

    ssrc: int
    unix_ns: int
    rtp_timestamp: int


def parse_sender_report(packet: bytes) -> SenderReport | None:
    """The sender report in a (compound) RTCP packet; None if it holds none; :class:`RtpPacketError` if garbage."""
    pos = 0
    while pos + 4 <= len(packet):
        b0, pt, words = struct.unpack_from("!BBH", packet, pos)
        if b0 >> 6 != 2:
            raise RtpPacketError(f"RTCP version {b0 >> 6}, expected 2")
        size = 4 * (words + 1)
        if pos + size > len(packet):
            raise RtpPacketError("RTCP packet runs past its frame")
        if pt == 200:
            if size < 28:
                raise RtpPacketError("RTCP sender report shorter than 28 bytes")
            ssrc, msw, lsw, rtp_ts = struct.unpack_from("!IIII", packet, pos + 4)
            unix_ns = (msw - NTP_UNIX_OFFSET_S) * 1_000_000_000 + (lsw * 1_000_000_000 >> 32)
            return SenderReport(ssrc, unix_ns, rtp_ts)
        pos += size
    if pos != len(packet):
        raise RtpPacketError("RTCP packet truncated")
    return None


class SenderReportClock:
    """RTP timestamp → the sender's wall clock (ns), from its latest sender report."""

    def __init__(self, clock_rate: int = CLOCK_RATE) -> None:
        self.clock_rate = clock_rate
        self.report: SenderReport | None = None

    def update(self, report: SenderReport) -> None:
        self.report = report

    def unix_ns(self, rtp_timestamp: int) -> int | None:
        """The capture time of ``rtp_timestamp`` (None before the first sender report)."""
        r = self.report
        if r is None:
            return None
        diff = (rtp_timestamp - r.rtp_timestamp) & 0xFFFFFFFF
        if diff >= 1 << 31:
            diff -= 1 << 32  # before the report (32-bit wrap-around)
        return r.unix_ns + diff * 1_000_000_000 // self.clock_rate
