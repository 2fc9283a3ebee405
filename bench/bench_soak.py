"""Soak: the composed driver for an hour under the operator's normal use, sampled for leaks (issue 25).

``axis_camera`` (stream + PTZ node in one process, as the README and launch file start it) against the simulated
214 (``axis_camera_sim``, another process), with this process as the operator: a subscriber on the video (704×576,
alternating 30 and 15 fps through the parameter service every 2 minutes), a PTZ command every second (absolute
moves), and a camera reboot every 10 minutes through the simulator's control endpoint. Every 10 s it samples the
driver process's RSS, threads and open file descriptors from ``/proc``; at the end it prints the RSS slope over the
second half (least squares, MB/h), the ranges of threads and descriptors over the second half, and the oldest frame
delivered (receipt − the frame's capture stamp) against the stall watchdog.

    python bench/bench_soak.py                 # 60 minutes
    python bench/bench_soak.py --minutes 5     # a short check
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import threading
import time
import urllib.request
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pipelines import BIN, ROOT, Proc, start_sim  # noqa: E402
from report import inputs, row  # noqa: E402
from soak_common import SAMPLE_EVERY_S, rss_slope_mb_per_h, sample  # noqa: E402
from soak_common import ranges as half_ranges  # noqa: E402

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import rclpy  # noqa: E402
from rcl_interfaces.srv import SetParameters  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import CompressedImage  # noqa: E402

from axis_ptz_interfaces.msg import PtzCommand  # noqa: E402
from axis_ptz_ros2.nodes.common import COMMAND_QOS, STREAM_QOS  # noqa: E402

WATCHDOG_S = 1.0  # the stream node's default stall watchdog (stall_timeout)


def main() -> int:  # noqa: PLR0915 - one scripted hour
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--reboot-every-min", type=float, default=10.0)
    args = ap.parse_args()
    inputs(
        "axis_ptz_ros2/axis_ptz_ros2/nodes",
        "axis_ptz_ros2/axis_ptz_ros2/streaming",
        "axis_ptz_ros2/axis_ptz_ros2/ptz",
        "axis_ptz_ros2/axis_ptz_ros2/vapix",
        "bench/bench_soak.py",
        "bench/soak_common.py",
    )

    sim, port = start_sim()
    ns = "/soak"
    model = ROOT / "config" / "axis214.yaml"
    values = {"port": port, "fps": 30, "resolution": "704x576", "compression": 30, "camera_model": model}
    cmd_line = [str(BIN / "axis_camera"), "--ros-args", "-r", f"__ns:={ns}"]
    for k, v in values.items():
        cmd_line += ["-p", f"{k}:={v}"]
    driver = Proc(cmd_line, "axis_camera")
    rclpy.init()
    node = Node("soak_operator", namespace=ns)
    ages: list[float] = []
    frames = [0]
    lock = threading.Lock()

    def on_image(msg: CompressedImage) -> None:
        age = time.time() - (msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)
        with lock:
            frames[0] += 1
            ages.append(age)

    node.create_subscription(CompressedImage, "image_raw/compressed", on_image, STREAM_QOS)
    cmd = node.create_publisher(PtzCommand, "ptz/cmd/absolute", COMMAND_QOS)
    params = node.create_client(SetParameters, f"{ns}/axis_stream/set_parameters")
    spin = threading.Thread(target=rclpy.spin, args=(node,), daemon=True)
    spin.start()

    t0 = time.monotonic()
    deadline = t0 + 60.0
    while frames[0] == 0 and time.monotonic() < deadline:
        time.sleep(0.1)
    if frames[0] == 0:
        print("no frame within 60 s; driver output:", *driver.lines[-20:], sep="\n")
        return 1
    print(f"first frame after {time.monotonic() - t0:.1f} s; soaking {args.minutes:g} min", flush=True)

    samples: list[tuple[float, float, int, int]] = []  # t (s), RSS MB, threads, fds
    reboots = 0
    fps_switches = 0
    start = time.monotonic()
    end = start + 60.0 * args.minutes
    next_cmd = next_sample = start
    next_fps = start + 120.0
    next_reboot = start + 60.0 * args.reboot_every_min
    i = 0
    while time.monotonic() < end and driver.p.poll() is None:
        now = time.monotonic()
        if now >= next_cmd:
            i += 1
            pan = math.radians(30.0 * math.sin(i / 7.0))
            cmd.publish(
                PtzCommand(
                    pan=pan, tilt=math.radians(5.0 * math.cos(i / 5.0)), zoom=1.0 + 500.0 * (i % 4), speed=math.nan
                )
            )
            next_cmd += 1.0
        if now >= next_fps and params.service_is_ready():
            fps_switches += 1
            req = SetParameters.Request(
                parameters=[Parameter("fps", value=15 if fps_switches % 2 else 30).to_parameter_msg()]
            )
            params.call_async(req)
            next_fps += 120.0
        if now >= next_reboot:
            reboots += 1
            urllib.request.urlopen(f"http://127.0.0.1:{port}/sim/control?reboot=20", timeout=5).read()  # noqa: S310 - loopback
            next_reboot += 60.0 * args.reboot_every_min
        if now >= next_sample:
            samples.append(sample(driver.p.pid, now - start))
            if len(samples) % 30 == 1:
                t, rss, th, fds = samples[-1]
                print(
                    f"t={t / 60:5.1f} min  RSS {rss:6.1f} MB  threads {th}  fds {fds}  frames {frames[0]}", flush=True
                )
            next_sample += SAMPLE_EVERY_S
        time.sleep(0.05)

    alive = driver.p.poll() is None
    exit_s = driver.interrupt()
    node.destroy_node()
    rclpy.try_shutdown()
    sim.stop()

    slope = rss_slope_mb_per_h(samples)
    threads, fds = half_ranges(samples)
    with lock:
        oldest = max(ages) if ages else math.inf
        count = frames[0]
    summary = {
        "minutes": args.minutes, "frames": count, "reboots": reboots, "fps_switches": fps_switches,
        "rss_first_mb": samples[0][1], "rss_last_mb": samples[-1][1], "rss_slope_mb_per_h_second_half": slope,
        "threads_second_half": threads, "fds_second_half": fds, "oldest_frame_s": oldest,
        "driver_alive": alive, "ctrl_c_exit_s": exit_s,
    }  # fmt: skip
    print(json.dumps(summary))
    ok_rss = abs(slope) <= 1.0
    ok_flat = threads[1] - threads[0] <= 2 and fds[1] - fds[0] <= 4
    ok_age = oldest <= WATCHDOG_S + 1.0  # the capture stamp is the camera's clock: loopback, same machine
    row(
        f"soak {args.minutes:g} min: RSS slope and threads, fds over the second half; oldest frame delivered",
        f"{slope:+.2f} MB/h (RSS {samples[0][1]:.0f}→{samples[-1][1]:.0f} MB); threads {threads[0]}–{threads[1]}, "
        f"fds {fds[0]}–{fds[1]}; {oldest:.2f} s over {count} frames, {reboots} reboots",
        "≤ 1 MB/h; flat; ≤ watchdog",
        ok_rss and ok_flat and ok_age and alive,
    )
    return 0 if alive else 1


if __name__ == "__main__":
    sys.exit(main())
