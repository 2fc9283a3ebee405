"""Camera time → host time (streaming/clock_sync.py) on synthetic clocks.

The camera's clock is 30 s behind the host's and its crystal runs 50 ppm slow; every frame is late by a fixed
latency (encoder 39 ms + network 1 ms) plus a random queueing delay (mostly a few ms, now and then hundreds of
ms, and a stall that releases a burst); a sender report every 5 s (sent after the encoder, so late by the
network's latency + queueing only). Stamps must be the capture time + the fixed latency within 50 ms (with
sender reports: + the network's latency only), strictly increasing, the reported offset within 100 ms of the
truth, and a step of the camera's clock by ±30 s must not send a stamp backwards."""

from __future__ import annotations

import random
from collections.abc import Iterator
from dataclasses import dataclass

import pytest

from axis_ptz_ros2.streaming.clock_sync import LowerEnvelope, StreamClock

pytestmark = pytest.mark.unit

NS = 1_000_000_000
FPS = 30
ENCODER_NS = 39_000_000
NETWORK_NS = 1_000_000
LATENCY_NS = ENCODER_NS + NETWORK_NS  #: fixed
HOST_T0 = 1_780_000_000 * NS


@dataclass(frozen=True, slots=True)
class Frame:
    capture_host_ns: int  # truth: when the picture was taken, on the host clock
    rtp: int  # 90 kHz, wrapped to 32 bits
    camera_ns: int  # the camera's wall clock for it (what the sender reports give)
    arrival_ns: int  # when it arrived, host clock
    report: tuple[int, int] | None = None  # a sender report just before it: (RTP time, arrival), or None

    @property
    def expected_ns(self) -> int:
        return self.capture_host_ns + LATENCY_NS

    @property
    def true_offset_ns(self) -> int:
        return self.capture_host_ns - self.camera_ns


def frames(
    seconds: float,
    *,
    seed: int = 1,
    behind_s: float = 30.0,
    drift_ppm: float = -50.0,
    wall_step_at_s: float | None = None,
    wall_step_s: float = 0.0,
    rtp_step_at_s: float | None = None,
    rtp_step_s: float = 0.0,
    stall_at_s: float | None = None,
    stall_s: float = 0.0,
    report_every_s: float | None = None,
) -> Iterator[Frame]:
    """A camera's frames: its crystal runs ``drift_ppm`` off the host clock; ``rtp_origin`` is random."""
    rng = random.Random(seed)
    rtp_origin = rng.randrange(1 << 32)
    rate = 1 + drift_ppm * 1e-6
    released = 0  # host time before which nothing arrives (a stall)
    for i in range(int(seconds * FPS)):
        t = i * NS // FPS
        cam_elapsed = int(t * rate)
        wall = HOST_T0 - int(behind_s * NS) + cam_elapsed
        if wall_step_at_s is not None and t >= wall_step_at_s * NS:
            wall += int(wall_step_s * NS)
        ticks = cam_elapsed * 90_000 // NS
        if rtp_step_at_s is not None and t >= rtp_step_at_s * NS:
            ticks += int(rtp_step_s * 90_000)
        u = rng.random()
        delay = int(rng.expovariate(1 / 8e6))  # mostly a few ms
        if u < 0.03:
            delay += rng.randrange(100_000_000, 600_000_000)  # now and then a long queue
        arrival = HOST_T0 + t + LATENCY_NS + delay
        if stall_at_s is not None and stall_at_s * NS <= t < (stall_at_s + stall_s) * NS:
            released = HOST_T0 + int((stall_at_s + stall_s) * NS) + LATENCY_NS
        arrival = max(arrival, released + i % 7 * 1000)
        report = None
        if report_every_s is not None and i % int(report_every_s * FPS) == 0:  # sent when the frame is encoded
            sent_ticks = ticks + int(ENCODER_NS * rate) * 90_000 // NS
            sr_arrival = HOST_T0 + t + LATENCY_NS + int(rng.expovariate(1 / 2e6))
            report = ((rtp_origin + sent_ticks) & 0xFFFFFFFF, max(sr_arrival, released))
        yield Frame(HOST_T0 + t, (rtp_origin + ticks) & 0xFFFFFFFF, wall, arrival, report)


def play(clock: StreamClock, fs: Iterator[Frame]) -> list[tuple[Frame, int]]:
    out = []
    for f in fs:
        if f.report is not None:
            clock.sender_report(*f.report)
        out.append((f, clock.stamp(f.rtp, f.arrival_ns, f.camera_ns)))
    return out


