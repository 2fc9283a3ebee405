"""H.264 against today's MJPEG ladder over the weak link (issue 21's targets), side by side in one run.

The two-host setting of ``bench/bench_link.py`` (``tests/netns/hosts.py`` over ``tests/support/link.py``): robot and
operator in two network namespaces joined by a veth shaped to 2 Mbit/s (``--rate-kbit``: issue 21's second case is
1000) with 2 % random loss each way, the shipped Fast DDS weak-link profile (``config/fastdds_weak_link.xml``) in
every process on both sides, the simulated Axis 214 on the robot's loopback, ``axis_camera`` asked for 704x576 @ 30
fps. The camera stays still. Sessions, one after another in one
invocation (each on a fresh link, so they never share it):

  mjpeg           ``codec: mjpeg`` (compression 30, ``adapt_to_link``), ``axis_link_monitor`` on the operator side
  h264            ``codec: h264`` (the stream node transcodes the camera's MJPEG), ``axis_link_monitor`` with
                  ``codec: h264`` on the operator side (decodes, reports feedback and decode errors)
  h264-nofb       ``codec: h264``, a viewer that sends no feedback (a plain subscription to ``image_raw/ffmpeg``,
                  reliable keep-last 10 as image_transport subscribes by default)
  mjpeg-nofb      ``codec: mjpeg``, a viewer that sends no feedback (plain subscription to ``image_raw/compressed``)
  h264-step       as ``h264``, the link dropping from 2 to 1 Mbit/s 20 s into the measurement (only if asked for)
  h264-cut        as ``h264``, the link cut 15-25 s into the measurement (only if asked for)

The operator's measuring viewer is this script's ``--viewer`` mode: with feedback it *is* ``axis_link_monitor``
(its node class, run in-process with its parameters, so the link carries one copy of the video as in the README's
setup) with every frame also recorded; without feedback a plain subscription (``STREAM_QOS``) that decodes.

Per frame: age = decode (H.264) or receipt (MJPEG) time at the operator - the simulated camera's capture stamp (the
JPEG comment ``tests/support/stamps.py`` reads; for H.264 the capture-time SEI ``media/annexb`` extracts: the
stream node carries the JPEG's stamp into it); both namespaces share one clock. kbit/s = bytes received per second
(every message, decodable or not); picture size; fps = pictures shown per second; PSNR (every 3rd picture,
the mean squared error over B, G, R) of the shown picture, upscaled to 704x576 when smaller, against three
references the simulated camera makes of the same still view when it starts:

  soft    its view through its optics and video chain (``CameraModel.soften`` of ``PtzRenderer.render``) before
          sensor noise and compression -- the issue's reference; the targets are held to this one
  render  its render before the softening too (``PtzRenderer.render``)
  c0      one compression-0 JPEG of that view as the camera sends it (softened, sensor noise, quality ~ 100)
          -- the reference the issue's prototype used

The camera's own compression-0 JPEG against the first two is printed as the ceiling.

First picture: from the viewer process's start (and from its node being up) to its first shown picture, with the
robot side already running; for H.264 without feedback the viewer is started ``--starts`` times (worst reported).

    .venv/bin/python bench/bench_link_h264.py [--seconds 40] [--plot bench/results/link_h264.png]
        [--sessions mjpeg,h264,h264-nofb,mjpeg-nofb] [--starts 5]

Needs root (network namespaces); installs nftables if missing.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from bench_link import LineReader, pct  # noqa: E402  (the two-host bench's helpers)

SIM_PORT = 8080
NS = 1_000_000_000
W, H = 704, 576
#: The 214 is a PAL camera: asked for 704x576 @ 30 it serves 25 pictures/s (vapix.md; the simulator does the
#: same). The issue's ">= 29 fps" was written against a simulator that served 30; a viewer cannot see more
#: pictures than the camera takes, so the frame-rate target is 29 fps or 97 % of the camera's rate, whichever
#: is lower, and the README row says which.
CAMERA_FPS = 25.0
FPS_TARGET = min(29.0, 0.97 * CAMERA_FPS)
ASK = ["-p", "fps:=30", "-p", f"resolution:={W}x{H}"]
#: the link's rate each way (kbit/s; ``--rate-kbit``): the thesis's link is 2000, issue 21's second case 1000
LINK_KBIT = 2000
SETTLE_S = 10.0  # the first seconds of a measurement (the MJPEG ladder finding its rate) are reported apart
PSNR_EVERY = 3


# ---------------------------------------------------------------------------------------------------------
# robot side: the simulated camera, which writes its references of the (still) view when it starts
# ---------------------------------------------------------------------------------------------------------
def robot_sim(port: int, refdir: str) -> int:
    import numpy as np

    from axis_ptz_ros2.sim.camera import SimulatedCamera

    cam = SimulatedCamera(host="127.0.0.1", port=port).start()
    pan, tilt, zoom = cam.frames.position()
    ref = Path(refdir)
    ref.mkdir(parents=True, exist_ok=True)
    render = np.ascontiguousarray(cam.frames.renderer.render(pan, tilt, zoom, W, H))
    np.save(ref / "render.npy", render)
    np.save(ref / "soft.npy", np.ascontiguousarray(cam.persona.picture.soften(render, zoom)))
    (ref / "c0.jpg").write_bytes(cam.frames.frame_jpeg(W, H, 0))
    print(json.dumps({"t": "ready", "pose": [pan, tilt, zoom]}), flush=True)
    try:
        while True:
            time.sleep(1.0)
            print(json.dumps({"t": "pose", "pose": list(cam.frames.position())}), flush=True)
    except KeyboardInterrupt:
        pass
    finally:
        cam.stop()
    return 0


# ---------------------------------------------------------------------------------------------------------
# operator side: the measuring viewer (axis_link_monitor itself, or a plain subscription)
# ---------------------------------------------------------------------------------------------------------
def viewer(codec: str, feedback: bool, refdir: str) -> int:
    import cv2
    import numpy as np
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter import Parameter

    t_start = time.time_ns()
    render = np.load(Path(refdir) / "render.npy")
    c0 = cv2.imdecode(np.frombuffer((Path(refdir) / "c0.jpg").read_bytes(), np.uint8), cv2.IMREAD_COLOR)
    soft = np.load(Path(refdir) / "soft.npy")
    refs = {"soft": soft.astype(np.float32), "render": render.astype(np.float32), "c0": c0.astype(np.float32)}
    lock = threading.Lock()
    count = [0]

    def emit(rec: dict[str, Any]) -> None:
        with lock:
            sys.stdout.write(json.dumps(rec, separators=(",", ":")) + "\n")
            sys.stdout.flush()

    def psnr(img: Any) -> dict[str, float]:
        if img.shape[:2] != (H, W):
            img = cv2.resize(img, (W, H), interpolation=cv2.INTER_LINEAR)
        x = img.astype(np.float32)
        out = {}
        for name, ref in refs.items():
            mse = float(np.mean((x - ref) ** 2))
            out[name] = 10.0 * math.log10(255.0**2 / mse) if mse > 0 else 99.0
        return out

    def shown(rx: int, capture_ns: int, nbytes: int, img: Any | None, w: int, h: int, pts: int = -1) -> None:
        rec: dict[str, Any] = {"t": "pic", "rx": rx, "cap": capture_ns, "bytes": nbytes, "w": w, "h": h, "pts": pts}
        count[0] += 1
        if count[0] % PSNR_EVERY == 1 and img is not None:
            rec["psnr"] = psnr(img)
        emit(rec)

    def on_jpeg(data: bytes, rx: int) -> None:
        from axis_ptz_ros2.streaming import jpeg_size
        from tests.support.stamps import sim_stamp

        st = sim_stamp(data)
        size = jpeg_size(data) or (0, 0)
        img = None
        if count[0] % PSNR_EVERY == 0:  # decode only the pictures measured
            img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
        shown(rx, st[1] if st else 0, len(data), img, size[0], size[1])

    last_pts = [-1]

    def on_au(data: bytes, decoded: Any | None, rx0: int, pts: int) -> None:
        rx = time.time_ns()
        gap = pts - last_pts[0] - 1 if 0 <= last_pts[0] < pts else 0  # access units lost on the way
        last_pts[0] = pts
        if gap:
            emit({"t": "gap", "rx": rx0, "n": gap})
        if decoded is None:
            emit({"t": "lost", "rx": rx0, "bytes": len(data), "pts": pts})
            return
        h, w = decoded.image.shape[:2]
        shown(rx, decoded.capture_ns or 0, len(data), decoded.image, w, h, pts)

    rclpy.init(args=["link_h264_viewer"])
    node: Node
    if feedback:
        from axis_ptz_ros2.nodes import link_monitor as lm

        class Recording(lm.FeedbackPublisher):
            def add(self, msg: Any, nbytes: int | None = None, rx: float | None = None) -> None:
                super().add(msg, nbytes, rx)
                if codec == "mjpeg":
                    on_jpeg(bytes(msg.data), time.time_ns())

        class Receiver:
            """The monitor's AccessUnitReceiver, every result recorded."""

            def __init__(self, inner: Any) -> None:
                self.inner = inner

            def feed(self, data: bytes, pts: int | None = None) -> Any:
                rx0 = time.time_ns()
                out = self.inner.feed(data, pts)
                on_au(data, out, rx0, -1 if pts is None else int(pts))
                return out

            def take_unusable(self) -> int:
                return int(self.inner.take_unusable())

            @property
            def stats(self) -> Any:
                return self.inner.stats

        lm.FeedbackPublisher = Recording  # type: ignore[misc]
        node = lm.LinkMonitorNode(parameter_overrides=[Parameter("codec", value=codec)])
        if node.receiver is not None:
            node.receiver = Receiver(node.receiver)  # type: ignore[assignment]
    else:
        from axis_ptz_ros2.nodes.common import STREAM_QOS

        node = Node("plain_viewer")
        if codec == "h264":
            from ffmpeg_image_transport_msgs.msg import FFMPEGPacket
            from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

            from axis_ptz_ros2.streaming.h264 import AccessUnitReceiver

            rcv = AccessUnitReceiver()

            def cb(msg: Any) -> None:
                rx0 = time.time_ns()
                data = bytes(msg.data)
                on_au(data, rcv.feed(data, int(msg.pts)), rx0, int(msg.pts))

            # as a stock subscriber: image_transport (rqt_image_view, the ffmpeg plugin) subscribes with
            # rmw_qos_profile_default, reliable keep-last 10
            plain = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
            node.create_subscription(FFMPEGPacket, "image_raw/ffmpeg", cb, plain)
        else:
            from sensor_msgs.msg import CompressedImage

            node.create_subscription(
                CompressedImage, "image_raw/compressed", lambda m: on_jpeg(bytes(m.data), time.time_ns()), STREAM_QOS
            )
    from axis_ptz_interfaces.msg import VideoParams
    from axis_ptz_ros2.nodes.common import LATCHED_QOS

    def on_params(m: Any) -> None:  # the stream node's settings and budget (latched, rarely sent)
        emit({"t": "params", "rx": time.time_ns(), "budget": m.max_bitrate_kbps, "source": m.source,
              "fps": m.fps, "resolution": m.resolution, "compression": m.compression})  # fmt: skip

    node.create_subscription(VideoParams, "video/params", on_params, LATCHED_QOS)
    emit({"t": "ready", "rx": time.time_ns(), "start": t_start})
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


