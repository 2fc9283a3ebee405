"""Encoder, transcoder and decoder on the simulated camera's own JPEGs (704×576, compression 0) and real libx264."""

from __future__ import annotations

import statistics

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.annexb import NalType
from axis_ptz_ros2.media.decoder import H264Decoder
from axis_ptz_ros2.media.encoder import H264Encoder
from axis_ptz_ros2.media.errors import EncoderError, TranscodeError
from axis_ptz_ros2.media.frame import EncodedFrame
from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.media.transcoder import MjpegTranscoder
from axis_ptz_ros2.sim.camera_model import PicturePool
from axis_ptz_ros2.sim.persona import AXIS_214
from axis_ptz_ros2.sim.renderer import PtzRenderer, encode_jpeg
from axis_ptz_ros2.sim.scene import shared_scene
from axis_ptz_ros2.sim.world import load_world
from tests.support.picture import psnr_db

pytestmark = pytest.mark.unit


@pytest.fixture(scope="module")
def renderer() -> PtzRenderer:
    world = load_world()
    return PtzRenderer(world, shared_scene(world))


@pytest.fixture(scope="module")
def views(renderer: PtzRenderer) -> list[np.ndarray]:
    """40 views of the camera panning slowly, 0.2° per frame (6°/s at 30 fps), before the camera model."""
    return [renderer.render(-30.0 + 0.2 * i, -3.0, 1.0, 704, 576) for i in range(40)]


@pytest.fixture(scope="module")
def jpegs(views: list[np.ndarray]) -> list[bytes]:
    """The views as the simulated 214 sends them at compression 0 (its camera model: the PAL chain's softness and
    sensor noise, a new noise field per picture)."""
    pool = PicturePool(AXIS_214.picture)
    return [pool.jpeg(("pan", i), lambda v=v: v, 1.0, 0) for i, v in enumerate(views)]


@pytest.fixture(scope="module")
def fast_pan(renderer: PtzRenderer) -> list[bytes]:
    """30 frames panning 3° per frame: enough new picture that the bitrate limits the frame sizes."""
    return [encode_jpeg(renderer.render(40.0 + 3.0 * i, -8.0, 1.0, 704, 576), 0) for i in range(30)]


def bgr(jpeg: bytes) -> np.ndarray:
    img = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
    assert img is not None
    return img


def check_idr_headers(frame: EncodedFrame) -> None:
    types = annexb.nal_types(frame.data)
    assert frame.keyframe == (NalType.IDR in types)
    if frame.keyframe:
        assert types.index(NalType.SPS) < types.index(NalType.PPS) < types.index(NalType.IDR)
    else:
        assert NalType.SPS not in types
        assert NalType.PPS not in types


@pytest.mark.parametrize(
    ("jpeg_decoder", "motion", "median_db"),
    [("cv2", "still", 35.0), ("pyav", "still", 35.0), ("cv2", "panning", 33.0), ("pyav", "panning", 33.0)],
)
def test_round_trip_psnr_at_1500_kbits(jpegs: list[bytes], jpeg_decoder: str, motion: str, median_db: float) -> None:
    """Against the camera's own compression-0 JPEG, decoded: ≥ 35 dB camera still, ≥ 33 dB panning (issue 21)."""
    tc = MjpegTranscoder(
        H264Settings(bitrate_kbps=1500, fps=30, preset="veryfast", profile="baseline", refresh="idr"),
        jpeg_decoder=jpeg_decoder,  # type: ignore[arg-type]
    )
    dec = H264Decoder()
    psnr = []
    sizes = []
    frames = jpegs if motion == "panning" else [jpegs[0]] * len(jpegs)
    for i, jpeg in enumerate(frames):
        out = tc.transcode(jpeg, capture_ns=1_000 + i)
        assert (out.pts, out.width, out.height, out.capture_ns) == (i, 704, 576, 1_000 + i)
        check_idr_headers(out)
        sizes.append(len(out.data))
        pic = dec.decode(out.data)
        assert pic is not None
        assert pic.image.shape == (576, 704, 3)
        assert pic.capture_ns == 1_000 + i
        psnr.append(cv2.PSNR(bgr(jpeg), pic.image))
    print(
        f"{jpeg_decoder} {motion}: PSNR median {statistics.median(psnr):.1f} dB, min {min(psnr):.1f} dB, "
        f"{8 * sum(sizes) / len(sizes) * 30 / 1000:.0f} kbit/s"
    )
    assert statistics.median(psnr) >= median_db
    assert min(psnr) >= 30.0
    assert dec.stats.decode_errors == 0
    assert dec.stats.pictures == len(frames)
    assert 8 * sum(sizes) / len(sizes) * 30 <= 1_500_000 * 1.3  # the rate holds (first IDR included)


