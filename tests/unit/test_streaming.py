"""streaming.py: JPEG header readers, back-off, meter, bandwidth controller, reader thread (fake sources)."""

from __future__ import annotations

import queue
import threading
import time

import cv2
import numpy as np
import pytest

from axis_ptz_ros2.streaming import (
    AXIS214_PAL_RESOLUTIONS,
    Backoff,
    BandwidthController,
    BitrateMeter,
    BudgetConfig,
    ReaderConfig,
    StreamReader,
    StreamState,
    compression_size_factor,
    jpeg_comments,
    jpeg_size,
)
from axis_ptz_ros2.vapix.errors import AuthError, CameraTimeout, CameraUnreachable, InvalidArgument
from axis_ptz_ros2.vapix.mjpeg import MjpegStats
from axis_ptz_ros2.vapix.models import Resolution, VideoParams
from tests.support.stamps import sim_stamp
from tests.support.waiting import wait_until

pytestmark = pytest.mark.unit

P704 = VideoParams(Resolution(704, 576), fps=30, compression=0)


def encode(w: int, h: int, comment: bytes | None = None, quality: int = 80) -> bytes:
    img = np.zeros((h, w, 3), np.uint8)
    cv2.rectangle(img, (w // 4, h // 4), (w // 2, h // 2), (0, 200, 50), -1)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, quality])
    assert ok
    data = buf.tobytes()
    if comment is not None:  # after SOI, as the simulator does
        seg = b"\xff\xfe" + (len(comment) + 2).to_bytes(2, "big") + comment
        data = data[:2] + seg + data[2:]
    return data


# --------------------------------------------------------------------------------------------------------
# JPEG headers
# --------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("w", "h"), [(704, 576), (352, 288), (176, 144), (1920, 1080), (8, 8)])
def test_jpeg_size_reads_sof(w, h):
    assert jpeg_size(encode(w, h)) == (w, h)
    assert jpeg_size(encode(w, h, comment=b"x" * 300)) == (w, h)


def test_jpeg_size_progressive_and_garbage():
    img = np.full((50, 70, 3), 128, np.uint8)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1])
    assert ok
    assert jpeg_size(buf.tobytes()) == (70, 50)
    assert jpeg_size(b"") is None
    assert jpeg_size(b"not a jpeg at all") is None
    assert jpeg_size(b"\xff\xd8\xff\xe0\x00\x10JFIF") is None  # truncated before SOF
    assert jpeg_size(encode(64, 48)[:30]) is None


def test_sim_stamp_and_comments():
    data = encode(64, 48, comment=b"axsim seq=42 t=1700000000123456789")
    assert jpeg_comments(data) == [b"axsim seq=42 t=1700000000123456789"]
    assert sim_stamp(data) == (42, 1700000000123456789)
    assert sim_stamp(encode(64, 48)) is None
    assert sim_stamp(encode(64, 48, comment=b"axsim seq=x t=1")) is None


# --------------------------------------------------------------------------------------------------------
# Back-off and meter
# --------------------------------------------------------------------------------------------------------
def test_backoff_doubles_caps_and_resets():
    b = Backoff(0.1, 2.0)
    assert [round(b.next(), 3) for _ in range(7)] == [0.1, 0.2, 0.4, 0.8, 1.6, 2.0, 2.0]
    b.reset()
    assert b.next() == pytest.approx(0.1)
    with pytest.raises(ValueError, match="back-off"):
        Backoff(0.0, 1.0)


def test_meter_rate_and_quiet_stream():
    m = BitrateMeter(window_s=2.0)
    for i in range(31):  # 10 fps, 1000 B each, over 3 s
        m.add(100.0 + i * 0.1, 1000)
    r = m.rate(103.0)
    assert r.fps == pytest.approx(10.0)
    assert r.kbps == pytest.approx(80.0)
    assert r.bytes_per_frame == pytest.approx(1000.0)
    assert m.rate(110.0).kbps == 0.0  # nothing in the window any more
    m.reset()
    assert m.rate(103.0).frames == 0


