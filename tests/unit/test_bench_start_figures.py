"""The weak-link bench's first-picture figures (``bench/link_h264_results.py``): over many viewer starts, the
worst, how many missed 2 s and the median; a start that showed nothing is the worst and counts as a miss."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.unit

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))


def test_the_worst_the_misses_and_the_median_of_the_starts() -> None:
    from link_h264_results import start_figures

    r = start_figures([0.9, 2.3, 1.0, 2.0, 1.1])
    assert r["first_s"] == pytest.approx(2.3)
    assert r["first_over_2"] == 1  # exactly 2.0 s meets the target
    assert r["first_median"] == pytest.approx(1.1)
    assert r["first_all"] == "0.9 2.3 1.0 2.0 1.1"


def test_a_start_that_showed_nothing_is_the_worst_and_a_miss() -> None:
    from link_h264_results import start_figures

    r = start_figures([0.8, math.nan, 1.2])
    assert r["first_s"] == math.inf
    assert r["first_over_2"] == 1
    assert r["first_median"] == pytest.approx(1.0)  # of the starts that showed a picture
    assert r["first_all"] == "0.8 — 1.2"


def test_no_start_at_all() -> None:
    from link_h264_results import start_figures

    r = start_figures([])
    assert math.isnan(r["first_s"])
    assert math.isnan(r["first_median"])
    assert r["first_over_2"] == 0
