"""Annex B, SPS, sprop-parameter-sets and the capture-time SEI, on real libx264 output of the simulator's pictures.

The malformed-input properties (hypothesis) hold every parser to "a result or BitstreamError", nothing else.
"""

from __future__ import annotations

import base64
import contextlib
from fractions import Fraction

import av
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.annexb import NalType
from axis_ptz_ros2.media.decoder import H264Decoder
from axis_ptz_ros2.media.errors import BitstreamError
from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.media.transcoder import MjpegTranscoder
from axis_ptz_ros2.sim.renderer import PtzRenderer, encode_jpeg
from axis_ptz_ros2.sim.scene import shared_scene
from axis_ptz_ros2.sim.world import load_world

pytestmark = pytest.mark.unit


@pytest.fixture(scope="module")
def renderer() -> PtzRenderer:
    world = load_world()
    return PtzRenderer(world, shared_scene(world))


@pytest.fixture(scope="module")
def stream(renderer: PtzRenderer) -> list[bytes]:
    """Eight access units (IDR + 7 P) of the simulated camera panning, from libx264 via the transcoder."""
    tc = MjpegTranscoder(
        H264Settings(bitrate_kbps=1500, fps=30, preset="veryfast", profile="baseline", refresh="idr"), stamp_sei=False
    )
    return [tc.transcode(encode_jpeg(renderer.render(20.0 + 1.0 * i, -4.0, 1.0, 704, 576), 0)).data for i in range(8)]


def high_profile_idr(width: int, height: int) -> bytes:
    """An IDR from libx264's High profile (chroma_format_idc and friends present in its SPS)."""
    ctx = av.VideoCodecContext.create("libx264", "w")
    ctx.width, ctx.height, ctx.pix_fmt = width, height, "yuv420p"
    ctx.time_base = Fraction(1, 25)
    ctx.options = {"profile": "high", "preset": "medium", "tune": "zerolatency"}
    ctx.open()
    frame = av.VideoFrame.from_ndarray(np.full((height, width, 3), 90, np.uint8), format="bgr24")
    frame.pts = 0
    return b"".join(bytes(p) for p in ctx.encode(frame))


# ---- framing ------------------------------------------------------------------------------------------------
def test_split_and_join_round_trip_with_3_and_4_byte_start_codes(stream: list[bytes]) -> None:
    nals = annexb.split_nal_units(stream[0])
    assert [n[0] & 0x1F for n in nals][:2] == [NalType.SPS, NalType.PPS]
    assert nals[-1][0] & 0x1F == NalType.IDR
    assert annexb.split_nal_units(annexb.join_nal_units(nals)) == nals
    mixed = b"\x00\x00\x01" + nals[0] + b"\x00\x00\x00\x01" + nals[1] + b"\x00\x00\x01" + nals[2] + b"\x00\x00"
    assert annexb.split_nal_units(mixed) == nals[:3]
    assert annexb.is_idr(stream[0])
    assert not any(annexb.is_idr(au) for au in stream[1:])
    assert annexb.nal_types(stream[1]) == [NalType.SLICE]


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (b"", "no Annex B start code"),
        (b"\x65\x88\x84", "no Annex B start code"),
        (b"\x12\x00\x00\x01\x65", "garbage before"),
        (b"\x00\x00\x01\x00\x00\x01\x65", "empty NAL unit"),
        (b"\x00\x00\x01\xe5\x00", "forbidden_zero_bit"),
        (b"\x00\x00\x00\x01", "empty NAL unit"),
    ],
)
def test_malformed_framing_is_refused_with_a_reason(data: bytes, reason: str) -> None:
    with pytest.raises(BitstreamError, match=reason):
        annexb.split_nal_units(data)


@settings(database=None)
@given(st.binary(max_size=200), st.integers(1, 255), st.integers(0, 3))
def test_emulation_prevention_round_trips_and_leaves_no_start_code(body: bytes, stop: int, zero_words: int) -> None:
    # An RBSP ends in the byte holding rbsp_stop_one_bit (never 0), then optionally cabac_zero_words (00 00 each)
    # (H.264 §7.3.2.10, §7.4.1). Hypothesis found that an odd run of zeros after the stop byte cannot be escaped
    # and round-tripped; it is not an RBSP, so it is not generated.
    rbsp = body + bytes([stop]) + b"\x00\x00" * zero_words
    ebsp = annexb.rbsp_to_ebsp(rbsp)
    for bad in (b"\x00\x00\x00", b"\x00\x00\x01", b"\x00\x00\x02"):
        assert bad not in ebsp
    assert not ebsp.endswith(b"\x00")
    assert annexb.ebsp_to_rbsp(ebsp) == rbsp


