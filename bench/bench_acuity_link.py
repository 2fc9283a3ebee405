"""What the operator can read over the weak link: the acuity chart at 35 m, read at the operator (issue 39 item 3).

``bench/bench_link_h264.py``'s sessions (robot and operator in two network namespaces over a veth shaped to a rate
with 2 % random loss each way, the shipped Fast DDS weak-link profile, the simulated camera on the robot's loopback,
``axis_camera`` asked for its size @ 30 fps; its ``run_session``, roles and figures), each with the camera first aimed
at the demo world's 35 m chart (``config/sim_world.yaml``: ``acuity_35m``; the picture and its answer key:
``bench/acuity_chart.py``) and zoomed as far as the whole chart stays in the view, at most the tele limit: the pose
``bench/bench_acuity.py`` reads it at (``bench/link_h264_roles.py``'s ``aim_at``: one ``ptz.cgi`` move through the
simulator's own handler, before the session measures). Sessions, one after another in one run, each on a fresh link:

  mjpeg       2 Mbit/s: ``codec: mjpeg`` (compression 30, ``adapt_to_link``: the MJPEG ladder) + ``axis_link_monitor``
  h264        2 Mbit/s: ``codec: h264`` (the 214's MJPEG transcoded) + ``axis_link_monitor`` (feedback)
  h264-nofb   2 Mbit/s: ``codec: h264``, a plain viewer (no feedback)
  h264-1m     1 Mbit/s: ``codec: h264`` + ``axis_link_monitor``
  h264-pan    2 Mbit/s: as ``h264``, the head sweeping at 10°/s across the chart (``continuouspantiltmove``,
              reversing every time it has moved one view width, so the chart goes from one edge of the view to the
              other)
  q6075-h264  2 Mbit/s: the current-Axis persona (1920x1080 asked), its RTSP H.264 passed through + the monitor
  q6075-auto  2 Mbit/s: the same with ``resolution`` auto: the driver picks the size by the bitrate in force
              (``streaming/passthrough_size.py``; the robot gets ``-p resolution:=""`` after the size asked, the last
              ``-p`` wins); its pictures are upscaled to 1920x1080 before they are read
  h264-still  2 Mbit/s: as ``h264``, the operator asking for a full-quality still (``still/capture``) every 5 s
              (``bench_link_h264.py``'s ``h264-still``: its still figures too); each still that arrived is read as
              the live pictures are, against the camera's own compression-0 rows (target: equal). Only if asked for.

How a picture is read: ``bench/acuity.py`` through the chart's homography at the camera's pose (known from the
simulator, so the reading is the picture's detail, not whether its fiducials were found); a picture smaller than the
size asked (the MJPEG ladder's) is upscaled to it first, as the PSNR does. **Rows read**: rows of 5 tumbling Es read
from the top (a row at 3 of 5) down to the first that is not.

- Still sessions: the operator's viewer keeps every ``--every``-th picture it shows (twice that above 704x576), as
  decoded, and they are read after the session (reading a 1920x1080 picture costs ~0.4 s of CPU: in the viewer's
  process it would compete with the decoding it times and the monitor's feedback); the reference is the median rows
  read in :data:`REF_DRAWS` compression-0 JPEGs of the camera at that pose (each with its own sensor noise) -- what
  the camera itself sends at its best.
- Panning: the viewer saves every 3rd picture (as ``h264-pan`` does for its PSNR); every ``--every``/3-th saved
  picture is read after the session, through the homography at the pose it was rendered at, against one
  compression-0 JPEG of that pose; only pictures whose compression-0 JPEG reads at least one row (the chart in
  view) count.

**Rows lost to the link** per picture = the camera's own rows read - the operator's; median and worst over the
pictures read after the first 10 s, beside PSNR (median / 5th percentile, vs the camera's view before noise and
compression), frame age (p50 / p95) and, for H.264, the encoder's bitrate: its target as the stream node reports it
(``/diagnostics`` "h264 bitrate target", read on the robot's side, median: what the target "the encoder at >= 1.2
Mbit/s" is checked on; x264 sends less where the picture needs less, as the still chart does) and what the operator
received (kbit/s of H.264 access units).

    sudo .venv/bin/python bench/bench_acuity_link.py [--seconds 40] [--every 15]
        [--sessions mjpeg,h264,h264-nofb,h264-1m,h264-pan,q6075-h264,q6075-auto]

Needs root (network namespaces); installs nftables if missing.
"""