# --------------------------------------------------------------------------------------------------------
# Bandwidth controller
# --------------------------------------------------------------------------------------------------------
def test_ladder_order_compression_then_fps_then_resolution():
    c = BandwidthController(P704, 1000, AXIS214_PAL_RESOLUTIONS, BudgetConfig(max_compression=60))
    ladder = c.ladder
    assert ladder[0] == P704
    comps = [p.compression for p in ladder[:7]]
    assert comps == [0, 10, 20, 30, 40, 50, 60]
    assert all(p.fps == 30 and p.resolution == P704.resolution for p in ladder[:7])
    fps_part = [p.fps for p in ladder[7:14]]
    assert fps_part == [25, 20, 15, 10, 5, 2, 1]
    tail = [str(p.resolution) for p in ladder[14:]]
    assert tail == ["352x288", "176x144"]  # 2CIF (704x288, half the lines) is another shape: skipped
    assert all(p.compression == 60 and p.fps == 1 for p in ladder[14:])


def test_ladder_keeps_the_requested_shape_while_the_camera_has_sizes_of_it():
    sizes = [Resolution(w, h) for w, h in ((1920, 1080), (1280, 960), (1280, 720), (1024, 768), (640, 480), (640, 360))]
    hd = VideoParams(fps=30, resolution=Resolution(1920, 1080), compression=30)
    c = BandwidthController(hd, 1000, sizes, BudgetConfig(max_compression=60))
    assert [str(r) for r in dict.fromkeys(p.resolution for p in c.ladder)] == ["1920x1080", "1280x720", "640x360"]
    # no size of the requested shape below it: the smaller ones of any shape, rather than no resolution step
    odd = VideoParams(fps=30, resolution=Resolution(1280, 960), compression=30)
    c = BandwidthController(odd, 1000, [Resolution(1280, 960), Resolution(640, 360)], BudgetConfig(max_compression=60))
    assert [str(r) for r in dict.fromkeys(p.resolution for p in c.ladder)] == ["1280x960", "640x360"]


def test_compression_prior_is_monotone():
    values = [compression_size_factor(c) for c in range(0, 101, 5)]
    assert values[0] == 1.0
    assert all(b <= a for a, b in zip(values, values[1:], strict=False))
    assert compression_size_factor(100) == pytest.approx(0.276)


class FakeCamera:
    """Bytes per frame ∝ pixels · q(compression); fps as asked up to ``max_fps``."""

    def __init__(self, bpf_full: float = 15000.0, max_fps: float = 30.0, steep: bool = False) -> None:
        self.bpf_full = bpf_full
        self.max_fps = max_fps
        self.steep = steep  # like a JPEG encoder at quality 100 - compression: c=10 is already ~3x smaller

    def measure(self, p: VideoParams) -> tuple[float, float, float]:
        pixels = p.resolution.width * p.resolution.height / (704 * 576)
        q = 0.35 * (1.0 - 0.6 * p.compression / 100.0) if self.steep and p.compression else 1.0
        if not self.steep:
            q = 1.0 - 0.8 * p.compression / 100.0
        bpf = self.bpf_full * pixels * q
        fps = min(float(p.fps), self.max_fps)
        return bpf * fps * 8 / 1000, fps, bpf


def run_controller(c: BandwidthController, cam: FakeCamera, seconds: float, t0: float = 0.0, dt: float = 0.25):
    t = t0
    history = []
    while t < t0 + seconds:
        kbps, fps, bpf = cam.measure(c.current)
        c.update(t, kbps, fps, bpf, frames=10)
        history.append((t, c.current, cam.measure(c.current)[0]))
        t += dt
    return history


def test_controller_gets_under_budget_fast_and_stays():
    cam = FakeCamera()  # 704x576@30 c0: 3600 kbit/s
    c = BandwidthController(P704, 2500.0)
    hist = run_controller(c, cam, 20.0)
    under = [t for t, _, k in hist if k <= 2500]
    assert under, "never got under the budget"
    assert under[0] <= 3.0
    # after getting under it never goes over for long (at most one probe step up that overshoots)
    late = [k for t, _, k in hist if t > 10.0]
    assert max(late) <= 2500 * 1.1
    assert min(late) >= 2500 * 0.6  # and it does not sit needlessly low
    assert c.current.fps == 30
    assert c.current.resolution == P704.resolution


def test_controller_learns_a_camera_unlike_the_prior():
    cam = FakeCamera(steep=True)  # c=0 -> 3600 kbit/s, c=10 -> ~1200: far steeper than the thesis' prior
    c = BandwidthController(P704, 1500.0)
    hist = run_controller(c, cam, 12.0)
    under = [t for t, _, k in hist if k <= 1500]
    assert under[0] <= 2.0
    late = [k for t, _, k in hist if t > 8.0]
    assert max(late) <= 1500 * 1.1
    assert min(late) >= 1500 * 0.5, "stuck far below the budget"


