"""The ``ptz.cgi`` and ``ptzconfig.cgi`` argument language of the simulated head (vapix.md §4, §4.6; ROS-free).

A request is validated as a whole into a *plan* (lower-case argument name → typed value) before anything changes:
ranges from the VAPIX documentation, malformed numbers, repeated and unknown arguments → :class:`PtzCommandError`
(the camera's ``200 Error:``). What a plan does to the head is :class:`axis_ptz_ros2.sim.ptz.PtzState`'s business;
the few checks that depend on its state (zoom range, presets, firmware features) take that state as arguments.
"""

from __future__ import annotations

import math
import re
from collections.abc import Collection
from dataclasses import dataclass
from typing import Any

Plan = dict[str, Any]  #: a validated request: lower-case argument name → typed value


class PtzCommandError(ValueError):
    """A request the camera answers with ``200 Error:\\n<message>\\n``."""


@dataclass(frozen=True, slots=True)
class HeadFacts:
    """What validating a request needs to know of the head's state."""

    max_zoom: int  #: ``MaxZoom``: zoom arguments accept up to ``max(max_zoom, 9999)``
    attributes: bool  #: the firmware knows ``query=attributes`` and ``format=``
    preset_names: Collection[str]  #: ``goto``/``remove`` of any other preset is refused
    preset_numbers: Collection[int]


MOVES = {
    "up": (0.0, 1.0),
    "down": (0.0, -1.0),
    "left": (-1.0, 0.0),
    "right": (1.0, 0.0),
    "upleft": (-1.0, 1.0),
    "upright": (1.0, 1.0),
    "downleft": (-1.0, -1.0),
    "downright": (1.0, -1.0),
}  #: ``move=<direction>`` → (pan sign, tilt sign)
_QUERIES = ("position", "limits", "speed", "presetposcam", "presetposall", "attributes", "mode")
_PRESET_NAME = re.compile(r'^[^"<>~:]{1,31}$')


def _float(key: str, value: str, lo: float, hi: float) -> float:
    try:
        v = float(value)
    except ValueError as err:
        raise PtzCommandError(f"{key}: invalid value: {value}") from err
    if not math.isfinite(v) or not lo <= v <= hi:
        raise PtzCommandError(f"{key}: value out of range: {value}")
    return v


def _int(key: str, value: str, lo: int, hi: int) -> int:
    """VAPIX integers: float input is truncated ("with no guarantee of rounding")."""
    return int(_float(key, value, lo, hi))


def _pair(key: str, value: str, lo: float, hi: float, n: int = 2) -> list[float]:
    parts = value.split(",")
    if len(parts) != n:
        raise PtzCommandError(f"{key}: expected {n} comma separated values: {value}")
    return [_float(key, p, lo, hi) for p in parts]


