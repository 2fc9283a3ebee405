"""RTP for H.264 both ways: the simulator's packetiser (sim/rtsp/rtp.py) and our client's depacketiser
(vapix/rtsp_rtp.py), RTCP sender reports, and what the depacketiser does with damaged input (hypothesis).

Damaged input (truncated, lost, reordered, duplicated or corrupted packets) must give a typed error
(:class:`RtpPacketError`) or a dropped access unit, never another exception, never half an access unit, and
never unbounded buffering.
"""

from __future__ import annotations

import contextlib
import os
import struct

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.sim.rtsp.rtp import H264Packetizer, interleave, ntp_timestamp, sender_report
from axis_ptz_ros2.vapix.rtsp_rtp import (
    H264Depacketizer,
    RtpPacketError,
    SenderReportClock,
    parse_rtp,
    parse_sender_report,
)

pytestmark = pytest.mark.unit


def _nal(kind: int, size: int, seed: int = 0) -> bytes:
    body = bytes((seed + i * 7) % 251 + 1 for i in range(size - 1))  # no zero bytes: no start-code emulation
    return bytes([0x60 | kind]) + body


def _au(*sizes: int, idr: bool = False) -> bytes:
    kinds = [annexb.NalType.SEI] + [annexb.NalType.IDR if idr else 1] * (len(sizes) - 1)
    return annexb.join_nal_units(_nal(int(k), s, i) for i, (k, s) in enumerate(zip(kinds, sizes, strict=True)))


def test_small_nal_units_go_alone_large_ones_in_fu_a_and_the_marker_ends_the_access_unit() -> None:
    p = H264Packetizer(max_payload=100, ssrc=0x1234)
    packets = p.packetize(_au(40, 350), 90_000)
    kinds = [pkt[12] & 0x1F for pkt in packets]
    assert kinds[0] == annexb.NalType.SEI  # single NAL unit packet
    assert kinds[1:] == [28] * 4  # 349 bytes after the header in ≤ 98-byte fragments
    fu = [pkt[13] for pkt in packets[1:]]
    assert [f & 0xC0 for f in fu] == [0x80, 0, 0, 0x40]  # S on the first fragment, E on the last
    assert [pkt[1] >> 7 for pkt in packets] == [0, 0, 0, 0, 1]
    assert all(len(pkt) <= 112 for pkt in packets)
    seqs = [struct.unpack_from("!H", pkt, 2)[0] for pkt in packets]
    assert seqs == [(seqs[0] + i) & 0xFFFF for i in range(5)]
    assert {struct.unpack_from("!I", pkt, 4)[0] for pkt in packets} == {90_000}


def test_round_trip_of_many_access_units() -> None:
    p = H264Packetizer(max_payload=200)
    d = H264Depacketizer(payload_type=96, first_seq=p.seq)
    aus = [_au(30, 1000 + 97 * i, idr=i % 5 == 0) for i in range(40)]
    out = []
    for i, au in enumerate(aus):
        for pkt in p.packetize(au, 3000 * i):
            out += d.push(pkt)
    assert [u.data for u in out] == aus
    assert [u.rtp_timestamp for u in out] == [3000 * i for i in range(40)]
    assert d.dropped == 0


def test_a_lost_fragment_drops_its_access_unit_and_the_next_one_is_whole() -> None:
    p = H264Packetizer(max_payload=200)
    d = H264Depacketizer(first_seq=p.seq)
    first, second = p.packetize(_au(30, 900), 0), p.packetize(_au(30, 700), 3000)
    out = [u for pkt in first[:2] + first[3:] + second for u in d.push(pkt)]
    assert [u.data for u in out] == [_au(30, 700)]
    assert d.dropped == 1


def test_a_lost_marker_packet_drops_both_access_units_it_may_belong_to() -> None:
    p = H264Packetizer(max_payload=200)
    d = H264Depacketizer(first_seq=p.seq)
    first, second, third = (p.packetize(_au(30, 150 + i), 3000 * i) for i in range(3))
    out = [u for pkt in first[:-1] + second + third for u in d.push(pkt)]
    assert [u.data for u in out] == [_au(30, 152)]  # never half a unit: the next whole one
    assert d.dropped == 2


def test_without_the_first_sequence_number_the_first_access_unit_is_dropped() -> None:
    p = H264Packetizer(max_payload=200)
    packets = [pkt for i in range(2) for pkt in p.packetize(_au(30, 400), 3000 * i)]
    d = H264Depacketizer()
    assert [u.rtp_timestamp for pkt in packets[1:] for u in d.push(pkt)] == [3000]


def test_a_timestamp_change_without_a_gap_ends_an_access_unit_that_lacks_its_marker() -> None:
    d = H264Depacketizer(first_seq=1)
    first = struct.pack("!BBHII", 0x80, 96, 1, 0, 1) + _nal(1, 30)
    second = struct.pack("!BBHII", 0x80, 96 | 0x80, 2, 3000, 1) + _nal(1, 20)
    assert d.push(first) == []
    assert [u.data for u in d.push(second)] == [
        annexb.join_nal_units([_nal(1, 30)]),
        annexb.join_nal_units([_nal(1, 20)]),
    ]