from __future__ import annotations

import argparse
import functools
import math
import os
import statistics
import subprocess
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import acuity  # noqa: E402  (bench/acuity.py)
from bench_link_h264 import INPUTS, run_session  # noqa: E402
from link_h264_results import (  # noqa: E402
    NS,
    PAN_SPEED,
    SETTLE_S,
    STILL_AGE_TARGET_MS,
    STILL_FPS_TARGET,
    STILL_TARGET_S,
    Session,
    figures,
    fmt,
    plot,
    print_stills,
    print_table,
    session,
    still_figures,
    still_good,
    still_max,
)
from link_h264_roles import PSNR_EVERY  # noqa: E402

CHART = "acuity_35m"
SESSIONS = ("mjpeg", "h264", "h264-nofb", "h264-1m", "h264-pan", "q6075-h264", "q6075-auto")
#: sessions run only when asked for (``--sessions``)
EXTRA = ("h264-still",)
#: sessions that are another one with extra robot parameters (``BENCH_LINK_ROBOT_ARGS`` of bench_link_h264.py)
VARIANTS = {"h264-1m": ("h264", ""), "q6075-auto": ("q6075-h264", '-p resolution:=""')}
REF_DRAWS = 5  #: compression-0 JPEGs of the still view read for the camera's own rows (median)
SWEEP_VIEWS = 1.0  #: the panning head reverses after moving this many view widths (the chart edge to edge)


@functools.cache
def chart_pose(model: str, size: tuple[int, int]) -> tuple[Any, Any, tuple[float, float, float]]:
    """(a camera of ``model``, not started, one per model; the chart; the pose ``aim_at`` puts the head in: aimed at
    the chart's centre, zoomed as far as it fits in ``size``)."""
    from axis_ptz_ros2.sim.camera import SimulatedCamera

    cam = SimulatedCamera(host="127.0.0.1", port=0, model=model)
    renderer = cam.frames.renderer
    target = renderer.scene.target(CHART)
    pan, tilt = acuity.aim(cam.world, target.center)
    return cam, target, (pan, tilt, float(round(acuity.fit_zoom(renderer, target, pan, tilt, *size))))