# ---- SPS and the codec string -------------------------------------------------------------------------------
def test_sps_of_our_encoder_gives_size_profile_and_codec_string(stream: list[bytes]) -> None:
    sps = annexb.find_sps(stream[0])
    assert sps is not None
    assert (sps.width, sps.height) == (704, 576)
    assert sps.profile_idc == 66
    assert sps.constraint_flags & 0x40
    assert sps.codec_string == f"avc1.42{sps.constraint_flags:02X}{sps.level_idc:02X}"
    assert sps.max_num_ref_frames == 1
    # FFmpeg's own reading of the same stream agrees on size and profile
    dec = av.VideoCodecContext.create("h264", "r")
    frames = dec.decode(av.Packet(stream[0]))
    assert (frames[0].width, frames[0].height) == (704, 576)
    assert dec.profile == "Constrained Baseline"
    assert annexb.find_sps(stream[1]) is None


@pytest.mark.parametrize(("width", "height"), [(704, 576), (1920, 1080), (706, 482), (176, 144)])
def test_sps_of_high_profile_with_cropping(width: int, height: int) -> None:
    sps = annexb.find_sps(high_profile_idr(width, height))
    assert sps is not None
    assert (sps.width, sps.height, sps.profile_idc, sps.chroma_format_idc) == (width, height, 100, 1)
    assert sps.codec_string.startswith("avc1.64")


def test_parse_sps_refuses_other_nal_types_and_truncation(stream: list[bytes]) -> None:
    sps_nal, pps_nal = annexb.split_nal_units(stream[0])[:2]
    with pytest.raises(BitstreamError, match="not an SPS"):
        annexb.parse_sps(pps_nal)
    with pytest.raises(BitstreamError, match="ends early"):
        annexb.parse_sps(sps_nal[:6])


# ---- sprop-parameter-sets and prepending SPS/PPS ------------------------------------------------------------
def sprop_of(au: bytes) -> str:
    sps, pps = annexb.split_nal_units(au)[:2]
    return base64.b64encode(sps).decode() + "," + base64.b64encode(pps).decode()


def test_sprop_parameter_sets_parse(stream: list[bytes]) -> None:
    ps = annexb.parse_sprop_parameter_sets(" " + sprop_of(stream[0]) + " ")
    assert (ps.info.width, ps.info.height) == (704, 576)
    assert ps.sps == annexb.split_nal_units(stream[0])[0]


@pytest.mark.parametrize(
    ("value", "reason"),
    [
        ("", "empty"),
        ("Z0IAKe%%%", "not base64"),
        ("aM48gA==", "lacks an SPS"),
        ("ZQ==", "not an SPS or PPS"),
    ],
)
def test_sprop_parameter_sets_refused(value: str, reason: str) -> None:
    with pytest.raises(BitstreamError, match=reason):
        annexb.parse_sprop_parameter_sets(value)


def test_sprop_without_pps_refused(stream: list[bytes]) -> None:
    with pytest.raises(BitstreamError, match="lacks a PPS"):
        annexb.parse_sprop_parameter_sets(sprop_of(stream[0]).split(",")[0])


def test_bare_idr_gets_the_sdp_parameter_sets_and_then_decodes(stream: list[bytes]) -> None:
    params = annexb.parse_sprop_parameter_sets(sprop_of(stream[0]))
    nals = annexb.split_nal_units(stream[0])
    bare = annexb.join_nal_units(n for n in nals if n[0] & 0x1F not in (NalType.SPS, NalType.PPS))
    # a bare IDR does not decode on its own
    assert H264Decoder().decode(bare) is None
    fixed = annexb.prepend_parameter_sets(bare, params)
    assert annexb.nal_types(fixed)[:2] == [NalType.SPS, NalType.PPS]
    assert annexb.prepend_parameter_sets(stream[0], params) is stream[0]  # already complete
    assert annexb.prepend_parameter_sets(stream[1], params) is stream[1]  # not an IDR
    dec = H264Decoder()
    assert all(dec.decode(au) is not None for au in [fixed, *stream[1:]])
    # the tracker: SDP first, then in-band; a bare IDR with nothing known is refused
    tracker = annexb.ParameterSetTracker(params)
    assert annexb.nal_types(tracker.process(bare))[:2] == [NalType.SPS, NalType.PPS]
    with pytest.raises(BitstreamError, match="none known"):
        annexb.ParameterSetTracker().process(bare)
    learner = annexb.ParameterSetTracker()
    learner.process(stream[0])
    assert learner.parameter_sets == params


