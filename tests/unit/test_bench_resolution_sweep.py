"""``bench/resolution_acuity.py``'s panning sweep: a triangle wave at the speed asked, one view width either way about
the chart's centre, so the chart goes from one edge of the view to the other and back."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.unit

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))


def test_the_sweep_starts_at_the_centre_moves_at_its_speed_and_turns_half_a_view_either_side() -> None:
    from resolution_acuity import sweep_pan

    pan0, view, speed = 100.0, 2.0, 8.0  # a turn every 0.25 s
    assert sweep_pan(pan0, view, speed, 0.0) == pytest.approx(pan0)
    assert sweep_pan(pan0, view, speed, 0.1) == pytest.approx(pan0 + 0.8)  # 8°/s for 0.1 s, towards +pan
    assert sweep_pan(pan0, view, speed, 0.125) == pytest.approx(pan0 + 1.0)  # the turn, half a view out
    assert sweep_pan(pan0, view, speed, 0.2) == pytest.approx(pan0 + 0.4)  # on the way back
    pans = [sweep_pan(pan0, view, speed, k / 1000) for k in range(2000)]
    assert min(pans) == pytest.approx(pan0 - 1.0, abs=1e-2)
    assert max(pans) == pytest.approx(pan0 + 1.0, abs=1e-2)
    steps = [abs(b - a) for a, b in zip(pans, pans[1:], strict=False)]
    assert max(steps) == pytest.approx(speed / 1000)  # never faster than the speed asked