def acuity_session(name: str, every: int) -> Session:
    """Session ``name`` (:data:`SESSIONS`) in acuity mode."""
    if name not in SESSIONS + EXTRA:
        raise ValueError(f"unknown session {name!r}: one of {', '.join(SESSIONS + EXTRA)}")
    s = session(VARIANTS[name][0] if name in VARIANTS else name)
    s.name = name
    s.rate_kbit = 1000 if name == "h264-1m" else 2000
    s.aim = CHART
    s.diagnostics = s.codec == "h264"
    if s.pan_speed:  # read after the session, at each picture's pose (``on_saved``), not by the viewer
        cam, _target, (_pan, _tilt, zoom) = chart_pose(s.model, s.size)
        view_deg = math.degrees(cam.world.zoom_model.hfov(zoom))
        deg_s = PAN_SPEED / 100.0 * cam.state.speeds.pan_deg_s  # continuouspantiltmove's speed is % of the fastest
        s.pan_flip_s = SWEEP_VIEWS * view_deg / deg_s
        s.on_saved = panning_reader(s, every // PSNR_EVERY)
    else:
        s.acuity_every = every
    return s


def upscaled(img: Any, size: tuple[int, int]) -> Any:
    import cv2

    return img if img.shape[1::-1] == size else cv2.resize(img, size, interpolation=cv2.INTER_LINEAR)


def panning_reader(s: Session, every_saved: int) -> Any:
    """``Session.on_saved`` for a panning session: every ``every_saved``-th picture saved after the first
    :data:`SETTLE_S` s, and the camera's compression-0 JPEG of its pose, read through the chart's homography at that
    pose; appended to ``s.acuity`` (``ref_rows``: the camera's own)."""
    seen = [0]

    def read(r: dict[str, Any], img: Any, cam: Any, pose: list[float], c0: Any) -> None:
        if r["rx"] < s.t0 + int(SETTLE_S * NS):
            return
        seen[0] += 1
        if (seen[0] - 1) % max(every_saved, 1):
            return
        renderer = cam.frames.renderer
        H = acuity.pose_homography(renderer, renderer.scene.target(CHART), *pose, *s.size)
        mine, camera = acuity.score(upscaled(img, s.size), H), acuity.score(c0, H)
        off = math.remainder(pose[0] - s.pose0[0], 360.0)  # from the chart's centre: the sweep's
        s.acuity.append({"rx": r["rx"], "cap": r["cap"], "rows": mine.rows_read, "ref_rows": camera.rows_read,
                         "cf": mine.corrected_fraction, "pan_off": off})  # fmt: skip

    return read


def read_kept(s: Session, refdir: Path) -> list[int]:
    """A still session: read the chart in the pictures the viewer kept (``refdir/pics/<capture ns>.npy``, every
    ``s.acuity_every``-th shown) after the first :data:`SETTLE_S` s into ``s.acuity``, and in :data:`REF_DRAWS`
    compression-0 JPEGs of the view the session measured (``s.pose0``); returns the latter's rows. Both through the
    chart's homography at that pose (``refdir/chart_h.npy``, written where the head was aimed); the last picture read
    is kept as ``refdir/operator-last.png`` to look at, the others are deleted."""
    import cv2
    import numpy as np

    H = np.load(refdir / "chart_h.npy")
    last = None
    for r in s.pics:
        f = refdir / "pics" / f"{r['cap']}.npy"
        if not r.get("acuity") or r["rx"] < s.t0 + int(SETTLE_S * NS) or not f.exists():
            continue
        last = upscaled(np.load(f), s.size)
        sc = acuity.score(last, H)
        s.acuity.append({"rx": r["rx"], "cap": r["cap"], "rows": sc.rows_read, "cf": sc.corrected_fraction})
    if last is not None:
        cv2.imwrite(str(refdir / "operator-last.png"), last)
    for f in (refdir / "pics").glob("*.npy"):
        f.unlink()
    cam, _target, _pose = chart_pose(s.model, s.size)
    cam.teleport(*s.pose0)
    return [acuity.score(cam.frame_jpeg(*s.size, 0), H).rows_read for _ in range(REF_DRAWS)]


def acuity_figures(s: Session, refdir: Path, seconds: float) -> dict[str, Any]:
    """The session's figures (``link_h264_results.figures``) and the acuity's: rows read by the camera and the
    operator, rows lost, the H.264 encoder's bitrate (target; received = the session's kbit/s)."""
    a = s.t0 + int(SETTLE_S * NS)
    out = figures(s, seconds)
    ref = [] if s.pan_speed else read_kept(s, refdir)
    reads = [r for r in s.acuity if r["rx"] >= a]
    if s.pan_speed:
        off = [r["pan_off"] for r in reads]
        in_view = [r for r in reads if r["ref_rows"] >= 1]  # the chart in view
        out["sweep"] = (
            f"{len(in_view)} of {len(reads)} pictures read had the chart in view (pan {min(off, default=0):+.2f} .. "
            f"{max(off, default=0):+.2f}° from its centre)"
        )
        reads = in_view
        ref = [r["ref_rows"] for r in reads]
        out["ref"] = f"{statistics.median(ref):g} ({min(ref)}..{max(ref)})" if ref else "—"
        lost = [r["ref_rows"] - r["rows"] for r in reads]
    else:
        out["ref"] = f"{statistics.median(ref):g} ({' '.join(map(str, ref))})"
        lost = [statistics.median(ref) - r["rows"] for r in reads]
    rows = [r["rows"] for r in reads]
    out["ref_p50"] = statistics.median(ref) if ref else math.nan
    out["rows_p50"] = statistics.median(rows) if rows else math.nan
    out["rows_range"] = f"{min(rows)}..{max(rows)}" if rows else "—"
    out["lost_p50"] = statistics.median(lost) if lost else math.nan
    out["lost_worst"] = max(lost) if lost else math.nan
    out["acuity_n"] = len(reads)
    out["cf_p50"] = statistics.median(r["cf"] for r in reads) if reads else math.nan
    targets = [d["target_kbps"] for d in s.diag if d["rx"] >= a]
    out["enc_target"] = statistics.median(targets) if targets else math.nan
    out["enc_kbps"] = out["kbps"] if s.codec == "h264" else math.nan
    if s.still_every:
        out.update(still_figures(s, s.t0 + int(seconds * NS)))
        out.update(still_acuity(out["still_requests"], refdir, s.size, ref))
    return out


def still_acuity(requests: list[dict[str, Any]], refdir: Path, size: tuple[int, int], ref: list[int]) -> dict[str, Any]:
    """The stills that arrived (``refdir/stills/<stamp>.jpg``, kept by the viewer) read through the chart's homography
    at the session's pose, as the live pictures are (a smaller one upscaled to ``size`` first), against the camera's
    own compression-0 rows ``ref`` (:data:`REF_DRAWS` draws): rows per still, their median, equal or not."""
    import cv2
    import numpy as np

    H = np.load(refdir / "chart_h.npy")
    rows = []
    for q in requests:
        st = q["still"]
        f = refdir / "stills" / f"{st['stamp']}.jpg" if st else None
        if f is None or not f.exists():
            continue
        img = cv2.imdecode(np.frombuffer(f.read_bytes(), np.uint8), cv2.IMREAD_COLOR)
        rows.append(acuity.score(upscaled(img, size), H).rows_read)
    out: dict[str, Any] = {"still_rows": rows}
    out["still_rows_p50"] = statistics.median(rows) if rows else math.nan
    out["still_rows_equal"] = bool(rows) and bool(ref) and statistics.median(rows) == statistics.median(ref)
    return out


#: the acuity rows of the side-by-side table: (label, format, figure key, target)
TABLE = (
    ("acuity chart at 35 m: the camera's own rows read (c0)", "{}", "ref", ""),
    ("  rows read at the operator, median", "{:g}", "rows_p50", ""),
    ("  rows read at the operator, range", "{}", "rows_range", ""),
    ("  rows lost to the link, median", "{:g}", "lost_p50", "0 (2 Mbit/s + monitor), <= 1 (others)"),
    ("  rows lost to the link, worst", "{:g}", "lost_worst", ""),
    ("  chance-corrected fraction at the operator, median", "{:.3f}", "cf_p50", ""),
    ("  pictures read", "{}", "acuity_n", ""),
    ("H.264 encoder: bitrate target (diagnostics) [kbit/s]", "{:.0f}", "enc_target", ">= 1200 (2 Mbit/s + monitor)"),
    ("H.264 encoder: received at the operator [kbit/s]", "{:.0f}", "enc_kbps", ""),
)


def readme_rows(results: dict[str, dict[str, Any]]) -> bool:
    """The README rows of the sessions run; True if every row with a target meets it."""
    from report import inputs, row

    inputs(*INPUTS, "bench/bench_acuity_link.py", "bench/acuity.py", "bench/acuity_chart.py")
    ok = True

    def lost(r: dict[str, Any]) -> str:
        return (
            f"{fmt(r['lost_p50'], '{:g}')} / {fmt(r['lost_worst'], '{:g}')} rows (camera {r['ref']}, operator "
            f"{fmt(r['rows_p50'], '{:g}')}, {r['acuity_n']} pictures); {fmt(r['psnr_soft_p50'], '{:.1f}')}, "
            f"{fmt(r['psnr_soft_p5'], '{:.1f}')} dB; age {fmt(r['age_p50'], '{:.0f}')} / "
            f"{fmt(r['age_p95'], '{:.0f}')} ms"
        )

    def encoder(r: dict[str, Any]) -> str:
        return f"; encoder {fmt(r['enc_kbps'], '{:.0f}')} kbit/s received (target {fmt(r['enc_target'], '{:.0f}')})"

    what = "acuity chart at 35 m (zoom limit), two hosts, {} 2 % loss, {}: rows lost to the link (camera's own " \
        "compression-0 picture − operator's) median / worst; PSNR median, 5th pct; age p50 / p95"  # fmt: skip

    def checked(name: str, link: str, how: str, target: str, good: Any, extra: str = "") -> None:
        nonlocal ok
        r = results.get(name)
        if r is None:
            return
        g = None if good is None else bool(good(r))
        row(what.format(link, how) + extra, lost(r) + ("" if math.isnan(r["enc_kbps"]) else encoder(r)), target, g)
        ok &= g is not False

    checked("mjpeg", "2 Mbit/s", "MJPEG ladder + link monitor", "report", None)
    checked(
        "h264", "2 Mbit/s", "H.264 + link monitor", "median 0 rows / ≥ 1200 kbit/s",
        lambda r: r["lost_p50"] <= 0 and r["enc_target"] >= 1200, "; encoder bitrate",
    )  # fmt: skip
    checked("h264-nofb", "2 Mbit/s", "H.264, plain viewer", "median ≤ 1 row", lambda r: r["lost_p50"] <= 1)
    checked("h264-1m", "1 Mbit/s", "H.264 + link monitor", "median ≤ 1 row", lambda r: r["lost_p50"] <= 1)
    checked(
        "h264-pan", "2 Mbit/s", f"H.264 + link monitor, the head sweeping {PAN_SPEED}°/s across the chart",
        "median ≤ 1 row", lambda r: r["lost_p50"] <= 1, " (each picture against the camera's own at its pose)",
    )  # fmt: skip
    h = results.get("h264")
    checked(
        "q6075-h264", "2 Mbit/s", "current-Axis persona 1920x1080, its H.264 passed through + link monitor",
        "more rows read than the 214 (H.264 + monitor" + (f": {fmt(h['rows_p50'], '{:g}')})" if h else ")"),
        (lambda r: r["rows_p50"] > h["rows_p50"]) if h else None,
    )  # fmt: skip
    st = results.get("h264-still")
    if st is not None:
        g = bool(still_good(st) and st["still_rows_equal"])
        row(
            "acuity chart at 35 m (zoom limit), two hosts, 2 Mbit/s 2 % loss, H.264 + link monitor, a full-quality "
            "still asked every 5 s: stills arrived / asked; call → still median, max; rows read in the stills vs the "
            "camera's own compression-0 pictures; live video fps / age p95 from each call to its still's arrival",
            f"{st['still_arrived']} / {st['still_asked']}; {fmt(st['still_arrival_p50'], '{:.2f}')}, "
            f"{still_max(st)}; stills {' '.join(map(str, st['still_rows'])) or '—'} rows "
            f"(camera {st['ref']}); {fmt(st['still_win_fps'], '{:.1f}')} fps / "
            f"{fmt(st['still_win_age_p95'], '{:.0f}')} ms",
            f"all / ≤ {STILL_TARGET_S} s; equal; ≥ {STILL_FPS_TARGET:.0f} fps / ≤ {STILL_AGE_TARGET_MS:.0f} ms",
            g,
        )
        ok &= g
    q = results.get("q6075-h264")
    checked(
        "q6075-auto", "2 Mbit/s", "current-Axis persona, resolution auto (size by the bitrate), passed through + "
        "link monitor", "more rows read than 1920x1080 passed through" + (
            f" ({fmt(q['rows_p50'], '{:g}')})" if q else ""
        ), (lambda r: r["rows_p50"] > q["rows_p50"]) if q else None,
    )  # fmt: skip
    return ok


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=40.0, help="measurement per session (s, >= 20)")
    ap.add_argument("--sessions", default=",".join(SESSIONS), help="comma-separated, of " + ", ".join(SESSIONS + EXTRA))
    ap.add_argument("--every", type=int, default=15, help=f"read every N-th picture shown (a multiple of {PSNR_EVERY})")
    ap.add_argument("--plot", default="", help="PNG of the sessions over time ('' = none)")
    ap.add_argument(
        "--fastdds-profile",
        default=str(ROOT / "config/fastdds_weak_link.xml"),
        help="Fast DDS profile for every process on both hosts ('' = Fast DDS defaults)",
    )
    a = ap.parse_args()
    if a.every < PSNR_EVERY or a.every % PSNR_EVERY:
        ap.error(f"--every must be a positive multiple of {PSNR_EVERY}, not {a.every}")
    names = [n for n in a.sessions.split(",") if n]
    for n in names:
        if n not in SESSIONS + EXTRA:
            ap.error(f"unknown session {n!r}: one of {', '.join(SESSIONS + EXTRA)}")
    from tests.support import link as linkmod

    reason = linkmod.available()
    if reason:
        print(f"FAIL: {reason}")
        return 1
    seconds = max(a.seconds, 20.0)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT)
    profile = os.path.relpath(a.fastdds_profile, ROOT) if a.fastdds_profile else "none (Fast DDS defaults)"
    print(
        f"commit {commit.stdout.strip() or '?'}; ROS_DOMAIN_ID {os.environ.get('ROS_DOMAIN_ID', '0')}; "
        f"Fast DDS profile {profile}; load average {os.getloadavg()[0]:.1f}; chart {CHART}, every {a.every}th "
        "picture read"
    )
    logs = ROOT / "artifacts" / "bench_acuity_link"
    sessions, results = [], []
    for name in names:
        s = acuity_session(name, a.every)
        _cam, _t, (pan, tilt, zoom) = chart_pose(s.model, s.size)
        sweep = f", sweeping {PAN_SPEED}°/s reversing every {s.pan_flip_s:.2f} s" if s.pan_speed else ""
        print(f"== {name}: {seconds:.0f} s on the link; {s.model} aimed at {CHART}: pan {pan:.2f} tilt {tilt:.2f} "
              f"zoom {zoom:.0f}{sweep}", flush=True)  # fmt: skip
        extra = VARIANTS.get(name, ("", ""))[1]
        saved = os.environ.get("BENCH_LINK_ROBOT_ARGS")
        os.environ["BENCH_LINK_ROBOT_ARGS"] = f"{saved or ''} {extra}".strip()
        try:
            run_session(s, seconds, 1, logs, a.fastdds_profile)
        finally:
            if saved is None:
                del os.environ["BENCH_LINK_ROBOT_ARGS"]
            else:
                os.environ["BENCH_LINK_ROBOT_ARGS"] = saved
        r = acuity_figures(s, logs / f"ref-{s.name}", seconds)
        print(f"   load average {os.getloadavg()[0]:.1f}" + (f"; {r['sweep']}" if "sweep" in r else ""), flush=True)
        sessions.append(s)
        results.append(r)
    print()
    print_table(results, seconds, 2000, TABLE)
    for r in results:
        if "still_asked" in r:
            print_stills(r)
            print(
                f"{r['name']}: acuity chart in the stills: {' '.join(map(str, r['still_rows'])) or '—'} rows read "
                f"(median {fmt(r['still_rows_p50'], '{:g}')}); the camera's own compression-0 pictures: {r['ref']}; "
                f"target: equal -> {'equal' if r['still_rows_equal'] else 'NOT equal'}"
            )
    if a.plot:
        plot(sessions, seconds, Path(a.plot), 2000)
        print(f"\nplot: {os.path.relpath(a.plot, ROOT)}")
    ok = readme_rows({r["name"]: r for r in results})
    print(f"acuity over the weak link: {'all targets met' if ok else 'some targets missed'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