# ---------------------------------------------------------------------------------------------------------
# one session
# ---------------------------------------------------------------------------------------------------------
@dataclass
class Session:
    name: str
    codec: str
    feedback: bool
    t0: int = 0
    pics: list[dict[str, Any]] = field(default_factory=list)
    params: list[dict[str, Any]] = field(default_factory=list)
    lost: list[dict[str, Any]] = field(default_factory=list)
    gaps: list[dict[str, Any]] = field(default_factory=list)
    first_s: list[float] = field(default_factory=list)  # viewer process start -> first picture (s), per start
    first_node_s: list[float] = field(default_factory=list)  # viewer node up -> first picture (s)
    pose_moved: bool = False
    note: str = ""
    events: dict[str, int] = field(default_factory=dict)  # what happened to the link, and when (ns)

    def t(self, ns: int) -> float:
        return (ns - self.t0) / NS


#: scripted link changes of a session, seconds into its measurement: issue 21's step (2 -> 1 Mbit/s) and cut (10 s)
SCRIPTS: dict[str, list[tuple[float, str]]] = {
    "h264-step": [(20.0, "rate1000")],
    "h264-cut": [(15.0, "down"), (25.0, "up")],
}


def start_viewer(hosts: Any, link: Any, s: Session, env: dict[str, str], refdir: Path, k: int) -> tuple[Any, Any]:
    argv = [sys.executable, str(Path(__file__).resolve()), "--viewer", s.codec, "--ref", str(refdir)]
    if not s.feedback:
        argv.append("--no-feedback")
    err = open(hosts.logs / f"{hosts.tag}-viewer-{k}.log", "wb")  # noqa: SIM115 - closed below, the child keeps it
    spawned = time.time_ns()
    proc = link.popen("operator", argv, env=env, stdout=subprocess.PIPE, stderr=err, cwd=str(ROOT))
    err.close()
    hosts.procs.append((f"viewer{k}", proc))
    return proc, (LineReader(proc.stdout), spawned)


