"""CPU of ``axis_stream`` passing a camera's own H.264 through (RTSP, no re-encoding) next to its MJPEG
pass-through, both 1920x1080 @ 30 fps from the simulated current-Axis camera (``--model q6075``, plain HTTP,
no authentication), each node in its own process, this process the subscriber (issue 21: pass-through CPU
<= 1.2x the MJPEG pass-through's). CPU from /proc/<pid>/stat, % of one core; the simulator's own CPU (it
renders and encodes) is printed beside it, and the frame rate that arrived.

    .venv/bin/python bench/bench_passthrough_cpu.py [--seconds 10]
"""

from __future__ import annotations

import argparse
import threading
import time

from pipelines import BIN, Proc, Subscriber, wait_until

SIZE = "1920x1080"


class Counter:
    """Messages received (the subscriber's executor thread)."""

    def __init__(self) -> None:
        self.n = 0
        self._lock = threading.Lock()

    def add(self, _msg: object) -> None:
        with self._lock:
            self.n += 1


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=10.0)
    args = ap.parse_args()
    sim = Proc([str(BIN / "axis_camera_sim"), "--model", "q6075", "--port", "0", "--no-https", "--auth", "none"], "sim")
    m = sim.wait_line(r"at https?://127\.0\.0\.1:(\d+)/.*RTSP H\.264 at rtsp://127\.0\.0\.1:(\d+)/")
    port, rtsp_port = int(m.group(1)), int(m.group(2))
    sub = Subscriber()
    results: dict[str, tuple[float, float, float]] = {}
    try:
        for codec in ("mjpeg", "h264"):
            ns = f"/cpu_{codec}"
            node = Proc(
                [
                    str(BIN / "axis_stream"),
                    "--ros-args",
                    "-r",
                    f"__ns:={ns}",
                    *("-p", f"port:={port}", "-p", f"rtsp_port:={rtsp_port}", "-p", f"codec:={codec}"),
                    *("-p", f"resolution:={SIZE}", "-p", "fps:=30", "-p", "compression:=30"),
                ],
                f"axis_stream({codec})",
            )
            counter = Counter()
            on_msg = counter.add

            from ffmpeg_image_transport_msgs.msg import FFMPEGPacket
            from sensor_msgs.msg import CameraInfo, CompressedImage

            from axis_ptz_ros2.nodes.common import STREAM_QOS

            if codec == "mjpeg":
                subs = [
                    sub.node.create_subscription(CompressedImage, f"{ns}/image_raw/compressed", on_msg, STREAM_QOS),
                    sub.node.create_subscription(CameraInfo, f"{ns}/camera_info", lambda _m: None, STREAM_QOS),
                ]
            else:
                subs = [sub.node.create_subscription(FFMPEGPacket, f"{ns}/image_raw/ffmpeg", on_msg, STREAM_QOS)]
            try:
                if not wait_until(lambda c=counter: c.n >= 30, 30):
                    print(f"{codec}: no frames; node output: {node.lines[-10:]}")  # noqa: T201
                    continue
                time.sleep(2.0)  # settle
                n0, c0, s0, t0 = counter.n, node.cpu_s(), sim.cpu_s(), time.monotonic()
                time.sleep(args.seconds)
                dt = time.monotonic() - t0
                results[codec] = (
                    100 * (node.cpu_s() - c0) / dt,
                    100 * (sim.cpu_s() - s0) / dt,
                    (counter.n - n0) / dt,
                )
            finally:
                for s in subs:
                    sub.node.destroy_subscription(s)
                node.stop()
    finally:
        sub.close()
        sim.stop()
    for codec, (cpu, sim_cpu, fps) in results.items():
        print(  # noqa: T201
            f"{codec:5s} pass-through {SIZE}@30: axis_stream {cpu:5.1f} % of a core, {fps:4.1f} msg/s received, "
            f"{10 * cpu / max(fps, 1e-9):.2f} ms CPU per message (simulator {sim_cpu:5.1f} %)"
        )
    if len(results) == 2:
        ratio = results["h264"][0] / max(results["mjpeg"][0], 1e-9)
        print(f"H.264 / MJPEG pass-through CPU: {ratio:.2f}x (target <= 1.2x)")  # noqa: T201
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
