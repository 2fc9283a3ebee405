"""What the driver's processes cost, side by side in one run: CPU of each process (the scheduler's run time of
all its threads, ns) over the same fixed windows, so every process sees the same machine load; sections (1) and
(2) run twice, the processes started in one order and then the reverse, and report the mean (the process started
first costs more: ``cpu_compare.measure_cpu_both_orders``), each state (idle, streaming) as every process's
median over three windows.

Processes are started as the robot would (console scripts, each in its own namespace) against simulated cameras
(``axis_camera_sim`` subprocesses); this process is the only subscriber.

(1) 704×576 (the 214), idle (no subscriber) and streaming at 30 fps (compression 30) with one subscriber
    (``image_raw/compressed`` + ``camera_info``, what every consumer takes): ``axis_stream`` alone, ``axis_ptz``
    alone (state at 20 Hz), ``axis_camera`` (both in one process), ``axis_stream`` + ``axis_ptz`` as two
    processes of one camera (the stream node then takes ``ptz/state`` over DDS, as in the composed process),
    and ``bench/minimal_pipeline.py``. Targets (issue 26): ``axis_camera`` idle ≤ 1.1× (stream + PTZ alone),
    ``axis_ptz`` ≤ 3 % of a core, streaming ``axis_camera`` ≤ 1.2× (minimal + PTZ), stream node ≤ 1.2× minimal.
(2) 1920×1080 @ 30 fps from the current-Axis persona (``--model q6075 --no-https --auth none``): the same.
(3) four cameras (four simulators, 704×576 @ 15 fps, one subscriber each, ``ptz/state`` watched): all in one
    ``axis_camera --cameras`` process, then four ``axis_camera`` processes. Target (one process): ≤ 40 % of a
    core, every stream ≥ 14.5 fps, every state ≥ 19.5 Hz.
(4) a camera that stops answering (the simulator black-holes every packet, as in a reboot) next to one that
    answers, one ``axis_camera`` each, idle and with a subscriber: the silent one must cost no more.

    .venv/bin/python bench/bench_cpu.py [--seconds 12] [--quick]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # tests.support (the pipelines' subscriber uses it)
import pipelines  # noqa: E402
from pipelines import ROOT, Proc, Recorder, Subscriber, fps_of, wait_until
from report import SIM_CONFIG, inputs, row  # noqa: E402

MODEL_214 = str(ROOT / "config" / "axis214.yaml")  # explicit: no ament index lookup needed
RESULTS: list[tuple[str, bool]] = []


# --------------------------------------------------------------------------------------------------------
# machine load and CPU windows
# --------------------------------------------------------------------------------------------------------
def _machine_busy() -> tuple[float, float]:
    """(busy, total) jiffies of the whole machine from /proc/stat."""
    f = [int(x) for x in Path("/proc/stat").read_text().splitlines()[0].split()[1:]]
    idle = f[3] + f[4]
    return sum(f) - idle, sum(f)


@dataclass
class Window:
    cpu: dict[str, float]  # % of one core per process name
    seconds: float
    machine_busy: float  # % of all cores busy (every process on the machine)
    loadavg: str


def measure(procs: Iterable[Proc], seconds: float) -> Window:
    """CPU of every process over one window (the same wall-clock interval for all)."""
    procs = list(procs)
    b0, t0j = _machine_busy()
    c0 = {p.name: p.cpu_s() for p in procs}
    t0 = time.monotonic()
    time.sleep(seconds)
    c1 = {p.name: p.cpu_s() for p in procs}
    dt = time.monotonic() - t0
    b1, t1j = _machine_busy()
    cpu = {n: 100.0 * (c1[n] - c0[n]) / dt for n in c0}
    load = " ".join(Path("/proc/loadavg").read_text().split()[:3])
    return Window(cpu, dt, 100.0 * (b1 - b0) / max(1, t1j - t0j), load)


def measure_median(procs: Iterable[Proc], seconds: float, n: int = 3) -> Window:
    """``n`` consecutive windows of ``seconds``; each process's figure is its median over them (one window of a
    ~2 % process moved its ratios by ±20 % from run to run: 704×576 idle 1.16× and 1080p idle 0.89× for the same
    code in one run at ae710b6)."""
    procs = list(procs)
    windows = [measure(procs, seconds) for _ in range(n)]
    cpu = {name: statistics.median(w.cpu[name] for w in windows) for name in windows[0].cpu}
    busy = statistics.median(w.machine_busy for w in windows)
    return Window(cpu, sum(w.seconds for w in windows), busy, windows[-1].loadavg)


def say_load(w: Window) -> str:
    return f"machine over the window: {w.machine_busy:.0f} % of {os.cpu_count()} cores busy, load average {w.loadavg}"


def verdict(name: str, ok: bool, detail: str) -> bool:
    RESULTS.append((name, ok))
    print(f"  [{'PASS' if ok else 'FAIL'}] {name}: {detail}", flush=True)
    return ok


# --------------------------------------------------------------------------------------------------------
# processes
# --------------------------------------------------------------------------------------------------------
def start_sim(*extra: str, name: str = "sim") -> tuple[Proc, int]:
    proc = Proc([str(pipelines.BIN / "axis_camera_sim"), "--port", "0", *extra], name)
    port = int(proc.wait_line(r"https?://127\.0\.0\.1:(\d+)/").group(1))
    return proc, port


def ros_args(params: dict[str, object]) -> list[str]:
    out: list[str] = []
    for k, v in params.items():
        out += ["-p", f"{k}:={str(v).lower() if isinstance(v, bool) else v}"]
    return out


def start_exe(exe: str, ns: str, port: int, resolution: str, fps: int, model: str = "", name: str = "") -> Proc:
    params: dict[str, object] = {"port": port}
    if exe in ("axis_stream", "axis_camera"):
        params.update(fps=fps, resolution=resolution, compression=30)
    if model:
        params["camera_model"] = model
    cmd = [str(pipelines.BIN / exe), "--ros-args", "-r", f"__ns:={ns}", *ros_args(params), "--log-level", "warn"]
    return Proc(cmd, name or f"{exe}{ns}")


def start_minimal(port: int, ns: str, resolution: str, fps: int) -> Proc:
    cmd = [sys.executable, str(ROOT / "bench" / "minimal_pipeline.py"), "--port", str(port)]
    cmd += ["--fps", str(fps), "--resolution", resolution, "--ns", ns]
    return Proc(cmd, f"minimal{ns}")


def stop_all(procs: list[Proc]) -> None:
    for p in reversed(procs):
        p.stop()
    procs.clear()


# --------------------------------------------------------------------------------------------------------
# the subscriber side
# --------------------------------------------------------------------------------------------------------
@dataclass
class Watch:
    """Images + camera_info (a Recorder) and ptz/state arrival times of one namespace."""

    rec: Recorder | None = None
    handles: list[object] = field(default_factory=list)
    states: list[float] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def state_hz(self, t0: float, t1: float) -> float:
        with self.lock:
            w = [t for t in self.states if t0 <= t <= t1]
        return (len(w) - 1) / (w[-1] - w[0]) if len(w) > 1 else 0.0


def wait_up(sub: Subscriber, stream_ns: Iterable[str] = (), ptz_ns: Iterable[str] = ()) -> None:
    from std_srvs.srv import Trigger

    from axis_ptz_interfaces.srv import SetVideoParams

    for ns in stream_ns:
        sub.call_ready(f"{ns}/video/set_params", 40.0, srv_type=SetVideoParams)
    for ns in ptz_ns:
        sub.call_ready(f"{ns}/ptz/home", 40.0, srv_type=Trigger)


def watch(sub: Subscriber, ns: str, images: bool = True, state: bool = False) -> Watch:
    from axis_ptz_interfaces.msg import PtzState
    from axis_ptz_ros2.nodes.common import STREAM_QOS

    w = Watch()
    if images:
        w.rec, w.handles = sub.subscribe(ns)
    if state:

        def on_state(_msg: PtzState) -> None:
            t = time.monotonic()
            with w.lock:
                w.states.append(t)

        w.handles.append(sub.node.create_subscription(PtzState, f"{ns}/ptz/state", on_state, STREAM_QOS))
    return w


def unwatch(sub: Subscriber, watches: Iterable[Watch]) -> None:
    for w in watches:
        sub.unsubscribe(w.handles)
        w.handles = []


def wait_frames(watches: dict[str, Watch], n: int = 10, timeout: float = 30.0) -> None:
    for ns, w in watches.items():
        rec = w.rec
        if rec is not None and not wait_until(lambda r=rec: len(r.frames) >= n, timeout):  # type: ignore[misc]
            raise RuntimeError(f"{ns}: no frames within {timeout:.0f} s")


def fps_since(w: Watch, t0: float, t1: float) -> float:
    assert w.rec is not None
    return fps_of([f for f in w.rec.since(t0) if f.t_rx <= t1])


def ratio(a: float, b: float) -> float:
    return a / b if b > 0 else math.inf


# --------------------------------------------------------------------------------------------------------
# sections
# --------------------------------------------------------------------------------------------------------
@dataclass
class Composition:
    idle: Window
    streaming: Window
    fps: dict[str, float]


def composition_both_orders(
    sub: Subscriber, label: str, sim_args: list[str], resolution: str, model: str, secs: float
) -> Composition:
    """:func:`composition` with the processes started in one order, then in the reverse one; every figure is the
    mean of the two. Identical pipelines side by side do not cost the same: the one started first cost 6-16 %
    more (cpu_compare.measure_cpu_both_orders), a bias the size of the targets' margins."""
    a = composition(sub, label, sim_args, resolution, model, secs, reverse=False)
    b = composition(sub, label, sim_args, resolution, model, secs, reverse=True)

    def mean(x: Window, y: Window) -> Window:
        cpu = {n: (x.cpu[n] + y.cpu[n]) / 2.0 for n in x.cpu}
        return Window(cpu, x.seconds + y.seconds, (x.machine_busy + y.machine_busy) / 2.0, y.loadavg)

    fps = {ns: (a.fps[ns] + b.fps[ns]) / 2.0 for ns in a.fps}
    return Composition(mean(a.idle, b.idle), mean(a.streaming, b.streaming), fps)