def first_picture(s: Session, reader: LineReader, spawned: int, timeout: float, hosts: Any) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        pics = reader.of("pic")
        ready = reader.of("ready")
        if pics and ready:
            s.first_s.append((pics[0]["rx"] - spawned) / NS)
            s.first_node_s.append((pics[0]["rx"] - ready[0]["rx"]) / NS)
            return True
        hosts.check_alive()
        time.sleep(0.05)
    s.first_s.append(math.nan)
    s.first_node_s.append(math.nan)
    got = reader.of("lost")
    print(f"  {s.name}: no picture {timeout:.0f} s after a start; {len(got)} access units received", flush=True)
    return False


def stop(proc: Any) -> None:
    import signal

    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=5.0)


def run_session(s: Session, seconds: float, starts: int, logs: Path, profile: str) -> Session:
    from tests.netns.hosts import TwoHosts, host_env, wait_for

    hosts = TwoHosts(f"h264{s.name.replace('-', '')[:6]}", logs)
    link = hosts.link
    env = host_env(FASTRTPS_DEFAULT_PROFILES_FILE=profile) if profile else host_env()
    refdir = logs / f"ref-{s.name}"
    try:
        link.set_rate(LINK_KBIT)
        link.set_loss(2)
        sim = link.popen(
            "robot",
            [sys.executable, str(Path(__file__).resolve()), "--robot-sim", str(SIM_PORT), "--ref", str(refdir)],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            cwd=str(ROOT),
        )
        hosts.procs.append(("sim", sim))
        sim_log = LineReader(sim.stdout)
        wait_for(lambda: sim_log.of("ready"), 60, "the simulated camera", hosts)
        pose0 = sim_log.of("ready")[0]["pose"]
        codec_args = ["-p", "codec:=h264"] if s.codec == "h264" else ["-p", "compression:=30"]
        hosts.start(
            "robot",
            "axis_camera",
            ["axis_camera", "--ros-args", "-p", "hostname:=127.0.0.1", "-p", f"port:={SIM_PORT}", *ASK, *codec_args]
            + ["-p", "adapt_to_link:=true", "--log-level", os.environ.get("BENCH_LINK_LOG_LEVEL", "warn")]
            + os.environ.get("BENCH_LINK_ROBOT_ARGS", "").split(),  # experiments: more -p name:=value for the robot
            env,
        )
        time.sleep(6.0)  # the robot side up (nodes, discovery on its loopback) before the viewer starts
        n = starts if (s.codec == "h264" and not s.feedback) else 1
        for k in range(1, n):  # extra starts: the viewer comes and goes; each start's first picture is timed
            proc, (reader, spawned) = start_viewer(hosts, link, s, env, refdir, k)
            first_picture(s, reader, spawned, 15.0, hosts)
            stop(proc)
            hosts.procs.remove((f"viewer{k}", proc))
            time.sleep(1.0)
        proc, (reader, spawned) = start_viewer(hosts, link, s, env, refdir, 0)
        got = first_picture(s, reader, spawned, 40.0 if s.feedback else 20.0, hosts)
        if not got:
            s.note = "no picture within the start's timeout"
        s.t0 = time.time_ns()
        end = s.t0 + int(seconds * NS)
        script = list(SCRIPTS.get(s.name, []))
        while time.time_ns() < end:
            hosts.check_alive()
            while script and time.time_ns() >= s.t0 + int(script[0][0] * NS):
                _at, what = script.pop(0)
                if what.startswith("rate"):
                    link.set_rate(int(what[4:]))
                else:
                    link.set_up(what == "up")
                s.events[what] = time.time_ns()
            time.sleep(0.05)
        s.pics = [r for r in reader.of("pic") if s.t0 <= r["rx"] < end]
        s.lost = [r for r in reader.of("lost") if s.t0 <= r["rx"] < end]
        s.gaps = [r for r in reader.of("gap") if s.t0 <= r["rx"] < end]
        s.params = reader.of("params")
        s.pose_moved = any(p["pose"] != pose0 for p in sim_log.of("pose"))
    finally:
        hosts.close()
    return s


