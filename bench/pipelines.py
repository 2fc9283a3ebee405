"""The processes and the subscriber of the stream benches (``bench_stream``, ``bench_stream_1080p``, ``bench_cpu``,
``bench_h264_loopback``, ``bench_soak``): the simulated camera, ``axis_stream`` and ``bench/minimal_pipeline.py`` as
subprocesses with their CPU (the scheduler's per-thread run time) and RSS, and a ROS subscriber in this process that
records each frame's latency from the simulator's JPEG stamp.

    .venv/bin/python bench/pipelines.py --sim-child   # a simulator that streams as fast as it can (fps forced to 0)
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests.support (the subscriber reads sim stamps)
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.pop("ROS_LOCALHOST_ONLY", None)
os.environ.setdefault("ROS_DOMAIN_ID", str(150 + os.getpid() % 50))

ROOT = Path(__file__).resolve().parent.parent
BIN = Path(sys.executable).parent
CLK = os.sysconf("SC_CLK_TCK")


def process_cpu_s(pid: int) -> float:
    """CPU time of a process's live threads in seconds, from the scheduler's own accounting
    (``/proc/<pid>/task/<tid>/schedstat``, nanoseconds). ``utime + stime`` from ``/proc/<pid>/stat`` count in
    ticks (10 ms): a 10 s window of a process at 3 % of a core then reads 3.0 ± 0.1 %, which alone moved the
    judged ratio of two such processes by up to ±7 %. Falls back to ``/proc/<pid>/stat`` without schedstat."""
    total_ns = 0
    try:
        tasks = os.listdir(f"/proc/{pid}/task")
    except FileNotFoundError:
        return 0.0
    for tid in tasks:
        try:
            total_ns += int(Path(f"/proc/{pid}/task/{tid}/schedstat").read_text().split()[0])
        except FileNotFoundError:  # the thread ended meanwhile
            continue
        except (OSError, ValueError, IndexError):
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
            return (int(fields[11]) + int(fields[12])) / CLK  # utime, stime (all threads)
    return total_ns / 1e9


# --------------------------------------------------------------------------------------------------------
# simulator child with fps forced to 0 (ingest ceiling)
# --------------------------------------------------------------------------------------------------------
def sim_child() -> int:
    """Run a simulator whose video handler streams as fast as possible whatever fps= the client asks."""
    import dataclasses

    from stopping import wait_for_stop  # bench/stopping.py (bench/ is on sys.path)

    from axis_ptz_ros2.sim.camera import SimulatedCamera
    from axis_ptz_ros2.sim.http import mjpeg

    original = mjpeg.image_args

    def unlimited(cam, args, video):  # noqa: ANN001, ANN202 - bench-only shim of the stream's argument check
        req = original(cam, args, video)
        return dataclasses.replace(req, fps=0) if video else req

    mjpeg.image_args = unlimited
    cam = SimulatedCamera(port=0).start()
    print(f"Simulated AXIS 214 PTZ at {cam.base_url}/ (fps forced to 0)", flush=True)
    wait_for_stop()
    cam.stop()
    return 0


# --------------------------------------------------------------------------------------------------------
# processes
# --------------------------------------------------------------------------------------------------------
class Proc:
    def __init__(self, cmd: list[str], name: str) -> None:
        self.name = name
        self.p = subprocess.Popen(
            cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT, start_new_session=True
        )
        self.lines: list[str] = []
        threading.Thread(target=self._drain, daemon=True).start()

    def _drain(self) -> None:
        assert self.p.stdout is not None
        for line in self.p.stdout:
            self.lines.append(line.rstrip())

    def wait_line(self, pattern: str, timeout: float = 20.0) -> re.Match[str]:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for line in list(self.lines):
                m = re.search(pattern, line)
                if m:
                    return m
            if self.p.poll() is not None:
                break
            time.sleep(0.05)
        raise RuntimeError(f"{self.name}: no line matching {pattern!r}; output: {self.lines[-10:]}")

    def cpu_s(self) -> float:
        return process_cpu_s(self.p.pid)

    def rss_mb(self) -> float:
        for line in Path(f"/proc/{self.p.pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
        return float("nan")

    def cpu_percent(self, seconds: float) -> float:
        c0, t0 = self.cpu_s(), time.monotonic()
        time.sleep(seconds)
        return 100.0 * (self.cpu_s() - c0) / (time.monotonic() - t0)

    def interrupt(self, timeout: float = 10.0) -> float:
        """SIGINT (Ctrl-C); seconds until the process exited."""
        t0 = time.monotonic()
        self.p.send_signal(signal.SIGINT)
        try:
            self.p.wait(timeout)
        except subprocess.TimeoutExpired:
            self.p.kill()
            self.p.wait()
            return float("inf")
        return time.monotonic() - t0

    def stop(self) -> None:
        if self.p.poll() is None:
            self.p.send_signal(signal.SIGINT)
            try:
                self.p.wait(5)
            except subprocess.TimeoutExpired:
                self.p.kill()
                self.p.wait()


def start_sim(force_fps0: bool = False) -> tuple[Proc, int]:
    if force_fps0:
        proc = Proc([sys.executable, str(Path(__file__).resolve()), "--sim-child"], "sim(fps=0)")
    else:
        proc = Proc([str(BIN / "axis_camera_sim"), "--port", "0"], "sim")
    port = int(proc.wait_line(r"http://127\.0\.0\.1:(\d+)/").group(1))
    return proc, port


def start_ours(port: int, **params: object) -> Proc:
    values = {
        "port": port,
        "fps": 30,
        "resolution": "704x576",
        "compression": 30,
        "camera_model": str(ROOT / "config" / "axis214.yaml"),  # explicit: no ament index lookup needed
        **params,
    }
    args = [str(BIN / "axis_stream"), "--ros-args", "-r", "__ns:=/ours"]
    for k, v in values.items():
        args += ["-p", f"{k}:={str(v).lower() if isinstance(v, bool) else v}"]
    return Proc(args, "axis_stream")


def start_minimal(port: int, fps: int = 30, skip_unsubscribed: bool = False) -> Proc:
    cmd = [sys.executable, str(ROOT / "bench" / "minimal_pipeline.py"), "--port", str(port), "--fps", str(fps)]
    return Proc(cmd + (["--skip-unsubscribed"] if skip_unsubscribed else []), "minimal")


def sim_get(port: int, path: str) -> dict:
    import httpx

    return httpx.get(f"http://127.0.0.1:{port}{path}", timeout=5.0, trust_env=False).json()


# --------------------------------------------------------------------------------------------------------
# subscriber
# --------------------------------------------------------------------------------------------------------
@dataclass
class Rx:
    t_rx: float  # monotonic
    latency_ms: float
    seq: int
    nbytes: int
    size: tuple[int, int] | None


@dataclass
class Recorder:
    frames: list[Rx] = field(default_factory=list)
    infos: list[float] = field(default_factory=list)  # monotonic receive times of camera_info
    lock: threading.Lock = field(default_factory=threading.Lock)

    def since(self, t: float) -> list[Rx]:
        with self.lock:
            return [f for f in self.frames if f.t_rx >= t]

    def last(self) -> Rx | None:
        with self.lock:
            return self.frames[-1] if self.frames else None


class Subscriber:
    def __init__(self) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        rclpy.init()
        self.node = rclpy.create_node("bench_stream_probe")
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def subscribe(self, ns: str) -> tuple[Recorder, list[object]]:
        """Subscribe to ``<ns>/image_raw/compressed`` and ``<ns>/camera_info`` (what every consumer takes)."""
        from sensor_msgs.msg import CameraInfo, CompressedImage

        from axis_ptz_ros2.nodes.common import STREAM_QOS
        from axis_ptz_ros2.streaming import jpeg_size
        from tests.support.stamps import sim_stamp

        rec = Recorder()

        def on_image(msg: CompressedImage) -> None:
            now_ns = time.time_ns()
            t = time.monotonic()
            view = memoryview(msg.data)
            st = sim_stamp(view) or (-1, now_ns)
            f = Rx(t, (now_ns - st[1]) / 1e6, st[0], len(view), jpeg_size(view))
            with rec.lock:
                rec.frames.append(f)

        def on_info(msg: CameraInfo) -> None:
            t = time.monotonic()
            with rec.lock:
                rec.infos.append(t)

        subs = [
            self.node.create_subscription(CompressedImage, f"{ns}/image_raw/compressed", on_image, STREAM_QOS),
            self.node.create_subscription(CameraInfo, f"{ns}/camera_info", on_info, STREAM_QOS),
        ]
        return rec, subs

    def unsubscribe(self, subs: list[object]) -> None:
        for s in subs:
            self.node.destroy_subscription(s)

    def call(self, srv_type: type, name: str, request: object, timeout: float = 10.0) -> object:
        client = self.node.create_client(srv_type, name)
        try:
            if not client.wait_for_service(timeout_sec=timeout):
                raise RuntimeError(f"service {name} not available")
            fut = client.call_async(request)
            deadline = time.monotonic() + timeout
            while not fut.done() and time.monotonic() < deadline:
                time.sleep(0.005)
            if not fut.done():
                raise RuntimeError(f"service {name} timed out")
            return fut.result()
        finally:
            self.node.destroy_client(client)

    def call_ready(self, name: str, timeout: float = 15.0, *, srv_type: type | None = None) -> None:
        """Wait until the service ``name`` (of ``srv_type``; default ``SetVideoParams``) is available."""
        if srv_type is None:
            from axis_ptz_interfaces.srv import SetVideoParams

            srv_type = SetVideoParams
        client = self.node.create_client(srv_type, name)
        try:
            if not client.wait_for_service(timeout_sec=timeout):
                raise RuntimeError(f"{name} did not come up")
        finally:
            self.node.destroy_client(client)

    def set_video(self, fps: int = 0, resolution: str = "", compression: int = -1) -> object:
        from axis_ptz_interfaces.srv import SetVideoParams

        req = SetVideoParams.Request(fps=fps, resolution=resolution, compression=compression)
        res = self.call(SetVideoParams, "/ours/video/set_params", req)
        if not res.success:
            raise RuntimeError(res.message)
        return res

    def set_param(self, name: str, value: object) -> None:
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        req = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
        res = self.call(SetParameters, "/ours/axis_stream/set_parameters", req)
        if not res.results[0].successful:
            raise RuntimeError(res.results[0].reason)

    def close(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=1.0)
        self.thread.join(2.0)
        self.node.destroy_node()
        rclpy.try_shutdown()


def wait_until(pred: Callable[[], object], timeout: float, period: float = 0.01) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(period)
    return False


def kbps(frames: list[Rx]) -> float:
    if len(frames) < 2 or frames[-1].t_rx <= frames[0].t_rx:
        return float("nan")
    return sum(f.nbytes for f in frames[1:]) * 8 / 1000 / (frames[-1].t_rx - frames[0].t_rx)


def fps_of(frames: list[Rx]) -> float:
    if len(frames) < 2:
        return 0.0
    return (len(frames) - 1) / (frames[-1].t_rx - frames[0].t_rx)


def pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, round(q / 100 * (len(s) - 1)))] if s else float("nan")


@contextlib.contextmanager
def subscribed(sub: Subscriber, ns: str) -> Iterator[Recorder]:
    rec, handle = sub.subscribe(ns)
    try:
        yield rec
    finally:
        sub.unsubscribe(handle)


if __name__ == "__main__":
    if sys.argv[1:] != ["--sim-child"]:
        raise SystemExit("usage: bench/pipelines.py --sim-child")
    raise SystemExit(sim_child())