def test_controller_steps_fps_then_resolution_for_tight_budgets():
    cam = FakeCamera()
    c = BandwidthController(P704, 300.0)
    run_controller(c, cam, 15.0)
    p = c.current
    kbps = cam.measure(p)[0]
    assert kbps <= 300
    assert p.compression == 60
    assert p.fps < 30 or p.resolution != P704.resolution
    c2 = BandwidthController(P704, 15.0)
    run_controller(c2, cam, 15.0)
    assert c2.current.resolution != P704.resolution  # had to go down in size too


def test_controller_climbs_back_with_hysteresis_when_budget_grows():
    cam = FakeCamera()
    c = BandwidthController(P704, 800.0)
    run_controller(c, cam, 10.0)
    degraded = c.level
    assert degraded > 0
    c.configure(budget_kbps=800.0)  # same budget, restart: gets back to the same level
    run_controller(c, cam, 10.0, t0=10.0)
    assert c.level == degraded
    # the scene gets 10x simpler: it climbs back, each climb after >= up_hold_s of room
    cam.bpf_full /= 10.0
    changes = []
    last = c.level
    for t, p, _ in run_controller(c, cam, 60.0, t0=20.0):
        if c.ladder.index(p) != last:
            changes.append(t)
            last = c.ladder.index(p)
    assert c.level == 0
    assert 1 <= len(changes) <= degraded
    assert all(b - a >= 3.0 - 1e-9 for a, b in zip(changes, changes[1:], strict=False))


def test_controller_off_returns_request_and_never_exceeds_it():
    cam = FakeCamera()
    c = BandwidthController(P704, 500.0)
    run_controller(c, cam, 8.0)
    degraded = c.level
    assert 0 < degraded < len(c.ladder) - 1
    # while on, a measurement far over budget degrades further (and says so); switching off restores the request
    assert c.update(100.0, 5000, 30, 1000, 10) == c.current
    assert c.level > degraded
    assert c.configure(budget_kbps=0.0, now=101.0) == P704
    assert c.update(102.0, 99999.0, 30.0, 20000.0, 10) is None
    assert c.current == P704
    for p in BandwidthController(P704, 1.0).ladder:
        assert p.fps <= P704.fps
        assert p.compression >= P704.compression
        assert p.resolution.width * p.resolution.height <= 704 * 576


def test_controller_respects_camera_fps_ceiling():
    cam = FakeCamera(max_fps=12.0)  # the camera cannot deliver 30: prediction uses what it delivers
    c = BandwidthController(P704, 1300.0)
    run_controller(c, cam, 10.0)
    assert cam.measure(c.current)[0] <= 1300
    assert c.current.fps == 30  # lowering fps from 30 to 25 would change nothing: compression used instead


# --------------------------------------------------------------------------------------------------------
# Reader thread with fake sources
# --------------------------------------------------------------------------------------------------------
class FakeSource:
    def __init__(self, frames: queue.Queue[bytes | None]) -> None:
        self.frames = frames
        self.closed = threading.Event()
        self.parser_stats = MjpegStats(dropped_corrupt=1)

    def __iter__(self):
        while not self.closed.is_set():
            try:
                item = self.frames.get(timeout=0.01)
            except queue.Empty:
                continue
            if item is None:
                return
            if self.closed.is_set():
                return
            yield item

    def close(self) -> None:
        self.closed.set()

    @property
    def stats(self) -> MjpegStats:
        return self.parser_stats


class FakeOpener:
    def __init__(self) -> None:
        self.calls: list[tuple[float, VideoParams]] = []
        self.script: list[BaseException | None] = []  # None = succeed
        self.sources: list[FakeSource] = []
        self.frames: queue.Queue[bytes | None] = queue.Queue()

    def __call__(self, params: VideoParams, read_timeout_s: float) -> FakeSource:
        self.calls.append((time.monotonic(), params))
        action = self.script.pop(0) if self.script else None
        if action is not None:
            raise action
        src = FakeSource(self.frames)
        self.sources.append(src)
        return src


def wait_for(pred, timeout=3.0):
    return wait_until(pred, timeout, 0.005)


@pytest.fixture
def reader_factory():
    readers: list[StreamReader] = []

    def make(opener, config=None, active=True, **kw):
        got: list[tuple[bytes, int]] = []
        r = StreamReader(opener, lambda j, t: got.append((j, t)), P704, config, active=active, **kw)
        r.got = got  # type: ignore[attr-defined]
        readers.append(r)
        r.start()
        return r

    yield make
    for r in readers:
        assert r.stop(2.0)


