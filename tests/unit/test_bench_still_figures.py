"""The weak-link bench's still figures (``bench/link_h264_results.py``, session ``h264-still``): each still is
matched to the request it answers by its stamp, a refused request gets none and counts against the target, and the
live video is measured in the windows from each request to its still's arrival only."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.unit

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

NS = 1_000_000_000


def live(seconds: int = 30, fps: int = 25, slow: tuple[float, float] = (0.0, 0.0)) -> list[dict[str, int]]:
    """``fps`` pictures/s of 704x576 from t=0, 40 ms old; in ``slow`` (s) one picture in five arrives, 400 ms old."""
    out = []
    for k in range(seconds * fps):
        rx = k * NS // fps
        in_slow = slow[0] * NS <= rx < slow[1] * NS
        if in_slow and k % 5:
            continue
        out.append({"rx": rx, "cap": rx - (400 if in_slow else 40) * 1_000_000, "w": 704, "h": 576, "bytes": 1})
    return out


def session(stills: list[dict[str, object]], pics: list[dict[str, int]]):  # noqa: ANN201 - the bench's Session
    from link_h264_results import Session

    s = Session("h264-still", "h264", True, still_every=5.0)
    s.t0, s.pics, s.stills = 0, pics, stills
    return s


def req(k: int, at: float) -> dict[str, object]:
    return {"t": "still_req", "k": k, "rx": int(at * NS), "ready": True}


def ans(k: int, at: float, ok: bool = True) -> dict[str, object]:
    return {"t": "still_ans", "k": k, "rx": int(at * NS), "ok": ok, "msg": "m"}


def still(at: float, stamp: float, w: int = 704, h: int = 576) -> dict[str, object]:
    return {"t": "still", "rx": int(at * NS), "stamp": int(stamp * NS), "bytes": 90_000, "w": w, "h": h}


def test_every_still_on_time_with_the_video_holding_meets_the_target() -> None:
    from link_h264_results import still_figures, still_good

    stills = [req(1, 10), still(11.0, 10.1), ans(1, 11.1), req(2, 15), still(16.2, 15.1), ans(2, 16.3)]
    r = still_figures(session(stills, live()), 30 * NS)
    assert (r["still_asked"], r["still_ok"], r["still_arrived"]) == (2, 2, 2)
    assert r["still_arrival_p50"] == pytest.approx(1.0)
    assert r["still_arrival_max"] == pytest.approx(1.2)
    assert r["still_answer_max"] == pytest.approx(1.3)
    assert r["still_sizes"] == "704x576"
    assert r["still_win_fps"] == pytest.approx(25, abs=1.5)
    assert r["still_win_age_p95"] == pytest.approx(40)
    assert still_good({**r, "name": "h264-still"})


def test_a_refused_request_a_slow_still_and_the_video_stalling_in_its_window_miss() -> None:
    from link_h264_results import still_figures, still_good

    # request 2 comes while still 1 is on its way (refused, no still); still 1 takes 6 s; video slow 10-16 s
    stills = [req(1, 10), ans(2, 15.1, ok=False), req(2, 15), still(16.0, 10.2), ans(1, 16.1)]
    r = still_figures(session(stills, live(slow=(10.0, 16.0))), 30 * NS)
    assert (r["still_asked"], r["still_ok"], r["still_arrived"]) == (2, 1, 1)
    assert r["still_requests"][0]["still"] is not None
    assert r["still_requests"][1]["still"] is None
    assert math.isinf(r["still_arrival_max"])  # a request without its still: never on time
    assert r["still_win_fps"] == pytest.approx(5, abs=0.5)
    assert r["still_win_age_p95"] == pytest.approx(400)
    assert not still_good({**r, "name": "h264-still"})


def test_a_small_still_and_a_late_request_left_out() -> None:
    from link_h264_results import STILL_GRACE_S, still_figures

    stills = [req(1, 10), still(10.5, 10.1, 352, 288), ans(1, 10.6), req(2, 30 - STILL_GRACE_S + 0.5)]
    r = still_figures(session(stills, live()), 30 * NS)
    assert r["still_asked"] == 1  # the request too close to the end is not counted
    assert r["still_sizes"] == "352x288"
    assert not r["still_size_ok"]
