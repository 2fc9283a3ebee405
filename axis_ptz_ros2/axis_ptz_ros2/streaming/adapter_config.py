"""The link adapter's tuning (:class:`AdapterConfig`) and its H.264 values (:func:`h264_adapter_config`). ROS-free.

What each setting judges is in :mod:`.feedback` (the adapter) and in the fields' comments; what each cost without it,
found in the weak-link bench's debug logs, is in docs/weak-link.md ("Why the H.264 adapter is tuned as it is").
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class AdapterConfig:
    """Tuning of :class:`LinkAdapter` (seconds, fractions, kbit/s)."""

    delay_high_s: float = 0.15
    delay_low_s: float = 0.05
    # Received fps below this fraction of the sent fps: more than 3 frames in 10 are lost, so trade picture size
    # for frame rate (a smaller frame is fewer packets to lose or repair; at 2 % packet loss a 9 kB frame in
    # 1400-byte datagrams reached the operator ~55 % of the time on a 2 Mbit/s link, a 3.7 kB one ~95 %) ...
    delivery_low: float = 0.7
    delivery_clear: float = 0.8  # ... at or above it (and a short queue): room to grow
    min_expected_frames: int = 8  # judge delivery only when the window should hold at least this many frames
    decrease: float = 0.8
    increase: float = 1.2
    headroom: float = 1.6  # the budget grows to at most this × what is sent ...
    step_margin: float = 1.35  # ... or this × the next better setting's predicted rate (room to try it)
    decrease_hold_s: float = 1.5
    min_kbps: float = 100.0
    good_memory_s: float = 10.0  # a congested step up returns to the rate received cleanly this recently ...
    good_margin: float = 1.15  # ... times this (the ladder picks a setting predicted under its budget's fraction)
    probe_backoff_s: float = 5.0  # after congestion, stay under what was sent then for this long ...
    probe_backoff_max_s: float = 20.0  # ... doubled (up to this) each time a new try congests again
    silence_s: float = 2.0
    release_s: float = 30.0
    delivery_by_bytes: bool = False  # delivery = kbit/s received / sent (H.264) instead of frames
    climb_hold_s: float = 2.0  # past ``grow_from_kbps`` the budget grows at most once per this (a report window)
    # this many access units newly lost (since that consumer's last report) with the queue at ``delay_low_s`` or
    # more: congested; with a shorter queue: steady (the link's random loss, see :func:`h264_adapter_config`)
    lost_congested: int = 0
    # from ``decrease`` x the rate that last congested on, grow by this instead of ``increase``, once per
    # ``climb_hold_s`` (0: ``increase``, no different growth there)
    probe_increase: float = 0.0
    # a congestion after at least this long of clear reports at (``stable_share`` of) the rate sent now is the link
    # changing under a steady stream, not a probe past the start: the received rate decides (see :meth:`report`)
    stable_s: float = 4.0
    stable_share: float = 0.9
    # the *median* delay over its minimum above this: congested (0: not judged). A queue delays every frame, a
    # repaired loss only the few behind it, so the median sees a queue that the p95 thresholds, set wide for the
    # repairs' tails, read as steady (H.264, :func:`h264_adapter_config`)
    median_high_s: float = 0.0
    # the *floor* (the smallest delay of the report's last half) over its minimum above this while growing back near
    # a rate that congested: a queue stands, so the sender is at the link's edge: congested (0: not judged). Every
    # frame waits in a standing queue, the quickest too, while a repaired loss delays only the slow ones; and the
    # floor covers the last second only, so it sees the queue a second before the median does
    floor_high_s: float = 0.0
    # while growing back near a rate that congested, the budget grows to at most this x what is sent (0: ``headroom``)
    probe_headroom: float = 0.0
    # after a congestion of a steady stream (the link itself stepped down, see ``stable_s``) the budget stays at most at
    # what that decrease set and at what the link delivered while full for this long (0: no hold; decreases go on): a
    # link that just stepped down is probed again only then
    step_down_hold_s: float = 0.0
    # after the link stepped down (``step_down_hold_s``), a floor still over this ``drain_recheck_s`` after the decrease
    # (no clear report between): decrease again before ``decrease_hold_s``, once (0: not judged)
    drain_floor_s: float = 0.0
    drain_recheck_s: float = 1.0
    # that first decrease after a step down goes further, to (1 - the queue's p95 / ``drain_s``) x what arrived (at
    # least ``drain_min_share``, at most ``decrease``): the queue standing then drains within about ``drain_s``
    # (0: ``decrease`` x what arrived, as any congestion)
    drain_s: float = 0.0
    drain_min_share: float = 0.5

    def __post_init__(self) -> None:
        """Refuse settings that would not converge."""
        if not 0.0 < self.delay_low_s < self.delay_high_s:
            raise ValueError("need 0 < delay_low_s < delay_high_s")
        if not 0.0 < self.decrease < 1.0 or self.increase <= 1.0 or self.headroom <= 1.0 or self.step_margin <= 1.0:
            raise ValueError("need 0 < decrease < 1 < increase and headroom, step_margin > 1")
        if not 0.0 < self.delivery_low <= self.delivery_clear <= 1.0:
            raise ValueError("need 0 < delivery_low <= delivery_clear <= 1")
        if self.good_memory_s < 0 or self.good_margin < 1.0:
            raise ValueError("need good_memory_s >= 0 and good_margin >= 1")
        if self.climb_hold_s < 0:
            raise ValueError("need climb_hold_s >= 0")
        if self.stable_s < 0 or not 0.0 < self.stable_share <= 1.0:
            raise ValueError("need stable_s >= 0 and 0 < stable_share <= 1")
        if self.lost_congested < 0:
            raise ValueError("need lost_congested >= 0")
        if self.probe_increase != 0.0 and not 1.0 < self.probe_increase <= self.increase:
            raise ValueError("need probe_increase 0 (= increase) or 1 < probe_increase <= increase")
        if self.median_high_s < 0 or self.median_high_s >= self.delay_high_s:
            raise ValueError("need 0 <= median_high_s < delay_high_s (0 = the median not judged)")
        if self.floor_high_s < 0 or (self.probe_headroom != 0.0 and not 1.0 < self.probe_headroom <= self.headroom):
            raise ValueError("need floor_high_s >= 0 (0 = not judged), probe_headroom 0 or in (1, headroom]")
        if self.step_down_hold_s < 0 or self.drain_floor_s < 0 or self.drain_recheck_s <= 0:
            raise ValueError("need step_down_hold_s >= 0, drain_floor_s >= 0 (0 = not judged), drain_recheck_s > 0")
        if self.drain_s < 0 or not 0.0 < self.drain_min_share <= self.decrease:
            raise ValueError("need drain_s >= 0 (0 = no deeper first decrease) and 0 < drain_min_share <= decrease")
        if self.min_kbps <= 0 or self.silence_s <= 0 or self.release_s < self.silence_s:
            raise ValueError("need min_kbps > 0 and release_s >= silence_s > 0")


def h264_adapter_config(release_s: float = 30.0) -> AdapterConfig:
    """The adapter's tuning for H.264 (see the module docstring and the fields' comments): delivery by bytes,
    a queue only past wide p95 thresholds (the repairs' tails of random loss are no queue), an access unit lost
    behind a queue as congestion, careful probing back towards a rate that congested, the median and the floor for a
    queue the p95 does not see. What each setting cost without it (the debug logs it was found in) is in
    docs/weak-link.md ("Why the H.264 adapter is tuned as it is")."""
    return AdapterConfig(
        delay_high_s=0.5,
        delay_low_s=0.25,
        delivery_by_bytes=True,
        release_s=release_s,
        lost_congested=1,
        decrease_hold_s=2.5,  # past a report window (2 s): the next judgement no longer holds the congested rate
        probe_backoff_s=10.0,
        probe_backoff_max_s=40.0,
        probe_increase=1.05,
        median_high_s=0.08,
        floor_high_s=0.015,
        probe_headroom=1.1,
        step_down_hold_s=20.0,
        drain_floor_s=0.1,
        # the floor covers the report's last second: at 0.9 s that second is (all but) after the decrease; reports come
        # every 0.5 s with some jitter (the one 0.98 s after a decrease waited another 0.5 s at 1.0, debug log)
        drain_recheck_s=0.9,
        # a queue of 0.3 s or more (what a 2 -> 1 Mbit/s step has built when it is seen) halves what arrived: the step
        # bench's frame age was back under 100 ms 3.7 s after the step without it, 2.4-3.1 s with 1.0, 1.4-2.6 s with
        # 0.6 (docs/weak-link.md, "The drain after the link steps down")
        drain_s=0.6,
    )
