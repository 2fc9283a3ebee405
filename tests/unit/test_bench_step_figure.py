"""The weak-link bench's step figure (``bench/link_h264_results.py``): the frame age's p95 over 1 s windows back
under 100 ms for good, which a single late picture (a loss repair) does not hold back."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.unit

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

NS = 1_000_000_000


def pictures(ages_ms: dict[int, float], seconds: int = 10, fps: int = 25) -> list[dict[str, int]]:
    """25 pictures/s from t=0, 30 ms old unless ``ages_ms`` (picture index -> age) says otherwise."""
    out = []
    for k in range(seconds * fps):
        rx = k * NS // fps
        out.append({"rx": rx, "cap": rx - int(ages_ms.get(k, 30.0) * 1e6)})
    return out


def test_the_step_figure_counts_the_late_burst_not_a_single_late_picture() -> None:
    from link_h264_results import RECOVERY_WINDOW_S, age_recovery_s

    burst = {k: 200.0 for k in range(0, 38)}  # the first 1.5 s after the step (t=0) late
    single = {125: 140.0}  # one repair tail at 5 s
    pics = pictures({**burst, **single})
    got = age_recovery_s(pics, 0, pics[-1]["rx"])
    # the last window whose p95 is over 100 ms ends a window's length after the burst
    assert got == pytest.approx(1.5 + RECOVERY_WINDOW_S, abs=0.15)
    assert age_recovery_s(pictures(single), 0, pics[-1]["rx"]) == 0.0  # a single late picture: none
    two = {125: 140.0, 130: 150.0}  # two in one second: that window's p95 is over
    # the last window holding both ends a window after the first of them
    assert age_recovery_s(pictures(two), 0, pics[-1]["rx"]) == pytest.approx(125 / 25 + RECOVERY_WINDOW_S, abs=0.15)


def test_a_scripted_session_run_three_times_is_judged_on_its_median_and_its_worst_stale_picture() -> None:
    from link_h264_results import combine_runs

    runs = [
        {"name": "h264-step", "recovery_s": r, "tail_fps": 25.0, "tail_age_p95": a, "late_pictures": 3}
        for r, a in ((5.0, 60.0), (2.4, 40.0), (2.8, 50.0))
    ]
    e = combine_runs(runs)
    assert e["recovery_s"] == 2.8  # the median, not the first run's 5.0 or the best
    assert e["tail_age_p95"] == 50.0
    assert e["runs"] == runs
    cuts = [
        {"name": "h264-cut", "first_after_heal_s": f, "stale_after_heal": n, "during_cut": 0, "tail_fps": 25.0}
        for f, n in ((0.5, 0), (0.6, 2), (0.7, 0))
    ]
    c = combine_runs(cuts)
    assert c["first_after_heal_s"] == 0.6
    assert c["stale_after_heal"] == 2  # a stale picture in any run counts