def parse_ptz(args: list[tuple[str, str]], head: HeadFacts) -> Plan:
    """Validate one ``ptz.cgi`` request into a plan for the head described by ``head``; raises
    :class:`PtzCommandError`."""
    if not args:
        raise PtzCommandError("no arguments")
    plan: Plan = {}
    ztop = int(max(float(head.max_zoom), 9999))
    for raw_key, value in args:
        key = raw_key.lower()
        if key in plan and key not in ("camera",):
            raise PtzCommandError(f"{key}: given more than once")
        if key == "camera":
            if value not in ("1",):
                raise PtzCommandError(f"camera: invalid value: {value}")
            plan[key] = 1
        elif key in ("pan", "tilt"):
            plan[key] = _float(key, value, -180.0, 180.0)
        elif key in ("rpan", "rtilt"):
            plan[key] = _float(key, value, -360.0, 360.0)
        elif key == "zoom":
            plan[key] = float(_int(key, value, 1, ztop))
        elif key in ("focus", "iris", "brightness"):
            plan[key] = _int(key, value, 1, 9999)
        elif key == "rzoom":
            plan[key] = float(_int(key, value, -ztop, ztop))
        elif key in ("rfocus", "riris", "rbrightness"):
            plan[key] = _int(key, value, -9999, 9999)
        elif key in ("autofocus", "autoiris", "backlight"):
            if value not in ("on", "off"):
                raise PtzCommandError(f"{key}: invalid value: {value}")
            plan[key] = value == "on"
        elif key == "ircutfilter":
            if value not in ("on", "off", "auto"):
                raise PtzCommandError(f"{key}: invalid value: {value}")
            plan[key] = value
        elif key == "continuouspantiltmove":
            plan[key] = _pair(key, value, -100.0, 100.0)
        elif key in (
            "continuouszoommove",
            "continuousfocusmove",
            "continuousirismove",
            "continuousbrightnessmove",
        ):
            plan[key] = _float(key, value, -100.0, 100.0)
        elif key == "speed":
            plan[key] = _int(key, value, 1, 100)
        elif key == "move":
            if value not in MOVES and value not in ("home", "stop"):
                raise PtzCommandError(f"move: unknown value: {value}")
            plan[key] = value
        elif key == "center":
            plan[key] = _pair(key, value, -1e6, 1e6)
        elif key == "areazoom":
            x, y, z = _pair(key, value, -1e6, 1e6, 3)
            if z < 1:
                raise PtzCommandError(f"areazoom: invalid zoom factor: {value}")
            plan[key] = [x, y, z]
        elif key in ("imagewidth", "imageheight"):
            plan[key] = _int(key, value, 1, 100000)
        elif key == "query":
            if value not in _QUERIES or (value == "attributes" and not head.attributes):
                raise PtzCommandError(f"query: unknown value: {value}")
            plan[key] = value
        elif key == "format" and head.attributes:
            if value not in ("json", "text"):
                raise PtzCommandError(f"format: invalid value: {value}")
            plan[key] = value
        elif key in ("info", "whoami"):
            if value not in ("1", "yes"):
                raise PtzCommandError(f"{key}: invalid value: {value}")
            plan[key] = True
        elif key in ("gotoserverpresetname", "setserverpresetname", "removeserverpresetname"):
            if not _PRESET_NAME.match(value):
                raise PtzCommandError(f"{key}: invalid preset name: {value}")
            if key != "setserverpresetname" and value not in head.preset_names:
                raise PtzCommandError(f"{key}: no such preset: {value}")
            plan[key] = value
        elif key in ("gotoserverpresetno", "setserverpresetno", "removeserverpresetno"):
            n = _int(key, value, 1, 1000)
            if key != "setserverpresetno" and n not in head.preset_numbers:
                raise PtzCommandError(f"{key}: no such preset: {value}")
            plan[key] = n
        elif key == "imagerotation":
            if value not in ("0", "90", "180", "270"):
                raise PtzCommandError(f"{key}: invalid value: {value}")
            plan[key] = int(value)
        else:
            raise PtzCommandError(f"Unknown argument: {raw_key}")
    if "center" in plan and "areazoom" in plan:  # both name the point to centre on (the camera's answer: a guess)
        raise PtzCommandError("center and areazoom cannot be combined")
    if ("imagewidth" in plan or "imageheight" in plan) and not ("center" in plan or "areazoom" in plan):
        raise PtzCommandError("imagewidth/imageheight only valid with center or areazoom")
    return plan


def parse_ptzconfig(args: list[tuple[str, str]], head: HeadFacts) -> Plan:
    """Validate one ``ptzconfig.cgi`` request (vapix.md §4.6, preset management); raises :class:`PtzCommandError`.

    The plan holds the ``ptz.cgi`` preset arguments it shares with :func:`parse_ptz` plus ``home`` (the preset
    being set becomes home), ``rename``/``newname`` and ``removeall``.
    """
    plan: Plan = {}
    rest: list[tuple[str, str]] = []
    for k, v in args:
        kl = k.lower()
        if kl == "home":
            if v != "yes":
                raise PtzCommandError(f"home: invalid value: {v}")
            plan["home"] = True
        elif kl == "removeallserverpresets":
            if v != "yes":
                raise PtzCommandError(f"{k}: invalid value: {v}")
            plan["removeall"] = True
        elif kl == "renameserverpresetno":
            plan["rename"] = _int(kl, v, 1, 1000)
        elif kl == "newname":
            if not _PRESET_NAME.match(v):
                raise PtzCommandError(f"newname: invalid preset name: {v}")
            plan["newname"] = v
        elif kl in (
            "setserverpresetname",
            "setserverpresetno",
            "removeserverpresetname",
            "removeserverpresetno",
            "camera",
        ):
            rest.append((kl, v))
        else:
            raise PtzCommandError(f"Unknown argument: {k}")
    if "rename" in plan and ("newname" not in plan or int(plan["rename"]) not in head.preset_numbers):
        raise PtzCommandError("renameserverpresetno: no such preset or missing newname")
    if "home" in plan and not any(k.startswith("setserverpreset") for k, _ in rest):
        raise PtzCommandError("home=yes needs setserverpresetname or setserverpresetno")
    if rest:
        plan.update(parse_ptz(rest, head))
    return plan