@pytest.mark.parametrize("packet", [b"", b"\x80\x60", b"\x40" + bytes(15), b"\xa0\x60" + bytes(10) + b"\x00"])
def test_garbage_packets_are_typed_errors(packet: bytes) -> None:
    with pytest.raises(RtpPacketError):
        H264Depacketizer().push(packet)


def test_sender_report_maps_rtp_time_to_the_wall_clock() -> None:
    unix_ns = 1_795_000_000_123_456_789
    rtcp = sender_report(0xABCD, unix_ns, 4_000_000_000, 10, 1000, "cam")
    assert interleave(1, rtcp)[:4] == b"$\x01" + struct.pack("!H", len(rtcp))
    report = parse_sender_report(rtcp)
    assert report is not None
    assert abs(report.unix_ns - unix_ns) < 2  # NTP fraction rounding
    clock = SenderReportClock()
    assert clock.unix_ns(0) is None
    clock.update(report)
    assert abs(clock.unix_ns(4_000_000_000 + 90_000) - (unix_ns + 1_000_000_000)) < 2
    wrapped = (4_000_000_000 + 900_000) & 0xFFFFFFFF  # 10 s later, past the 32-bit wrap
    assert abs(clock.unix_ns(wrapped) - (unix_ns + 10_000_000_000)) < 2
    assert abs(clock.unix_ns(4_000_000_000 - 9000) - (unix_ns - 100_000_000)) < 2
    assert ntp_timestamp(0)[0] == 2_208_988_800
    with pytest.raises(RtpPacketError):
        parse_sender_report(rtcp[:20])


# ---- damaged input (hypothesis) ---------------------------------------------------------------------------------
_AUS = [_au(20, 60 + 53 * i, idr=i == 0) for i in range(6)]


def _packets() -> list[bytes]:
    p = H264Packetizer(max_payload=48, ssrc=7)
    p.seq = 65530  # cross the 16-bit wrap
    return [pkt for i, au in enumerate(_AUS) for pkt in p.packetize(au, 3000 * i)]


_PACKETS = _packets()
_edit = st.one_of(
    st.tuples(st.just("drop"), st.integers(0, len(_PACKETS) - 1)),
    st.tuples(st.just("swap"), st.integers(0, len(_PACKETS) - 2)),
    st.tuples(st.just("dup"), st.integers(0, len(_PACKETS) - 1)),
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(edits=st.lists(_edit, max_size=6))
def test_lost_reordered_or_duplicated_packets_never_give_half_an_access_unit(edits: list[tuple[str, int]]) -> None:
    """What sequence numbers reveal. (A packet cut short inside its frame is not detectable by RTP itself:
    the next property holds it to a typed error or well-formed output.)"""
    packets = list(_PACKETS)
    for e in edits:
        if e[0] == "drop" and e[1] < len(packets):
            del packets[e[1]]
        elif e[0] == "swap" and e[1] + 1 < len(packets):
            packets[e[1]], packets[e[1] + 1] = packets[e[1] + 1], packets[e[1]]
        elif e[0] == "dup" and e[1] < len(packets):
            packets.insert(e[1], packets[e[1]])
    d = H264Depacketizer(first_seq=65530)
    out = []
    for pkt in packets:
        with contextlib.suppress(RtpPacketError):
            out += d.push(pkt)
    last = d.flush()
    out += [last] if last is not None else []
    for unit in out:
        assert unit.data in _AUS, "an access unit that is not one the camera sent"
        assert unit.rtp_timestamp == 3000 * _AUS.index(unit.data)
    if not edits:
        assert [u.data for u in out] == _AUS


@settings(max_examples=300, deadline=None)
@given(
    position=st.integers(0, len(_PACKETS) - 1),
    offset=st.integers(0, 47),
    value=st.integers(0, 255),
    cut=st.integers(0, 60),
    junk=st.binary(max_size=80),
)
def test_corrupted_truncated_and_junk_packets_give_a_typed_error_or_well_formed_output(
    position: int, offset: int, value: int, cut: int, junk: bytes
) -> None:
    packets = list(_PACKETS)
    pkt = bytearray(packets[position])
    pkt[offset % len(pkt)] = value
    packets[position] = bytes(pkt)
    packets[-1 - position] = packets[-1 - position][:cut]
    packets.insert(position, junk)
    d = H264Depacketizer()
    for p in packets:
        try:
            units = d.push(p)
        except RtpPacketError:
            continue
        for u in units:
            nals = annexb.split_nal_units(u.data)
            assert nals
            assert all(n and not n[0] & 0x80 and 1 <= n[0] & 0x1F <= 23 for n in nals)


def test_a_huge_fragmented_nal_unit_is_dropped_not_buffered() -> None:
    d = H264Depacketizer(first_seq=0)
    head = struct.pack("!BBHII", 0x80, 96, 0, 0, 1)
    d.push(head + bytes([0x7C, 0x85]) + os.urandom(60000))  # FU-A start of an IDR
    for seq in range(1, 200):  # 12 MB of middle fragments, no end
        d.push(struct.pack("!BBHII", 0x80, 96, seq, 0, 1) + bytes([0x7C, 0x05]) + bytes(60000))
    assert d._fu is None  # noqa: SLF001 - the bound is what is under test
    assert d.push(struct.pack("!BBHII", 0x80, 96 | 0x80, 200, 0, 1) + bytes([0x7C, 0x45, 1])) == []
    assert d.dropped == 1
    assert parse_rtp(head + b"\x01").seq == 0