def test_reader_delivers_frames_stamped_at_arrival(reader_factory):
    opener = FakeOpener()
    r = reader_factory(opener)
    wait_for(lambda: opener.sources)
    before = time.time_ns()
    for i in range(5):
        opener.frames.put(b"\xff\xd8frame%d\xff\xd9" % i)
    wait_for(lambda: len(r.got) == 5)
    assert [j for j, _ in r.got] == [b"\xff\xd8frame%d\xff\xd9" % i for i in range(5)]
    assert all(before <= t <= time.time_ns() for _, t in r.got)
    s = r.stats()
    assert s.state is StreamState.STREAMING
    assert s.frames == 5
    assert s.connects == 1
    assert s.drops == 1  # parser counters of the live stream are included


def test_reader_backs_off_exponentially_then_resets(reader_factory):
    opener = FakeOpener()
    opener.script = [CameraUnreachable("refused")] * 4
    events = []
    r = reader_factory(
        opener, ReaderConfig(backoff_initial_s=0.05, backoff_max_s=0.2), on_event=lambda s, m: events.append(s)
    )
    wait_for(lambda: len(opener.sources) == 1)
    gaps = [b[0] - a[0] for a, b in zip(opener.calls, opener.calls[1:], strict=False)]
    assert gaps[0] == pytest.approx(0.05, abs=0.03)
    assert gaps[1] == pytest.approx(0.10, abs=0.03)
    assert gaps[2] == pytest.approx(0.20, abs=0.03)
    assert gaps[3] == pytest.approx(0.20, abs=0.03)  # capped
    assert StreamState.RECONNECTING in events
    assert "refused" in r.stats().last_error
    opener.frames.put(b"\xff\xd8a\xff\xd9")
    wait_for(lambda: r.got)
    opener.frames.put(None)  # camera ends the stream: back-off starts again from the initial delay
    wait_for(lambda: len(opener.sources) == 2)
    assert opener.calls[-1][0] - opener.calls[-2][0] < 0.2
    assert r.stats().reconnects == 5


def test_reader_auth_failure_retries_slowly(reader_factory):
    opener = FakeOpener()
    opener.script = [AuthError("GET /axis-cgi/mjpg/video.cgi: HTTP 401, authentication failed")] * 10
    r = reader_factory(opener, ReaderConfig(auth_retry_s=0.3))
    wait_for(lambda: len(opener.calls) >= 3)  # it does retry ...
    wait_for(lambda: r.stats().auth_failures == 3)
    starts = [t for t, _ in opener.calls[:3]]
    gaps = [b - a for a, b in zip(starts, starts[1:], strict=False)]
    assert all(g >= 0.3 - 0.02 for g in gaps), gaps  # ... but not hammered: one try per auth_retry_s
    s = r.stats()
    assert s.state is StreamState.AUTH_FAILED
    assert "401" in s.last_error
    assert s.auth_failures == len(opener.calls)


def test_reader_invalid_params_wait_for_new_ones(reader_factory):
    opener = FakeOpener()
    opener.script = [InvalidArgument("resolution 1x1 not supported")]
    r = reader_factory(opener, ReaderConfig(auth_retry_s=30.0))
    wait_for(lambda: r.state is StreamState.INVALID_PARAMS)
    time.sleep(0.1)  # a window in which no retry may come: the thing under test is that nothing happens
    assert len(opener.calls) == 1
    r.set_params(VideoParams(Resolution(352, 288), 10, 30))  # new params wake it up at once
    wait_for(lambda: len(opener.sources) == 1)
    assert opener.calls[-1][1].resolution == Resolution(352, 288)


def test_reader_watchdog_turns_a_stall_into_a_reconnect(reader_factory):
    opener = FakeOpener()
    r = reader_factory(opener, ReaderConfig(stall_timeout_s=0.15, backoff_initial_s=0.01))
    wait_for(lambda: opener.sources)
    opener.frames.put(b"\xff\xd8a\xff\xd9")
    wait_for(lambda: r.got)
    assert not r.check_watchdog()  # fresh
    assert r.check_watchdog(now=time.monotonic() + 0.2)  # as if 0.2 s (> stall_timeout_s) had passed
    wait_for(lambda: len(opener.sources) == 2)
    assert opener.sources[0].closed.is_set()
    s = r.stats()
    assert s.stalls == 1
    assert s.reconnects == 1
    assert "stalled" in s.last_error


