"""The two processes ``bench/bench_link_h264.py`` starts on the link: the robot's simulated camera and the operator's
measuring viewer (each run as ``bench_link_h264.py --robot-sim`` / ``--viewer`` in its network namespace).

Robot side (:func:`robot_sim`): the simulated camera (the 214, or the current-Axis persona with its RTSP H.264),
which writes its references of the still view when it starts (``refdir``: ``render.npy`` its render,
``soft.npy`` that render through its optics and video chain, before sensor noise and compression, ``c0.jpg`` one
compression-0 JPEG as it sends it), prints its pose every second and, when asked to pan, sweeps the head with
``continuouspantiltmove`` (reversing every :data:`PAN_FLIP_S` s of motion) and prints the pose each MJPEG picture was
rendered at with the capture stamp the picture carries (``{"t": "shot", "cap": ns, "pose": [...]}``): a panning
session's reference of a picture is rendered afterwards from that pose (``link_h264_figures.panning_psnr``). It
prints every MJPEG JPEG's send time too (``{"t": "sent", "cap": ns, "conn": its connection}``;
``bench/capture_match.py``): the stream node
stamps a transcoded picture with its JPEG's arrival, and the bench finds that JPEG's send time among these.

Operator side (:func:`viewer`): ``axis_link_monitor`` itself (its node class in-process, with its parameters, so the
link carries one copy of the video) with every picture also recorded, or a plain subscription that sends no
feedback. Every picture shown is a JSON line (receipt time, capture stamp -- the simulator's send time in an
MJPEG picture's comment, the stream node's stamp in a transcoded picture's SEI, an RTSP camera's capture time in
its own SEI --, bytes, size, pts); every
:data:`PSNR_EVERY`-th (every 2·:data:`PSNR_EVERY`-th above 704x576) carries its PSNR against the still references,
or, when the camera pans, is saved (``refdir/pics/<capture ns>.npy``) for the reference rendered later.

Acuity mode (``bench/bench_acuity_link.py``): the robot side first aims the head at a chart of the world
(:func:`aim_at`: ``ptz.cgi`` pan/tilt/zoom through the simulator's own handler, zoomed as far as the whole chart fits,
at most the tele limit; a panning head then sweeps across it, ``pan_flip_s`` of motion end to end), writes the chart's
homography at that pose (``refdir/chart_h.npy``) and can print the stream node's H.264 bitrate target from
``/diagnostics`` (read on the robot's side: nothing more crosses the link); the viewer keeps every
``acuity_every``-th picture it shows (twice that above 704x576) as ``refdir/pics/<capture ns>.npy``, its line marked
``"acuity": true``, for the chart to be read after the session (reading a 1920x1080 picture costs ~0.4 s of CPU:
in the viewer's process it would delay the pictures it times and the monitor's feedback).

Stills (``h264-still``; :func:`still_client`): the viewer also calls the stream node's ``still/capture``
(std_srvs/Trigger) every ``still_every`` s from :data:`STILL_AFTER_S` after its first picture, and subscribes
``still/compressed`` with the QoS the node publishes it with (``LATCHED_QOS``: reliable, transient local, depth 1);
JSON lines per call (``still_req``: its time, or that the service was not discovered yet and nothing was sent), per
answer (``still_ans``: time, success, message) and per still that arrived (``still``: time, stamp, bytes, the
JPEG's width and height); each still is kept as ``refdir/stills/<stamp ns>.jpg`` (read for the acuity chart after
the session).
"""

from __future__ import annotations

import json
import math
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

#: a panning session's head: the seconds of ``continuouspantiltmove`` from one end of its sweep to the other
PAN_FLIP_S = 5.0
PSNR_EVERY = 3
#: ``still_every``: the viewer's first still request comes this long after its first picture shown
STILL_AFTER_S = 10.0


# ---------------------------------------------------------------------------------------------------------
# robot side
# ---------------------------------------------------------------------------------------------------------
def aim_at(cam: Any, target_name: str, w: int, h: int) -> tuple[tuple[float, float, float], Any]:
    """Aim the simulated head at the world target ``target_name``'s centre, zoomed as far as the whole target stays
    in the ``w`` x ``h`` view (at most the tele limit; ``bench/acuity.py``'s pose, as ``bench/bench_acuity.py``), with
    one ``ptz.cgi`` absolute move through the simulator's own handler; returns the pose once the head is there and
    the chart's homography (chart mm -> picture px) at that pose."""
    import acuity  # bench/acuity.py (bench/ is on sys.path)

    renderer = cam.frames.renderer
    target = renderer.scene.target(target_name)
    pan, tilt = acuity.aim(cam.world, target.center)
    zoom = round(acuity.fit_zoom(renderer, target, pan, tilt, w, h))  # VAPIX zoom is an integer
    cam.state.handle([("pan", f"{pan:.5f}"), ("tilt", f"{tilt:.5f}"), ("zoom", str(zoom))])
    deadline = time.monotonic() + 30.0
    while cam.state.moving():
        if time.monotonic() > deadline:
            raise RuntimeError(f"the head did not reach {target_name} in 30 s")
        time.sleep(0.05)
    pose = cam.frames.position()
    return pose, acuity.pose_homography(renderer, target, *pose, w, h)


