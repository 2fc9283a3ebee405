"""The VAPIX endpoints of the simulated camera, other than the MJPEG stream (ROS-free, no sockets).

Each handler takes the camera, the request method, the parsed arguments (query string and form body) and the raw
query, and returns the :class:`Reply` a real camera gives (vapix.md §11): ``ptz.cgi``, ``ptzconfig.cgi``,
``param.cgi``, ``imagesize.cgi``, ``videostatus.cgi`` and the ``image.cgi`` snapshot. :func:`image_args`
validates image and video arguments for both ``image.cgi`` and the stream (:mod:`axis_ptz_ros2.sim.http.mjpeg`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from axis_ptz_ros2.sim.frames import MAX_COMPRESSION, MAX_FPS, stamp
from axis_ptz_ros2.sim.http.pages import ERROR_HTML, NOT_FOUND_HTML
from axis_ptz_ros2.sim.params import READ_ONLY_PREFIXES, list_params
from axis_ptz_ros2.sim.ptz_args import PtzCommandError
from axis_ptz_ros2.sim.request_args import int_arg
from axis_ptz_ros2.sim.view import CameraView
from axis_ptz_ros2.sim.world import PtzLimits

Args = list[tuple[str, str]]

HTML = "text/html; charset=ISO-8859-1"
ENDPOINTS: dict[str, str] = {
    "/axis-cgi/com/ptz.cgi": "ptz",
    "/axis-cgi/com/ptzconfig.cgi": "ptzconfig",
    "/axis-cgi/mjpg/video.cgi": "video",
    "/mjpg/video.mjpg": "video",
    "/axis-cgi/jpg/image.cgi": "image",
    "/axis-cgi/param.cgi": "param",
    "/axis-cgi/admin/param.cgi": "param",
    "/axis-cgi/operator/param.cgi": "param",
    "/axis-cgi/view/param.cgi": "param",
    "/axis-cgi/imagesize.cgi": "imagesize",
    "/axis-cgi/view/imagesize.cgi": "imagesize",
    "/axis-cgi/videostatus.cgi": "videostatus",
    "/axis-cgi/view/videostatus.cgi": "videostatus",
}
_LIMIT_KEYS = ("MinPan", "MaxPan", "MinTilt", "MaxTilt", "MinZoom", "MaxZoom")


@dataclass(frozen=True)
class Reply:
    """An HTTP reply: status, body, ``Content-Type`` and extra headers."""

    status: int
    body: bytes | str = b""
    ctype: str = "text/plain"
    headers: dict[str, str] = field(default_factory=dict)


def not_found(path: str) -> Reply:
    """The camera's 404 page."""
    return Reply(404, NOT_FOUND_HTML.format(path=path), HTML)


def error_page(code: int) -> Reply:
    """The camera's 500 or 503 page."""
    reason = {500: "Internal Server Error", 503: "Service Unavailable"}[code]
    return Reply(code, ERROR_HTML.format(code=code, reason=reason), HTML)


@dataclass(frozen=True)
class ImageRequest:
    """Validated ``image.cgi`` / ``video.cgi`` arguments."""

    width: int
    height: int
    compression: int
    overlay: str  #: text drawn on the picture ("" = none); strftime codes when ``clock``
    fps: int
    duration: int
    nbrofframes: int
    clock: bool


def image_args(cam: CameraView, args: Args, video: bool) -> ImageRequest:
    """Validate image/video arguments (raises :class:`ValueError` with the camera's message)."""
    a = {k.lower(): v for k, v in args}
    p = cam.params
    if a.get("camera", "1") != "1":
        raise ValueError(f"Camera {a['camera']} not available")
    squarepixel = int_arg(a, "squarepixel", 0, 1, 0)
    w, h = cam.persona.parse_resolution(a.get("resolution", p["Image.I0.Appearance.Resolution"]), squarepixel == 1)
    compression = int_arg(a, "compression", 0, MAX_COMPRESSION, int(p["Image.I0.Appearance.Compression"]))
    int_arg(a, "rotation", 0, 0, 0)
    fps, duration, nbrofframes = cam.default_fps, 0, 0
    if video:
        fps = int_arg(a, "fps", 0, MAX_FPS, cam.default_fps)
        duration = int_arg(a, "duration", 0, 10**7, 0)
        nbrofframes = int_arg(a, "nbrofframes", 0, 10**9, 0)
    parts = []
    if a.get("date") == "1":
        parts.append("%Y-%m-%d")
    if a.get("clock") == "1":
        parts.append("%H:%M:%S")
    overlay = time.strftime(" ".join(parts)) if parts else ""
    if a.get("text") == "1" and a.get("textstring"):
        overlay = (overlay + " " + a["textstring"]).strip()
    return ImageRequest(w, h, compression, overlay, fps, duration, nbrofframes, bool(parts))