def test_live_bitrate_change_changes_the_output_size(fast_pan: list[bytes]) -> None:
    images = [bgr(j) for j in fast_pan]
    enc = H264Encoder(
        H264Settings(
            bitrate_kbps=2000, fps=30, keyframe_interval=600, preset="veryfast", profile="baseline", refresh="idr"
        ),
        704,
        576,
    )
    high = [len(enc.encode_bgr(img).data) for img in images[:15]]
    enc.set_bitrate(300)
    low = [len(enc.encode_bgr(img).data) for img in images[15:]]
    assert enc.reopens == 0  # lowering is live, no new IDR
    # the low rate judged once the VBV buffer of the high one (VBV_BUFFER_S of 2000 kbit/s) is spent: ~8 frames
    mean_high, mean_low = statistics.mean(high[3:]), statistics.mean(low[8:])
    print(f"P-frames at 2000 kbit/s {mean_high:.0f} B, at 300 kbit/s {mean_low:.0f} B")
    assert mean_high > 2 * mean_low
    assert mean_low * 8 * 30 <= 300_000 * 1.5
    # above the rate it opened with: re-opened (x264 keeps its VBV maxrate), the next frame is an IDR
    enc.set_bitrate(3000)
    out = enc.encode_bgr(images[0])
    assert enc.reopens == 1
    assert out.keyframe
    assert enc.opened_max_bitrate_bps == 3_000_000
    check_idr_headers(out)


def test_a_new_vbv_buffer_waits_for_the_next_idr_and_bounds_it(fast_pan: list[bytes]) -> None:
    """The VBV buffer bounds the IDR; a new one re-opens the encoder only at an IDR it makes anyway (no extra
    keyframe), keeps the opened maxrate, and a change within VBV_REOPEN_SLACK is no re-open at all."""
    images = [bgr(j) for j in fast_pan]
    enc = H264Encoder(
        H264Settings(
            bitrate_kbps=1000, fps=30, keyframe_interval=10, preset="veryfast", profile="baseline", refresh="idr"
        ),
        704,
        576,
    )
    assert enc.opened_vbv_bits == 150_000  # VBV_BUFFER_S of the bitrate
    keys, sizes = [], []
    for i, img in enumerate(images):
        if i == 3:
            enc.set_bitrate(600)
            enc.set_vbv(40)
            assert enc.reopens == 0  # not yet: waits for the IDR at frame 10
        if i == 22:
            enc.set_vbv(44)  # within the slack of 40 kbit: nothing to do
        out = enc.encode_bgr(img)
        check_idr_headers(out)
        keys.append(out.keyframe)
        sizes.append(len(out.data) * 8)
    assert [i for i, k in enumerate(keys) if k] == [0, 10, 20]  # the periodic ones, no extra IDR
    assert enc.reopens == 1
    assert enc.opened_vbv_bits == 40_000
    assert enc.opened_max_bitrate_bps == 1_000_000  # kept: a bitrate back up to it stays live
    print(f"IDR sizes {sizes[0]}, {sizes[10]}, {sizes[20]} bit")
    assert sizes[0] > 80_000  # the fast pan fills the 150 kbit buffer ...
    assert sizes[10] <= 40_000 * 1.1  # ... and then the 40 kbit one bounds it
    assert sizes[20] <= 40_000 * 1.1
    with pytest.raises(EncoderError, match="VBV buffer"):
        enc.set_vbv(-1)
    with pytest.raises(EncoderError, match="VBV buffer"):
        H264Settings(vbv_kbit=60_000)


def test_idr_on_demand_periodic_keyframes_and_headers(jpegs: list[bytes]) -> None:
    images = [bgr(j) for j in jpegs[:30]]
    enc = H264Encoder(
        H264Settings(fps=30, keyframe_interval=10, preset="veryfast", profile="baseline", refresh="idr"), 704, 576
    )
    keys = []
    for i, img in enumerate(images):
        if i == 13:
            enc.request_idr()
        if i == 20:
            enc.set_keyframe_interval(4)
        out = enc.encode_bgr(img)
        check_idr_headers(out)
        assert out.pts == i
        keys.append(out.keyframe)
    # 0 (first), 10 (interval), 13 (on demand: the very next frame), 20 (13 + 10 would be 23: new interval 4
    # counts from 13, already past) then every 4
    assert [i for i, k in enumerate(keys) if k] == [0, 10, 13, 20, 24, 28]