def watch_diagnostics() -> None:
    """Print the stream node's H.264 bitrate target (``/diagnostics``) as ``{"t": "diag", ...}`` lines, from a node
    of this process spun on a daemon thread (on the robot's side: nothing more crosses the link)."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor

    key = "h264 bitrate target [kbit/s]"
    rclpy.init(args=["link_h264_diagnostics"])
    node = rclpy.create_node("bench_diagnostics_watch")

    def on_diag(m: Any) -> None:
        for st in m.status:
            for kv in st.values:
                if kv.key == key:
                    print(json.dumps({"t": "diag", "rx": time.time_ns(), "target_kbps": float(kv.value)}), flush=True)

    node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 10)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    threading.Thread(target=executor.spin, daemon=True).start()


def robot_sim(  # noqa: C901, PLR0912, PLR0915 - one process's set-up, step by step
    port: int,
    refdir: str,
    model: str = "axis214",
    pan_speed: int = 0,
    aim: str = "",
    pan_flip_s: float = 0.0,
    diagnostics: bool = False,
) -> int:
    import numpy as np
    from capture_match import log_sends  # bench/capture_match.py (bench/ is on sys.path)

    import axis_ptz_ros2.sim.http.mjpeg as mjpeg_side
    from axis_ptz_ros2.sim import persona as personas
    from axis_ptz_ros2.sim.camera import SimulatedCamera
    from tests.support.stamps import sim_stamp

    p = personas.persona(model)
    w, h = p.resolutions[p.default_resolution]
    rtsp = port + 1 if p.key != "axis214" else None  # the current-Axis persona's RTSP H.264
    cam = SimulatedCamera(host="127.0.0.1", port=port, model=model, https=False, auth="none", rtsp_port=rtsp)
    lock = threading.Lock()

    # every JPEG's send time: a transcoded picture's capture time is found among them (capture_match.match)
    def sent(_seq: int, t: int, connection: str) -> None:
        with lock:
            sys.stdout.write(json.dumps({"t": "sent", "cap": t, "conn": connection}) + "\n")
            sys.stdout.flush()

    log_sends(sent)
    if pan_speed:
        rendered: dict[int, list[float]] = {}  # id(JPEG bytes) -> the pose it was rendered at
        frames = cam.frames
        render_jpeg, stamp = frames.frame_jpeg, mjpeg_side.stamp

        def frame_jpeg(width: int, height: int, compression: int, overlay: str = "") -> bytes:
            pose = list(frames.position())
            jpeg = render_jpeg(width, height, compression, overlay)
            with lock:
                rendered[id(jpeg)] = pose
            return jpeg

        def stamped(jpeg: bytes, seq: int) -> bytes:
            out = stamp(jpeg, seq)
            st = sim_stamp(out)
            with lock:
                pose = rendered.pop(id(jpeg), None)
            if st and pose:
                print(json.dumps({"t": "shot", "cap": st[1], "pose": pose}), flush=True)
            return out

        frames.frame_jpeg = frame_jpeg  # type: ignore[method-assign]  # bench instrumentation, this process only
        mjpeg_side.stamp = stamped  # type: ignore[assignment]
    cam.start()
    ref = Path(refdir)
    ref.mkdir(parents=True, exist_ok=True)
    if aim:  # the chart's homography at the aimed pose: its pictures are read through it (bench_acuity_link.py)
        np.save(ref / "chart_h.npy", aim_at(cam, aim, w, h)[1])
    if diagnostics:
        watch_diagnostics()
    pan, tilt, zoom = cam.frames.position()
    render = np.ascontiguousarray(cam.frames.renderer.render(pan, tilt, zoom, w, h))
    np.save(ref / "render.npy", render)
    np.save(ref / "soft.npy", np.ascontiguousarray(cam.persona.picture.soften(render, zoom)))
    (ref / "c0.jpg").write_bytes(cam.frames.frame_jpeg(w, h, 0))
    print(json.dumps({"t": "ready", "pose": [pan, tilt, zoom], "size": [w, h]}), flush=True)
    # a sweep centred on the view it starts from, reversed where the head is PAN_FLIP_S (``pan_flip_s``) of motion
    # from one end: by position, so late reversals (a loaded machine) never walk the sweep's centre away
    flip_s = pan_flip_s or PAN_FLIP_S
    half = pan_speed / 100.0 * cam.state.speeds.pan_deg_s * flip_s / 2  # degrees either side of the centre
    direction = 1
    if pan_speed:
        cam.state.handle([("continuouspantiltmove", f"{pan_speed},0")])
    tick = min(0.2, flip_s / 20) if pan_speed else 1.0  # a reversal overshoots by at most a tick's motion
    next_pose = 0.0
    try:
        while True:
            time.sleep(tick)
            if pan_speed and direction * math.remainder(cam.frames.position()[0] - pan, 360.0) >= half:
                direction = -direction
                cam.state.handle([("continuouspantiltmove", f"{direction * pan_speed},0")])
            if time.monotonic() >= next_pose:  # the pose about once a second
                next_pose = time.monotonic() + 0.9
                print(json.dumps({"t": "pose", "pose": list(cam.frames.position())}), flush=True)
    except KeyboardInterrupt:
        pass
    finally:
        cam.stop()
        if diagnostics:
            import rclpy

            rclpy.try_shutdown()
    return 0


# ---------------------------------------------------------------------------------------------------------
# operator side
# ---------------------------------------------------------------------------------------------------------
def still_client(node: Any, emit: Callable[[dict[str, Any]], None], ref: Path, every: float, first: list[int]) -> None:
    """On ``node`` (spun by the viewer's executor): ``still/capture`` every ``every`` s from :data:`STILL_AFTER_S`
    after ``first[0]`` (the first picture shown, ns; 0 until then), ``still/compressed`` recorded (module docstring).
    A request is made whether or not the previous still has come (the node refuses one while a still is in flight,
    and says so)."""
    from sensor_msgs.msg import CompressedImage
    from std_srvs.srv import Trigger

    from axis_ptz_ros2.nodes.common import LATCHED_QOS
    from axis_ptz_ros2.nodes.stream_still import STILL_SERVICE, STILL_TOPIC
    from axis_ptz_ros2.streaming import jpeg_size

    stills = ref / "stills"
    stills.mkdir(parents=True, exist_ok=True)
    client = node.create_client(Trigger, STILL_SERVICE)
    ns = 1_000_000_000

    def on_still(msg: Any) -> None:
        rx = time.time_ns()
        data = bytes(msg.data)
        stamp = int(msg.header.stamp.sec) * ns + int(msg.header.stamp.nanosec)
        w, h = jpeg_size(data) or (0, 0)
        (stills / f"{stamp}.jpg").write_bytes(data)
        emit({"t": "still", "rx": rx, "stamp": stamp, "bytes": len(data), "w": w, "h": h, "format": msg.format})

    node.create_subscription(CompressedImage, STILL_TOPIC, on_still, LATCHED_QOS)
    k, next_at = [0], [0]

    def answered(n: int, fut: Any) -> None:
        rx = time.time_ns()
        try:
            r = fut.result()
        except Exception as err:  # noqa: BLE001 - recorded, the bench goes on
            emit({"t": "still_ans", "k": n, "rx": rx, "ok": False, "msg": f"{type(err).__name__}: {err}"})
            return
        emit({"t": "still_ans", "k": n, "rx": rx, "ok": bool(r.success), "msg": str(r.message)})

    def tick() -> None:
        if not first[0]:
            return
        now = time.time_ns()
        if not next_at[0]:
            next_at[0] = first[0] + int(STILL_AFTER_S * ns)
        if now < next_at[0]:
            return
        next_at[0] += int(every * ns)
        k[0] += 1
        n = k[0]
        if not client.service_is_ready():
            emit({"t": "still_req", "k": n, "rx": now, "ready": False})
            return
        t = time.time_ns()
        fut = client.call_async(Trigger.Request())
        fut.add_done_callback(lambda f, n=n: answered(n, f))
        emit({"t": "still_req", "k": n, "rx": t, "ready": True})

    node.create_timer(0.02, tick)


def viewer(  # noqa: C901, PLR0915
    codec: str,
    feedback: bool,
    refdir: str,
    save_pictures: bool = False,
    acuity_every: int = 0,
    still_every: float = 0.0,
) -> int:
    import cv2
    import numpy as np
    import rclpy
    from rclpy.node import Node
    from rclpy.parameter import Parameter

    from tests.support.spin import spin_until_stopped

    t_start = time.time_ns()
    ref = Path(refdir)
    refs: dict[str, Any] = {}
    if not save_pictures:
        c0 = cv2.imdecode(np.frombuffer((ref / "c0.jpg").read_bytes(), np.uint8), cv2.IMREAD_COLOR)
        refs = {
            "soft": np.load(ref / "soft.npy").astype(np.float32),
            "render": np.load(ref / "render.npy").astype(np.float32),
            "c0": c0.astype(np.float32),
        }
    pics = ref / "pics"
    if save_pictures or acuity_every:
        pics.mkdir(parents=True, exist_ok=True)
    lock = threading.Lock()
    count = [0]
    first = [0]  # when the first picture was shown (ns): the still requests count from it

    def emit(rec: dict[str, Any]) -> None:
        with lock:
            sys.stdout.write(json.dumps(rec, separators=(",", ":")) + "\n")
            sys.stdout.flush()

    if acuity_every % PSNR_EVERY:  # the pictures kept are among those decoded for the PSNR
        raise ValueError(f"acuity_every must be a multiple of {PSNR_EVERY}, not {acuity_every}")

    def psnr(img: Any) -> dict[str, float]:
        return {name: psnr_db(img, r) for name, r in refs.items()}

    def measured(w: int) -> bool:
        every = PSNR_EVERY * (2 if w > 704 else 1)
        return count[0] % every == 0

    def shown(rx: int, capture_ns: int, nbytes: int, img: Any | None, w: int, h: int, pts: int = -1) -> None:
        rec: dict[str, Any] = {"t": "pic", "rx": rx, "cap": capture_ns, "bytes": nbytes, "w": w, "h": h, "pts": pts}
        if acuity_every and img is not None and capture_ns and count[0] % (acuity_every * (2 if w > 704 else 1)) == 0:
            np.save(pics / f"{capture_ns}.npy", img)  # the chart is read after the session, not here
            rec["acuity"] = True
        if measured(w) and img is not None:
            if save_pictures and capture_ns:
                np.save(pics / f"{capture_ns}.npy", img)
                rec["saved"] = True
            elif refs:
                rec["psnr"] = psnr(img)
        count[0] += 1
        first[0] = first[0] or rx
        emit(rec)

    def on_jpeg(data: bytes, rx: int) -> None:
        from axis_ptz_ros2.streaming import jpeg_size
        from tests.support.stamps import sim_stamp

        st = sim_stamp(data)
        size = jpeg_size(data) or (0, 0)
        img = None
        if measured(size[0]):  # decode only the pictures measured
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
            from rclpy.event_handler import SubscriptionEventCallbacks
            from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

            from axis_ptz_ros2.streaming.receiver import AccessUnitReceiver

            rcv = AccessUnitReceiver()
            arrived = [False]

            def cb(msg: Any) -> None:
                rx0 = time.time_ns()
                data = bytes(msg.data)
                if not arrived[0]:  # the start's breakdown: when the first access unit came, and whether an IDR
                    arrived[0] = True
                    emit({"t": "first_au", "rx": rx0, "key": bool(int(msg.flags) & 1), "pts": int(msg.pts)})
                on_au(data, rcv.feed(data, int(msg.pts)), rx0, int(msg.pts))

            # as a stock subscriber: image_transport (rqt_image_view, the ffmpeg plugin) subscribes with
            # rmw_qos_profile_default, reliable keep-last 10
            plain = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
            # the reader's side of discovery: when this subscription matched the stream node's writer
            events = SubscriptionEventCallbacks(
                matched=lambda info: emit({"t": "matched", "rx": time.time_ns(), "n": int(info.current_count)})
            )
            node.create_subscription(FFMPEGPacket, "image_raw/ffmpeg", cb, plain, event_callbacks=events)
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
    if still_every > 0:
        still_client(node, emit, ref, still_every, first)
    emit({"t": "ready", "rx": time.time_ns(), "start": t_start})
    spin_until_stopped(node)
    return 0


def psnr_db(img: Any, ref: Any) -> float:
    """PSNR (dB) of a BGR picture against a float32 reference, the mean squared error over B, G, R; a smaller
    picture is upscaled (bilinear) to the reference's size first."""
    import cv2
    import numpy as np

    rh, rw = ref.shape[:2]
    if img.shape[:2] != (rh, rw):
        img = cv2.resize(img, (rw, rh), interpolation=cv2.INTER_LINEAR)
    mse = float(np.mean((img.astype(np.float32) - ref) ** 2))
    return 10.0 * math.log10(255.0**2 / mse) if mse > 0 else 99.0
