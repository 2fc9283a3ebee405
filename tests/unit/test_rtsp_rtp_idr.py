"""The depacketiser's two additions for issue 40 (vapix/rtsp_rtp.py): without ``RTP-Info`` the first access unit
is taken when its first packet starts one (and dropped when it does not); a dropped access unit that held an IDR
or a parameter set is counted apart (``dropped_idrs``: what follows cannot be decoded until the next IDR)."""

from __future__ import annotations

import pytest

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.sim.rtsp.rtp import H264Packetizer
from axis_ptz_ros2.vapix.rtsp_rtp import H264Depacketizer, starts_access_unit

pytestmark = pytest.mark.unit


def _slice(kind: int, first_mb_zero: bool, size: int) -> bytes:
    """A slice NAL unit whose header starts with first_mb_in_slice = 0 (bit 1) or not (bits 010 = 1)."""
    lead = 0x88 if first_mb_zero else 0x40
    return bytes([0x60 | kind, lead]) + bytes((i * 7) % 251 + 1 for i in range(size - 2))


IDR = annexb.join_nal_units([bytes([0x06, 0x05, 0x01, 0x80]), _slice(5, True, 500)])
P = annexb.join_nal_units([_slice(1, True, 300)])


def test_unit_starts_are_recognised_in_every_packetisation() -> None:
    assert starts_access_unit(_slice(5, True, 10))
    assert starts_access_unit(_slice(1, True, 10))
    assert not starts_access_unit(_slice(1, False, 10))  # the second slice of a picture
    assert starts_access_unit(bytes([0x06, 0x05]))  # SEI
    assert starts_access_unit(bytes([0x09, 0xF0]))  # access unit delimiter
    assert starts_access_unit(bytes([0x7C, 0x85, 0x88, 0x00]))  # FU-A start of an IDR slice, first_mb 0
    assert not starts_access_unit(bytes([0x7C, 0x05, 0x88, 0x00]))  # FU-A middle fragment
    assert not starts_access_unit(bytes([0x7C, 0x85, 0x40, 0x00]))  # FU-A start of a later slice
    assert starts_access_unit(bytes([0x78, 0x00, 0x02, 0x67, 0x42]))  # STAP-A beginning with an SPS
    assert not starts_access_unit(b"")
    assert not starts_access_unit(bytes([0x7C]))


def test_without_rtp_info_the_first_idr_is_taken_when_whole() -> None:
    p = H264Packetizer(max_payload=120)
    packets = p.packetize(IDR, 0) + p.packetize(P, 3000)
    d = H264Depacketizer()
    out = [u for pkt in packets for u in d.push(pkt)]
    assert [u.data for u in out] == [IDR, P]
    assert [u.keyframe for u in out] == [True, False]  # the IDR slice is seen, also in FU-A fragments
    assert d.dropped == 0


def test_without_rtp_info_a_first_packet_in_the_middle_drops_that_unit_as_a_lost_idr() -> None:
    p = H264Packetizer(max_payload=120)
    packets = p.packetize(IDR, 0) + p.packetize(P, 3000)
    d = H264Depacketizer()
    out = [u for pkt in packets[2:] for u in d.push(pkt)]  # joined after the IDR's start
    assert [u.data for u in out] == [P]
    assert (d.dropped, d.dropped_idrs) == (1, 1)


def test_a_lost_p_frame_fragment_is_no_lost_idr() -> None:
    p = H264Packetizer(max_payload=120)
    d = H264Depacketizer(first_seq=p.seq)
    idr, pf, idr2 = p.packetize(IDR, 0), p.packetize(P, 3000), p.packetize(IDR, 6000)
    out = [u for pkt in idr + pf[:1] + pf[2:] + idr2 for u in d.push(pkt)]
    assert [u.rtp_timestamp for u in out] == [0, 6000]
    assert (d.dropped, d.dropped_idrs) == (1, 0)
    d2 = H264Depacketizer(first_seq=p.seq)
    idr, pf = p.packetize(IDR, 9000), p.packetize(P, 12000)
    out = [u for pkt in idr[:1] + idr[2:] + pf for u in d2.push(pkt)]
    assert [u.rtp_timestamp for u in out] == [12000]
    assert (d2.dropped, d2.dropped_idrs) == (1, 1)