def composition(
    sub: Subscriber, label: str, sim_args: list[str], resolution: str, model: str, secs: float, reverse: bool = False
) -> Composition:
    """Section (1)/(2): every arrangement of one camera's driver, idle then streaming, side by side (started in
    the order listed, or ``reverse``)."""
    procs: list[Proc] = []
    try:
        sim, port = start_sim(*sim_args, name=f"sim {label}")
        procs.append(sim)
        print(f"simulator ({label}) on port {port}; processes started {'last to first' if reverse else 'in order'}",
              flush=True)  # fmt: skip
        starters: list[Callable[[], Proc]] = [
            lambda: start_exe("axis_stream", "/alone_s", port, resolution, 30, model, "axis_stream"),
            lambda: start_exe("axis_ptz", "/alone_p", port, resolution, 30, model, "axis_ptz"),
            lambda: start_exe("axis_camera", "/cam", port, resolution, 30, model, "axis_camera"),
            lambda: start_exe("axis_stream", "/pair", port, resolution, 30, model, "pair: axis_stream"),
            lambda: start_exe("axis_ptz", "/pair", port, resolution, 30, model, "pair: axis_ptz"),
            lambda: start_minimal(port, "/minimal", resolution, 30),
        ]
        procs += [start() for start in (reversed(starters) if reverse else starters)]
        wait_up(sub, ("/alone_s", "/cam", "/pair"), ("/alone_p", "/cam", "/pair"))
        measured = [p for p in procs if p is not sim]
        time.sleep(3.0)  # start-up work done (camera discovery, DDS discovery)
        idle = measure_median(measured, secs)
        watches = {ns: watch(sub, ns) for ns in ("/alone_s", "/cam", "/pair", "/minimal")}
        try:
            wait_frames(watches)
            time.sleep(2.0)
            t0 = time.monotonic()
            streaming = measure_median(measured, secs)
            t1 = time.monotonic()
            fps = {ns: fps_since(w, t0, t1) for ns, w in watches.items()}
        finally:
            unwatch(sub, watches.values())
        return Composition(idle, streaming, fps)
    finally:
        stop_all(procs)