def ptz(cam: CameraView, method: str, args: Args, query: str) -> Reply:
    """``ptz.cgi``: a move, a query or a preset (204 when there is nothing to say)."""
    cam.requests.log_ptz(method, query, args)
    try:
        reply = cam.state.handle(args)
    except PtzCommandError as err:
        return Reply(200, f"Error:\n{err}\n")
    return Reply(204) if reply is None else Reply(200, reply)


def ptzconfig(cam: CameraView, method: str, args: Args, query: str) -> Reply:
    """``ptzconfig.cgi``."""
    cam.requests.log_ptz(method, query, args)
    try:
        cam.state.handle_config(args)
    except PtzCommandError as err:
        return Reply(200, f"Error:\n{err}\n")
    return Reply(204)


def param(cam: CameraView, method: str, args: Args, query: str) -> Reply:
    """``param.cgi``: ``action=list`` and ``action=update`` (new PTZ limits apply to the head at once)."""
    action = next((v for k, v in args if k == "action"), "")
    if action == "list":
        groups = [g for k, v in args if k == "group" for g in v.split(",") if g]
        return Reply(200, list_params(cam.current_params(), groups))
    if action != "update":
        return Reply(200, f"# Error: Invalid action '{action}'\n")
    lines: list[str] = []
    limits_changed = False
    for k, v in args:
        if k in ("action", "usergroup"):
            continue
        name = k[5:] if k.startswith("root.") else k
        if name not in cam.params or name.startswith(READ_ONLY_PREFIXES):
            lines.append(f"# Error: Error setting '{k}' to '{v}'!")
            continue
        if name.startswith("PTZ.Limit.L1."):
            try:
                float(v)
            except ValueError:
                lines.append(f"# Error: Error setting '{k}' to '{v}'!")
                continue
            limits_changed = True
        cam.params[name] = v
    if limits_changed:
        lim = [float(cam.params[f"PTZ.Limit.L1.{key}"]) for key in _LIMIT_KEYS]
        cam.state.set_limits(PtzLimits(lim[0], lim[1], lim[2], lim[3], int(lim[4]), int(lim[5])))
    return Reply(200, "\n".join(lines) + "\n" if lines else "OK\n")


def imagesize(cam: CameraView, method: str, args: Args, query: str) -> Reply:
    """``imagesize.cgi``."""
    if cam.faults.no_imagesize:  # firmware without imagesize.cgi (issue 23)
        return not_found("/axis-cgi/imagesize.cgi")
    a = dict(args)
    camera = a.get("camera", "1")
    if camera != "1":
        return Reply(200, f"<!-- Camera {camera} not available. -->\n")
    try:
        w, h = cam.persona.parse_resolution(
            a.get("resolution", cam.params["Image.I0.Appearance.Resolution"]), a.get("squarepixel") == "1"
        )
    except ValueError as err:
        return Reply(200, f"<!-- {err} -->\n")
    return Reply(200, f"image width = {w}\nimage height = {h}\n")


def videostatus(cam: CameraView, method: str, args: Args, query: str) -> Reply:
    """``videostatus.cgi``."""
    return Reply(200, "Video 1 = video\n")


def image(cam: CameraView, method: str, args: Args, query: str) -> Reply:
    """``image.cgi``: one stamped JPEG snapshot."""
    try:
        req = image_args(cam, args, video=False)
    except ValueError as err:
        return Reply(400, f"Error:\n{err}\n")
    jpeg = stamp(cam.frame_jpeg(req.width, req.height, req.compression, req.overlay), cam.count_snapshot())
    return Reply(200, jpeg, "image/jpeg", {"Cache-Control": "no-cache", "Pragma": "no-cache"})


#: handlers by endpoint name (the MJPEG stream, ``video``, is served by :mod:`axis_ptz_ros2.sim.http.mjpeg`)
HANDLERS: dict[str, Callable[[CameraView, str, Args, str], Reply]] = {
    "ptz": ptz,
    "ptzconfig": ptzconfig,
    "param": param,
    "imagesize": imagesize,
    "videostatus": videostatus,
    "image": image,
}
