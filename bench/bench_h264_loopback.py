"""H.264 on loopback (issue 21): the pass-through's CPU next to the MJPEG pass-through's, and the age of a decoded
picture at a subscriber, passed through and transcoded.

(a) CPU: ``axis_stream`` passing the simulated current-Axis camera's own H.264 through (``--model q6075``, RTSP, no
    re-encoding) next to its MJPEG pass-through, both 1920x1080 @ 30 fps, each node in its own process one after
    the other, this process the subscriber (target: H.264 <= 1.2x MJPEG). CPU is the scheduler's run time of the
    node's threads (``bench/pipelines.py``); the simulator's own CPU (it renders and encodes) and the message rate
    that arrived are printed beside it. Single windows one after the other: indicative (README, "How CPU is
    compared").
(b) Age: camera capture -> picture decoded at a subscriber in another process (``AccessUnitReceiver``, the link
    monitor's decoder): the q6075's own H.264 passed through at 1920x1080 @ 30, from the capture time the
    simulator puts in its SEI, and the simulated 214's MJPEG transcoded by the stream node at 704x576 @ 30, from
    the 214's send time of the picture's JPEG (the stream node stamps it with the JPEG's arrival, so the bench
    runs a 214 that logs every send, ``bench/capture_match.py``, and finds each picture's JPEG among them).
    Target: median <= 50 ms each.

    .venv/bin/python bench/bench_h264_loopback.py [--seconds 10]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import threading
import time
from pathlib import Path
from typing import Any

from capture_match import lag_summary, match, sends_of
from pipelines import BIN, Proc, Subscriber, pct, wait_until
from report import SIM_CONFIG, inputs, row

SIZE = "1920x1080"
HERE = Path(__file__).resolve().parent


class Counter:
    """Messages received (the subscriber's executor thread)."""

    def __init__(self) -> None:
        self.n = 0
        self._lock = threading.Lock()

    def add(self, _msg: object) -> None:
        with self._lock:
            self.n += 1


class Ages:
    """Decodes every access unit (the subscriber's executor thread); each picture shown: pts, the capture stamp in
    its SEI, when it was decoded (ns)."""

    def __init__(self) -> None:
        from axis_ptz_ros2.streaming.receiver import AccessUnitReceiver

        self.receiver = AccessUnitReceiver()
        self.shown: list[tuple[int, int, int]] = []
        self.measuring = False
        self._lock = threading.Lock()

    def add(self, msg: Any) -> None:
        picture = self.receiver.feed(bytes(msg.data), int(msg.pts))
        now = time.time_ns()
        if picture is not None and picture.capture_ns and self.measuring:
            with self._lock:
                self.shown.append((int(msg.pts), picture.capture_ns, now))

    def ages(self, sends: dict[str, list[int]] | None = None) -> list[float]:
        """Each picture's age (ms): from the capture stamp in its SEI, or with ``sends`` (the simulator's log)
        from the send time of its JPEG (:func:`capture_match.match`), printed with the match's lag."""
        with self._lock:
            shown = list(self.shown)
        if sends is None:
            return [(rx - cap) / 1e6 for _pts, cap, rx in shown]
        pairs = [(pts, cap) for pts, cap, _rx in shown]
        matched = match(pairs, sends)
        print(f"(b) transcoded: {lag_summary(pairs, matched)}")
        return [(rx - m) / 1e6 for (_pts, _cap, rx), m in zip(shown, matched, strict=True) if m is not None]

    @property
    def count(self) -> int:
        return self.receiver.stats.pictures


def start_node(ns: str, port: int, *params: str) -> Proc:
    args = [str(BIN / "axis_stream"), "--ros-args", "-r", f"__ns:={ns}", "-p", f"port:={port}", "-p", "fps:=30"]
    for p in params:
        args += ["-p", p]
    return Proc(args, f"axis_stream({ns})")


def cpu_window(sub: Subscriber, codec: str, port: int, rtsp_port: int, sim: Proc, seconds: float) -> tuple:
    from ffmpeg_image_transport_msgs.msg import FFMPEGPacket
    from sensor_msgs.msg import CameraInfo, CompressedImage

    from axis_ptz_ros2.nodes.common import STREAM_QOS

    ns = f"/cpu_{codec}"
    node = start_node(ns, port, f"rtsp_port:={rtsp_port}", f"codec:={codec}", f"resolution:={SIZE}", "compression:=30")
    counter = Counter()
    if codec == "mjpeg":
        subs = [
            sub.node.create_subscription(CompressedImage, f"{ns}/image_raw/compressed", counter.add, STREAM_QOS),
            sub.node.create_subscription(CameraInfo, f"{ns}/camera_info", lambda _m: None, STREAM_QOS),
        ]
    else:
        subs = [sub.node.create_subscription(FFMPEGPacket, f"{ns}/image_raw/ffmpeg", counter.add, STREAM_QOS)]
    try:
        if not wait_until(lambda: counter.n >= 30, 30):
            raise RuntimeError(f"{codec}: no frames; node output: {node.lines[-10:]}")
        time.sleep(2.0)  # settle
        n0, c0, s0, t0 = counter.n, node.cpu_s(), sim.cpu_s(), time.monotonic()
        time.sleep(seconds)
        dt = time.monotonic() - t0
        return 100 * (node.cpu_s() - c0) / dt, 100 * (sim.cpu_s() - s0) / dt, (counter.n - n0) / dt
    finally:
        for s in subs:
            sub.node.destroy_subscription(s)
        node.stop()


def age_window(sub: Subscriber, node: Proc, ns: str, seconds: float) -> Ages:
    from ffmpeg_image_transport_msgs.msg import FFMPEGPacket

    from axis_ptz_ros2.nodes.common import VIDEO_QOS

    ages = Ages()
    handle = sub.node.create_subscription(FFMPEGPacket, f"{ns}/image_raw/ffmpeg", ages.add, VIDEO_QOS)
    try:
        if not wait_until(lambda: ages.count >= 30, 30):
            raise RuntimeError(f"{ns}: no decoded pictures; node output: {node.lines[-10:]}")
        time.sleep(2.0)
        ages.measuring = True
        time.sleep(seconds)
        ages.measuring = False
        return ages
    finally:
        sub.node.destroy_subscription(handle)
        node.stop()


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=10.0)
    args = ap.parse_args()
    inputs(
        "bench/bench_h264_loopback.py",
        "bench/pipelines.py",
        "bench/capture_match.py",
        "axis_ptz_ros2/axis_ptz_ros2/streaming",
        "axis_ptz_ros2/axis_ptz_ros2/media",
        "axis_ptz_ros2/axis_ptz_ros2/nodes/stream_node.py",
        "axis_ptz_ros2/axis_ptz_ros2/sim",  # the pictures: their content sets the bytes
        *SIM_CONFIG,
        "config/sim_world.yaml",
    )
    sub = Subscriber()
    cpu: dict[str, tuple] = {}
    ages: dict[str, list[float]] = {}
    try:
        sim = Proc(
            [str(BIN / "axis_camera_sim"), "--model", "q6075", "--port", "0", "--no-https", "--auth", "none"], "sim"
        )
        try:
            m = sim.wait_line(r"at https?://127\.0\.0\.1:(\d+)/.*RTSP H\.264 at rtsp://127\.0\.0\.1:(\d+)/")
            port, rtsp_port = int(m.group(1)), int(m.group(2))
            for codec in ("mjpeg", "h264"):
                cpu[codec] = cpu_window(sub, codec, port, rtsp_port, sim, args.seconds)
            node = start_node(
                "/age_pass", port, f"rtsp_port:={rtsp_port}", "codec:=h264", f"resolution:={SIZE}", "compression:=30"
            )
            ages["pass-through 1920x1080"] = age_window(sub, node, "/age_pass", args.seconds).ages()
        finally:
            sim.stop()
        sim = Proc([sys.executable, str(HERE / "capture_match.py"), "--sim"], "sim(214, sends logged)")
        try:
            port = int(sim.wait_line(r"http://127\.0\.0\.1:(\d+)/").group(1))
            node = start_node("/age_tc", port, "codec:=h264", "resolution:=704x576")
            shown = age_window(sub, node, "/age_tc", args.seconds)
            ages["transcoded 704x576"] = shown.ages(sends_of(sim.lines))
        finally:
            sim.stop()
    finally:
        sub.close()
    for codec, (c, sim_cpu, fps) in cpu.items():
        print(
            f"(a) {codec:5s} pass-through {SIZE}@30: axis_stream {c:5.1f} % of a core, {fps:4.1f} msg/s received, "
            f"{10 * c / max(fps, 1e-9):.2f} ms CPU per message (simulator {sim_cpu:5.1f} %)"
        )
    ratio = cpu["h264"][0] / max(cpu["mjpeg"][0], 1e-9)
    print(f"(a) H.264 / MJPEG pass-through CPU: {ratio:.2f}x (target <= 1.2x)")
    for what, a in ages.items():
        print(
            f"(b) {what}: capture -> decoded at the subscriber, median {statistics.median(a):.1f} ms, "
            f"p95 {pct(a, 95):.1f} ms, {len(a)} pictures (target: median <= 50 ms)"
        )
    row(
        f"H.264 pass-through of the current-Axis persona's own stream, {SIZE} @ 30, vs its MJPEG pass-through: "
        "axis_stream CPU (single windows one after the other)",
        f"{cpu['h264'][0]:.1f} % vs {cpu['mjpeg'][0]:.1f} % of a core = {ratio:.2f}× "
        f"({cpu['h264'][2]:.1f} / {cpu['mjpeg'][2]:.1f} msg/s)",
        "≤ 1.2×",
        ratio <= 1.2,
    )
    meds = {k: statistics.median(v) for k, v in ages.items()}
    row(
        "H.264 on loopback, camera capture → picture decoded at a subscriber, median (p95): passed through "
        "1920×1080 / transcoded 704×576",
        " / ".join(f"{meds[k]:.1f} ms ({pct(ages[k], 95):.1f})" for k in ages),
        "≤ 50 ms each",
        all(v <= 50.0 for v in meds.values()),
    )
    return 0 if ratio <= 1.2 and all(v <= 50.0 for v in meds.values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
