"""RTP for H.264 (RFC 6184) and RTCP sender reports (RFC 3550), as the simulated camera sends them (ROS-free).

- :class:`H264Packetizer`: one access unit (Annex B) → RTP packets: a NAL unit that fits the payload size goes
  alone (single NAL unit packet, RFC 6184 §5.6), a larger one in FU-A fragments (§5.8); the marker bit is set on
  the last packet of the access unit; payload type 96; timestamps on the 90 kHz clock.
- :func:`sender_report`: a compound RTCP packet (SR + SDES CNAME) that ties the RTP clock to the NTP wall clock,
  which is how a client computes capture time.
- :func:`interleave`: RTP/RTCP over the RTSP TCP connection (RFC 2326 §10.12, ``$`` channel length).
"""

from __future__ import annotations

import secrets
import struct
from typing import Final

from axis_ptz_ros2.media import annexb

PAYLOAD_TYPE: Final = 96
CLOCK_RATE: Final = 90_000
MAX_PAYLOAD: Final = 1400  #: bytes of RTP payload per packet (an Ethernet MTU's worth, as cameras use)
NTP_UNIX_OFFSET_S: Final = 2_208_988_800  #: seconds from 1900-01-01 (NTP era 0) to 1970-01-01
_FU_A: Final = 28


class H264Packetizer:
    """RTP packets of one H.264 stream: random SSRC and initial sequence number, counters for the SR."""

    def __init__(self, max_payload: int = MAX_PAYLOAD, ssrc: int | None = None) -> None:
        """``max_payload`` bytes of RTP payload at most per packet (≥ 16)."""
        if max_payload < 16:
            raise ValueError("max_payload must be >= 16")
        self.max_payload = max_payload
        self.ssrc = secrets.randbits(32) if ssrc is None else ssrc
        self.seq = secrets.randbits(16)
        self.packets = 0  #: packets sent (for the SR)
        self.octets = 0  #: payload octets sent (for the SR)

    def packetize(self, access_unit: bytes, timestamp: int) -> list[bytes]:
        """The RTP packets of one access unit (Annex B), all with ``timestamp`` (90 kHz, wrapped to 32 bits)."""
        payloads: list[bytes] = []
        for nal in annexb.split_nal_units(access_unit):
            if len(nal) <= self.max_payload:
                payloads.append(nal)
                continue
            header = nal[0]
            indicator = (header & 0xE0) | _FU_A
            body = nal[1:]
            step = self.max_payload - 2
            for start in range(0, len(body), step):
                chunk = body[start : start + step]
                fu = header & 0x1F
                if start == 0:
                    fu |= 0x80  # S
                if start + step >= len(body):
                    fu |= 0x40  # E
                payloads.append(bytes([indicator, fu]) + chunk)
        out = []
        for i, payload in enumerate(payloads):
            marker = 0x80 if i == len(payloads) - 1 else 0
            head = struct.pack("!BBHII", 0x80, marker | PAYLOAD_TYPE, self.seq, timestamp & 0xFFFFFFFF, self.ssrc)
            self.seq = (self.seq + 1) & 0xFFFF
            self.packets += 1
            self.octets += len(payload)
            out.append(head + payload)
        return out


def ntp_timestamp(unix_ns: int) -> tuple[int, int]:
    """The 64-bit NTP timestamp (seconds since 1900, fraction of 2**-32 s) of a Unix time in ns."""
    secs, rem = divmod(unix_ns, 1_000_000_000)
    return (secs + NTP_UNIX_OFFSET_S) & 0xFFFFFFFF, (rem << 32) // 1_000_000_000


def sender_report(ssrc: int, unix_ns: int, rtp_timestamp: int, packets: int, octets: int, cname: str) -> bytes:
    """Compound RTCP: a sender report (wall clock ``unix_ns`` ↔ ``rtp_timestamp``) and an SDES with CNAME."""
    msw, lsw = ntp_timestamp(unix_ns)
    sr = struct.pack(
        "!BBHIIIIII",
        0x80,
        200,
        6,
        ssrc,
        msw,
        lsw,
        rtp_timestamp & 0xFFFFFFFF,
        packets & 0xFFFFFFFF,
        octets & 0xFFFFFFFF,
    )
    text = cname.encode()[:255]
    chunk = struct.pack("!IBB", ssrc, 1, len(text)) + text + b"\x00"
    chunk += b"\x00" * (-len(chunk) % 4)
    sdes = struct.pack("!BBH", 0x81, 202, len(chunk) // 4) + chunk
    return sr + sdes


def interleave(channel: int, packet: bytes) -> bytes:
    """``packet`` framed for the RTSP TCP connection: ``$``, channel, 16-bit length."""
    if not 0 <= channel <= 255 or len(packet) > 0xFFFF:
        raise ValueError("interleaved channel must be 0…255 and the packet at most 65535 bytes")
    return struct.pack("!cBH", b"$", channel, len(packet)) + packet
