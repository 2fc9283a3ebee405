"""``axis_camera_sim``: run a simulated Axis PTZ camera (the 214 by default, ``--model q6075``) from the command
line."""

from __future__ import annotations

import argparse
import ipaddress
import os
import signal
import sys
import threading
import time

from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.sim.digest import AUTH_MODES, CHALLENGE_STYLES, NONCE_LIFETIME_S
from axis_ptz_ros2.sim.faults import FaultConfig
from axis_ptz_ros2.sim.persona import PERSONAS, persona
from axis_ptz_ros2.sim.ptz import Speeds
from axis_ptz_ros2.sim.world import load_world


def _is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _rtsp_port(asked: int | None, http_port: int) -> int | None:
    """The RTSP port to bind: as asked (-1: none), else 8554, or a free one when HTTP picks a free one too."""
    if asked is None:
        return 0 if http_port == 0 else 8554
    return None if asked < 0 else asked


def build_parser() -> argparse.ArgumentParser:
    """The CLI definition."""
    p = argparse.ArgumentParser(
        prog="axis_camera_sim",
        description="Simulated Axis PTZ network camera: the Axis 214 PTZ (VAPIX 2, default) or a current "
        "1080p PTZ dome (--model q6075: VAPIX 3, Digest, HTTPS).",
    )
    p.add_argument(
        "--model",
        default="axis214",
        help=f"camera persona: {', '.join(PERSONAS)} (aliases 214, q6075-e, modern)",
    )
    https = p.add_mutually_exclusive_group()
    https.add_argument("--https", dest="https", action="store_true", default=None, help="serve HTTPS")
    https.add_argument("--no-https", dest="https", action="store_false", help="serve plain HTTP")
    p.add_argument("--host", default="127.0.0.1", help="bind address (loopback only unless --allow-remote)")
    p.add_argument("--port", type=int, default=8080, help="TCP port (0 = pick a free one)")
    p.add_argument(
        "--rtsp-port",
        type=int,
        default=None,
        help="RTSP port of a model that streams H.264 (q6075: rtsp://host:PORT/axis-media/media.amp; a real camera "
        "uses 554, which needs root; 0 = pick a free one, -1 = no RTSP; default 8554, or a free one with --port 0)",
    )
    p.add_argument("--allow-remote", action="store_true", help="allow a non-loopback --host")
    p.add_argument("--auth", choices=AUTH_MODES, default=None, help="HTTP authentication policy (default: the model's)")
    p.add_argument("--user", default="root", help="user name for basic/digest auth")
    p.add_argument("--password", default=None, help="password (default: $AXIS_SIM_PASSWORD, else 'pass')")
    p.add_argument(
        "--nonce-lifetime", type=float, default=NONCE_LIFETIME_S, help="Digest nonce lifetime (s); then stale=true"
    )
    p.add_argument(
        "--challenge-style",
        choices=CHALLENGE_STYLES,
        default="current",
        help="401 form: current (algorithm=MD5, HTML body) or legacy (empty body, stale=FALSE, no algorithm)",
    )
    p.add_argument("--world", default=None, help="world YAML (default: config/sim_world.yaml)")
    p.add_argument("--pan-speed", type=float, default=None, help="max pan speed (deg/s; default: the model's)")
    p.add_argument("--tilt-speed", type=float, default=None, help="max tilt speed (deg/s; default: the model's)")
    p.add_argument("--zoom-time", type=float, default=None, help="full zoom travel time (s; default: the model's)")
    p.add_argument("--default-fps", type=int, default=30, help="frame rate when a client gives no fps=")
    g = p.add_argument_group("faults")
    for name in FaultConfig.field_names():
        default = getattr(FaultConfig(), name)
        flag = "--fault-" + name.replace("_", "-")
        if isinstance(default, bool):
            g.add_argument(flag, action="store_true", dest=f"fault_{name}")
        else:
            g.add_argument(flag, type=type(default), default=default, dest=f"fault_{name}")
    return p


def without_ros_args(argv: list[str]) -> list[str]:
    """``argv`` without ROS's ``--ros-args … [--]`` sections (``ros2 launch`` may add them to any executable it
    starts as a node; the simulator is no ROS node and has none)."""
    out: list[str] = []
    inside = False
    for a in argv:
        if a == "--ros-args":
            inside = True
        elif inside and a == "--":
            inside = False
        elif not inside:
            out.append(a)
    return out


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``axis_camera_sim`` console script."""
    args = build_parser().parse_args(without_ros_args(sys.argv[1:] if argv is None else argv))
    if not _is_loopback(args.host) and not args.allow_remote:
        print(f"refusing to bind non-loopback address {args.host!r} without --allow-remote", file=sys.stderr)
        return 2
    try:
        model = persona(args.model)
    except ValueError as err:
        print(str(err), file=sys.stderr)
        return 2
    password = args.password if args.password is not None else os.environ.get("AXIS_SIM_PASSWORD", "pass")
    base = model.speeds
    speeds = Speeds(
        base.pan_deg_s if args.pan_speed is None else args.pan_speed,
        base.tilt_deg_s if args.tilt_speed is None else args.tilt_speed,
        base.zoom_full_travel_s if args.zoom_time is None else args.zoom_time,
        base.focus_full_travel_s,
    )
    faults = FaultConfig(**{n: getattr(args, f"fault_{n}") for n in FaultConfig.field_names()})
    try:
        world = load_world(args.world)
    except ValueError as err:  # WorldError: names the file, the target and the field
        print(f"bad world file: {err}", file=sys.stderr)
        return 2
    cam = SimulatedCamera(
        world=world,
        host=args.host,
        port=args.port,
        auth=args.auth,
        user=args.user,
        password=password,
        faults=faults,
        speeds=speeds,
        default_fps=args.default_fps,
        nonce_lifetime_s=args.nonce_lifetime,
        challenge_style=args.challenge_style,
        model=model,
        https=args.https,
        rtsp_port=_rtsp_port(args.rtsp_port, args.port),
    )
    done = threading.Event()
    # Both stop signals explicitly: a process started in the background by a shell inherits SIGINT ignored,
    # and Python then never turns it into KeyboardInterrupt (the demo stops its children with SIGINT).
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: done.set())
    cam.start()
    tls = f"; CA certificate {cam.ca_file}" if cam.ca_file else ""
    if cam.rtsp is not None:
        tls += f"; RTSP H.264 at {cam.rtsp.url('')}"
    print(f"Simulated {model.product} at {cam.base_url}/ (auth={cam.auth}{tls}); Ctrl-C to stop", flush=True)
    try:
        while not done.wait(0.5):
            pass
    except KeyboardInterrupt:
        pass
    finally:
        for sig in (signal.SIGTERM, signal.SIGINT):  # a second signal (launch's, after the terminal's) changes
            signal.signal(sig, signal.SIG_IGN)  # nothing; SIG_IGN also survives the interpreter's finalisation
        cam.stop()
        # Let the request threads (daemons) leave before the interpreter finalises: one still inside OpenCV
        # at exit aborted the process ("terminate called without an active exception", exit -6).
        deadline = time.monotonic() + 2.0  # a frame render takes well under that; never hold the exit long
        for t in threading.enumerate():
            if t is not threading.current_thread() and t.daemon:
                t.join(max(0.0, deadline - time.monotonic()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
