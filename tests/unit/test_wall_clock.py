"""Steps of this host's wall clock (streaming/wall_clock.py) on scripted clocks."""

from __future__ import annotations

import pytest

from axis_ptz_ros2.streaming.wall_clock import WallClockSteps, in_old_basis

pytestmark = pytest.mark.unit

S = 1_000_000_000


def test_a_step_is_reported_once_and_a_slew_is_followed_not_reported() -> None:
    wall, mono = [1_780_000_000 * S], [5 * S]
    w = WallClockSteps(wall_ns=lambda: wall[0], mono_ns=lambda: mono[0])
    assert w.check() == 0  # the first look: nothing to compare with
    for _ in range(100):  # NTP's fastest slew, 500 ppm, looked at every 40 ms for 4 s: 2 ms in all
        mono[0] += 40_000_000
        wall[0] += 40_000_000 + 20_000
        assert w.check() == 0
    mono[0] += 40_000_000
    wall[0] += 40_000_000 - 10 * S  # stepped back 10 s
    assert w.check() == -10 * S
    assert w.check() == 0  # reported once
    wall[0] += 3600 * S
    assert w.check() == 3600 * S
    assert w.steps == 2
    assert w.wall_at_look_ns == wall[0]
    with pytest.raises(ValueError, match="threshold_s"):
        WallClockSteps(threshold_s=0.0)


def test_a_time_read_before_the_step_is_told_from_one_read_after_it() -> None:
    now = 1_780_000_000 * S
    for step in (-10 * S, 10 * S, -3600 * S):
        assert in_old_basis(now - step - 30_000_000, now, step)  # read 30 ms before the look, on the old clock
        assert not in_old_basis(now - 30_000_000, now, step)  # read 30 ms before the look, on the new clock


def test_check_read_puts_a_time_read_before_the_step_on_the_new_clock() -> None:
    wall, mono = [1_780_000_000 * S], [5 * S]
    w = WallClockSteps(wall_ns=lambda: wall[0], mono_ns=lambda: mono[0])
    assert w.check_read(wall[0] - 30_000_000) == (0, wall[0] - 30_000_000)  # no step: as read
    before = wall[0] + 10_000_000  # read 10 ms on, before the step
    mono[0] += 40_000_000
    wall[0] += 40_000_000 - 10 * S  # stepped back 10 s
    assert w.check_read(before) == (-10 * S, before - 10 * S)
    after = wall[0] - 5_000_000  # read 5 ms before the next look, after the step
    mono[0] += 40_000_000
    wall[0] += 40_000_000 + 10 * S  # and forward again
    assert w.check_read(after) == (10 * S, after + 10 * S)