# ---------------------------------------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------------------------------------
def age_ms(r: dict[str, Any]) -> float:
    return (r["rx"] - r["cap"]) / 1e6 if r["cap"] else math.nan


def figures(s: Session, seconds: float) -> dict[str, Any]:
    a = s.t0 + int(SETTLE_S * NS)
    span = seconds - SETTLE_S
    steady = [r for r in s.pics if r["rx"] >= a]
    lost = [r for r in s.lost if r["rx"] >= a]
    ages = [x for x in (age_ms(r) for r in steady) if not math.isnan(x)]
    full = [r for r in steady if (r["w"], r["h"]) == (W, H)]
    out: dict[str, Any] = {"name": s.name}
    out["fps"] = len(steady) / span
    pts = [r["pts"] for r in steady + lost if r.get("pts", -1) >= 0]
    # H.264: access units the stream node sent in the window (its pts count every one): the camera's own rate
    # (the simulated PAL 214 makes 25 pictures/s when asked for 30)
    out["sent_fps"] = (max(pts) - min(pts) + 1) / span if pts else math.nan
    out["fps_full"] = len(full) / span
    out["kbps"] = (sum(r["bytes"] for r in steady) + sum(r["bytes"] for r in lost)) * 8 / 1000 / span
    out["age_p50"], out["age_p95"] = pct(ages, 0.5), pct(ages, 0.95)
    out["age_max"] = max(ages, default=math.nan)
    sizes: dict[str, int] = {}
    for r in steady:
        k = f"{r['w']}x{r['h']}"
        sizes[k] = sizes.get(k, 0) + 1
    out["sizes"] = ", ".join(f"{k}: {v}" for k, v in sorted(sizes.items(), key=lambda kv: -kv[1])) or "none"
    for ref in ("soft", "render", "c0"):
        p = [r["psnr"][ref] for r in steady if "psnr" in r]
        out[f"psnr_{ref}_p50"], out[f"psnr_{ref}_p5"] = pct(p, 0.5), pct(p, 0.05)
    out["psnr_n"] = sum(1 for r in steady if "psnr" in r)
    out["undecodable"] = len(lost)
    gaps = [r for r in s.gaps if r["rx"] >= a]
    out["gap_aus"] = sum(r["n"] for r in gaps)
    out["gap_events"] = len(gaps)
    # a start that showed nothing is the worst
    out["first_s"] = math.inf if any(math.isnan(x) for x in s.first_s) else max(s.first_s, default=math.nan)
    out["first_all"] = " ".join("—" if math.isnan(x) else f"{x:.1f}" for x in s.first_s)
    out["first_node_all"] = " ".join("—" if math.isnan(x) else f"{x:.1f}" for x in s.first_node_s)
    out["starts"] = len(s.first_s)
    out["pose_moved"] = s.pose_moved
    budgets = [p["budget"] for p in s.params if p["rx"] >= a]
    out["budget"] = f"{min(budgets)}..{max(budgets)}" if budgets else (str(s.params[-1]["budget"]) if s.params else "?")
    last = s.params[-1] if s.params else None
    out["settings"] = f"{last['resolution']}@{last['fps']} c{last['compression']}" if last else "?"
    out["note"] = s.note
    return out


