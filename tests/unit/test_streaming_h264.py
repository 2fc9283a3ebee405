"""The H.264 stage (ROS-free) on the simulated camera's own JPEGs with real libx264, and the controller's codec
policy: lazy, pts, SPS/PPS with every IDR, IDR on demand (rate-limited), keyframes within a second, bitrate from
the budget, resolution changes, bad JPEGs, the pass-through seam, and the receiver's loss handling."""

from __future__ import annotations

import numpy as np
import pytest

from axis_ptz_ros2.media import annexb
from axis_ptz_ros2.media.annexb import NalType
from axis_ptz_ros2.media.errors import EncoderError
from axis_ptz_ros2.media.frame import EncodedFrame
from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.media.transcoder import MjpegTranscoder
from axis_ptz_ros2.sim.frames import stamp
from axis_ptz_ros2.sim.renderer import PtzRenderer, encode_jpeg
from axis_ptz_ros2.sim.scene import shared_scene
from axis_ptz_ros2.sim.world import load_world
from axis_ptz_ros2.streaming.controller import VideoController
from axis_ptz_ros2.streaming.feedback import FeedbackReport
from axis_ptz_ros2.streaming.h264 import (
    IDR_MIN_INTERVAL_S,
    NEW_SUBSCRIBER_IDR_AGAIN_S,
    RATE_WINDOW,
    H264Stage,
)
from axis_ptz_ros2.streaming.h264_policy import IDR_LINK_S, h264_target_kbps, h264_vbv_kbit
from axis_ptz_ros2.streaming.meter import BitrateMeter
from axis_ptz_ros2.streaming.receiver import AccessUnitReceiver
from axis_ptz_ros2.streaming.video_types import VideoSettings
from tests.support.stamps import sim_stamp

pytestmark = pytest.mark.unit


@pytest.fixture(scope="module")
def renderer() -> PtzRenderer:
    world = load_world()
    return PtzRenderer(world, shared_scene(world))


@pytest.fixture(scope="module")
def jpegs(renderer: PtzRenderer) -> list[bytes]:
    """24 frames of a slow pan, compression 0, stamped like the simulated camera stamps them."""
    return [stamp(encode_jpeg(renderer.render(-30.0 + 0.3 * i, -3.0, 1.0, 704, 576), 0), i) for i in range(24)]


@pytest.fixture(scope="module")
def small(renderer: PtzRenderer) -> list[bytes]:
    return [encode_jpeg(renderer.render(10.0 + 0.3 * i, -3.0, 1.0, 352, 288), 0) for i in range(6)]


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


class Harness:
    """A stage with settings the test changes, a fake clock, and what it published."""

    def __init__(self, settings: H264Settings | None = None) -> None:
        self.settings = settings or H264Settings(bitrate_kbps=1000, keyframe_interval=30, fps=10)
        self.clock = Clock()
        self.out: list[EncodedFrame] = []
        self.made: list[H264Settings] = []  # what each transcoder was opened with
        self.transcoders: list[MjpegTranscoder] = []
        self.problems: list[str] = []

        def factory(cfg: H264Settings) -> MjpegTranscoder:
            self.made.append(cfg)
            self.transcoders.append(MjpegTranscoder(cfg))
            return self.transcoders[-1]

        self.stage = H264Stage(
            lambda: self.settings,
            self.out.append,
            transcoder_factory=factory,
            on_problem=self.problems.append,
            clock=self.clock,
        )

    def feed(self, jpegs: list[bytes], start_ns: int = 1_000_000_000) -> list[EncodedFrame | None]:
        res = []
        for i, j in enumerate(jpegs):
            self.clock.t += 0.1
            res.append(self.stage.on_jpeg(j, start_ns + i * 100_000_000))
        return res


def test_inactive_stage_never_opens_an_encoder(jpegs: list[bytes]) -> None:
    h = Harness()
    assert h.feed(jpegs[:5]) == [None] * 5
    assert h.made == []
    assert h.out == []
    assert not h.stage.encoder_open
    assert h.stage.stats.skipped_inactive == 5