def _check_increasing(out: list[tuple[Frame, int]]) -> None:
    stamps = [s for _, s in out]
    assert all(b > a for a, b in zip(stamps, stamps[1:], strict=False))


def test_thirty_seconds_behind_drifting_and_queued_the_stamps_are_host_capture_time() -> None:
    clock = StreamClock()
    out = play(clock, frames(600))  # 10 minutes: 30 ms of drift
    _check_increasing(out)
    errors = [abs(s - f.expected_ns) for f, s in out]
    assert max(errors) < 50_000_000, max(errors)
    settled = sorted(errors[FPS * 5 :])
    assert settled[len(settled) // 2] < 5_000_000  # the median: the queueing delay is gone, not averaged in
    last = out[-1][0]
    assert clock.camera_offset_ns is not None
    assert abs(clock.camera_offset_ns - last.true_offset_ns) < 100_000_000
    assert abs(clock.camera_offset_ns - 30 * NS) < 100_000_000
    assert 30 < clock.drift_ppm < 70, clock.drift_ppm  # the host runs 50 ppm faster than the camera
    assert clock.offset_warning
    assert clock.take_offset_warning()
    assert not clock.take_offset_warning()  # once


def test_with_sender_reports_the_stamps_are_the_capture_time() -> None:
    """The reports' arrivals show the encoder's latency: it is taken off (the network's 1 ms stays)."""
    clock = StreamClock()
    out = play(clock, frames(300, report_every_s=5.0, seed=5))
    _check_increasing(out)
    errors = [abs(s - f.capture_host_ns - NETWORK_NS) for f, s in out]
    assert max(errors) < 50_000_000, max(errors)
    settled = sorted(errors[FPS * 5 :])
    assert settled[len(settled) // 2] < 5_000_000
    assert abs(clock.encoder_latency_ns - ENCODER_NS) < 5_000_000
    assert clock.camera_offset_ns is not None
    assert abs(clock.camera_offset_ns - out[-1][0].true_offset_ns) < 10_000_000


def test_the_old_way_would_have_gone_backwards_by_the_clock_offset() -> None:
    """The first frames of a session used to be stamped with the arrival time, then with the camera's clock."""
    fs = list(frames(3))
    old = [f.arrival_ns for f in fs[:30]] + [f.camera_ns for f in fs[30:]]
    assert old[30] - old[29] < -29 * NS
    clock = StreamClock()
    _check_increasing(play(clock, iter(fs)))


@pytest.mark.parametrize("step_s", [30.0, -30.0])
def test_a_step_of_the_cameras_wall_clock_moves_the_offset_not_the_stamps(step_s: float) -> None:
    clock = StreamClock()
    out = play(clock, frames(120, wall_step_at_s=60, wall_step_s=step_s))
    _check_increasing(out)
    assert max(abs(s - f.expected_ns) for f, s in out) < 50_000_000
    assert clock.envelope.steps == 0
    assert clock.camera_offset_ns is not None
    assert abs(clock.camera_offset_ns - out[-1][0].true_offset_ns) < 100_000_000
    assert abs(clock.camera_offset_ns - int((30 - step_s) * NS)) < 100_000_000


@pytest.mark.parametrize("step_s", [30.0, -30.0])
def test_a_step_of_the_cameras_rtp_clock_is_survived(step_s: float) -> None:
    clock = StreamClock()
    out = play(clock, frames(120, rtp_step_at_s=60, rtp_step_s=step_s))
    _check_increasing(out)
    assert clock.envelope.steps == 1
    after = [(f, s) for f, s in out if f.capture_host_ns >= HOST_T0 + 64 * NS]  # confirmed (2 s) and settled
    before = [(f, s) for f, s in out if f.capture_host_ns < HOST_T0 + 60 * NS]
    assert max(abs(s - f.expected_ns) for f, s in before + after) < 50_000_000
    step = [(f, s) for f, s in out if HOST_T0 + 60 * NS <= f.capture_host_ns < HOST_T0 + 64 * NS]
    assert all(s <= f.arrival_ns + 1_000_000 for f, s in step)  # never a stamp from the future …
    assert all(s >= f.expected_ns - 3 * NS for f, s in step)  # … and back within the confirmation time
    assert clock.camera_offset_ns is not None
    assert abs(clock.camera_offset_ns - out[-1][0].true_offset_ns) < 100_000_000


def test_a_stall_and_its_burst_keep_the_capture_time() -> None:
    clock = StreamClock()
    out = play(clock, frames(60, stall_at_s=20, stall_s=3.0))
    _check_increasing(out)
    burst = [f for f, _ in out if f.arrival_ns - f.expected_ns > 2 * NS]
    assert len(burst) >= 25  # the scenario has a burst of frames 2-3 s late
    assert max(abs(s - f.expected_ns) for f, s in out) < 50_000_000
    assert clock.envelope.steps == 0


def test_a_new_session_and_a_host_clock_step_back_never_send_stamps_backwards() -> None:
    clock = StreamClock()
    first = play(clock, frames(10, seed=2))
    clock.new_session()  # a reconnect: new RTP origin, same stream
    second = [
        (f, clock.stamp(f.rtp, f.arrival_ns + 10 * NS, f.camera_ns + 10 * NS)) for f in frames(10, seed=3)
    ]  # (the new session's frames come 10 s later)
    _check_increasing(first + second)
    assert max(abs(s - f.expected_ns - 10 * NS) for f, s in second[5:]) < 50_000_000
    host_step = [(f, clock.stamp(f.rtp, f.arrival_ns - 5 * NS, f.camera_ns)) for f in frames(10, seed=4)]
    _check_increasing(first + second + host_step)


@pytest.mark.parametrize("step_s", [-10.0, -3600.0, 10.0])
def test_a_host_clock_step_that_is_noticed_moves_the_stamps_with_it(step_s: float) -> None:
    """The robot's clock steps (chrony finding its server after a boot in the field) and the step is noticed
    (:class:`~axis_ptz_ros2.streaming.wall_clock.WallClockSteps`): the stamps follow the host clock at once, as every
    other stamp on the host does. Without that, a step back froze them at the last stamp + 1 ns for as long as the
    step (a 10 s step: 250 frames within 250 ns of each other); a step forward stamped from the old line for 2 s."""
    clock = StreamClock()
    before = play(clock, frames(20, seed=5))
    clock.host_clock_stepped(int(step_s * NS))
    step = int(step_s * NS)
    after = [(f, clock.stamp(f.rtp, f.arrival_ns + step, f.camera_ns)) for f in list(frames(40, seed=5))[600:]]
    _check_increasing(before)
    _check_increasing(after)
    assert max(abs(s - f.expected_ns - step) for f, s in after) < 50_000_000  # capture time on the new clock
    assert clock.clamped == 0
    assert clock.envelope.steps == 0  # the line moved: no restart


def test_rtp_wrap_around_is_unwrapped() -> None:
    clock = StreamClock()
    t0 = HOST_T0
    stamps = []
    for i in range(300):
        rtp = ((1 << 32) - 30 * 3000 + i * 3000) & 0xFFFFFFFF  # wraps after 30 frames
        stamps.append(clock.stamp(rtp, t0 + i * NS // 30 + LATENCY_NS))
    assert all(b - a == pytest.approx(NS / 30, abs=1e6) for a, b in zip(stamps, stamps[1:], strict=False))
    assert clock.camera_offset_ns is None  # no sender report: no camera offset
    assert not clock.take_offset_warning()


def test_a_camera_on_time_gives_no_warning() -> None:
    clock = StreamClock()
    play(clock, frames(20, behind_s=0.2))
    assert clock.camera_offset_ns is not None
    assert abs(clock.camera_offset_ns - 200_000_000) < 100_000_000
    assert not clock.offset_warning
    assert not clock.take_offset_warning()


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="bucket_s"):
        LowerEnvelope(bucket_s=100.0, window_s=10.0)
    with pytest.raises(ValueError, match="clock_rate"):
        StreamClock(clock_rate=0)


def test_sender_reports_off_the_frames_timeline_are_ignored() -> None:
    clock = StreamClock()
    out = []
    for f in frames(30, seed=6):
        clock.sender_report((f.rtp + 2 * 90_000) & 0xFFFFFFFF, f.arrival_ns)  # "sent" 2 s after it arrived
        clock.sender_report((f.rtp - 3 * 90_000) & 0xFFFFFFFF, f.arrival_ns)  # 3 s "encoder latency"
        out.append((f, clock.stamp(f.rtp, f.arrival_ns, f.camera_ns)))
    assert clock.encoder_latency_ns == 0
    assert max(abs(s - f.expected_ns) for f, s in out) < 50_000_000
