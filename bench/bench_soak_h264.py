"""Soak of H.264 under faults (issue 40 item 4): two stream nodes for an hour, their viewers coming and going, the
cameras' links cut, the cameras rebooted and one camera's clock stepped.

Processes (all on this machine's loopback):

- ``transcoded``: the simulated 214 (``axis_camera_sim``, MJPEG only) and ``axis_stream`` with ``codec: h264``
  (it asks the camera for compression-0 JPEGs and encodes them), 704×576 at 15 fps;
- ``passthrough``: the current-Axis persona (``axis_camera_sim --model q6075``, RTSP H.264) and ``axis_stream`` with
  ``codec: h264`` and ``rtsp_port`` (the camera's own H.264 passed through), 640×360 at 15 fps;
- viewers: plain subscribers of ``<ns>/image_raw/ffmpeg`` (reliable keep-last 10, as ``rqt_image_view`` and the
  ffmpeg plugin subscribe), each its own process (``--viewer``) decoding with PyAV
  (:class:`~axis_ptz_ros2.streaming.receiver.AccessUnitReceiver`) and printing one JSON line per message. One
  viewer per stream stays the whole run (the monitor); the others join and leave.

The schedule (:func:`schedule`; the hour's times, scaled by ``--duration`` / 3600 for a shorter run, so a shorter run
has the same events closer together; the faults keep their real lengths):

- a 10 s cut of both cameras' links every 10 min (from 5 min): nftables drops every TCP packet to and from the
  cameras' ports on loopback (a table of this process's own, removed at the end), as a pulled cable does: open
  connections go silent, connects hang, nothing is closed. Needs root (CAP_NET_ADMIN), checked at the start;
- a reboot of both cameras every 15 min (from 7.5 min): the simulator's own reboot, off the network for 8 s (packets
  dropped: its black hole), then 2 s of 503s, then video;
- the passthrough camera's clock stepped 30 s back once (at 32.5 min): its RTCP sender reports then say a time 30 s
  behind (the simulator's ``clock_offset_s``); the 214 streams MJPEG, whose stamps take nothing from its clock;
- a viewer joins every 3 min (from 1.5 min), alternately on either stream, and leaves 4.5 min later; a join that
  would fall within 2.5 s before or 5 s after a fault is moved to the end of that window (a first picture is
  what the nodes make of a join, not of a fault).

Targets (issue 40): RSS slope of each stream node over the second half ≤ 1 MB/h; every viewer's first picture
≤ 2 s after it subscribed; no header stamp going back on either topic (at any viewer); no stale frame (a picture whose
capture time, the simulator's own in the SEI, is not after the last one shown); recovery ≤ 1.5 s after each reboot
(the camera's video back → the first picture captured after it at the monitor). Also shown: recovery after each cut,
age (arrival − capture) p50/p95, the passthrough node's reported camera clock offset against the truth.

    python bench/bench_soak_h264.py                    # the hour (./scripts/bench soak_h264)
    python bench/bench_soak_h264.py --duration 600     # the hour's schedule in 10 minutes
"""

from __future__ import annotations

