"""Capture-to-display of transcoded H.264 measured without the product's help (issue 38 item 3).

The stream node stamps a transcoded access unit (header and capture-stamp SEI) with the arrival of the JPEG it came
from, as it stamps ``image_raw/compressed``: it reads nothing the simulator writes into its JPEGs. The benches
measure a picture's age from the simulated camera's send time all the same, from the simulator's own record of
what it sent: the bench runs the simulator in a process of its own that logs every JPEG's send time
(:func:`log_sends`: the ``t=`` it writes into that JPEG's ``axsim`` comment), and :func:`match` finds the JPEG of
each decoded picture:

* its JPEG is the last one sent at or before the picture's stamp (the simulator and the stream node share one
  clock: the same host, or two network namespaces of one machine); the reader stamps a JPEG once it holds all of
  it, so never before it was sent, and on loopback a few milliseconds after;
* every access unit comes from a JPEG of its own, in order (the stage's ``pts`` counts them), so a picture ``k``
  pts before another came from a JPEG at least ``k`` sends before that one's: a picture whose JPEG the reader took
  only after the next had been sent (a loaded machine) is put back on its own JPEG when a later picture shows it;
* the sends are logged per connection (a stream node with an MJPEG subscriber in ``codec: h264`` reads a second
  stream, its MJPEG ladder, beside the compression-0 one it encodes): only the connections whose sends the
  pictures follow (median lag within :data:`NEAR_MS`, or near the best one's) are searched.

The lag of each match (stamp - send) is what :func:`lag_summary` reports: if it ever nears a frame interval, the
matching is in doubt and the bench says so.

    .venv/bin/python bench/capture_match.py --sim [--port 0]   # a simulated 214 that prints "sent <ns>" per JPEG
"""

from __future__ import annotations

