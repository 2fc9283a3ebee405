"""The text the simulated head answers ``ptz.cgi`` queries with (vapix.md §4.4, §4.5; ROS-free).

Numbers as the camera formats them, the ``info=1`` command list, ``query=limits`` and ``query=attributes``: pure
functions of the head's limits, zoom model and speeds. The replies that read the head's live state
(``query=position``, ``speed``, presets) are written by :class:`axis_ptz_ros2.sim.ptz.PtzState`.
"""

from __future__ import annotations

import json
import math
from typing import Any

from axis_ptz_ros2.optics import ZoomModel
from axis_ptz_ros2.sim.world import PtzLimits


def format_number(v: float) -> str:
    """VAPIX position formatting: at most 4 decimals, trailing zeros (and a bare point) stripped."""
    s = f"{v:.4f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


INFO_TEXT = """Available commands
:
{camera=[n]}
whoami=yes
center=[x],[y]
   imagewidth=[n]
   imageheight=[n]
areazoom=[x],[y],[z]
   imagewidth=[n]
   imageheight=[n]
move={ home | up | down | left | right | upleft | upright | downleft | downright | stop }
pan=[abspos]
tilt=[abspos]
zoom=[n]
focus=[n]
iris=[n]
brightness=[offset]
rpan=[offset]
rtilt=[offset]
rzoom=[offset]
rfocus=[offset]
riris=[offset]
rbrightness=[offset]
autofocus={ on | off }
autoiris={ on | off }
ircutfilter={ on | off | auto }
backlight={ on | off }
continuouspantiltmove=[x-speed],[y-speed]
continuouszoommove=[speed]
continuousfocusmove=[speed]
setserverpresetname=[name]
setserverpresetno=[n]
removeserverpresetname=[name]
removeserverpresetno=[n]
gotoserverpresetname=[name]
gotoserverpresetno=[n]
speed=[n]
query={ speed | position | limits | presetposcam | presetposall }
"""


def info_reply(attributes: bool) -> str:
    """The ``info=1`` command list (with ``query=attributes`` on firmware that knows it)."""
    if attributes:
        return INFO_TEXT.replace("presetposall }", "presetposall | attributes }")
    return INFO_TEXT


def limits_reply(limits: PtzLimits, zm: ZoomModel) -> str:
    """``query=limits``."""
    lines = [
        f"MinPan={format_number(limits.min_pan)}",
        f"MaxPan={format_number(limits.max_pan)}",
        f"MinTilt={format_number(limits.min_tilt)}",
        f"MaxTilt={format_number(limits.max_tilt)}",
        f"MinZoom={limits.min_zoom}",
        f"MaxZoom={limits.max_zoom}",
        "MinIris=1",
        "MaxIris=9999",
        "MinFocus=1",
        "MaxFocus=9999",
        f"MinFieldAngle={max(1, int(round(math.degrees(zm.hfov(zm.optical_max_zoom or limits.max_zoom)) * 10)))}",
        f"MaxFieldAngle={int(round(math.degrees(zm.hfov(limits.min_zoom)) * 10))}",
        "MinBrightness=1",
        "MaxBrightness=9999",
    ]
    return "\n".join(lines) + "\n"


def zoom_steps(limits: PtzLimits, zm: ZoomModel) -> list[tuple[int, float]]:
    """``zoomSteps`` of ``query=attributes``: (zoom units, magnification) at whole magnifications of the
    optical range, the optical end and the digital end."""
    top = zm.magnification(limits.max_zoom)
    optical_end = zm.optical_max_zoom or limits.max_zoom
    steps = {limits.min_zoom: zm.magnification(limits.min_zoom), optical_end: zm.magnification(optical_end)}
    for m in range(2, int(zm.magnification(optical_end)) + 1):
        steps[int(round(zm.zoom_for_magnification(float(m))))] = float(m)
    steps[limits.max_zoom] = top
    return sorted(steps.items())


def attributes_reply(limits: PtzLimits, zm: ZoomModel, pan_deg_s: float, as_json: bool) -> str:
    """``query=attributes`` (``format=json`` or text) of a head whose top pan speed is ``pan_deg_s``."""
    optical_end = zm.optical_max_zoom or limits.max_zoom
    optical = zm.magnification(optical_end)
    digital = zm.magnification(limits.max_zoom) / optical
    steps = zoom_steps(limits, zm)
    # VAPIX speed value → deg/s of this head (linear in the simulator).
    speeds = [(v, pan_deg_s * v / 100.0) for v in (1, 10, 25, 50, 75, 100)]
    if as_json:
        cam: dict[str, Any] = {
            "maxOpticalZoomMag": format_number(optical),
            "zoomSteps": [{"value": str(z), "zoom": format_number(m)} for z, m in steps],
            "speeds": [{"value": str(v), "speed": format_number(sp)} for v, sp in speeds],
        }
        if digital > 1.0 + 1e-9:
            cam["maxDigitalZoomMag"] = format_number(digital)
        return json.dumps({"Camera 1": cam}) + "\n"
    lines = [
        "Attributes for camera 1",
        "speeds=" + ",".join(f"value={v} | speed={format_number(sp)}" for v, sp in speeds),
        f"maxOpticalZoomMag={format_number(optical)}",
    ]
    if digital > 1.0 + 1e-9:
        lines.append(f"maxDigitalZoomMag={format_number(digital)}")
    lines.append("zoomSteps=" + ",".join(f"value={z} | zoom={format_number(m)}" for z, m in steps))
    return "\n".join(lines) + "\n"