def report_composition(label: str, c: Composition, size: str) -> tuple[bool, bool, bool, bool]:
    i, s = c.idle.cpu, c.streaming.cpu
    print(f"  {'process':<20} | idle (no subscriber) | streaming {size} @ 30, one subscriber | fps received")
    fps_of_name = {"axis_stream": "/alone_s", "axis_camera": "/cam", "pair: axis_stream": "/pair"}
    for name in ("axis_stream", "axis_ptz", "axis_camera", "pair: axis_stream", "pair: axis_ptz", "minimal/minimal"):
        ns = fps_of_name.get(name, "/minimal" if name.startswith("minimal") else "")
        f = f"{c.fps[ns]:.1f}" if ns in c.fps else ""
        print(f"  {name:<20} | {i[name]:17.2f} %  | {s[name]:33.2f} %  | {f}")
    pair_i = i["pair: axis_stream"] + i["pair: axis_ptz"]
    pair_s = s["pair: axis_stream"] + s["pair: axis_ptz"]
    print(f"  {'pair (sum)':<20} | {pair_i:17.2f} %  | {pair_s:33.2f} %  |")
    print(f"  idle:      {say_load(c.idle)}")
    print(f"  streaming: {say_load(c.streaming)}")
    parts_i = i["axis_stream"] + i["axis_ptz"]
    r_idle = ratio(i["axis_camera"], parts_i)
    base_s = s["minimal/minimal"] + s["axis_ptz"]
    r_cam_s = ratio(s["axis_camera"], base_s)
    r_stream = ratio(s["axis_stream"], s["minimal/minimal"])
    ok_idle = verdict(
        f"{label}: axis_camera idle <= 1.1x (axis_stream + axis_ptz alone)",
        r_idle <= 1.1,
        f"{i['axis_camera']:.2f} vs {i['axis_stream']:.2f} + {i['axis_ptz']:.2f} % = {r_idle:.2f}x "
        f"(two processes of one camera: {pair_i:.2f} %)",
    )
    ok_ptz = verdict(
        f"{label}: axis_ptz at 20 Hz <= 3 % of a core", i["axis_ptz"] <= 3.0, f"{i['axis_ptz']:.2f} % (idle window)"
    )
    ok_cam = verdict(
        f"{label}: axis_camera streaming <= 1.2x (minimal + axis_ptz)",
        r_cam_s <= 1.2,
        f"{s['axis_camera']:.2f} vs {s['minimal/minimal']:.2f} + {s['axis_ptz']:.2f} % = {r_cam_s:.2f}x "
        f"(two processes of one camera: {pair_s:.2f} %)",
    )
    ok_stream = verdict(
        f"{label}: axis_stream streaming <= 1.2x minimal",
        r_stream <= 1.2,
        f"{s['axis_stream']:.2f} vs {s['minimal/minimal']:.2f} % = {r_stream:.2f}x",
    )
    for ns, f in c.fps.items():
        if f < 29.0:
            print(f"  note: {ns} delivered only {f:.1f} fps (loaded machine?)")
    return ok_idle, ok_ptz, ok_cam, ok_stream