def test_frames_pts_headers_and_stamps(jpegs: list[bytes]) -> None:
    h = Harness()
    h.stage.set_active(True)
    out = [f for f in h.feed(jpegs) if f is not None]
    assert len(out) == len(jpegs) == len(h.out)
    assert [f.pts for f in out] == list(range(len(out)))
    assert out[0].keyframe
    for f in out:
        types = annexb.nal_types(f.data)
        assert f.keyframe == (NalType.IDR in types)
        if f.keyframe:  # SPS/PPS in front of every IDR
            assert types.index(NalType.SPS) < types.index(NalType.PPS) < types.index(NalType.IDR)
        assert (f.width, f.height) == (704, 576)
    # header stamp and SEI: the JPEG's arrival, as image_raw/compressed is stamped; the simulator's comment in the
    # JPEG (its own send time) is not read (issue 38: no simulator knowledge in the product)
    for i, f in enumerate(out):
        assert f.stamp_ns == 1_000_000_000 + i * 100_000_000
        assert annexb.extract_capture_stamp(f.data) == f.stamp_ns
    comment = sim_stamp(jpegs[3])
    assert comment is not None
    assert comment[1] != out[3].stamp_ns


def test_keyframe_interval_is_at_most_one_second(jpegs: list[bytes]) -> None:
    h = Harness(H264Settings(keyframe_interval=600, fps=5, refresh="idr"))  # 600 asked, 5 fps: an IDR every 5
    h.stage.set_active(True)
    out = [f for f in h.feed(jpegs) if f is not None]
    idrs = [f.pts for f in out if f.keyframe]
    assert idrs[:4] == [0, 5, 10, 15]


def test_intra_refresh_by_default_one_wave_a_second_and_idrs_only_on_demand(jpegs: list[bytes]) -> None:
    """The node's default (issue 39): x264's intra refresh in High profile, its wave at most one second of frames
    long; no IDR after the first but the ones asked for, each with SPS/PPS."""
    assert (H264Settings().refresh, H264Settings().profile) == ("intra", "high")
    h = Harness(H264Settings(keyframe_interval=600, fps=5))
    h.stage.set_active(True)
    out = [f for f in h.feed(jpegs[:12]) if f is not None]
    assert (h.made[0].keyframe_interval, h.made[0].refresh, h.made[0].profile) == (5, "intra", "high")
    assert [f.pts for f in out if f.keyframe] == [0]
    assert h.stage.request_idr()
    out = [f for f in h.feed(jpegs[12:16]) if f is not None]
    assert [f.keyframe for f in out] == [True, False, False, False]
    types = annexb.nal_types(out[0].data)
    assert types.index(NalType.SPS) < types.index(NalType.PPS) < types.index(NalType.IDR)
    assert annexb.find_sps(out[0].data).codec_string.startswith("avc1.64")  # type: ignore[union-attr]


def test_a_longer_wave_only_while_every_viewer_reports_and_back_at_once_with_an_idr(jpegs: list[bytes]) -> None:
    """While every H.264 viewer reports its losses (``long_wave``) the encoder's intra-refresh wave is
    ``h264_reported_wave``, not one second; when one stops reporting the wave is one second again from the
    next picture, which is an IDR (x264 takes a new wave only when it opens)."""
    h = Harness(H264Settings(keyframe_interval=30, fps=5, reported_wave=600, long_wave=True))
    h.stage.set_active(True)
    out = [f for f in h.feed(jpegs[:8]) if f is not None]
    assert h.made[0].keyframe_interval == 600
    assert h.stage.keyframe_interval == 600
    assert [f.pts for f in out if f.keyframe] == [0]
    h.settings = H264Settings(keyframe_interval=30, fps=5, reported_wave=600, long_wave=False)
    out = [f for f in h.feed(jpegs[8:12]) if f is not None]
    assert h.transcoders[-1].settings.keyframe_interval == 5
    assert h.stage.keyframe_interval == 5
    assert [f.keyframe for f in out] == [True, False, False, False]
    assert len(h.made) == 1  # the same transcoder: its encoder re-opened, not a new stage encoder
    # refresh idr: periodic IDRs heal a viewer that does not report, whoever reports
    assert (
        H264Settings(
            keyframe_interval=30, fps=5, refresh="idr", reported_wave=600, long_wave=True
        ).effective_keyframe_interval
        == 5
    )