import argparse
import atexit
import json
import math
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from pipelines import Proc

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests.support (the viewers' spin)
sys.path.insert(0, str(Path(__file__).resolve().parent))

HOUR_S = 3600.0
CUT_S = 10.0  #: each link cut
CUT_EVERY_S, CUT_FIRST_S = 600.0, 300.0
REBOOT_OFF_S, REBOOT_ERRORS_S = 8.0, 2.0  #: a reboot: off the network (black hole), then the web server's 503s
REBOOT_EVERY_S, REBOOT_FIRST_S = 900.0, 450.0
CLOCK_STEP_AT_S, CLOCK_STEP_S = 1950.0, -30.0  #: the camera's clock stepped back 30 s, once
JOIN_EVERY_S, JOIN_FIRST_S, STAY_S = 180.0, 90.0, 270.0
BEFORE_FAULT_S, AFTER_FAULT_S = 2.5, 5.0  #: no join this close to a fault
MIN_GAP_S = 10.0  #: between one fault's end and the next one's start
TAIL_S = 15.0  #: the run goes on at least this long after its last fault

FIRST_PICTURE_S = 2.0
RECOVERY_S = 1.5
RSS_SLOPE_MB_H = 1.0
OFFSET_TOLERANCE_S = 0.1

STREAMS = ("transcoded", "passthrough")
NS = 1_000_000_000


@dataclass(frozen=True)
class Event:
    """One scheduled action: ``cut``, ``reboot`` or ``clock`` (``length``: how long the fault lasts), ``join`` or
    ``leave`` (``viewer``: its number, ``stream``: which)."""

    t: float
    kind: str
    length: float = 0.0
    viewer: int = -1
    stream: str = ""


def schedule(duration: float) -> list[Event]:
    """The run's events in time order for a run of ``duration`` seconds (ROS-free). The hour's times are scaled by
    ``duration / 3600``; the faults keep their lengths, so too short a run (faults overlapping) is refused with a
    ValueError naming the shortest that works."""
    if not (math.isfinite(duration) and duration > 0):
        raise ValueError(f"duration must be a positive number of seconds, got {duration!r}")
    k = duration / HOUR_S
    faults = _faults(duration)
    problem = _fault_problem(faults, duration)
    if problem:
        raise ValueError(f"--duration {duration:g} s {problem}; it takes at least {shortest_duration():.0f} s")
    windows = [(e.t - BEFORE_FAULT_S, e.t + e.length + AFTER_FAULT_S) for e in faults]
    viewers: list[Event] = []
    for i, t0 in enumerate(_times(JOIN_FIRST_S, JOIN_EVERY_S)):
        t = t0 * k
        for lo, hi in windows:  # in time order: a join moved past one window may land in the next
            if lo <= t < hi:
                t = hi
        leave = min((t0 + STAY_S) * k, duration - 1.0)
        if leave - t < FIRST_PICTURE_S + 1.0:
            continue  # moved too late to be timed: dropped
        stream = STREAMS[i % 2]
        viewers += [Event(t, "join", viewer=i, stream=stream), Event(leave, "leave", viewer=i, stream=stream)]
    return sorted(faults + viewers, key=lambda e: (e.t, e.kind))


def shortest_duration() -> float:
    """The shortest run (s) whose scaled schedule keeps the faults apart, by bisection (gaps grow with the run)."""
    lo, hi = 1.0, HOUR_S
    for _ in range(40):
        mid = (lo + hi) / 2
        lo, hi = (lo, mid) if _fault_problem(_faults(mid), mid) is None else (mid, hi)
    return math.ceil(hi)


def _times(first: float, every: float) -> list[float]:
    """The hour's times of a periodic event."""
    out, t = [], first
    while t < HOUR_S:
        out.append(t)
        t += every
    return out


def _faults(duration: float) -> list[Event]:
    """The faults of a run of ``duration`` s in time order: the hour's times scaled, their lengths kept."""
    k = duration / HOUR_S
    faults = [Event(t * k, "cut", CUT_S) for t in _times(CUT_FIRST_S, CUT_EVERY_S)]
    faults += [Event(t * k, "reboot", REBOOT_OFF_S + REBOOT_ERRORS_S) for t in _times(REBOOT_FIRST_S, REBOOT_EVERY_S)]
    faults.append(Event(CLOCK_STEP_AT_S * k, "clock"))
    return sorted(faults, key=lambda e: e.t)


def _fault_problem(faults: list[Event], duration: float) -> str | None:
    """Why these faults do not fit a run of ``duration`` s (None: they do)."""
    for a, b in zip(faults, faults[1:], strict=False):
        if b.t - (a.t + a.length) < MIN_GAP_S:
            return f"puts a {b.kind} {b.t - (a.t + a.length):.1f} s after a {a.kind} (at least {MIN_GAP_S:g} s)"
    if faults[-1].t + faults[-1].length + TAIL_S > duration:
        return f"leaves less than {TAIL_S:g} s after the last fault"
    return None


# ---------------------------------------------------------------------------------------------------------
# the viewer (its own process)
# ---------------------------------------------------------------------------------------------------------
def viewer(ns: str, diagnostics: bool) -> int:
    """Subscribe to ``<ns>/image_raw/ffmpeg``, decode, print a JSON line per message (``rx`` arrival, ``st`` header
    stamp, ``cap`` the SEI capture time of a picture shown, ``ok`` shown); ``ready`` once subscribed; with
    ``diagnostics`` the node's reported camera clock offset (``diag``) whenever /diagnostics carries it."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from ffmpeg_image_transport_msgs.msg import FFMPEGPacket
    from rclpy.event_handler import SubscriptionEventCallbacks
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

    from axis_ptz_ros2.streaming.receiver import AccessUnitReceiver
    from tests.support.spin import spin_until_stopped

    out = sys.stdout

    def emit(rec: dict[str, object]) -> None:
        out.write(json.dumps(rec, separators=(",", ":")) + "\n")
        out.flush()

    rclpy.init(args=["soak_h264_viewer"])
    node = rclpy.create_node("soak_h264_viewer", namespace=ns)
    rcv = AccessUnitReceiver()

    def on_packet(msg: FFMPEGPacket) -> None:
        rx = time.time_ns()
        pic = rcv.feed(bytes(msg.data), int(msg.pts))
        st = msg.header.stamp.sec * NS + msg.header.stamp.nanosec
        cap = (pic.capture_ns or 0) if pic is not None else 0
        emit({"rx": rx, "st": st, "cap": cap, "ok": int(pic is not None)})

    plain = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
    # when discovery matched this reader with the node's writer: a slow first picture is discovery's or the node's
    events = SubscriptionEventCallbacks(
        matched=lambda info: emit({"t": "matched", "rx": time.time_ns(), "n": int(info.current_count)})
    )
    node.create_subscription(FFMPEGPacket, "image_raw/ffmpeg", on_packet, plain, event_callbacks=events)
    if diagnostics:
        last: list[object] = [None]

        def on_diag(msg: DiagnosticArray) -> None:
            for st in msg.status:
                for kv in st.values:
                    if kv.key == "rtsp camera clock offset [s]" and kv.value and kv.value != last[0]:
                        last[0] = kv.value
                        emit({"t": "diag", "rx": time.time_ns(), "off": float(kv.value)})

        node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 10)
    emit({"t": "ready", "rx": time.time_ns()})
    spin_until_stopped(node)
    return 0


# ---------------------------------------------------------------------------------------------------------
# the link cut
# ---------------------------------------------------------------------------------------------------------
class LinkCut:
    """The cameras' links cut by nftables: every TCP packet to or from ``ports`` dropped on this host (loopback
    included), in a table of this process's own that :meth:`restore` deletes."""

    def __init__(self, ports: list[int]) -> None:
        """Check that nftables can be used here (root); raise RuntimeError saying why not."""
        self.table = f"{self.PREFIX}{os.getpid()}"
        self.ports = ports
        self.active = False
        self._remove_orphans()
        probe = self._nft(f"add table inet {self.table}\ndelete table inet {self.table}\n")
        if probe:
            raise RuntimeError(f"the link cut needs nftables as root (CAP_NET_ADMIN): {probe}")
        atexit.register(self.restore)

    PREFIX = "axis_soak_h264_"  #: the tables' names: this prefix and the bench's process id

    def _remove_orphans(self) -> None:
        """Delete the tables a killed run left (their process gone): they would cut whoever gets those ports next."""
        try:
            listing = subprocess.run(["nft", "list", "tables"], text=True, capture_output=True, timeout=10, check=False)
        except (OSError, subprocess.TimeoutExpired):
            return
        for line in listing.stdout.splitlines():
            name = line.split()[-1] if line.startswith("table inet ") else ""
            pid = name.removeprefix(self.PREFIX)
            if name.startswith(self.PREFIX) and pid.isdigit() and not Path(f"/proc/{pid}").exists():
                self._nft(f"delete table inet {name}\n")
                print(f"removed the link cut a killed run left: table inet {name}", flush=True)

    @staticmethod
    def _nft(script: str) -> str:
        """Run an nft script; the error ('' when it worked)."""
        try:
            p = subprocess.run(
                ["nft", "-f", "-"], input=script, text=True, capture_output=True, timeout=10, check=False
            )
        except (OSError, subprocess.TimeoutExpired) as err:
            return str(err)
        return "" if p.returncode == 0 else (p.stderr.strip() or f"nft exited {p.returncode}")

    def cut(self) -> None:
        """Drop the cameras' packets from now on."""
        ports = ", ".join(str(p) for p in self.ports)
        err = self._nft(
            f"table inet {self.table} {{\n chain out {{\n  type filter hook output priority 0; policy accept;\n"
            f"  tcp dport {{ {ports} }} drop\n  tcp sport {{ {ports} }} drop\n }}\n}}\n"
        )
        if err:
            raise RuntimeError(f"link cut: {err}")
        self.active = True

    def restore(self) -> None:
        """The links back (nothing if not cut)."""
        if self.active:
            self._nft(f"delete table inet {self.table}\n")
            self.active = False