def test_intra_refresh_makes_idrs_only_on_demand_and_every_picture_decodes(jpegs: list[bytes]) -> None:
    """x264's periodic intra refresh (the stream node's default): no IDR after the first but the ones asked for;
    each wave's recovery point, which libx264 flags key (with SPS/PPS and a recovery-point SEI), is no IDR and is
    not passed on as a key frame (no decoder can start there); a new wave length re-opens x264 with an IDR."""
    images = [bgr(j) for j in jpegs[:40]]
    enc = H264Encoder(
        H264Settings(fps=25, keyframe_interval=8, refresh="intra", profile="high", preset="veryfast"), 704, 576
    )
    dec = H264Decoder()
    keys, recovery_points = [], []
    for i, img in enumerate(images):
        if i == 13:
            enc.request_idr()
        if i == 30:
            enc.set_keyframe_interval(8)  # the same wave: nothing happens
        if i == 33:
            enc.set_keyframe_interval(5)
        out = enc.encode_bgr(img)
        types = annexb.nal_types(out.data)
        assert out.keyframe == (NalType.IDR in types)
        if out.keyframe:
            assert types.index(NalType.SPS) < types.index(NalType.PPS) < types.index(NalType.IDR)
        elif NalType.SPS in types:  # a recovery point: x264 repeats SPS/PPS there (harmless, no key frame)
            recovery_points.append(i)
        keys.append(out.keyframe)
        assert dec.decode(out.data) is not None, i  # FFmpeg's decoder with err_detect=explode
    assert [i for i, k in enumerate(keys) if k] == [0, 13, 33]
    assert recovery_points, "no intra-refresh wave began (x264 not in intra-refresh mode?)"
    assert enc.reopens == 1
    assert dec.stats.decode_errors == 0
    assert (enc.codec_string or "").startswith("avc1.64")  # High profile


def test_a_new_wave_under_a_lowered_bitrate_keeps_the_ceiling_it_opened_with(jpegs: list[bytes]) -> None:
    """Opened at the ceiling (1500 kbit/s) and lowered live to 500, a new wave re-opens x264 at 1500 still: the
    link's budget climbing back from 500 then changes the bitrate live, not with a re-open (an IDR) at every step
    (two-host bench, 2 -> 1 Mbit/s: re-opened at the lowered rate, the climb's IDRs kept the link congested 12 s)."""
    images = [bgr(j) for j in jpegs[:12]]
    enc = H264Encoder(H264Settings(bitrate_kbps=1500, fps=25, keyframe_interval=100, refresh="intra"), 704, 576)
    for img in images[:3]:
        enc.encode_bgr(img)
    enc.set_bitrate(500)
    enc.encode_bgr(images[3])
    enc.set_keyframe_interval(25)
    assert enc.encode_bgr(images[4]).keyframe
    assert enc.reopens == 1
    assert enc.opened_max_bitrate_bps == 1_500_000
    for kbps, img in zip((700, 1000, 1400), images[5:8], strict=True):  # the budget climbs back
        enc.set_bitrate(kbps)
        assert not enc.encode_bgr(img).keyframe
    assert enc.reopens == 1


@pytest.mark.parametrize("reopen", ["wave", "vbv"])
def test_a_live_rise_after_a_reopen_at_a_lowered_bitrate_is_followed(jpegs: list[bytes], reopen: str) -> None:
    """x264 follows a live bitrate only when it opened as CBR (maxrate = bitrate); re-opened at a lowered target
    under the ceiling's maxrate (a new wave, a new VBV buffer at an IDR) it kept that target for good: on the
    two-host link at 1 Mbit/s the budget climbed from 616 to 1105 kbit/s while x264 sent 310-317, the rate it was
    re-opened at (debug log at 1abefee; offline: 280 kbit/s for a target of 1000). Re-opened at the ceiling and
    lowered live, it climbs with the target."""
    images = [bgr(j) for j in jpegs]
    enc = H264Encoder(H264Settings(bitrate_kbps=1350, fps=25, keyframe_interval=25, refresh="intra"), 704, 576)
    for img in images[:10]:
        enc.encode_bgr(img)
    enc.set_bitrate(275)
    if reopen == "wave":
        enc.set_keyframe_interval(30)
    else:
        enc.set_vbv(41)
        enc.request_idr()
    low = [len(enc.encode_bgr(img).data) * 8 for img in images[10:40]]
    assert enc.reopens == 1
    enc.set_bitrate(1000)
    high = [len(enc.encode_bgr(img).data) * 8 for img in images[::-1][:40]]  # the view sweeps back
    assert enc.reopens == 1  # live
    low_kbps, high_kbps = statistics.mean(low[5:]) * 25 / 1000, statistics.mean(high[-25:]) * 25 / 1000
    print(f"re-opened ({reopen}) at 275 kbit/s: {low_kbps:.0f} kbit/s; live 1000: {high_kbps:.0f} kbit/s")
    assert low_kbps <= 275 * 1.3
    assert high_kbps >= 0.7 * 1000