def test_reader_stall_limit_scales_with_low_fps():
    cfg = ReaderConfig(stall_timeout_s=1.0, read_timeout_s=5.0)
    assert cfg.stall_limit(30) == 1.0
    assert cfg.stall_limit(1) == 3.0
    assert cfg.read_timeout(30) == 1.0
    assert ReaderConfig(stall_timeout_s=1.0, read_timeout_s=0.5).read_timeout(30) == 0.5


def test_reader_read_timeout_mid_stream_counts_as_stall(reader_factory):
    class TimingOutSource(FakeSource):
        def __iter__(self):
            yield b"\xff\xd8a\xff\xd9"
            raise CameraTimeout("GET /axis-cgi/mjpg/video.cgi: camera did not answer in time")

    class StallingOpener(FakeOpener):
        def __init__(self) -> None:
            super().__init__()
            self.timeouts: list[float] = []

        def __call__(self, params, read_timeout_s):
            self.timeouts.append(read_timeout_s)
            src = super().__call__(params, read_timeout_s)
            return TimingOutSource(src.frames) if len(self.timeouts) == 1 else src

    opener2 = StallingOpener()
    timeouts = opener2.timeouts
    r = reader_factory(opener2, ReaderConfig(stall_timeout_s=0.7, read_timeout_s=5.0, backoff_initial_s=0.01))
    wait_for(lambda: len(timeouts) >= 2)
    assert timeouts[0] == pytest.approx(0.7)  # the socket read timeout is the stall limit
    wait_for(lambda: r.stats().stalls == 1)
    assert "did not answer" in r.stats().last_error or "stalled" in r.stats().last_error


def test_reader_new_params_reconnect_without_backoff(reader_factory):
    opener = FakeOpener()
    r = reader_factory(opener, ReaderConfig(backoff_initial_s=5.0, backoff_max_s=5.0))
    wait_for(lambda: opener.sources)
    p2 = VideoParams(Resolution(176, 144), 5, 50)
    t0 = time.monotonic()
    r.set_params(p2)
    wait_for(lambda: len(opener.sources) == 2)
    assert time.monotonic() - t0 < 0.5
    assert opener.calls[-1][1] == p2
    assert opener.sources[0].closed.is_set()
    assert r.stats().reconnects == 0
    r.set_params(p2)  # same params: nothing happens
    time.sleep(0.05)  # a window for a (wrong) reconnect: the thing under test is that none comes
    assert len(opener.sources) == 2


def test_reader_lazy_opens_nothing_until_active(reader_factory):
    opener = FakeOpener()
    r = reader_factory(opener, active=False)
    time.sleep(0.1)  # a window for a (wrong) connect while inactive: the thing under test is that none comes
    assert opener.calls == []
    assert r.state is StreamState.IDLE_LAZY
    r.set_active(True)
    wait_for(lambda: opener.sources)
    r.set_active(False)
    wait_for(lambda: opener.sources[0].closed.is_set())
    wait_for(lambda: r.state is StreamState.IDLE_LAZY)
    time.sleep(0.05)  # a window for a (wrong) reconnect: the thing under test is that none comes
    assert len(opener.calls) == 1


def test_reader_never_delivers_a_frame_twice_or_after_stop(reader_factory):
    opener = FakeOpener()
    r = reader_factory(opener)
    wait_for(lambda: opener.sources)
    for i in range(50):
        opener.frames.put(b"%d" % i)
    wait_for(lambda: len(r.got) == 50)
    t0 = time.monotonic()
    assert r.stop(1.0)
    assert time.monotonic() - t0 < 0.5
    opener.frames.put(b"late")
    time.sleep(0.05)  # a window for a (wrong) late delivery: the thing under test is that none comes
    assert [j for j, _ in r.got] == [b"%d" % i for i in range(50)]
    assert r.state is StreamState.STOPPED


class HangingOpener(FakeOpener):
    """Connects that hang until their timeout (a camera dropping packets), scripted like FakeOpener."""

    def __init__(self, hang_s: float) -> None:
        super().__init__()
        self.hang_s = hang_s

    def __call__(self, params: VideoParams, read_timeout_s: float) -> FakeSource:
        if self.script and isinstance(self.script[0], CameraTimeout):
            time.sleep(self.hang_s)  # the simulated camera: a connect that hangs until its timeout
        return super().__call__(params, read_timeout_s)