def event_figures(s: Session) -> dict[str, Any]:
    """The scripted sessions (:data:`SCRIPTS`): after the step to 1 Mbit/s, seconds until the frame age stays under
    100 ms (the last picture older than that, counted from the step) and the rate and age of the last 10 s; after
    the cut, the first decoded picture after the heal and the pictures delivered after it that are older than 1 s
    (stale: taken before or during the cut)."""
    out: dict[str, Any] = {"name": s.name}
    end = max((r["rx"] for r in s.pics), default=s.t0)
    tail = [r for r in s.pics if r["rx"] >= end - 10 * NS]
    ages = [x for x in (age_ms(r) for r in tail) if not math.isnan(x)]
    out["tail_fps"], out["tail_age_p95"] = len(tail) / 10.0, pct(ages, 0.95)
    if "rate1000" in s.events:
        t = s.events["rate1000"]
        late = [r["rx"] for r in s.pics if r["rx"] >= t and age_ms(r) > 100]
        out["recovery_s"] = (max(late) - t) / NS if late else 0.0
        out["late_pictures"] = len(late)
    if "up" in s.events:
        t = s.events["up"]
        after = [r for r in s.pics if r["rx"] >= t]
        out["first_after_heal_s"] = (after[0]["rx"] - t) / NS if after else math.inf
        out["stale_after_heal"] = sum(1 for r in after if age_ms(r) > 1000)
        during = [r for r in s.pics if s.events["down"] <= r["rx"] < t]
        out["during_cut"] = len(during)
    return out


def print_events(ev: list[dict[str, Any]]) -> None:
    for e in ev:
        if "recovery_s" in e:
            print(
                f"{e['name']}: link 2 -> 1 Mbit/s (2 % loss) at 20 s: frame age back under 100 ms "
                f"{e['recovery_s']:.1f} s after the step ({e['late_pictures']} pictures older than 100 ms after it); "
                f"last 10 s {e['tail_fps']:.1f} fps, age p95 {e['tail_age_p95']:.0f} ms   target <= 3 s"
            )
        if "first_after_heal_s" in e:
            print(
                f"{e['name']}: link cut 15-25 s: first decoded picture {e['first_after_heal_s']:.2f} s after the "
                f"heal; {e['stale_after_heal']} pictures older than 1 s delivered after it, {e['during_cut']} during "
                f"the cut; last 10 s {e['tail_fps']:.1f} fps, age p95 {e['tail_age_p95']:.0f} ms   "
                "target <= 1 s, no stale picture"
            )


def event_rows(ev: list[dict[str, Any]]) -> bool:
    """README rows of the scripted sessions; True if they meet their targets."""
    from report import row

    ok = True
    for e in ev:
        if "recovery_s" in e:
            good = e["recovery_s"] <= 3.0
            row(
                "two hosts, 2 % loss, H.264 + link monitor, the link dropping 2 → 1 Mbit/s mid-run: frame age back "
                "under 100 ms after the step / the last 10 s",
                f"{e['recovery_s']:.1f} s / {e['tail_fps']:.1f} fps, age p95 {e['tail_age_p95']:.0f} ms",
                "≤ 3 s",
                good,
            )
            ok &= good
        if "first_after_heal_s" in e:
            good = e["first_after_heal_s"] <= 1.0 and e["stale_after_heal"] == 0
            row(
                "two hosts, 2 Mbit/s 2 % loss, H.264 + link monitor, a 10 s cut healed: first decoded picture after "
                "the heal / pictures older than 1 s delivered after it",
                f"{e['first_after_heal_s']:.2f} s / {e['stale_after_heal']}",
                "≤ 1 s / 0",
                good,
            )
            ok &= good
    return ok


def ceiling(refdir: Path) -> None:
    """What the camera itself reaches: its compression-0 JPEG against the references."""
    import cv2
    import numpy as np

    c0 = cv2.imdecode(np.frombuffer((refdir / "c0.jpg").read_bytes(), np.uint8), cv2.IMREAD_COLOR).astype(np.float32)
    for name, what in (("soft", "its view before noise and compression"), ("render", "its unsoftened render")):
        mse = float(np.mean((c0 - np.load(refdir / f"{name}.npy").astype(np.float32)) ** 2))
        print(f"ceiling: the camera's own compression-0 JPEG vs {what}: {10 * math.log10(255**2 / mse):.1f} dB")


