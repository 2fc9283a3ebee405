"""Benchmark: the stream node at 1920x1080 @ 30 fps on the modern simulated camera (``--model q6075``), next to
``bench/minimal_pipeline.py`` at the same size, and the simulator's own cost for that stream.

(a) latency simulator send -> subscriber (JPEG COM stamp), median and p99, and CPU (% of one core) of
    ``axis_stream`` and of the minimal pipeline, each streaming 1920x1080 @ 30 fps, compression 30, to this
    process (subscribed to the image and camera_info). Both over plain HTTP without authentication (the
    simulator runs with ``--no-https --auth none``), so both do the same work; targets: latency <= 1.1x,
    CPU <= 1.2x the minimal pipeline's. For information: ``axis_stream`` over the camera's default
    HTTPS + Digest (its certificate as CA), which the minimal pipeline cannot speak.
(b) the simulator process's CPU and delivered frame rate for that stream with the head still, and while it pans
    continuously (every frame a new view: render + JPEG-encode 1920x1080); the in-process cost of one new
    1080p view (render, encode) for reference.

    .venv/bin/python bench/bench_stream_1080p.py [--seconds 10]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

from bench_stream import measure_load  # bench/bench_stream.py: the same load measurement
from cpu_compare import SHARED_WINDOWS, measure_cpu_both_orders
from pipelines import BIN, ROOT, Proc, Subscriber, fps_of, subscribed, wait_until
from report import SIM_CONFIG, inputs, row

SIZE = "1920x1080"


def start_sim(*extra: str) -> tuple[Proc, int, str]:
    proc = Proc([str(BIN / "axis_camera_sim"), "--model", "q6075", "--port", "0", *extra], "sim(q6075)")
    m = proc.wait_line(r"at (https?)://127\.0\.0\.1:(\d+)/ \(auth=\w+(?:; CA certificate ([^;)]+))?[;)]")
    return proc, int(m.group(2)), m.group(3) or ""


def start_ours(port: int, ns: str, **params: object) -> Proc:
    values = {"port": port, "fps": 30, "resolution": SIZE, "compression": 30, **params}
    args = [str(BIN / "axis_stream"), "--ros-args", "-r", f"__ns:={ns}"]
    for k, v in values.items():
        args += ["-p", f"{k}:={str(v).lower() if isinstance(v, bool) else v}"]
    return Proc(args, f"axis_stream{ns}")


def start_minimal(port: int) -> Proc:
    cmd = [sys.executable, str(ROOT / "bench" / "minimal_pipeline.py"), "--port", str(port), "--resolution", SIZE]
    return Proc(cmd + ["--fps", "30"], "minimal")


def ptz(port: int, query: str) -> None:
    import httpx

    httpx.get(f"http://127.0.0.1:{port}/axis-cgi/com/ptz.cgi?{query}", timeout=5.0, trust_env=False)


def render_cost(n: int = 20) -> tuple[float, float]:
    """Median CPU ms (all threads of this process) of one new 1080p view (render) and of its JPEG encode
    (compression 30); CPU time, not wall time, so a busy machine does not inflate it."""
    from axis_ptz_ros2.sim.camera import SimulatedCamera
    from axis_ptz_ros2.sim.renderer import encode_jpeg

    cam = SimulatedCamera(model="q6075", https=False)
    r = cam.renderer
    r.render(0.0, -5.0, 1.0, 1920, 1080)  # warm-up (scene built)
    rt, et = [], []
    for i in range(n):
        t0 = time.process_time()
        img = r.render(0.5 * (i + 1), -5.0, 1.0, 1920, 1080)  # a new pose each time: no cache hit
        t1 = time.process_time()
        encode_jpeg(img, 30)
        t2 = time.process_time()
        rt.append(1e3 * (t1 - t0))
        et.append(1e3 * (t2 - t1))
    return statistics.median(rt), statistics.median(et)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="measurement window per figure")
    args = ap.parse_args()
    window = args.seconds
    inputs(
        "axis_ptz_ros2/axis_ptz_ros2/streaming",
        "axis_ptz_ros2/axis_ptz_ros2/nodes/stream_node.py",
        "axis_ptz_ros2/axis_ptz_ros2/nodes/common.py",
        "axis_ptz_ros2/axis_ptz_ros2/nodes/runner.py",
        "axis_ptz_ros2/axis_ptz_ros2/camera_models.py",
        "axis_ptz_ros2/axis_ptz_ros2/vapix",
        "axis_ptz_ros2/axis_ptz_ros2/sim",
        *SIM_CONFIG,
        "bench/bench_stream_1080p.py",
        "bench/bench_stream.py",
        "bench/pipelines.py",
        "bench/cpu_compare.py",
        "bench/minimal_pipeline.py",
    )
    ok_all = True
    sub = Subscriber()
    procs: list[Proc] = []
    try:
        sim, port, _ = start_sim("--no-https", "--auth", "none")
        procs.append(sim)
        print(f"simulator (q6075, plain HTTP, anonymous) on port {port}; ROS_DOMAIN_ID={os.environ['ROS_DOMAIN_ID']}")

        print(f"\n== (a) {SIZE} @ 30 fps, compression 30: latency sim->subscriber, CPU", flush=True)
        ours = start_ours(port, "/ours")
        procs.append(ours)
        sub.call_ready("/ours/video/set_params")
        load_ours = measure_load(sub, ours, "/ours", window)
        mini = start_minimal(port)
        procs.append(mini)
        load_min = measure_load(sub, mini, "/minimal", window)
        ours.stop()
        mini.stop()
        sim_b, port_b, _ = start_sim("--no-https", "--auth", "none")  # the minimal pipeline's own simulator
        procs.append(sim_b)
        comparison = measure_cpu_both_orders(
            sub, lambda: start_ours(port, "/ours"), lambda: start_minimal(port_b), window
        )
        sim_b.stop()
        print("  pipeline    | frames | fps  | latency median | p99      | CPU %core | RSS MB")
        for name, ld in (("axis_stream", load_ours), ("minimal", load_min)):
            print(
                f"  {name:<11} | {ld.frames:>6} | {ld.fps:4.1f} | {ld.lat_med:10.2f} ms "
                f" | {ld.lat_p99:6.2f} ms | {ld.cpu:9.1f} | {ld.rss:6.1f}"
            )
        lat_ok = load_ours.lat_med <= 1.1 * load_min.lat_med
        print(
            "  CPU side by side (a simulator each, both streaming to a subscriber, the same windows): "
            + comparison.describe()
        )
        (cpu_ours, cpu_min), cpu_ratio = comparison.cpu, comparison.ratio
        cpu_ok = cpu_ratio <= 1.2
        ok_all &= lat_ok and cpu_ok
        print(f"  [{'PASS' if lat_ok else 'FAIL'}] latency median <= 1.1x minimal")
        print(
            f"  [{'PASS' if cpu_ok else 'FAIL'}] CPU <= 1.2x minimal: {cpu_ours:.2f} vs {cpu_min:.2f} % = "
            f"{cpu_ratio:.2f}x (geometric mean of both start orders' medians)"
        )
        row(
            "stream latency, 1920×1080 @ 30 fps (modern camera persona), median / p99",
            f"{load_ours.lat_med:.2f} / {load_ours.lat_p99:.2f} ms (minimal pipeline "
            f"{load_min.lat_med:.2f} / {load_min.lat_p99:.2f})",
            "≤ 1.1× minimal",
            lat_ok,
        )
        row(
            "stream node CPU, 1920×1080 @ 30 fps",
            f"{cpu_ours:.1f} % of a core (minimal {cpu_min:.1f} %; {cpu_ratio:.2f}×, both start orders, "
            f"{SHARED_WINDOWS})",
            "≤ 1.2× minimal",
            cpu_ok,
        )
        sim.stop()

        # the camera's default: HTTPS with its self-signed certificate as CA, Digest
        sim_tls, port_tls, ca = start_sim()
        procs.append(sim_tls)
        cred = Path(tempfile.mkdtemp(prefix="bench1080_")) / "camera.cred"
        cred.touch(mode=0o600)
        cred.write_text(f"root:{os.environ.get('AXIS_SIM_PASSWORD', 'pass')}\n", encoding="utf-8")
        tls = start_ours(port_tls, "/tls", use_https=True, verify_tls=True, ca_file=ca, password_file=str(cred))
        procs.append(tls)
        sub.call_ready("/tls/video/set_params")
        load_tls = measure_load(sub, tls, "/tls", window)
        tls.stop()
        sim_tls.stop()
        print(
            f"  axis_stream over HTTPS + Digest (certificate checked): {load_tls.fps:.1f} fps, latency "
            f"{load_tls.lat_med:.2f} / {load_tls.lat_p99:.2f} ms, CPU {load_tls.cpu:.1f} % of a core"
        )
        row(
            "same over the camera's default HTTPS + Digest (certificate checked), latency median / CPU",
            f"{load_tls.lat_med:.2f} ms / {load_tls.cpu:.1f} % of a core",
        )

        print(f"\n== (b) simulator cost for one {SIZE} @ 30 fps stream (axis_stream subscribed)", flush=True)
        sim2, port2, _ = start_sim("--no-https", "--auth", "none")
        procs.append(sim2)
        ours2 = start_ours(port2, "/sim")
        procs.append(ours2)
        sub.call_ready("/sim/video/set_params")
        with subscribed(sub, "/sim") as rec:
            wait_until(lambda: len(rec.frames) >= 10, 15.0)
            time.sleep(1.0)
            t0 = time.monotonic()
            cpu_still = sim2.cpu_percent(window)
            fps_still = fps_of(rec.since(t0))
            ptz(port2, "continuouspantiltmove=10,0")  # 10 % of 450 deg/s: every frame a new view
            time.sleep(1.0)
            t1 = time.monotonic()
            cpu_pan = sim2.cpu_percent(window)
            fps_pan = fps_of(rec.since(t1))
            ptz(port2, "continuouspantiltmove=0,0")
        render_ms, encode_ms = render_cost()
        print(f"  still:   {fps_still:.1f} fps delivered, simulator {cpu_still:.1f} % of a core")
        print(f"  panning: {fps_pan:.1f} fps delivered, simulator {cpu_pan:.1f} % of a core")
        print(f"  one new 1080p view in-process: render {render_ms:.1f} + JPEG encode {encode_ms:.1f} ms CPU (median)")
        row(
            "simulator, 1920×1080 @ 30 fps (modern persona), still / panning camera",
            f"{fps_still:.1f} fps at {cpu_still:.1f} % / {fps_pan:.1f} fps at {cpu_pan:.1f} % of a core; "
            f"new view {render_ms:.1f} + {encode_ms:.1f} ms CPU (render + encode)",
        )
    finally:
        for p in reversed(procs):
            p.stop()
        sub.close()
    print("\nall targets met" if ok_all else "\nSOME TARGETS MISSED")
    return 0 if ok_all else 1


if __name__ == "__main__":
    sys.exit(main())