@dataclass
class Fleet:
    one: Window
    several: Window
    fps_one: list[float]
    hz_one: list[float]
    fps_several: list[float]
    hz_several: list[float]


def fleet(sub: Subscriber, secs: float, n: int = 4) -> Fleet:
    """Section (3): n cameras in one process, then in n processes (same simulators)."""
    sims: list[Proc] = []
    procs: list[Proc] = []
    try:
        ports = []
        for k in range(n):
            s, p = start_sim(name=f"sim{k + 1}")
            sims.append(s)
            ports.append(p)
        names = [f"/robot{k + 1}" for k in range(n)]
        params = Path(tempfile.mkdtemp(prefix="bench_cpu_")) / "cameras.yaml"
        lines = ["/**:", "  ros__parameters:", "    fps: 15", "    resolution: 704x576", "    compression: 30",
                 f"    camera_model: {MODEL_214}"]  # fmt: skip
        for ns, port in zip(names, ports, strict=True):
            for node in ("axis_stream", "axis_ptz"):
                lines += [f"{ns}/{node}:", "  ros__parameters:", f"    port: {port}"]
        params.write_text("\n".join(lines) + "\n", encoding="utf-8")
        results: list[tuple[Window, list[float], list[float]]] = []
        for arrangement in ("one", "several"):
            if arrangement == "one":
                cmd = [str(pipelines.BIN / "axis_camera"), "--cameras", ",".join(names), "--ros-args",
                       "--params-file", str(params), "--log-level", "warn"]  # fmt: skip
                procs.append(Proc(cmd, f"axis_camera --cameras ({n})"))
            else:
                for ns, port in zip(names, ports, strict=True):
                    procs.append(start_exe("axis_camera", ns, port, "704x576", 15, MODEL_214, f"axis_camera{ns}"))
            wait_up(sub, names, names)
            watches = {ns: watch(sub, ns, images=True, state=True) for ns in names}
            try:
                wait_frames(watches)
                time.sleep(2.0)
                t0 = time.monotonic()
                w = measure(procs, secs)
                t1 = time.monotonic()
                fps = [fps_since(watches[ns], t0, t1) for ns in names]
                hz = [watches[ns].state_hz(t0, t1) for ns in names]
            finally:
                unwatch(sub, watches.values())
            results.append((w, fps, hz))
            stop_all(procs)
        (one, fps1, hz1), (several, fps4, hz4) = results
        return Fleet(one, several, fps1, hz1, fps4, hz4)
    finally:
        stop_all(procs)
        stop_all(sims)