def test_idr_on_demand_is_rate_limited_and_kept(jpegs: list[bytes]) -> None:
    h = Harness()
    h.stage.set_active(True)
    h.feed(jpegs[:10])  # clock advances 1.0 s
    assert h.stage.request_idr()
    f = h.feed(jpegs[10:11])[0]
    assert f is not None
    assert f.keyframe
    assert not h.stage.request_idr()  # inside the interval: refused now ...
    fs = h.feed(jpegs[11 : 11 + int(IDR_MIN_INTERVAL_S / 0.1) + 1])
    keys = [x.keyframe for x in fs if x is not None]
    assert keys[0] is False
    assert keys[-1] is True
    assert h.stage.stats.idr_requests == 2


def test_a_new_subscriber_gets_an_idr_at_once_and_another_shortly_after(jpegs: list[bytes]) -> None:
    """The publisher may learn of a subscriber before the subscriber learns of it: a second IDR follows
    NEW_SUBSCRIBER_IDR_AGAIN_S after the first, once, and for a pass-through source too (idr_wanted)."""
    h = Harness()  # periodic IDR every 30 frames at 10 fps: capped at one second (10 frames)
    h.stage.set_active(True)
    h.feed(jpegs[:3])  # clock at 100.3; IDR at frame 0
    h.stage.new_subscriber()
    fs = h.feed(jpegs[3:9])  # one frame per 0.1 s
    keys = [i for i, f in enumerate(fs) if f is not None and f.keyframe]
    assert len(keys) == 2  # at once, and again about NEW_SUBSCRIBER_IDR_AGAIN_S later (the first frame due)
    assert keys[0] == 0
    assert keys[1] * 0.1 == pytest.approx(NEW_SUBSCRIBER_IDR_AGAIN_S, abs=0.11)
    assert not h.stage.idr_wanted  # nothing more is due
    h.stage.new_subscriber()
    h.stage.idr_sent()  # a pass-through source asked its camera for the first one
    assert not h.stage.idr_wanted
    h.clock.t += NEW_SUBSCRIBER_IDR_AGAIN_S
    assert h.stage.idr_wanted  # the second one is due