def fmt(v: Any, f: str) -> str:
    if isinstance(v, float) and math.isnan(v):
        return "—"
    if isinstance(v, float) and math.isinf(v):
        return "none"
    return f.format(v)


def link_name() -> str:
    return f"{LINK_KBIT / 1000:g} Mbit/s"


def print_table(results: list[dict[str, Any]], seconds: float) -> None:
    col = 22

    def row(label: str, f: str, key: str, target: str = "") -> None:
        cells = "".join(f"{fmt(r[key], f):>{col}}" for r in results)
        print(f"{label:<50}{cells}" + (f"   target {target}" if target else ""))

    print(f"{'':<50}" + "".join(f"{r['name']:>{col}}" for r in results))
    print(
        f"{link_name()}, 2 % loss each way, camera still, {seconds - SETTLE_S:.0f} s after the first {SETTLE_S:.0f} s:"
    )
    row("  pictures shown [fps]", "{:.1f}", "fps")
    row("  H.264 access units sent by the stream node [/s]", "{:.1f}", "sent_fps")
    row(f"  of which {W}x{H} [fps]", "{:.1f}", "fps_full", f">= {FPS_TARGET:.2f} fps of {W}x{H} (29; PAL camera)")
    row("  frame age p50 [ms]", "{:.0f}", "age_p50")
    row("  frame age p95 [ms]", "{:.0f}", "age_p95", "<= 100 ms (with feedback)")
    row("  frame age max [ms]", "{:.0f}", "age_max")
    row("  received [kbit/s]", "{:.0f}", "kbps")
    row("  H.264 access units not shown (lost before/corrupt)", "{}", "undecodable")
    row("  H.264 access units lost on the way (pts gaps)", "{}", "gap_aus")
    row("  H.264 losses on the way (pts gaps)", "{}", "gap_events")
    row("  PSNR vs the camera's view before noise, median [dB]", "{:.1f}", "psnr_soft_p50", ">= 37 (nofb >= 36)")
    row("  PSNR vs the camera's view before noise, 5th pct [dB]", "{:.1f}", "psnr_soft_p5", ">= 34")
    row("  PSNR vs the unsoftened render, median [dB]", "{:.1f}", "psnr_render_p50")
    row("  PSNR vs the unsoftened render, 5th pct [dB]", "{:.1f}", "psnr_render_p5")
    row("  PSNR vs compression-0 JPEG, median [dB]", "{:.1f}", "psnr_c0_p50")
    row("  PSNR vs compression-0 JPEG, 5th pct [dB]", "{:.1f}", "psnr_c0_p5")
    row("  pictures measured for PSNR", "{}", "psnr_n")
    row("first picture after the viewer starts, worst [s]", "{:.1f}", "first_s", "<= 2 s (h264-nofb: 5 starts)")
    row("  every start, from process spawn [s]", "{}", "first_all")
    row("  every start, from its node up [s]", "{}", "first_node_all")
    row("stream node's budget (video/params) [kbit/s]", "{}", "budget")
    row("  last video/params settings", "{}", "settings")
    row("camera moved during the session (must be no)", "{}", "pose_moved")
    for r in results:
        print(f"{r['name']}: picture sizes shown (count): {r['sizes']}" + (f"; {r['note']}" if r["note"] else ""))


# ---------------------------------------------------------------------------------------------------------
# the picture (OpenCV drawing, as bench_link.py)
# ---------------------------------------------------------------------------------------------------------
COLORS = {"mjpeg": (40, 40, 210), "h264": (200, 110, 20), "h264-nofb": (40, 160, 40), "mjpeg-nofb": (150, 40, 150)}