@dataclass
class Silent:
    idle: Window
    streaming: Window
    fps_up: float


def silent_camera(sub: Subscriber, secs: float) -> Silent:
    """Section (4): one axis_camera per simulator; one simulator black-holes everything for the windows."""
    procs: list[Proc] = []
    try:
        s_up, p_up = start_sim(name="sim up")
        s_down, p_down = start_sim(name="sim down")
        procs += [s_up, s_down]
        up = start_exe("axis_camera", "/up", p_up, "704x576", 30, MODEL_214, "axis_camera answering")
        down = start_exe("axis_camera", "/down", p_down, "704x576", 30, MODEL_214, "axis_camera silent")
        procs += [up, down]
        wait_up(sub, ("/up", "/down"), ("/up", "/down"))
        time.sleep(2.0)
        import httpx

        blackhole = 2 * secs + 25.0
        httpx.get(
            f"http://127.0.0.1:{p_down}/sim/control?reboot={blackhole}&reboot_blackhole=1",
            timeout=5.0,
            trust_env=False,
        )
        time.sleep(4.0)  # the nodes notice, back off to their steady retry pace
        idle = measure((up, down), secs)
        watches = {ns: watch(sub, ns) for ns in ("/up", "/down")}
        try:
            wait_frames({"/up": watches["/up"]})
            time.sleep(2.0)
            t0 = time.monotonic()
            streaming = measure((up, down), secs)
            t1 = time.monotonic()
            fps_up = fps_since(watches["/up"], t0, t1)
            rec_down = watches["/down"].rec
            assert rec_down is not None
            if rec_down.frames:
                print("  note: the silent camera delivered frames (the black hole ended early?)")
        finally:
            unwatch(sub, watches.values())
        return Silent(idle, streaming, fps_up)
    finally:
        stop_all(procs)