def test_the_encoder_runs_at_the_rate_the_camera_makes(jpegs: list[bytes]) -> None:
    """Asked for 30, the camera makes 10 (the harness feeds a JPEG every 100 ms): once RATE_WINDOW arrivals say so,
    the encoder re-opens at 10 (x264 spends bitrate / fps on a picture) with an IDR; a rate within RATE_REOPEN_FPS
    of it, or a stall, does not re-open it."""
    h = Harness(H264Settings(bitrate_kbps=1000, keyframe_interval=30, fps=30))
    h.stage.set_active(True)
    frames = (jpegs * 3)[: RATE_WINDOW + 5]
    out = h.feed(frames)
    assert [c.fps for c in h.made] == [30, 10]
    assert h.stage.input_fps == pytest.approx(10.0)
    assert (h.stage.stats.encoder_opens, h.stage.stats.fps_reopens) == (2, 1)
    reopened = out[RATE_WINDOW - 1]
    assert reopened is not None
    assert reopened.keyframe
    assert [f.pts for f in out if f is not None] == list(range(len(frames)))  # pts go on
    # 11 pictures/s (within RATE_REOPEN_FPS) and one 5 s stall: no re-open
    t0 = 10_000_000_000
    for i, j in enumerate(jpegs[: RATE_WINDOW // 2]):
        h.stage.on_jpeg(j, t0 + i * 90_909_091 + (5_000_000_000 if i > 5 else 0))
    assert [c.fps for c in h.made] == [30, 10]


def test_consumer_errors_ask_for_an_idr_only_when_they_grow(jpegs: list[bytes]) -> None:
    h = Harness()
    h.stage.set_active(True)
    h.feed(jpegs[:10])  # clock advances 1.0 s
    assert h.stage.consumer_errors("/op/monitor", 3)  # new losses: an IDR
    f = h.feed(jpegs[10:11])[0]
    assert f is not None
    assert f.keyframe
    h.clock.t += 1.0
    # the consumer recovered: its window still holds the 3 errors, then fewer as they leave it: no new IDR
    assert not h.stage.consumer_errors("/op/monitor", 3)
    assert not h.stage.consumer_errors("/op/monitor", 2)
    assert not any(x is not None and x.keyframe for x in h.feed(jpegs[11:14]))
    assert h.stage.consumer_errors("/op/monitor", 5)  # new losses again
    assert h.stage.consumer_errors("/op/other", 1)  # each consumer on its own
    assert not h.stage.consumer_errors("/op/monitor", 0)
    assert h.stage.consumer_errors("/op/monitor", 1)  # after a clean report, any error is new
    assert h.stage.stats.idr_requests == 1


def test_deactivation_drops_the_encoder_and_reactivation_starts_with_an_idr(jpegs: list[bytes]) -> None:
    h = Harness()
    h.stage.set_active(True)
    h.feed(jpegs[:4])
    h.stage.set_active(False)
    assert not h.stage.encoder_open
    assert h.feed(jpegs[4:6]) == [None, None]
    h.stage.set_active(True)
    f = h.feed(jpegs[6:7])[0]
    assert f is not None
    assert f.keyframe
    assert f.pts == 4
    assert len(h.made) == 2


def test_bitrate_live_preset_and_fps_reopen(jpegs: list[bytes]) -> None:
    h = Harness(H264Settings(bitrate_kbps=2000, fps=10))
    h.stage.set_active(True)
    big = [f for f in h.feed(jpegs[:12]) if f is not None]
    h.settings = H264Settings(bitrate_kbps=150, fps=10)
    small_ = [f for f in h.feed(jpegs[12:24]) if f is not None]
    assert len(h.made) == 1  # bitrate down: live, no new encoder
    p_big = np.median([len(f.data) for f in big[2:] if not f.keyframe])
    p_small = np.median([len(f.data) for f in small_[2:] if not f.keyframe])
    assert p_small < 0.5 * p_big
    h.settings = H264Settings(bitrate_kbps=150, fps=10, preset="ultrafast")
    f = h.feed(jpegs[:1])[0]
    assert f is not None
    assert f.keyframe
    assert len(h.made) == 2
    assert h.made[-1].preset == "ultrafast"
    assert h.stage.stats.fps_reopens == 0  # a new preset is not a new rate
    h.settings = H264Settings(bitrate_kbps=150, fps=20, preset="ultrafast")
    f = h.feed(jpegs[1:2])[0]
    assert f is not None
    assert f.keyframe
    assert h.made[-1].fps == 20
    assert (h.stage.stats.encoder_opens, h.stage.stats.fps_reopens) == (3, 1)


def test_encoder_opens_at_the_ceiling_so_the_budget_moves_the_bitrate_live(jpegs: list[bytes]) -> None:
    """The budget holds the target under the request and lets it grow back: no re-open, no IDR, for either."""
    h = Harness(H264Settings(bitrate_kbps=300, fps=30, max_bitrate_kbps=1500))
    h.stage.set_active(True)
    h.feed(jpegs[:3])
    assert h.made[0].bitrate_kbps == 1500  # VBV maxrate = the request ...
    t = h.transcoders[0]
    assert t.settings.bitrate_kbps == 300  # ... the target the budget's, from the second frame on
    for kbps in (600, 1200, 1500, 400):
        h.settings = H264Settings(bitrate_kbps=kbps, fps=30, max_bitrate_kbps=1500)
        out = h.feed(jpegs[3:5])
        assert not any(f is not None and f.keyframe for f in out)
        assert t.settings.bitrate_kbps == kbps
    assert len(h.made) == 1
    assert t._encoder is not None
    assert t._encoder.reopens == 0


def test_resolution_change_gives_an_idr_of_the_new_size(jpegs: list[bytes], small: list[bytes]) -> None:
    h = Harness()
    h.stage.set_active(True)
    h.feed(jpegs[:3])
    f = h.feed(small[:1])[0]
    assert f is not None
    assert f.keyframe
    assert (f.width, f.height) == (352, 288)
    sps = annexb.find_sps(f.data)
    assert sps is not None
    assert (sps.width, sps.height) == (352, 288)


def test_bad_jpeg_is_dropped_and_the_stream_goes_on(jpegs: list[bytes]) -> None:
    h = Harness()
    h.stage.set_active(True)
    res = h.feed([jpegs[0], b"\xff\xd8 not a jpeg", jpegs[1]])
    assert res[1] is None
    assert res[0] is not None
    assert res[2] is not None
    assert res[2].pts == res[0].pts + 1  # nothing published for the bad one, no gap in pts
    assert h.stage.stats.bad_inputs == 1
    assert h.problems


def test_pass_through_seam_prepends_parameter_sets(jpegs: list[bytes]) -> None:
    """An access-unit source (an RTSP reader) whose IDRs lack SPS/PPS after the first: the stage adds them."""
    t = MjpegTranscoder(H264Settings(fps=10, keyframe_interval=4, preset="veryfast", profile="baseline", refresh="idr"))
    frames = [t.transcode(j) for j in jpegs[:9]]
    stripped = []
    for i, f in enumerate(frames):
        nals = annexb.split_nal_units(f.data)
        if f.keyframe and i > 0:
            nals = [n for n in nals if n[0] & 0x1F not in (NalType.SPS, NalType.PPS)]
        stripped.append(EncodedFrame(annexb.join_nal_units(nals), f.keyframe, f.pts, f.width, f.height))
    h = Harness()
    h.stage.set_active(True)
    out = [h.stage.on_access_unit(f, 5) for f in stripped]
    assert all(o is not None for o in out)
    for o in out:
        assert o is not None
        if o.keyframe:
            assert NalType.SPS in annexb.nal_types(o.data)
    # such a source makes its own IDRs: the stage says when one is wanted, rate-limited like the transcoder's
    h.clock.t += 1.0
    assert h.stage.request_idr()
    assert h.stage.idr_wanted
    h.stage.idr_sent()
    assert not h.stage.idr_wanted
    h.stage.request_idr()
    assert not h.stage.idr_wanted  # inside the interval
    h.clock.t += IDR_MIN_INTERVAL_S
    assert h.stage.idr_wanted
    # a bare IDR before any parameter set is refused, not published
    h2 = Harness()
    h2.stage.set_active(True)
    assert h2.stage.on_access_unit(stripped[4], 5) is None
    assert h2.stage.stats.bad_inputs == 1


def test_receiver_waits_for_an_idr_after_a_loss(jpegs: list[bytes]) -> None:
    h = Harness(H264Settings(keyframe_interval=8, fps=30, refresh="idr"))
    h.stage.set_active(True)
    out = [f for f in h.feed(jpegs[:20]) if f is not None]
    r = AccessUnitReceiver()
    shown = []
    for f in out:
        if f.pts == 3:
            continue  # lost on the way
        pic = r.feed(f.data, f.pts)
        shown.append(f.pts if pic is not None else None)
        if pic is not None:
            assert pic.image.shape == (576, 704, 3)
    # 0..2 shown, 4..7 unusable (predicted from the lost 3), 8 (IDR) onward shown again
    assert shown[:3] == [0, 1, 2]
    assert shown[3:7] == [None] * 4
    assert shown[7] == 8
    assert r.stats.lost == 1
    assert r.take_unusable() == 4
    assert r.take_unusable() == 0


# ---- the controller's codec policy ---------------------------------------------------------------------------
def controller(**kw: object) -> tuple[VideoController, Clock]:
    clock = Clock()
    return VideoController(VideoSettings(**kw), BitrateMeter(2.0), clock=clock), clock  # type: ignore[arg-type]


def test_h264_mode_asks_the_camera_for_compression_0_and_keeps_the_ladder_still() -> None:
    c, _ = controller(codec="h264", compression=50, fps=30, max_bitrate_kbps=300)
    assert c.current.compression == 0
    assert c.current.fps == 30
    s = c.h264_settings()
    assert s.bitrate_kbps == 300
    assert s.fps == 30
    m, _ = controller(codec="mjpeg", compression=50, fps=30)
    assert m.current.compression == 50
    assert m.h264_settings().bitrate_kbps == 1000  # without any budget: the request (the safe default)


def test_codec_values_are_checked_with_the_list() -> None:
    c, _ = controller()
    assert c.check(VideoSettings(codec="h265"), {"codec"}) == "codec='h265' is not one of mjpeg, h264"
    with pytest.raises(EncoderError, match="preset must be one of"):  # the settings check their own fields
        H264Settings(preset="placebo")
    # the parameters' bitrate range is narrower than the encoder's: the check names the parameter
    below = VideoSettings(h264=H264Settings(bitrate_kbps=60))
    assert "h264_bitrate_kbps=60 is outside" in (c.check(below, {"h264_bitrate_kbps"}) or "")
    assert c.check(VideoSettings(codec="h264"), {"codec"}) is None
    with pytest.raises(ValueError, match="codec"):
        VideoController(VideoSettings(codec="vp9"), BitrateMeter(2.0))


def test_switching_codec_changes_the_request() -> None:
    c, _ = controller(compression=40)
    c.apply(VideoSettings(compression=40, codec="h264"), {"codec"})
    assert c.current.compression == 0
    c.apply(VideoSettings(compression=40, codec="mjpeg"), {"codec"})
    assert c.current.compression == 40


def test_link_budget_lowers_the_h264_bitrate_judged_against_h264_bytes() -> None:
    c, clock = controller(codec="h264", fps=30, h264=H264Settings(bitrate_kbps=1500))
    # 4 s of 30 fps at ~1500 kbit/s sent as H.264 (6250 B/frame)
    for _i in range(120):
        clock.t += 1 / 30
        c.on_h264_frame(clock.t, 6250)
    # the consumer receives a third of the frames: congested, the budget drops under what it received
    report = FeedbackReport("/op", 20, 10.0, 500.0, 0.02, 0.01, 0.1, 2.0)
    j = c.feedback(report, lambda _name: True)
    assert j is not None
    assert j.decision.state == "congested"
    s = c.h264_settings()
    assert 100 <= s.bitrate_kbps <= 500
    assert c.current.compression == 0
    assert c.state().level == 0


# ---- the H.264 ceiling: a clear link raises the bitrate past h264_bitrate_kbps, up to h264_max_bitrate_kbps ----
@pytest.mark.parametrize(
    ("start", "ceiling", "link", "hand", "want"),
    [
        (1000, 1500, 0.0, 0.0, (1000, 1000)),  # no feedback: the start, the encoder opened at it
        (1000, 1500, 600.0, 0.0, (600, 1000)),  # a budget under the start lowers it (as before the ceiling)
        (1000, 1500, 1100.0, 0.0, (1000, 1000)),  # 0.9 x 1100 = 990: not past the start yet
        (1000, 1500, 1400.0, 0.0, (1260, 1500)),  # 0.9 x the budget, the ceiling announced
        (1000, 1500, 5000.0, 0.0, (1500, 1500)),  # never past the ceiling
        (1000, 1500, 5000.0, 1200.0, (1200, 1500)),  # the hand-set budget caps it
        (1000, 1000, 5000.0, 0.0, (1000, 1000)),  # ceiling = start: never above it (the behaviour before)
        (1000, 1000, 700.0, 0.0, (700, 1000)),
        (1000, 1500, 50.0, 0.0, (100, 1000)),  # the encoder's floor
    ],
)
def test_h264_target_follows_the_budget_up_to_the_ceiling(
    start: int, ceiling: int, link: float, hand: float, want: tuple[int, int]
) -> None:
    assert h264_target_kbps(start, ceiling, link, hand) == want


def test_ceiling_equal_to_start_keeps_the_old_rule() -> None:
    """min(start, every budget in force) for any budget, when h264_max_bitrate_kbps = h264_bitrate_kbps."""
    for link in (0.0, 80.0, 300.0, 999.0, 1000.0, 1001.0, 4000.0):
        for hand in (0.0, 250.0, 2000.0):
            budgets = [b for b in (link, hand) if b > 0]
            old = max(100, min(1000, int(min(budgets)))) if budgets else 1000
            assert h264_target_kbps(1000, 1000, link, hand)[0] == old, (link, hand)


def test_a_ceiling_at_or_below_the_start_is_accepted_and_never_raises_the_bitrate() -> None:
    """The default ceiling (1500 kbit/s) is above the start (1000): a clear link may raise the bitrate that far; a
    start set above the ceiling alone is accepted, and the ceiling then means "never above the start", as a ceiling
    equal to it does."""
    assert (VideoSettings().h264.bitrate_kbps, VideoSettings().h264.max_bitrate_kbps) == (1000, 1500)
    c, _ = controller(codec="h264")
    assert (
        c.check(VideoSettings(codec="h264", h264=H264Settings(max_bitrate_kbps=800)), {"h264_max_bitrate_kbps"}) is None
    )
    assert c.check(VideoSettings(h264=H264Settings(bitrate_kbps=2000)), {"h264_bitrate_kbps"}) is None
    VideoController(VideoSettings(h264=H264Settings(bitrate_kbps=3000)), BitrateMeter(2.0))  # starts
    for link in (0.0, 300.0, 2000.0, 4000.0, 10_000.0):
        assert h264_target_kbps(2000, 800, link)[0] == h264_target_kbps(2000, 2000, link)[0], link
        assert h264_target_kbps(2000, 800, link)[0] <= 2000
    assert "outside 100…20000" in (
        c.check(VideoSettings(h264=H264Settings(max_bitrate_kbps=30_000)), {"h264_max_bitrate_kbps"}) or ""
    )
    both = VideoSettings(h264=H264Settings(bitrate_kbps=2000, max_bitrate_kbps=3000))
    assert c.check(both, {"h264_bitrate_kbps", "h264_max_bitrate_kbps"}) is None


def _clear_reports(c: VideoController, clock: Clock, seconds: float, *, report: bool = True) -> list[int]:
    """``seconds`` of 25 access units/s at the encoder's target, a clear report every 0.5 s (``report``); the
    targets seen after each half second."""
    targets = []
    for _half in range(int(seconds * 2)):
        kbps = c.h264_settings().bitrate_kbps
        for _i in range(12):
            clock.t += 1 / 25
            c.on_h264_frame(clock.t, int(kbps * 1000 / 8 / 25))
        if report:
            fb = FeedbackReport("/op", 50, 25.0, float(kbps), 0.02, 0.01, 0.04, 2.0)
            c.feedback(fb, lambda _name: True)
        c.tick()
        targets.append(c.h264_settings().bitrate_kbps)
    return targets


def test_clear_link_raises_the_bitrate_to_the_ceiling_and_no_feedback_keeps_the_start() -> None:
    c, clock = controller(codec="h264", fps=30, h264=H264Settings(bitrate_kbps=1000, max_bitrate_kbps=1500))
    assert _clear_reports(c, clock, 4.0, report=False)[-1] == 1000  # nobody reports: the safe default
    targets = _clear_reports(c, clock, 10.0)
    assert targets[-1] == 1500, targets
    assert all(b >= a for a, b in zip(targets, targets[1:], strict=False)), targets  # one way, step by step
    assert targets.index(1500) >= 3, targets  # climbed in steps, each judged, not in one jump
    s = c.h264_settings()
    assert s.max_bitrate_kbps == 1500
    assert c.state().link_state == "clear"
    # the reports stop: held through the silence, released after link_release, back to the start
    clock.t += 31.0
    c.tick()
    assert c.h264_settings().bitrate_kbps == 1000
    # a ceiling equal to the start: the same clear reports never raise it
    c2, clock2 = controller(codec="h264", h264=H264Settings(bitrate_kbps=1000, max_bitrate_kbps=1000))
    assert set(_clear_reports(c2, clock2, 6.0)) == {1000}
    assert c2.state().link_budget_kbps == 0.0


def test_congestion_after_the_climb_brings_the_bitrate_back_down() -> None:
    c, clock = controller(codec="h264", fps=30, h264=H264Settings(bitrate_kbps=1000, max_bitrate_kbps=2000))
    _clear_reports(c, clock, 8.0)
    high = c.h264_settings().bitrate_kbps
    assert high > 1300
    sent = high
    # the consumer receives 60 % of what is sent, with a queue: congested
    for _i in range(12):
        clock.t += 1 / 25
        c.on_h264_frame(clock.t, int(sent * 1000 / 8 / 25))
    j = c.feedback(FeedbackReport("/op", 30, 15.0, 0.6 * sent, 0.9, 0.01, 0.2, 2.0), lambda _name: True)
    assert j is not None
    assert j.decision.state == "congested"
    assert c.h264_settings().bitrate_kbps < 0.8 * high


def test_encoder_reopens_once_at_the_ceiling_when_the_link_lets_it_climb(jpegs: list[bytes]) -> None:
    """Without feedback the encoder opens at the start; the climb past it re-opens it once, at the ceiling (one
    IDR), and every later step up or down is live."""
    h = Harness(H264Settings(bitrate_kbps=1000, fps=30, max_bitrate_kbps=1000))
    h.stage.set_active(True)
    h.feed(jpegs[:3])
    assert [m.bitrate_kbps for m in h.made] == [1000]
    h.settings = H264Settings(bitrate_kbps=1080, fps=30, max_bitrate_kbps=1500)
    out = h.feed(jpegs[3:5])
    assert [m.bitrate_kbps for m in h.made] == [1000, 1500]
    assert h.stage.stats.fps_reopens == 0  # re-made for the ceiling, not for a new picture rate
    assert out[0] is not None
    assert out[0].keyframe
    for kbps, top in ((1200, 1500), (1500, 1500), (800, 1000), (1300, 1500)):
        h.settings = H264Settings(bitrate_kbps=kbps, fps=30, max_bitrate_kbps=top)
        out = h.feed(jpegs[5:7])
        assert not any(f is not None and f.keyframe for f in out)
        assert h.transcoders[-1].settings.bitrate_kbps == kbps
    assert len(h.made) == 2


def test_vbv_buffer_follows_the_bitrate_and_with_periodic_idrs_at_most_a_slice_of_the_link_budget() -> None:
    """Without a link budget: 0.15 s of the bitrate now (1000 kbit/s: 150 kbit, what the encoder always had); with
    periodic IDRs under one, at most IDR_LINK_S of it, so an IDR crosses the link in about that long; with intra
    refresh (no periodic IDR) the bitrate's buffer whatever the budget."""
    assert h264_vbv_kbit(1000, 0.0, "idr") == 150
    assert h264_vbv_kbit(600, 0.0, "idr") == 90  # a lowered bitrate lowers the buffer too
    assert h264_vbv_kbit(850, 900.0, "idr") == round(900 * IDR_LINK_S)  # 1 Mbit/s link: 54 kbit, not 128
    assert h264_vbv_kbit(1000, 5000.0, "idr") == 150  # a wide link: the bitrate's buffer
    assert h264_vbv_kbit(1080, 1200.0, "intra") == 162  # not 72: the buffer x264 keeps until the next IDR
    assert h264_vbv_kbit(600, 0.0, "intra") == 90
    c, _ = controller(codec="h264", max_bitrate_kbps=400)
    assert c.h264_settings().vbv_kbit == 60  # a hand-set budget is no link measure: 0.15 s of 400 kbit/s


def test_stage_hands_a_new_vbv_buffer_to_the_encoder_and_no_extra_idr(jpegs: list[bytes]) -> None:
    kw = {"keyframe_interval": 10, "fps": 30, "max_bitrate_kbps": 1000, "refresh": "idr"}
    h = Harness(H264Settings(bitrate_kbps=1000, vbv_kbit=150, **kw))  # type: ignore[arg-type]
    h.stage.set_active(True)
    h.feed(jpegs[:3])
    assert [m.vbv_kbit for m in h.made] == [150]
    h.settings = H264Settings(bitrate_kbps=800, vbv_kbit=50, **kw)  # type: ignore[arg-type]
    out = h.feed(jpegs[3:14])
    assert len(h.made) == 1  # the same transcoder ...
    assert h.transcoders[0].settings.vbv_kbit == 50  # ... told the new buffer
    assert [i + 3 for i, f in enumerate(out) if f is not None and f.keyframe] == [10]  # the periodic IDR only


def test_with_intra_refresh_a_new_vbv_buffer_waits_for_the_next_idr_asked_for(jpegs: list[bytes]) -> None:
    """No periodic IDR: the buffer (which bounds an IDR) is in force from the next IDR on demand, the picture it
    matters for, and costs no IDR of its own."""
    kw = {"keyframe_interval": 10, "fps": 30, "max_bitrate_kbps": 1000}
    h = Harness(H264Settings(bitrate_kbps=1000, vbv_kbit=150, **kw))  # type: ignore[arg-type]
    h.stage.set_active(True)
    h.feed(jpegs[:3])
    h.settings = H264Settings(bitrate_kbps=800, vbv_kbit=50, **kw)  # type: ignore[arg-type]
    out = h.feed(jpegs[3:14])
    assert not any(f is not None and f.keyframe for f in out)
    encoder = h.transcoders[0]._encoder
    assert encoder is not None
    assert (encoder.reopens, encoder.opened_vbv_bits) == (0, 150_000)
    assert h.stage.request_idr()
    (idr,) = h.feed(jpegs[14:15])
    assert idr is not None
    assert idr.keyframe
    assert (encoder.reopens, encoder.opened_vbv_bits) == (1, 50_000)


def test_pts_gaps_count_missing_access_units_and_not_a_restart():
    from axis_ptz_ros2.streaming.receiver import PtsGaps

    gaps = PtsGaps()
    assert [gaps.see(p) for p in (5, 6, 7)] == [False, False, False]
    assert gaps.see(10)  # 8 and 9 never arrived
    assert gaps.lost == 2
    assert gaps.see(0)  # a restarted stream: a discontinuity, nothing lost
    assert not gaps.see(1)
    assert gaps.lost == 2