def plot(sessions: list[Session], seconds: float, path: Path) -> None:
    import cv2
    import numpy as np

    Wd, Hd = 1400, 1250
    img = np.full((Hd, Wd, 3), 255, np.uint8)
    left, right = 90, Wd - 30
    font = cv2.FONT_HERSHEY_SIMPLEX
    panels = [
        (80, 330, "frame age at the operator [ms] (log scale)", (10.0, 10000.0), True, (30, 100, 300, 1000, 3000)),
        (380, 620, "received [kbit/s] (1 s bins)", (0.0, 2500.0), False, (0, 500, 1000, 1500, 2000, 2500)),
        (670, 910, "picture width shown [px]", (0.0, 800.0), False, (176, 352, 704)),
        (
            960,
            1180,
            "PSNR vs the camera's view before noise and compression [dB]",
            (15.0, 45.0),
            False,
            (20, 25, 30, 34, 37, 40),
        ),
    ]

    def x_of(t: float) -> int:
        return int(left + (right - left) * min(max(t / seconds, 0.0), 1.0))

    def y_of(v: float, p: tuple[Any, ...]) -> int:
        top, bot, _l, (lo, hi), log, _ticks = p
        v = min(max(v, lo), hi)
        f = (math.log10(v) - math.log10(lo)) / (math.log10(hi) - math.log10(lo)) if log else (v - lo) / (hi - lo)
        return int(bot - f * (bot - top))

    cv2.putText(
        img, f"{W}x{H} @ 30 fps asked, {link_name()} + 2 % loss each way, camera still; robot -> operator, shaped veth",
        (left, 35), font, 0.6, (0, 0, 0), 2, cv2.LINE_AA,
    )  # fmt: skip
    for p in panels:
        top, bot, label, _r, _log, ticks = p
        cv2.rectangle(img, (left, top), (right, bot), (0, 0, 0), 1)
        cv2.putText(img, label, (left + 5, top - 8), font, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
        for v in ticks:
            y = y_of(float(v), p)
            cv2.line(img, (left, y), (right, y), (225, 225, 225), 1)
            cv2.putText(img, f"{v}", (left - 55, y + 4), font, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
        for t in range(0, int(seconds) + 1, 5):
            cv2.line(img, (x_of(t), bot), (x_of(t), bot + 5), (0, 0, 0), 1)
            cv2.putText(img, f"{t}", (x_of(t) - 8, bot + 20), font, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    age_p, kb_p, size_p, psnr_p = panels
    for v, p in ((100, age_p), (37, psnr_p), (34, psnr_p)):
        y = y_of(float(v), p)
        cv2.line(img, (left, y), (right, y), (0, 170, 0), 1)
    cv2.putText(img, "time since the measurement began [s]", (Wd // 2 - 150, Hd - 12), font, 0.5, (0, 0, 0), 1)
    for k, s in enumerate(sessions):
        color = COLORS.get(s.name, (0, 0, 0))
        for r in s.pics:
            x = x_of(s.t(r["rx"]))
            a = age_ms(r)
            if not math.isnan(a):
                cv2.circle(img, (x, y_of(a, age_p)), 1, color, -1)
            cv2.circle(img, (x, y_of(float(r["w"]), size_p) + 2 * k), 1, color, -1)
            if "psnr" in r:
                cv2.circle(img, (x, y_of(r["psnr"]["soft"], psnr_p)), 2, color, -1)
        bins: dict[int, int] = {}
        for r in s.pics + s.lost:
            b = int(s.t(r["rx"]))
            bins[b] = bins.get(b, 0) + r["bytes"]
        pts = [(x_of(b + 0.5), y_of(bins.get(b, 0) * 8 / 1000, kb_p)) for b in range(int(seconds))]
        cv2.polylines(img, [np.array(pts, np.int32)], False, color, 2, cv2.LINE_AA)
        label = {
            "mjpeg": "MJPEG ladder + axis_link_monitor",
            "h264": "H.264 + axis_link_monitor (codec h264)",
            "h264-nofb": "H.264, viewer without feedback",
            "mjpeg-nofb": "MJPEG, viewer without feedback",
        }.get(s.name, s.name)
        cv2.putText(img, label, (right - 420, kb_p[0] + 25 + 22 * k), font, 0.55, color, 2, cv2.LINE_AA)
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), img)


def readme_rows(results: dict[str, dict[str, Any]]) -> None:
    from report import inputs, row

    inputs(
        "bench/bench_link_h264.py",
        "axis_ptz_ros2/streaming",
        "axis_ptz_ros2/media",
        "axis_ptz_ros2/nodes/stream_node.py",
        "axis_ptz_ros2/nodes/link_monitor.py",
        "tests/support/link.py",
        "config/fastdds_weak_link.xml",
    )
    m, h = results.get("mjpeg"), results.get("h264")
    if h and LINK_KBIT != 2000:  # issue 21's 1 Mbit/s case: >= 29 fps at >= 35 dB (no age target there)
        row(
            f"two hosts, {link_name()} 2 % loss, H.264 + link monitor: {W}x{H} fps / age p95 / PSNR median, 5th pct "
            "(vs the camera's view before noise and compression, still)",
            f"{h['fps_full']:.1f} fps (of {h['sent_fps']:.1f} sent) / {h['age_p95']:.0f} ms / "
            f"{h['psnr_soft_p50']:.1f}, {h['psnr_soft_p5']:.1f} dB",
            f"≥ 29 fps (a PAL camera: ≥ {FPS_TARGET:.2f} of its {CAMERA_FPS:.0f}) / — / ≥ 35 dB"
            if LINK_KBIT == 1000
            else "—",
            bool(h["fps_full"] >= FPS_TARGET and h["psnr_soft_p50"] >= 35) if LINK_KBIT == 1000 else None,
        )
    elif h:
        ok = (
            h["fps_full"] >= FPS_TARGET and h["age_p95"] <= 100 and h["psnr_soft_p50"] >= 37 and h["psnr_soft_p5"] >= 34
        )
        mj = ""
        if m:
            mj = (
                f" (MJPEG ladder: {m['fps_full']:.1f} fps of {W}x{H} of {m['fps']:.1f}, {m['age_p95']:.0f} ms, "
                f"{m['psnr_soft_p50']:.1f} dB)"
            )
        row(
            f"two hosts, 2 Mbit/s 2 % loss, H.264 + link monitor: {W}x{H} fps / age p95 / PSNR median, 5th pct "
            "(vs the camera's view before noise and compression, still)",
            f"{h['fps_full']:.1f} fps (of {h['sent_fps']:.1f} sent) / {h['age_p95']:.0f} ms / "
            f"{h['psnr_soft_p50']:.1f}, {h['psnr_soft_p5']:.1f} dB{mj}",
            f"≥ 29 fps (a PAL camera: ≥ {FPS_TARGET:.2f} of its {CAMERA_FPS:.0f}) / ≤ 100 ms / ≥ 37, ≥ 34 dB",
            bool(ok),
        )
    n = results.get("h264-nofb")
    if n:
        row(
            f"two hosts, {link_name()} 2 % loss, H.264, viewer without feedback: {W}x{H} fps / PSNR median",
            f"{n['fps_full']:.1f} fps (of {n['sent_fps']:.1f} sent) / {n['psnr_soft_p50']:.1f} dB",
            f"≥ 29 fps (a PAL camera: ≥ {FPS_TARGET:.2f} of its {CAMERA_FPS:.0f}) / ≥ 36 dB",
            bool(n["fps_full"] >= FPS_TARGET and n["psnr_soft_p50"] >= 36),
        )
        row(
            f"two hosts, {link_name()} 2 % loss, H.264: first picture after the viewer starts, worst of {n['starts']}",
            f"{fmt(n['first_s'], '{:.1f}')} s",
            "≤ 2 s",
            bool(n["first_s"] <= 2),
        )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=40.0, help="measurement per session (s, >= 20)")
    ap.add_argument(
        "--sessions", default="mjpeg,h264,h264-nofb,mjpeg-nofb", help="also h264-step, h264-cut (scripted link changes)"
    )
    ap.add_argument("--starts", type=int, default=5, help="viewer starts timed in the h264-nofb session")
    ap.add_argument("--rate-kbit", type=int, default=2000, help="the link's rate each way (kbit/s)")
    ap.add_argument("--plot", default=str(ROOT / "bench/results/link_h264.png"), help="PNG to write ('' = none)")
    ap.add_argument(
        "--fastdds-profile",
        default=str(ROOT / "config/fastdds_weak_link.xml"),
        help="Fast DDS profile for every process on both hosts ('' = Fast DDS defaults)",
    )
    ap.add_argument("--robot-sim", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument("--viewer", choices=("mjpeg", "h264"), default="", help=argparse.SUPPRESS)
    ap.add_argument("--no-feedback", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--ref", default="", help=argparse.SUPPRESS)
    a = ap.parse_args()
    global LINK_KBIT  # noqa: PLW0603 - one run, one link
    LINK_KBIT = a.rate_kbit
    if a.robot_sim:
        return robot_sim(a.robot_sim, a.ref)
    if a.viewer:
        return viewer(a.viewer, not a.no_feedback, a.ref)
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
        f"Fast DDS profile {profile}; load average {os.getloadavg()[0]:.1f}"
    )
    logs = ROOT / "artifacts" / "bench_link_h264"
    sessions = []
    for name in a.sessions.split(","):
        s = Session(name, "h264" if name.startswith("h264") else "mjpeg", not name.endswith("-nofb"))
        print(f"== {name}: {seconds:.0f} s on the link ...", flush=True)
        sessions.append(run_session(s, seconds, a.starts, logs, a.fastdds_profile))
    scripted = [s for s in sessions if s.name in SCRIPTS]
    sessions = [s for s in sessions if s.name not in SCRIPTS]
    results = [figures(s, seconds) for s in sessions]
    events = [event_figures(s) for s in scripted]
    print()
    if sessions:
        ceiling(logs / f"ref-{sessions[0].name}")
        print_table(results, seconds)
    print_events(events)
    sessions += scripted
    if a.plot:
        plot(sessions, seconds, Path(a.plot))
        print(f"\nplot: {os.path.relpath(a.plot, ROOT)}")
    by = {r["name"]: r for r in results}
    readme_rows(by)
    ok = event_rows(events)
    h, n = by.get("h264"), by.get("h264-nofb")
    if h and LINK_KBIT == 1000:
        ok &= h["fps_full"] >= FPS_TARGET and h["psnr_soft_p50"] >= 35
    elif h and LINK_KBIT == 2000:
        ok &= (
            h["fps_full"] >= FPS_TARGET and h["age_p95"] <= 100 and h["psnr_soft_p50"] >= 37 and h["psnr_soft_p5"] >= 34
        )
    if n:
        ok &= n["fps_full"] >= FPS_TARGET and n["psnr_soft_p50"] >= 36 and n["first_s"] <= 2
    print(f"H.264: {'all targets met' if ok else 'some targets missed'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