def test_intra_refresh_heals_a_silent_loss_within_a_wave(jpegs: list[bytes]) -> None:
    """A viewer that lost a P-picture and asked for nothing (FFmpeg's decoder with its default concealment, as
    the ffmpeg image_transport plugin decodes): pictures equal to a loss-free decoder's again within about one
    wave after the loss; with a GOP as long and no refresh they never do."""
    import av  # noqa: PLC0415 - PyAV (the encoder needs it anyway)

    images = [bgr(j) for j in jpegs[:40]]

    def healed_after(refresh: str) -> int | None:
        enc = H264Encoder(H264Settings(fps=25, keyframe_interval=10 if refresh == "intra" else 600,
                                       refresh=refresh, preset="veryfast", profile="baseline"), 704, 576)  # fmt: skip
        lossy, twin = av.CodecContext.create("h264", "r"), av.CodecContext.create("h264", "r")
        healed = None
        for i, img in enumerate(images):
            data = enc.encode_bgr(img).data
            (ref,) = twin.decode(av.Packet(data))
            if i == 12:
                continue  # lost
            got = lossy.decode(av.Packet(data))
            same = bool(got) and np.array_equal(got[-1].to_ndarray(), ref.to_ndarray())
            if i > 12:
                healed = (healed if healed is not None else i) if same else None
        return None if healed is None else healed - 12

    intra = healed_after("intra")
    assert intra is not None
    assert intra <= 2 * 10 + 1  # within the wave under way and the next one
    assert healed_after("idr") is None


def test_codec_string_matches_the_sps_the_decoder_uses(jpegs: list[bytes]) -> None:
    tc = MjpegTranscoder(H264Settings(fps=30, preset="veryfast", profile="baseline", refresh="idr"))
    assert tc.codec_string is None
    out = tc.transcode(jpegs[0])
    sps = annexb.find_sps(out.data)
    assert sps is not None
    assert tc.codec_string == sps.codec_string
    assert sps.codec_string == "avc1.42C0" + f"{sps.level_idc:02X}"  # Constrained Baseline
    assert sps.level_idc >= 30  # 704×576 @ 30 needs level 3.0+
    pic = H264Decoder().decode(out.data)
    assert pic is not None
    assert pic.image.shape[1::-1] == (sps.width, sps.height)


def test_resolution_change_reopens_the_encoder_and_the_decoder_follows(
    jpegs: list[bytes], renderer: PtzRenderer
) -> None:
    small = encode_jpeg(renderer.render(0.0, -3.0, 1.0, 352, 288), 0)
    tc = MjpegTranscoder(H264Settings(fps=30, preset="veryfast", profile="baseline", refresh="idr"))
    dec = H264Decoder()
    outs = [tc.transcode(j) for j in (jpegs[0], jpegs[1], small, small, jpegs[2])]
    assert [o.keyframe for o in outs] == [True, False, True, False, True]
    assert [(o.width, o.height) for o in outs][1:4] == [(704, 576), (352, 288), (352, 288)]
    assert tc.encoder_opens == 3
    shapes = []
    for o in outs:
        pic = dec.decode(o.data)
        assert pic is not None
        shapes.append(pic.image.shape[:2])
    assert shapes == [(576, 704), (576, 704), (288, 352), (288, 352), (576, 704)]
    assert dec.stats.decode_errors == 0