# ---------------------------------------------------------------------------------------------------------
# the run
# ---------------------------------------------------------------------------------------------------------
@dataclass
class Viewer:
    """A viewer process and what it printed (parsed as it arrives)."""

    number: int
    stream: str
    proc: Proc
    monitor: bool = False
    joined_ns: int | None = None  #: subscribed
    matched_ns: int | None = None  #: discovery matched the subscription with the node's publisher
    left_ns: int | None = None
    msgs: list[tuple[int, int, int, int]] = field(default_factory=list)  # (rx, st, cap, ok)
    diag: list[tuple[int, float]] = field(default_factory=list)
    parsed: int = 0

    def parse(self) -> None:
        """Take the lines printed since the last call."""
        lines = self.proc.lines
        new, self.parsed = lines[self.parsed :], len(lines)
        for line in new:
            if not line.startswith("{"):
                continue
            try:
                rec = json.loads(line)
            except json.JSONDecodeError:
                continue
            if rec.get("t") == "ready":
                self.joined_ns = rec["rx"]
            elif rec.get("t") == "matched":
                if self.matched_ns is None and rec["n"] > 0:
                    self.matched_ns = rec["rx"]
            elif rec.get("t") == "diag":
                self.diag.append((rec["rx"], rec["off"]))
            elif "st" in rec:
                self.msgs.append((rec["rx"], rec["st"], rec["cap"], rec["ok"]))


