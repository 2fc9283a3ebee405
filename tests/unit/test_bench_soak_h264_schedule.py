"""The H.264 soak's schedule (``bench/bench_soak_h264.py``, issue 40 item 4): the issue's periods over the hour,
the same events closer together in a shorter run with the faults at their real lengths, no viewer joining at a
fault, and a clear refusal of a run too short for its faults."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.unit

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

import bench_soak_h264 as soak  # noqa: E402


def kinds(events: list[soak.Event], kind: str) -> list[soak.Event]:
    return [e for e in events if e.kind == kind]


def test_the_hour_has_the_issues_periods() -> None:
    events = soak.schedule(3600)
    cuts, reboots = kinds(events, "cut"), kinds(events, "reboot")
    assert [e.t for e in cuts] == [300, 900, 1500, 2100, 2700, 3300]  # every 10 min
    assert all(e.length == 10 for e in cuts)
    assert [e.t for e in reboots] == [450, 1350, 2250, 3150]  # every 15 min
    assert len(kinds(events, "clock")) == 1
    joins = kinds(events, "join")
    assert len(joins) == 20  # one every 3 min
    assert {e.stream for e in joins} == {"transcoded", "passthrough"}
    assert [e.t for e in events] == sorted(e.t for e in events)


@pytest.mark.parametrize("duration", [600.0, 1200.0])
def test_a_shorter_run_compresses_the_times_and_keeps_the_fault_lengths(duration: float) -> None:
    hour, short = soak.schedule(3600), soak.schedule(duration)
    for kind in ("cut", "reboot", "clock"):
        a, b = kinds(hour, kind), kinds(short, kind)
        assert len(b) == len(a) >= 1
        assert [e.t * duration / 3600 for e in a] == pytest.approx([e.t for e in b])
        assert [e.length for e in a] == [e.length for e in b]
    assert len(kinds(short, "join")) >= 1


@pytest.mark.parametrize("duration", [481.0, 600.0, 3600.0])
def test_no_viewer_joins_at_a_fault_and_every_one_stays_long_enough(duration: float) -> None:
    events = soak.schedule(duration)
    faults = [e for e in events if e.kind in ("cut", "reboot", "clock")]
    leaves = {e.viewer: e.t for e in kinds(events, "leave")}
    for j in kinds(events, "join"):
        for f in faults:
            assert not (f.t - soak.BEFORE_FAULT_S <= j.t < f.t + f.length + soak.AFTER_FAULT_S), (j, f)
        assert leaves[j.viewer] - j.t >= soak.FIRST_PICTURE_S + 1.0
        assert leaves[j.viewer] < duration


def test_too_short_a_run_is_refused_naming_the_shortest() -> None:
    shortest = soak.shortest_duration()
    soak.schedule(shortest)
    with pytest.raises(ValueError, match=f"at least {shortest:.0f} s"):
        soak.schedule(shortest - 2)
    for bad in (0.0, -60.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="positive number of seconds"):
            soak.schedule(bad)