def test_decoder_joining_mid_gop_waits_for_an_idr(jpegs: list[bytes]) -> None:
    tc = MjpegTranscoder(
        H264Settings(fps=30, keyframe_interval=600, preset="veryfast", profile="baseline", refresh="idr")
    )
    outs = []
    for i, j in enumerate(jpegs[:16]):
        if i == 10:
            tc.request_idr()
        outs.append(tc.transcode(j))
    dec = H264Decoder()
    results = [dec.decode(o.data) for o in outs[3:]]  # joins at frame 3, a P-frame
    assert all(r is None for r in results[:7])
    assert dec.waiting_for_idr is False
    assert all(r is not None for r in results[7:])
    assert dec.stats.waiting_drops == 7
    assert dec.stats.decode_errors == 0
    assert results[7] is not None
    assert results[7].keyframe


def test_decoder_recovers_after_corrupt_access_units(jpegs: list[bytes]) -> None:
    tc = MjpegTranscoder(
        H264Settings(fps=30, keyframe_interval=8, preset="veryfast", profile="baseline", refresh="idr")
    )
    outs = [tc.transcode(j).data for j in jpegs[:20]]
    dec = H264Decoder()
    got = []
    for i, au in enumerate(outs):
        if i == 3:
            au = au[: len(au) // 3]  # truncated slice
        elif i == 5:
            au = b"\x00\x00\x01\x41" + bytes(range(256)) * 4  # garbage in a P-slice header
        elif i == 6:
            au = b"\x12\x34"  # not Annex B at all
        got.append(dec.decode(au) is not None)
    assert dec.stats.decode_errors >= 2
    assert got[:3] == [True, True, True]
    assert not any(got[3:8])  # nothing (no smeared or old picture) until the IDR at frame 8
    assert all(got[8:])
    assert not dec.waiting_for_idr


@pytest.mark.parametrize(
    ("kwargs", "reason"),
    [
        ({"width": 703}, "width must be an even"),
        ({"height": 0}, "height must be an even"),
        ({"width": True}, "width must be an even"),
        ({"bitrate_kbps": 10}, "bitrate must be 50…50000 kbit/s"),
        ({"bitrate_kbps": True}, "bitrate must be"),
        ({"bitrate_kbps": 1000.0}, "bitrate must be"),
        ({"max_bitrate_kbps": 60_000}, "max bitrate must be"),
        ({"keyframe_interval": 601}, "keyframe interval"),
        ({"vbv_kbit": -1}, "VBV buffer"),
        ({"vbv_kbit": 0.0}, "VBV buffer"),
        ({"keyframe_interval": 0}, "keyframe interval"),
        ({"preset": "placebo"}, "preset must be one of"),
        ({"fps": 0}, "fps must be"),
        ({"threads": 0}, "threads must be"),
        ({"profile": "main"}, "profile must be one of"),
        ({"refresh": "gdr"}, "refresh must be one of"),
        ({"psy": 1}, "psy must be True or False"),
    ],
)
def test_bad_encoder_parameters_are_refused(kwargs: dict[str, object], reason: str) -> None:
    size = {"width": 704, "height": 576}
    settings = {k: v for k, v in kwargs.items() if k not in size}
    width, height = (kwargs.get(k, v) for k, v in size.items())
    with pytest.raises(EncoderError, match=reason):
        H264Encoder(H264Settings(**settings), width, height)  # type: ignore[arg-type]


def _x264_options(access_unit: bytes) -> dict[str, str]:
    """The options libx264 wrote into its version SEI (user data unregistered: a 16-byte UUID, then
    ``x264 - core … options: a=1 b=2 …``)."""
    texts = [
        payload[16:].decode("latin-1")
        for nal in annexb.split_nal_units(access_unit)
        if annexb.nal_type(nal) == NalType.SEI
        for ptype, payload in annexb.sei_messages(nal)
        if ptype == 5 and b"options: " in payload
    ]
    assert texts, "no x264 version SEI in the access unit"
    opts = texts[0].split("options: ", 1)[1].rstrip("\x00")
    return dict(kv.split("=", 1) for kv in opts.split() if "=" in kv)


def test_psy_off_codes_the_refresh_column_sharper_at_the_same_bitrate(views: list[np.ndarray]) -> None:
    """x264's psychovisual optimisations are off unless asked for (``H264Settings.psy``); x264 then codes the
    intra-refresh column at the intra quantiser. Three seconds of a still view as the 214 sends it (a new noise
    field per picture): against the view before the noise, at the same bitrate, the picture comes out closer
    (measured +0.5…0.8 dB still and panning, ``bench/encoder_tradeoff.py``)."""
    pool = PicturePool(AXIS_214.picture)
    view = views[0]
    jpegs = [pool.jpeg(("still", i), lambda: view, 1.0, 0) for i in range(75)]
    clean = AXIS_214.picture.soften(view, 1.0)
    results = {}
    for psy in (False, True):
        tc = MjpegTranscoder(H264Settings(bitrate_kbps=1000, fps=25, psy=psy))
        dec = H264Decoder()
        psnr, sizes = [], []
        for i, jpeg in enumerate(jpegs):
            out = tc.transcode(jpeg)
            if i == 0:
                opts = _x264_options(out.data)
            sizes.append(len(out.data))
            pic = dec.decode(out.data)
            assert pic is not None
            if i >= 25:  # after the first second (the first IDR, the rate control's start)
                psnr.append(psnr_db(pic.image, clean))
        results[psy] = (statistics.median(psnr), 8 * sum(sizes) / len(sizes) * 25 / 1000, opts)
    (off_db, off_kbps, off_opts), (on_db, on_kbps, on_opts) = results[False], results[True]
    print(f"psy off: {off_db:.2f} dB at {off_kbps:.0f} kbit/s; on: {on_db:.2f} dB at {on_kbps:.0f} kbit/s")
    assert (off_opts["psy"], on_opts["psy"]) == ("0", "1")
    assert off_kbps <= on_kbps * 1.1  # not bought with more bits
    assert off_db >= on_db + 0.2


def test_bad_jpeg_is_refused_and_the_stream_goes_on(jpegs: list[bytes]) -> None:
    for jpeg_decoder in ("cv2", "pyav"):
        tc = MjpegTranscoder(
            H264Settings(fps=30, preset="veryfast", profile="baseline", refresh="idr"),
            jpeg_decoder=jpeg_decoder,  # type: ignore[arg-type]
        )
        first = tc.transcode(jpegs[0])
        for bad in (b"", b"not a jpeg", jpegs[1][:200]):
            with pytest.raises(TranscodeError):
                tc.transcode(bad)
        nxt = tc.transcode(jpegs[1])
        assert (first.pts, nxt.pts, nxt.keyframe) == (0, 1, False)
        assert tc.bad_jpegs == 3
    enc = H264Encoder(H264Settings(fps=30, preset="veryfast", profile="baseline", refresh="idr"), 704, 576)
    with pytest.raises(EncoderError, match="expected a 704x576"):
        enc.encode_bgr(np.zeros((288, 352, 3), np.uint8))
    with pytest.raises(EncoderError, match="bitrate"):
        enc.set_bitrate(1)
    with pytest.raises(EncoderError, match="jpeg_decoder"):
        MjpegTranscoder(jpeg_decoder="libjpeg")  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def short_stream(jpegs: list[bytes]) -> list[bytes]:
    """IDR, P, P, IDR, P, P with capture stamps."""
    tc = MjpegTranscoder(
        H264Settings(fps=30, keyframe_interval=3, preset="veryfast", profile="baseline", refresh="idr")
    )
    return [tc.transcode(j, capture_ns=i).data for i, j in enumerate(jpegs[:6])]


BIG = 1 << 24  # draws have fixed bounds; positions are taken modulo the sizes


@settings(max_examples=60, deadline=None, database=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    edits=st.lists(st.tuples(st.integers(0, BIG), st.integers(0, BIG), st.integers(0, 255)), min_size=1, max_size=6),
    cut=st.tuples(st.integers(0, BIG), st.integers(0, BIG)),
)
def test_decoder_never_raises_on_mutated_streams(
    short_stream: list[bytes], edits: list[tuple[int, int, int]], cut: tuple[int, int]
) -> None:
    """Random byte changes anywhere in a real IDR + P stream: pictures or counted errors, never an exception."""
    aus = [bytearray(au) for au in short_stream]
    # Everything is drawn before the test runs, by strategies of fixed shape (never from inside it with st.data(),
    # never bounded by the stream's sizes): CI runs reported FlakyStrategyDefinition ("the second run stopped
    # drawing earlier") with draws made inside the test, once with size-bound draws and again without them.
    for which, where, value in edits:
        au = aus[which % len(aus)]
        au[where % len(au)] = value
    k = cut[0] % len(aus)
    aus[k] = aus[k][: cut[1] % (len(aus[k]) + 1)]
    dec = H264Decoder()
    out = [dec.decode(bytes(au)) for au in aus]
    assert dec.stats.access_units == len(aus)
    assert dec.stats.pictures == sum(pic is not None for pic in out)
    for pic in out:
        if pic is not None:
            assert pic.image.shape == (576, 704, 3)