def start_camera(model: str) -> tuple[Proc, int, int | None]:
    """A simulator process; its HTTP port and RTSP port (None for the 214)."""
    import re

    from pipelines import BIN, Proc

    cmd = [str(BIN / "axis_camera_sim"), "--model", model, "--port", "0", "--no-https", "--auth", "none"]
    if model != "axis214":
        cmd += ["--rtsp-port", "0"]
    proc = Proc(cmd, f"sim {model}")
    line = proc.wait_line(r"http://127\.0\.0\.1:(\d+)/", 30.0).string
    http = int(re.search(r"http://127\.0\.0\.1:(\d+)/", line).group(1))  # type: ignore[union-attr]
    m = re.search(r"rtsp://[^:/]+:(\d+)", line)
    return proc, http, int(m.group(1)) if m else None


def start_node(stream: str, http: int, rtsp: int | None) -> Proc:
    """``axis_stream`` for ``stream`` in namespace ``/soak_h264/<stream>``."""
    from pipelines import BIN, ROOT, Proc

    values: dict[str, object] = {"hostname": "127.0.0.1", "port": http, "codec": "h264", "fps": 15}
    if rtsp is None:
        values |= {"resolution": "704x576", "camera_model": ROOT / "config" / "axis214.yaml"}
    else:
        values |= {"resolution": "640x360", "rtsp_port": rtsp, "camera_model": ROOT / "config" / "q6075.yaml"}
    cmd = [str(BIN / "axis_stream"), "--ros-args", "-r", f"__ns:=/soak_h264/{stream}", "--log-level", "warn"]
    for k, v in values.items():
        cmd += ["-p", f"{k}:={v}"]
    return Proc(cmd, f"axis_stream {stream}")