def test_reader_back_off_counts_from_the_start_of_a_hung_connect(reader_factory):
    """A connect that hung for its whole timeout has waited already: the next try is not delayed again."""
    opener = HangingOpener(hang_s=0.4)
    opener.script = [CameraTimeout("connect timed out")] * 3
    r = reader_factory(opener, ReaderConfig(backoff_initial_s=0.4, backoff_max_s=0.4))
    wait_for(lambda: len(opener.sources) == 1, timeout=5.0)
    starts = [t for t, _ in opener.calls]
    gaps = [b - a for a, b in zip(starts, starts[1:], strict=False)]
    assert len(gaps) == 3
    # each attempt starts one back-off (0.4 s) after the previous one STARTED, not 0.4 s after it failed
    assert all(g < 0.4 + 0.25 for g in gaps), gaps
    assert r.stats().reconnects == 3


def test_reader_401_right_after_frames_is_a_rebooting_camera_not_a_refused_login(reader_factory):
    opener = FakeOpener()
    r = reader_factory(opener, ReaderConfig(backoff_initial_s=0.05, backoff_max_s=0.1, auth_retry_s=30.0))
    wait_for(lambda: opener.sources)
    opener.frames.put(b"\xff\xd8a\xff\xd9")
    wait_for(lambda: r.stats().frames == 1)
    opener.script = [AuthError("HTTP 401"), AuthError("HTTP 401")]
    opener.frames.put(None)  # the camera went away; while booting it answers 401
    wait_for(lambda: len(opener.sources) == 2, timeout=3.0)  # not after auth_retry_s = 30 s
    assert r.stats().auth_failures == 2
    assert r.state is not StreamState.AUTH_FAILED


def test_reader_401_without_recent_frames_waits_auth_retry(reader_factory):
    opener = FakeOpener()
    opener.script = [AuthError("HTTP 401")]
    r = reader_factory(opener, ReaderConfig(auth_retry_s=30.0))
    wait_for(lambda: r.state is StreamState.AUTH_FAILED)
    time.sleep(0.3)  # a window (auth_retry_s = 30 s) for a (wrong) early retry: the thing under test is none comes
    assert len(opener.calls) == 1


def test_a_worker_starts_once_and_stop_interrupts_and_joins():
    from axis_ptz_ros2.streaming.worker import Worker  # noqa: PLC0415

    interrupted: list[bool] = []
    holder: list[Worker] = []
    w = Worker("probe", "test-worker", lambda: holder[0].stopping.wait(5.0), lambda: interrupted.append(True))
    holder.append(w)
    assert not w.started
    w.start()
    with pytest.raises(RuntimeError, match="probe already started"):
        w.start()
    t0 = time.monotonic()
    assert w.stop(2.0) is True
    assert time.monotonic() - t0 < 1.0
    assert interrupted == [True]
    never = Worker("idle", "test-idle", lambda: None)
    assert never.stop(0.1) is True
    assert not never.started


def test_a_worker_is_interrupted_only_when_its_activity_changes():
    from axis_ptz_ros2.streaming.worker import Worker  # noqa: PLC0415

    interrupted: list[bool] = []
    w = Worker("lazy", "test-lazy", lambda: None, lambda: interrupted.append(w.active), active=False)
    assert not w.active
    w.set_active(False)
    assert interrupted == []
    w.set_active(True)
    w.set_active(True)
    w.set_active(False)
    assert interrupted == [True, False]  # once per change, the new value already in place
    assert Worker("plain", "test-plain", lambda: None).active  # active unless told otherwise


def test_consumer_counts_growth_first_report_restart_and_forgetting():
    from axis_ptz_ros2.streaming.meter import ConsumerCounts

    counts = ConsumerCounts(limit=2)
    assert counts.grew("/a", 5) == 0  # a first report has no growth...
    assert counts.grew("/b", 3, first=0) == 3  # ...unless compared with a starting count
    assert counts.grew("/a", 9) == 4
    assert counts.grew("/a", 9) == 0
    assert counts.grew("/a", 2) == 0  # a restarted consumer: no growth, and counted from here
    assert counts.grew("/a", 4) == 2
    counts.forget("/a")
    assert counts.grew("/a", 7) == 0
    assert counts.grew("/c", 1) == 0  # three consumers: within the limit of 2 + the new one
    assert counts.grew("/d", 1) == 0  # past the limit: everyone is forgotten
    assert counts.grew("/b", 10, first=0) == 10