# ---- capture-time SEI ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("stamp", [0, 1, 3, 0x0000_0300_0000_0001, 1_764_000_000_123_456_789, (1 << 64) - 1])
def test_capture_stamp_sei_round_trip_and_decodes(stream: list[bytes], stamp: int) -> None:
    idr = annexb.insert_capture_stamp(stream[0], stamp)
    p = annexb.insert_capture_stamp(stream[1], stamp + 1 if stamp < (1 << 64) - 1 else 0)
    assert annexb.extract_capture_stamp(idr) == stamp
    assert annexb.nal_types(idr)[-2:] == [NalType.SEI, NalType.IDR]
    assert annexb.nal_types(p) == [NalType.SEI, NalType.SLICE]
    sei = annexb.capture_stamp_sei(stamp)
    if stamp == 0:  # eight zero bytes: emulation prevention must have been applied
        assert b"\x00\x00\x03" in sei
    assert b"\x00\x00\x00" not in sei
    assert b"\x00\x00\x01" not in sei
    dec = H264Decoder()
    pics = [dec.decode(idr), dec.decode(p)]
    assert all(pic is not None for pic in pics)
    assert pics[0] is not None
    assert pics[0].capture_ns == stamp
    assert dec.stats.decode_errors == 0


def test_other_sei_is_not_a_capture_stamp(stream: list[bytes]) -> None:
    assert NalType.SEI in annexb.nal_types(stream[0])  # x264's version string (user data, another UUID)
    assert annexb.extract_capture_stamp(stream[0]) is None
    assert annexb.extract_capture_stamp(stream[1]) is None
    with pytest.raises(BitstreamError, match="fit"):
        annexb.capture_stamp_sei(-1)
    with pytest.raises(BitstreamError, match="no picture"):
        annexb.insert_capture_stamp(annexb.join_nal_units(annexb.split_nal_units(stream[0])[:2]), 5)


def test_truncated_sei_is_refused() -> None:
    sei = annexb.capture_stamp_sei(42)
    with pytest.raises(BitstreamError, match="runs past"):
        annexb.extract_capture_stamp(annexb.START_CODE + sei[:12])


def test_sei_type_and_size_of_255_and_more() -> None:
    payload = bytes(range(256)) * 2 + bytes(88)  # 600 bytes
    rbsp = b"\xff" + bytes([45]) + b"\xff\xff" + bytes([90]) + payload + b"\x80"  # type 255+45, size 2*255+90
    assert annexb.sei_messages(bytes([NalType.SEI]) + annexb.rbsp_to_ebsp(rbsp)) == [(300, payload)]
    for cut, what in ((b"\xff\xff", "type"), (b"\x05\xff\xff", "size")):
        with pytest.raises(BitstreamError, match=f"SEI payload {what} runs past"):
            annexb.sei_messages(bytes([NalType.SEI]) + cut)


# ---- malformed input: a result or BitstreamError, never anything else ---------------------------------------
def exercise(data: bytes) -> None:
    """Every parser on ``data``; anything but a result or BitstreamError fails the test."""
    try:
        nals = annexb.split_nal_units(data)
    except BitstreamError:
        return
    for nal in nals:
        t = nal[0] & 0x1F
        try:
            if t == NalType.SPS:
                annexb.parse_sps(nal)
            elif t == NalType.SEI:
                annexb.sei_messages(nal)
        except BitstreamError:
            pass
    for fn in (annexb.extract_capture_stamp, annexb.find_sps, annexb.is_idr):
        with contextlib.suppress(BitstreamError):
            fn(data)
    with contextlib.suppress(BitstreamError):
        annexb.insert_capture_stamp(data, 7)
    with contextlib.suppress(BitstreamError):
        annexb.ParameterSetTracker().process(data)


@settings(max_examples=300, deadline=None, database=None)
@given(st.binary(max_size=300))
def test_random_bytes_never_crash(data: bytes) -> None:
    exercise(data)
    exercise(b"\x00\x00\x01" + data)
    exercise(b"\x00\x00\x01\x67" + data)  # an "SPS" of random bytes
    exercise(b"\x00\x00\x01\x06" + data)  # an "SEI" of random bytes


BIG = 1 << 24  # draws have fixed bounds; positions are taken modulo the sizes


@settings(max_examples=200, deadline=None, database=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    which=st.integers(0, 1),
    cut=st.integers(0, BIG),
    edits=st.lists(st.tuples(st.integers(0, BIG), st.integers(0, 255)), min_size=1, max_size=8),
)
def test_truncated_and_mutated_real_access_units_never_crash(
    stream: list[bytes], which: int, cut: int, edits: list[tuple[int, int]]
) -> None:
    # Drawn before the test runs by strategies of fixed shape, never inside it with st.data() bounded by the sizes
    # (the same pattern failed a CI run with hypothesis' FlakyStrategyDefinition in test_media_codec.py).
    au = annexb.insert_capture_stamp(stream[which], 123456789)
    exercise(au[: cut % (len(au) + 1)])
    mutated = bytearray(au)
    for where, value in edits:
        mutated[where % min(len(au), 400)] = value  # headers, SEI and the slice start
    exercise(bytes(mutated))


@settings(database=None)
@given(st.text(max_size=80))
def test_random_sprop_text_is_parsed_or_refused(value: str) -> None:
    with contextlib.suppress(BitstreamError):
        annexb.parse_sprop_parameter_sets(value)