def start_viewer(number: int, stream: str, monitor: bool = False) -> Viewer:
    from pipelines import Proc

    cmd = [sys.executable, str(Path(__file__).resolve()), "--viewer", f"/soak_h264/{stream}"]
    if monitor and stream == "passthrough":
        cmd.append("--diagnostics")
    return Viewer(number, stream, Proc(cmd, f"viewer {number} ({stream})"), monitor=monitor)


def control(port: int, query: str) -> dict[str, Any]:
    from pipelines import sim_get

    return sim_get(port, f"/sim/control?{query}")


def pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, round(q / 100 * (len(s) - 1)))] if s else math.nan


def main() -> int:  # noqa: C901, PLR0912, PLR0915 - one scripted run, then its figures
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=HOUR_S, help="seconds (default 3600: the issue's hour)")
    ap.add_argument("--viewer", metavar="NS", help=argparse.SUPPRESS)  # internal: the viewer process
    ap.add_argument("--diagnostics", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.viewer:
        return viewer(args.viewer, args.diagnostics)
    try:
        events = schedule(args.duration)
    except ValueError as err:
        ap.error(str(err))
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # a stop cleans up too: links back, processes ended

    from pipelines import ROOT, sim_get
    from report import inputs
    from soak_common import SAMPLE_EVERY_S, sample

    # every process (stream nodes, viewers) runs with the project's shipped Fast DDS profile, as docs/weak-link.md
    # tells a deployment to: its 0.5 s participant announcements are what bound a joining viewer's discovery (with
    # Fast DDS's 3 s default, 10-minute runs had viewers matched 2.2-2.7 s after they subscribed)
    profile = ROOT / "config" / "fastdds_weak_link.xml"
    os.environ.setdefault("FASTRTPS_DEFAULT_PROFILES_FILE", str(profile))
    os.environ.setdefault("RMW_FASTRTPS_PUBLICATION_MODE", "AUTO")  # as docs/weak-link.md says, with the profile
    print(f"Fast DDS profile: {os.environ['FASTRTPS_DEFAULT_PROFILES_FILE']}")
    inputs(
        "config/fastdds_weak_link.xml",
        "axis_ptz_ros2/axis_ptz_ros2/nodes",
        "axis_ptz_ros2/axis_ptz_ros2/streaming",
        "axis_ptz_ros2/axis_ptz_ros2/media",
        "axis_ptz_ros2/axis_ptz_ros2/vapix",
        "bench/bench_soak_h264.py",
        "bench/soak_common.py",
    )
    count = {kind: sum(e.kind == kind for e in events) for kind in ("cut", "reboot", "clock", "join")}
    print(
        f"soak_h264: {args.duration:g} s; {count['cut']} link cuts of {CUT_S:g} s, {count['reboot']} reboots "
        f"({REBOOT_OFF_S:g} s off + {REBOOT_ERRORS_S:g} s of 503), {count['clock']} camera clock step of "
        f"{CLOCK_STEP_S:+g} s, {count['join']} viewers joining and leaving",
        flush=True,
    )
    procs: list[Proc] = []
    viewers: list[Viewer] = []
    cut: LinkCut | None = None
    try:
        sim_t, http_t, _ = start_camera("axis214")
        sim_p, http_p, rtsp_p = start_camera("q6075")
        procs += [sim_t, sim_p]
        assert rtsp_p is not None
        cut = LinkCut([http_t, http_p, rtsp_p])
        cams = {"transcoded": http_t, "passthrough": http_p}
        nodes = {
            "transcoded": start_node("transcoded", http_t, None),
            "passthrough": start_node("passthrough", http_p, rtsp_p),
        }
        procs += list(nodes.values())
        monitors = {s: start_viewer(-1 - i, s, monitor=True) for i, s in enumerate(STREAMS)}
        viewers += list(monitors.values())
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline and not all(any(m[3] for m in v.msgs) for v in monitors.values()):
            for v in monitors.values():
                v.parse()
            time.sleep(0.2)
        for s, v in monitors.items():
            if not any(m[3] for m in v.msgs):
                print(f"{s}: no picture within 60 s; node output:", *nodes[s].lines[-20:], sep="\n")
                return 1
        print("both monitors decode; the schedule starts", flush=True)

        samples: dict[str, list[tuple[float, float, int, int]]] = {s: [] for s in STREAMS}
        reboots: list[dict[str, float]] = []  # per reboot: when asked (wall), per stream camera back (wall s)
        cuts: list[tuple[float, float]] = []  # (start, end) wall s
        clock_step_wall: float | None = None
        churn: dict[int, Viewer] = {}
        start = time.monotonic()
        next_sample = start
        pending = list(events)
        restore_at: float | None = None
        back_checks: list[tuple[float, dict[str, float]]] = []
        while True:
            now = time.monotonic()
            t = now - start
            if t >= args.duration:
                break
            for s, node in nodes.items():
                if node.p.poll() is not None:
                    raise RuntimeError(f"axis_stream {s} exited; output: {node.lines[-20:]}")
            if restore_at is not None and now >= restore_at:
                cut.restore()
                cuts[-1] = (cuts[-1][0], time.time())
                restore_at = None
                print(f"t={t:6.1f} s  links back", flush=True)
            while pending and pending[0].t <= t:
                e = pending.pop(0)
                if e.kind == "cut":
                    cut.cut()
                    cuts.append((time.time(), math.nan))
                    restore_at = now + e.length
                elif e.kind == "reboot":
                    rec: dict[str, float] = {"asked": time.time()}
                    q = f"reboot={REBOOT_OFF_S:g}&reboot_blackhole=1&reboot_errors_s={REBOOT_ERRORS_S:g}"
                    for port in cams.values():
                        control(port, q)
                    reboots.append(rec)
                    back_checks.append((now + e.length + 1.0, rec))
                elif e.kind == "clock":
                    control(http_p, f"clock_offset_s={CLOCK_STEP_S:g}")
                    clock_step_wall = time.time()
                elif e.kind == "join":
                    churn[e.viewer] = start_viewer(e.viewer, e.stream)
                    viewers.append(churn[e.viewer])
                elif e.kind == "leave" and e.viewer in churn:
                    v = churn.pop(e.viewer)
                    v.left_ns = time.time_ns()
                    # stopped aside: a viewer's exit (up to 5 s) must not hold back the schedule
                    threading.Thread(target=v.proc.stop, daemon=True).start()
                print(
                    f"t={t:6.1f} s  {e.kind}" + (f" viewer {e.viewer} ({e.stream})" if e.viewer >= 0 else ""),
                    flush=True,
                )
            for due, rec in list(back_checks):
                if now >= due:
                    states = {s: sim_get(port, "/sim/state") for s, port in cams.items()}
                    if any(st["rebooting"] for st in states.values()):
                        continue  # not back yet: asked again on the next turn
                    back_checks.remove((due, rec))
                    for s, st in states.items():
                        rec[s] = st["video_ok_at"] if st["video_ok_at"] is not None else math.nan
            if now >= next_sample:
                for s, node in nodes.items():
                    samples[s].append(sample(node.p.pid, t))
                if len(samples["transcoded"]) % 6 == 1:
                    rss = "  ".join(f"{s} RSS {samples[s][-1][1]:.1f} MB" for s in STREAMS)
                    pics = "  ".join(f"{s} {sum(m[3] for m in monitors[s].msgs)} pictures" for s in STREAMS)
                    print(f"t={t:6.1f} s  {rss}  {pics}", flush=True)
                next_sample += SAMPLE_EVERY_S
            for v in viewers:
                v.parse()
            time.sleep(0.1)
        for v in churn.values():
            v.proc.stop()
            v.left_ns = time.time_ns()
        for v in viewers:
            v.parse()
        alive = all(n.p.poll() is None for n in nodes.values())
    finally:
        if cut is not None:
            cut.restore()
        for v in viewers:
            v.proc.stop()
        for p in reversed(procs):
            p.stop()

    run = Run(samples, viewers, reboots, cuts, clock_step_wall, alive)
    return 0 if judge(run, args.duration) else 1


@dataclass
class Run:
    """What a run recorded, for :func:`judge`."""

    samples: dict[str, list[tuple[float, float, int, int]]]  # per stream node: (t, RSS MB, threads, fds)
    viewers: list[Viewer]
    reboots: list[dict[str, float]]  # "asked" (wall s), per stream the camera's video back (wall s)
    cuts: list[tuple[float, float]]  # (start, end) wall s
    clock_step_wall: float | None
    alive: bool

    def monitor(self, stream: str) -> Viewer:
        return next(v for v in self.viewers if v.monitor and v.stream == stream)

    def recovery(self, stream: str, back_wall: float) -> float:
        """Seconds from ``back_wall`` to the monitor's first picture captured after it."""
        ns = int(back_wall * NS)
        for rx, _st, cap, ok in self.monitor(stream).msgs:
            if ok and cap >= ns:
                return (rx - ns) / NS
        return math.inf


def judge(run: Run, duration: float) -> bool:  # noqa: PLR0915 - one target after the other
    """Print every target's figures with PASS/MISS (and the README rows); whether all were met."""
    from report import row
    from soak_common import ranges, rss_slope_mb_per_h

    ok_all = run.alive
    head = f"soak H.264 {duration / 60:g} min"
    joined = sum(not v.monitor for v in run.viewers)
    step = "done" if run.clock_step_wall else "not done"
    print(f"\n{head}: {len(run.cuts)} cuts, {len(run.reboots)} reboots, clock step {step}, {joined} viewers joined")

    def target(what: str, fig: str, goal: str, ok: bool | None) -> None:
        nonlocal ok_all
        ok_all &= ok is not False
        mark = "info" if ok is None else "PASS" if ok else "MISS"
        print(f"  [{mark}] {what}: {fig}" + (f" (target {goal})" if ok is not None else ""), flush=True)
        row(f"{head}: {what}", fig, goal, ok)

    # RSS
    slopes = {s: rss_slope_mb_per_h(run.samples[s]) for s in STREAMS}
    figs = []
    for s in STREAMS:
        sm = run.samples[s]
        (th0, th1), (fd0, fd1) = ranges(sm)
        figs.append(
            f"{s} {slopes[s]:+.2f} MB/h (RSS {sm[0][1]:.0f}→{sm[-1][1]:.0f} MB, threads {th0}–{th1}, fds {fd0}–{fd1})"
        )
    ok = all(abs(v) <= RSS_SLOPE_MB_H for v in slopes.values())
    target("RSS slope of the stream nodes over the second half", "; ".join(figs), f"≤ {RSS_SLOPE_MB_H:g} MB/h", ok)

    # first picture (and, to tell discovery from waiting for a start point, the first message of any kind)
    firsts: list[tuple[str, float, float, float]] = []  # (stream, matched, first message, first picture) s after
    for v in run.viewers:
        if v.monitor or v.joined_ns is None:
            continue
        shown = [m[0] for m in v.msgs if m[3]]
        matched = (v.matched_ns - v.joined_ns) / NS if v.matched_ns is not None else math.inf
        first_msg = (v.msgs[0][0] - v.joined_ns) / NS if v.msgs else math.inf
        firsts.append((v.stream, matched, first_msg, (shown[0] - v.joined_ns) / NS if shown else math.inf))
    worst = max((f[3] for f in firsts), default=math.nan)
    never = sum(not math.isfinite(f[3]) for f in firsts)
    each = "; ".join(f"{s}: " + ", ".join(f"{f[3]:.2f}" for f in firsts if f[0] == s) for s in STREAMS)
    fig = f"worst {worst:.2f} s of {len(firsts)} joins ({each} s)" + (f"; {never} never shown" if never else "")
    slow = [f for f in firsts if f[3] > FIRST_PICTURE_S]
    if slow:
        fig += "; of those > 2 s, matched / first message: " + ", ".join(f"{f[1]:.2f}/{f[2]:.2f}" for f in slow)
        fig += " s"
    target(
        "viewers' first picture after joining",
        fig,
        f"≤ {FIRST_PICTURE_S:g} s",
        bool(firsts) and worst <= FIRST_PICTURE_S,
    )

    # stamps going back, stale pictures, age
    back = dict.fromkeys(STREAMS, 0)
    worst_back = dict.fromkeys(STREAMS, 0.0)
    stale = dict.fromkeys(STREAMS, 0)
    msgs = dict.fromkeys(STREAMS, 0)
    ages: dict[str, list[float]] = {s: [] for s in STREAMS}
    for v in run.viewers:
        last_st = last_cap = None
        for rx, st, cap, ok_pic in v.msgs:
            msgs[v.stream] += 1
            if last_st is not None and st < last_st:
                back[v.stream] += 1
                worst_back[v.stream] = max(worst_back[v.stream], (last_st - st) / NS)
            last_st = st
            if ok_pic and cap:
                stale[v.stream] += last_cap is not None and cap <= last_cap
                last_cap = cap
                if v.monitor:
                    ages[v.stream].append((rx - cap) / 1e6)
    fig = "; ".join(
        f"{s} {back[s]} of {msgs[s]}" + (f" (up to {worst_back[s]:.3f} s)" if back[s] else "") for s in STREAMS
    )
    target(
        "header stamps going back (every viewer, per topic)", fig, "0", sum(back.values()) == 0 and all(msgs.values())
    )
    fig = "; ".join(f"{s} {stale[s]}" for s in STREAMS)
    ok = sum(stale.values()) == 0 and all(msgs.values())
    target("stale pictures shown (capture time not after the last one's)", fig, "0", ok)
    fig = "; ".join(f"{s} p50 {pct(ages[s], 50):.0f} ms, p95 {pct(ages[s], 95):.0f} ms" for s in STREAMS)
    target("age at the monitors (arrival − capture)", fig, "—", None)

    # recovery after reboots (target) and cuts (shown)
    rec = {s: [run.recovery(s, r[s]) for r in run.reboots if math.isfinite(r.get(s, math.nan))] for s in STREAMS}
    unread = sum(not math.isfinite(r.get(s, math.nan)) for r in run.reboots for s in STREAMS)
    worst = max((x for v in rec.values() for x in v), default=math.nan)
    fig = "; ".join(f"{s} " + ", ".join(f"{x:.2f}" for x in rec[s]) + " s" for s in STREAMS)
    fig += f"; {unread} camera returns not read" if unread else ""
    ok = bool(run.reboots) and not unread and worst <= RECOVERY_S
    target("recovery after each camera reboot (video back → first picture)", fig, f"≤ {RECOVERY_S:g} s", ok)
    rec = {s: [run.recovery(s, end) for _, end in run.cuts if math.isfinite(end)] for s in STREAMS}
    fig = "; ".join(f"{s} " + ", ".join(f"{x:.2f}" for x in rec[s]) + " s" for s in STREAMS)
    target(f"recovery after each {CUT_S:g} s link cut (links back → first picture)", fig, "—", None)

    # the camera clock offset the passthrough node reports, against the truth (host − camera)
    diag = run.monitor("passthrough").diag
    t_step = run.clock_step_wall
    after = [off for rx, off in diag if t_step is not None and rx >= (t_step + 5.0) * NS]
    before = [off for rx, off in diag if t_step is None or rx < t_step * NS]
    truth = -CLOCK_STEP_S
    b = f"{before[-1]:+.3f}" if before else "none"
    a = f"{after[-1]:+.3f}" if after else "none"
    ok = bool(after) and abs(after[-1] - truth) <= OFFSET_TOLERANCE_S
    fig = f"before the step {b} s (truth 0), after it {a} s (truth {truth:+g} s)"
    target("passthrough node's camera clock offset in /diagnostics", fig, f"within {OFFSET_TOLERANCE_S:g} s", ok)
    if not run.alive:
        print("  a stream node exited during the run")
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"{head}: {'every target met' if ok_all else 'targets missed'} (load average at the end {load})", flush=True)
    return ok_all


if __name__ == "__main__":
    sys.exit(main())