import bisect
import math
import statistics
import sys
import threading
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests.support (the simulator's comment reader)

#: the line a :func:`sim_child` prints per JPEG sent: ``sent <ns> <connection>``
SENT_PREFIX = "sent "
#: ms: a connection whose sends the pictures' stamps follow by at most this (median) is one they come from
NEAR_MS = 10.0

Sends = Sequence[int] | Mapping[str, Sequence[int]]


def log_sends(record: Callable[[int, int, str], None]) -> None:
    """Have this process's simulated cameras call ``record(seq, send_ns, connection)`` for every MJPEG JPEG they
    send (the values of the comment they write into it; ``connection`` names the stream it went out on: each is
    served on a thread of its own, its ``seq`` counting from 1); bench instrumentation of this process only."""
    import axis_ptz_ros2.sim.http.mjpeg as mjpeg_side
    from tests.support.stamps import sim_stamp

    stamp = mjpeg_side.stamp
    last: dict[int, tuple[int, int]] = {}  # thread -> (its connections so far, the last seq)

    def stamped(jpeg: bytes, seq: int) -> bytes:
        out = stamp(jpeg, seq)
        st = sim_stamp(out)
        if st is not None:
            ident = threading.get_ident()
            n, prev = last.get(ident, (0, 0))
            if st[0] <= prev:  # a new connection on a thread used before
                n += 1
            last[ident] = (n, st[0])
            record(st[0], st[1], f"{ident}.{n}")
        return out

    mjpeg_side.stamp = stamped  # type: ignore[assignment]


def _lag_ms(pictures: Sequence[tuple[int, int]], sent: Sequence[int]) -> float:
    """Median lag (ms) of the pictures stamped within the span of ``sent`` (sorted) behind its last send before."""
    lags = [
        stamp - sent[bisect.bisect_right(sent, stamp) - 1]
        for _pts, stamp in pictures
        if sent[0] <= stamp <= sent[-1] + 1_000_000_000
    ]
    return statistics.median(lags) / 1e6 if lags else math.inf


def followed(pictures: Sequence[tuple[int, int]], sends: Sends) -> list[int]:
    """The send times of the connections the pictures come from (see the module docstring), sorted."""
    if not isinstance(sends, Mapping):
        return sorted(sends)
    per = {k: sorted(v) for k, v in sends.items() if v}
    lag = {k: _lag_ms(pictures, v) for k, v in per.items()}
    best = min(lag.values(), default=math.inf)
    keep = [k for k, v in lag.items() if v <= max(NEAR_MS, 1.5 * best)]
    return sorted(t for k in keep for t in per[k])


def match(pictures: Sequence[tuple[int, int]], sends: Sends) -> list[int | None]:
    """The send time (ns) of each picture's JPEG; ``pictures`` are ``(pts, stamp_ns)`` of the pictures decoded (any
    order, some missing), ``sends`` every send time of the simulator (any order), or those of each connection
    (:func:`followed`). None: no send before its stamp."""
    sent = followed(pictures, sends)
    by_time = [bisect.bisect_right(sent, stamp) - 1 for _pts, stamp in pictures]
    idx = list(by_time)
    order = sorted(range(len(pictures)), key=lambda i: pictures[i][0])
    later = -1  # the picture with the next higher pts (already settled)
    for i in reversed(order):
        pts = pictures[i][0]
        if later >= 0 and idx[later] >= 0 and idx[i] >= 0 and 0 <= pts < pictures[later][0]:  # (no pts: -1)
            idx[i] = min(idx[i], idx[later] - (pictures[later][0] - pts))
        later = i
    if _median_lag_ms(pictures, sent, idx) > _median_lag_ms(pictures, sent, by_time) + NEAR_MS:
        # the pts order moved the bulk of the pictures back, not a few behind the camera: a pts counted without a
        # JPEG of its own somewhere after them shifts every earlier picture by a send (seen in the acuity and link
        # benches at b6fc656 and d15a689: "stamp - send: median 40.8 ms", every picture scored against the pose one
        # frame later); the time alone is the better match then
        idx = by_time
    return [sent[k] if k >= 0 else None for k in idx]


def _median_lag_ms(pictures: Sequence[tuple[int, int]], sent: Sequence[int], idx: Sequence[int]) -> float:
    """Median stamp - send (ms) of the pictures matched by ``idx`` (0 if none is)."""
    lags = [(stamp - sent[k]) / 1e6 for (_pts, stamp), k in zip(pictures, idx, strict=True) if k >= 0]
    return statistics.median(lags) if lags else 0.0


def lag_summary(pictures: Sequence[tuple[int, int]], matched: Sequence[int | None]) -> str:
    """How long after its send each matched picture's JPEG was stamped by the stream node: median, max, and how
    many matches the pts order moved back (a reader behind the camera)."""
    lags = [(stamp - m) / 1e6 for (_pts, stamp), m in zip(pictures, matched, strict=True) if m is not None]
    if not lags:
        return "no picture matched a send"
    unmatched = sum(m is None for m in matched)
    return (
        f"{len(lags)} pictures matched to the simulator's sends (stamp - send: median {statistics.median(lags):.1f} "
        f"ms, max {max(lags):.1f} ms)" + (f"; {unmatched} without a send before them" if unmatched else "")
    )


def rekey(pictures: list[dict[str, Any]], sends: Sends, saved: Path | None = None) -> str:
    """Give each picture record (``{"pts": n, "cap": stamp ns, ...}``, a transcoded picture as the link bench's
    viewer records it) the send time of its JPEG as ``cap`` (its own stamp kept as ``stamp``; left as it is when no
    send precedes it), renaming a picture saved as ``saved/<stamp>.npy`` to ``<cap>.npy``; returns
    :func:`lag_summary`."""
    todo = [r for r in pictures if r.get("cap")]
    pairs = [(int(r["pts"]), int(r["cap"])) for r in todo]
    matched = match(pairs, sends)
    for r, m in zip(todo, matched, strict=True):
        if m is None:
            continue
        r["stamp"], r["cap"] = r["cap"], m
        f = saved / f"{r['stamp']}.npy" if saved is not None else None
        if f is not None and f.exists():
            f.rename(f.with_name(f"{m}.npy"))
    return lag_summary(pairs, matched)


def sim_child(port: int = 0) -> int:
    """A simulated Axis 214 that prints its address as ``axis_camera_sim`` does, then ``sent <ns>`` per JPEG."""
    from stopping import wait_for_stop  # bench/stopping.py (bench/ is on sys.path)

    from axis_ptz_ros2.sim.camera import SimulatedCamera

    lock = threading.Lock()

    def record(_seq: int, t_ns: int, connection: str) -> None:
        with lock:
            print(f"{SENT_PREFIX}{t_ns} {connection}", flush=True)

    log_sends(record)
    cam = SimulatedCamera(port=port).start()  # as axis_camera_sim --port <port>
    print(f"Simulated AXIS 214 PTZ at {cam.base_url}/ (logging every JPEG's send time)", flush=True)
    wait_for_stop()
    cam.stop()
    return 0


def sends_of(lines: Sequence[str]) -> dict[str, list[int]]:
    """The send times a :func:`sim_child` printed, per connection."""
    out: dict[str, list[int]] = {}
    for line in lines:
        if line.startswith(SENT_PREFIX):
            t, connection = line[len(SENT_PREFIX) :].split()
            out.setdefault(connection, []).append(int(t))
    return out


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sim", action="store_true", help="run the logging simulator")
    ap.add_argument("--port", type=int, default=0)
    a = ap.parse_args()
    if not a.sim:
        ap.error("nothing to do without --sim")
    raise SystemExit(sim_child(a.port))