# --------------------------------------------------------------------------------------------------------
def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=12.0, help="CPU window per measurement")
    ap.add_argument("--quick", action="store_true", help="6 s windows (noisier)")
    ap.add_argument("--only", default="", help="comma-separated sections to run: 704,1080,fleet,silent")
    ap.add_argument("--bin", default="", help="run the executables of another checkout's .venv/bin (A/B)")
    args = ap.parse_args()
    if args.bin:
        pipelines.BIN = Path(args.bin).resolve()
        print(f"executables from {pipelines.BIN}")
    secs = 6.0 if args.quick else args.seconds
    only = {s.strip() for s in args.only.split(",") if s.strip()} or {"704", "1080", "fleet", "silent"}
    inputs(
        "axis_ptz_ros2/axis_ptz_ros2/nodes/common.py",
        "axis_ptz_ros2/axis_ptz_ros2/nodes/runner.py",
        "axis_ptz_ros2/axis_ptz_ros2/nodes/camera_main.py",
        "axis_ptz_ros2/axis_ptz_ros2/nodes/stream_node.py",
        "axis_ptz_ros2/axis_ptz_ros2/nodes/ptz_node.py",
        "axis_ptz_ros2/axis_ptz_ros2/streaming",
        "axis_ptz_ros2/axis_ptz_ros2/ptz",
        "axis_ptz_ros2/axis_ptz_ros2/vapix",
        "axis_ptz_ros2/axis_ptz_ros2/sim",
        *SIM_CONFIG,
        "bench/bench_cpu.py",
        "bench/pipelines.py",
        "bench/minimal_pipeline.py",
    )
    print(
        f"{os.cpu_count()} cores, load average at start {' '.join(Path('/proc/loadavg').read_text().split()[:3])}; "
        f"windows of {secs:g} s; ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID')}. Per-process CPU time is what is "
        "compared: every process of a table is measured over the same window.",
        flush=True,
    )
    sub = Subscriber()
    try:
        if "704" in only:
            print("\n== (1) 704x576 (Axis 214 persona): idle, and streaming 30 fps to one subscriber", flush=True)
            c = composition_both_orders(sub, "704x576", [], "704x576", MODEL_214, secs)
            ok_i, ok_p, ok_c, ok_s = report_composition("704x576", c, "704x576")
            i, s = c.idle.cpu, c.streaming.cpu
            pair_i = i["pair: axis_stream"] + i["pair: axis_ptz"]
            row(
                "composed `axis_camera` vs its nodes alone, idle (no subscriber, state polled at 20 Hz); the same two "
                "nodes as two processes (the stream node then takes `ptz/state` over DDS, as when composed)",
                f"{i['axis_camera']:.1f} % vs {i['axis_stream']:.1f} + {i['axis_ptz']:.1f} % of a core "
                f"({ratio(i['axis_camera'], i['axis_stream'] + i['axis_ptz']):.2f}×); two processes {pair_i:.1f} %",
                "≤ 1.1×",
                ok_i,
            )
            row("`axis_ptz` alone, state polled at 20 Hz", f"{i['axis_ptz']:.1f} % of a core", "≤ 3 %", ok_p)
            base = s["minimal/minimal"] + s["axis_ptz"]
            row(
                "composed `axis_camera` streaming 704×576 @ 30 fps to one subscriber vs minimal pipeline + `axis_ptz`",
                f"{s['axis_camera']:.1f} % vs {s['minimal/minimal']:.1f} + {s['axis_ptz']:.1f} % "
                f"({ratio(s['axis_camera'], base):.2f}×); `axis_stream` {s['axis_stream']:.1f} % "
                f"({ratio(s['axis_stream'], s['minimal/minimal']):.2f}× minimal)",
                "≤ 1.2× / ≤ 1.2×",
                ok_c and ok_s,
            )
        if "1080" in only:
            print("\n== (2) 1920x1080 (current-Axis persona, plain HTTP): idle, and streaming 30 fps", flush=True)
            sim_args = ["--model", "q6075", "--no-https", "--auth", "none"]
            c = composition_both_orders(sub, "1920x1080", sim_args, "1920x1080", "", secs)
            _, _, ok_c, ok_s = report_composition("1920x1080", c, "1920x1080")
            s = c.streaming.cpu
            base = s["minimal/minimal"] + s["axis_ptz"]
            row(
                "composed `axis_camera` streaming 1920×1080 @ 30 fps vs minimal pipeline + `axis_ptz`",
                f"{s['axis_camera']:.1f} % vs {s['minimal/minimal']:.1f} + {s['axis_ptz']:.1f} % "
                f"({ratio(s['axis_camera'], base):.2f}×); `axis_stream` {s['axis_stream']:.1f} % "
                f"({ratio(s['axis_stream'], s['minimal/minimal']):.2f}× minimal)",
                "≤ 1.2× / ≤ 1.2×",
                ok_c and ok_s,
            )
        if "fleet" in only:
            print("\n== (3) four cameras, 704x576 @ 15 fps, one subscriber each, ptz/state watched", flush=True)
            f = fleet(sub, secs)
            one = sum(f.one.cpu.values())
            several = sum(f.several.cpu.values())
            print(f"  one process:   {one:.1f} % of a core; fps " + ", ".join(f"{x:.1f}" for x in f.fps_one)
                  + "; state Hz " + ", ".join(f"{x:.1f}" for x in f.hz_one))  # fmt: skip
            print(f"    {say_load(f.one)}")
            print(
                f"  four processes: {several:.1f} % of a core ("
                + ", ".join(f"{v:.1f}" for v in f.several.cpu.values())
                + "); fps "
                + ", ".join(f"{x:.1f}" for x in f.fps_several)
                + "; state Hz "
                + ", ".join(f"{x:.1f}" for x in f.hz_several)
            )
            print(f"    {say_load(f.several)}")
            ok = verdict(
                "four cameras in one process: <= 40 % of a core, every stream >= 14.5 fps, every state >= 19.5 Hz",
                one <= 40.0 and min(f.fps_one) >= 14.5 and min(f.hz_one) >= 19.5,
                f"{one:.1f} %, fps >= {min(f.fps_one):.1f}, state >= {min(f.hz_one):.1f} Hz",
            )
            row(
                "four cameras (704×576 @ 15 fps, one subscriber each): one `axis_camera --cameras` process / four "
                "`axis_camera` processes; slowest stream, slowest state",
                f"{one:.1f} % / {several:.1f} % of a core; {min(f.fps_one):.1f} fps, {min(f.hz_one):.1f} Hz / "
                f"{min(f.fps_several):.1f} fps, {min(f.hz_several):.1f} Hz",
                "one process ≤ 40 %, ≥ 14.5 fps, ≥ 19.5 Hz",
                ok,
            )
        if "silent" in only:
            print("\n== (4) a camera that stops answering (black hole) next to one that answers", flush=True)
            sc = silent_camera(sub, secs)
            ui, di = sc.idle.cpu["axis_camera answering"], sc.idle.cpu["axis_camera silent"]
            us, ds = sc.streaming.cpu["axis_camera answering"], sc.streaming.cpu["axis_camera silent"]
            print(f"  idle:      answering {ui:.2f} %, silent {di:.2f} %   ({say_load(sc.idle)})")
            print(
                f"  subscribed: answering {us:.2f} % ({sc.fps_up:.1f} fps), silent {ds:.2f} %   "
                f"({say_load(sc.streaming)})"
            )
            ok = verdict(
                "a silent camera costs no more than an answering one (idle and subscribed)",
                di <= ui * 1.05 + 0.1 and ds <= us * 1.05 + 0.1,
                f"idle {di:.2f} vs {ui:.2f} %, subscribed {ds:.2f} vs {us:.2f} %",
            )
            row(
                "`axis_camera` whose camera stops answering vs one whose camera answers, idle / subscribed",
                f"{di:.1f} vs {ui:.1f} % / {ds:.1f} vs {us:.1f} % of a core",
                "no more",
                ok,
            )
    finally:
        sub.close()
    print("\n== summary")
    for name, ok in RESULTS:
        print(f"  {'PASS' if ok else 'FAIL'}  {name}")
    return 0 if all(ok for _, ok in RESULTS) else 1


if __name__ == "__main__":
    sys.exit(main())
