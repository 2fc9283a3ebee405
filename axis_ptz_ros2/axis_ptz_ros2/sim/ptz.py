"""The simulated PTZ head: state and dynamics behind ``ptz.cgi``/``ptzconfig.cgi`` (ROS-free).

Implements vapix.md §4 and the simulator contract of §11: a request is validated as a whole first
(:mod:`axis_ptz_ros2.sim.ptz_args`: malformed numbers and unknown arguments → ``Error:`` and *nothing* changes),
in-range values beyond ``PTZ.Limit`` are clamped (§4.3 simulator rule), motion is finite-speed and integrated
lazily from a monotonic clock, and any absolute/relative command cancels continuous motion.

Sign convention (written here once, independently of :class:`axis_ptz_ros2.geometry.VapixConvention`, so a
sign bug in the driver is not silently cancelled by the simulator): **VAPIX +pan = the camera turns right =
clockwise seen from above = towards −y of ``base_link``**, so ``yaw_rad = −radians(pan_deg)``; **+tilt = up**,
so ``elevation_rad = +radians(tilt_deg)``.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from axis_ptz_ros2.geometry import center_on_pixel
from axis_ptz_ros2.optics import ZoomModel
from axis_ptz_ros2.sim.ptz_args import MOVES, HeadFacts, Plan, parse_ptz, parse_ptzconfig
from axis_ptz_ros2.sim.ptz_replies import attributes_reply, format_number, info_reply, limits_reply
from axis_ptz_ros2.sim.world import PtzLimits


# --------------------------------------------------------------------------------------------------------
# The simulator's own sign mapping (see the module docstring).
# --------------------------------------------------------------------------------------------------------
def vapix_to_ros(pan_deg: float, tilt_deg: float) -> tuple[float, float]:
    """VAPIX degrees (+pan right, +tilt up) → REP-103 radians (+yaw left/CCW, +elevation up)."""
    return -math.radians(pan_deg), math.radians(tilt_deg)


def ros_to_vapix(pan_rad: float, tilt_rad: float) -> tuple[float, float]:
    """REP-103 radians → VAPIX degrees (inverse of :func:`vapix_to_ros`)."""
    return -math.degrees(pan_rad), math.degrees(tilt_rad)


MOVE_STEP_DEG = 5.0  # VAPIX v2 (214 era): "moves the device 5 degrees in the specified direction"


@dataclass(frozen=True, slots=True)
class Speeds:
    """Maximum speeds of the simulated head (vapix.md §7 simulator defaults)."""

    pan_deg_s: float = 100.0
    tilt_deg_s: float = 90.0
    zoom_full_travel_s: float = 3.5
    focus_full_travel_s: float = 1.5


@dataclass
class Preset:
    """A server preset (number, name, VAPIX pose)."""

    number: int
    name: str
    pan: float
    tilt: float
    zoom: float


@dataclass
class _Axis:
    """One motion axis: position, absolute target (or None) and continuous velocity (units/s)."""

    pos: float
    target: float | None = None
    velocity: float = 0.0

    def step(self, dt: float, vmax: float, lo: float, hi: float) -> None:
        if self.velocity != 0.0:
            self.pos = min(max(self.pos + self.velocity * dt, lo), hi)
            if self.pos in (lo, hi) and (self.velocity > 0) == (self.pos == hi):
                self.velocity = 0.0  # ran into a limit
        elif self.target is not None:
            d = self.target - self.pos
            stepmax = vmax * dt
            if abs(d) <= stepmax:
                self.pos, self.target = self.target, None
            else:
                self.pos += math.copysign(stepmax, d)

    def moving(self) -> bool:
        return self.velocity != 0.0 or self.target is not None


@dataclass
class PtzState:
    """Thread-safe state and dynamics of the simulated head. All public angles are VAPIX degrees."""

    zoom_model: ZoomModel  # the optics: the world file's or the persona's (no camera's figures in code)
    limits: PtzLimits = field(default_factory=PtzLimits)
    speeds: Speeds = field(default_factory=Speeds)
    default_image_size: tuple[int, int] = (704, 576)
    clock: Callable[[], float] = time.monotonic
    move_step_fov: float = 0.0  # move=<dir>: 0 → 5° (VAPIX v2), else this fraction of the current HFOV (v3)
    attributes: bool = False  # query=attributes answered (newer firmware only)
    whoami: str = "Sony_camblock"

    def __post_init__(self) -> None:
        self._lock = threading.RLock()
        self._pan = _Axis(0.0)
        self._tilt = _Axis(0.0)
        self._zoom = _Axis(1.0)
        self._focus = _Axis(5000.0)
        self.iris = 5000
        self.brightness = 4999
        self.autofocus = True
        self.autoiris = True
        self.ircutfilter = "auto"
        self.backlight = False
        self.speed = 100
        self.presets: dict[int, Preset] = {1: Preset(1, "Home", 0.0, 0.0, 1.0)}
        self.home = 1
        self._t = self.clock()

    # ---- dynamics -----------------------------------------------------------------------------------
    def _update(self) -> None:
        now = self.clock()
        dt = max(0.0, now - self._t)
        self._t = now
        if dt == 0.0:
            return
        s = self.speed / 100.0
        L = self.limits
        if self.pan_wraps:  # endless pan: no end stops; keep the reading in [-180, 180)
            self._pan.step(dt, self.speeds.pan_deg_s * s, -math.inf, math.inf)
            shift = 360.0 * math.floor((self._pan.pos + 180.0) / 360.0)
            if shift:
                self._pan.pos -= shift
                if self._pan.target is not None:
                    self._pan.target -= shift
        else:
            self._pan.step(dt, self.speeds.pan_deg_s * s, L.min_pan, L.max_pan)
        self._tilt.step(dt, self.speeds.tilt_deg_s * s, L.min_tilt, L.max_tilt)
        zrate = (L.max_zoom - L.min_zoom) / self.speeds.zoom_full_travel_s
        self._zoom.step(dt, zrate, float(L.min_zoom), float(L.max_zoom))
        self._focus.step(dt, 9998.0 / self.speeds.focus_full_travel_s, 1.0, 9999.0)

    def position(self) -> tuple[float, float, float]:
        """True current (pan°, tilt°, zoom units) — intermediate while moving."""
        with self._lock:
            self._update()
            return self._pan.pos, self._tilt.pos, self._zoom.pos

    def moving(self) -> bool:
        """Whether any axis is still moving."""
        with self._lock:
            self._update()
            return self._pan.moving() or self._tilt.moving() or self._zoom.moving()

    def reset(self) -> None:
        """Power-on state (after a reboot): at the home position, stopped."""
        with self._lock:
            home = self.presets.get(self.home, Preset(0, "Home", 0.0, 0.0, 1.0))
            self._pan, self._tilt, self._zoom = _Axis(home.pan), _Axis(home.tilt), _Axis(home.zoom)
            self._t = self.clock()

    def arrive_now(self, pan: float, tilt: float, zoom: float) -> None:
        """Put the head at a VAPIX pose at once (clamped to the limits), every motion stopped."""
        if not all(math.isfinite(v) for v in (pan, tilt, zoom)):
            raise ValueError(f"pose must be finite: {pan}, {tilt}, {zoom}")
        with self._lock:
            self._update()
            self._cancel_continuous()
            self._pan = _Axis(self._clamp_pan(pan))
            self._tilt = _Axis(self._clamp_tilt(tilt))
            self._zoom = _Axis(self._clamp_zoom(zoom))

    def set_limits(self, limits: PtzLimits) -> None:
        """Change ``PTZ.Limit.L1`` (positions are clamped into the new box)."""
        with self._lock:
            self._update()
            self.limits = limits
            self._pan.pos = self._clamp_pan(self._pan.pos)
            self._tilt.pos = self._clamp_tilt(self._tilt.pos)
            self._zoom.pos = self._clamp_zoom(self._zoom.pos)

    @property
    def pan_wraps(self) -> bool:
        """Endless pan: the limits span the full circle (MinPan=-180, MaxPan=180 on a modern dome)."""
        return self.limits.max_pan - self.limits.min_pan >= 360.0 - 1e-9

    def _clamp_pan(self, v: float) -> float:
        if self.pan_wraps:
            return v - 360.0 * math.floor((v + 180.0) / 360.0)
        return min(max(v, self.limits.min_pan), self.limits.max_pan)

    def _clamp_tilt(self, v: float) -> float:
        return min(max(v, self.limits.min_tilt), self.limits.max_tilt)

    def _clamp_zoom(self, v: float) -> float:
        return min(max(v, float(self.limits.min_zoom)), float(self.limits.max_zoom))

    # ---- command language ---------------------------------------------------------------------------
    def handle(self, args: list[tuple[str, str]]) -> str | None:
        """Execute one ``ptz.cgi`` request. Returns the 200 text body of a query, or None for a command
        (→ 204). Raises :class:`~axis_ptz_ros2.sim.ptz_args.PtzCommandError` (→ ``200 Error:``) without changing
        anything."""
        with self._lock:
            self._update()
            plan = parse_ptz(args, self._facts())
            return self._apply(plan)

    def _facts(self) -> HeadFacts:
        names = frozenset(p.name for p in self.presets.values())
        return HeadFacts(self.limits.max_zoom, self.attributes, names, frozenset(self.presets))

    def _preset_by_name(self, name: str) -> Preset | None:
        return next((p for p in self.presets.values() if p.name == name), None)

    def _cancel_continuous(self) -> None:
        self._pan.velocity = self._tilt.velocity = self._zoom.velocity = self._focus.velocity = 0.0

    def _goto(self, pan: float | None, tilt: float | None, zoom: float | None) -> None:
        self._cancel_continuous()
        if pan is not None and self.pan_wraps:  # the short way round, across ±180 if that is shorter
            self._pan.target = self._pan.pos + math.remainder(pan - self._pan.pos, 360.0)
        elif pan is not None:
            self._pan.target = self._clamp_pan(pan)
        if tilt is not None:
            self._tilt.target = self._clamp_tilt(tilt)
        if zoom is not None:
            self._zoom.target = self._clamp_zoom(zoom)

    def _apply(self, plan: Plan) -> str | None:  # noqa: C901 - a flat dispatch table
        pan, tilt, zoom = self._pan.pos, self._tilt.pos, self._zoom.pos
        if "speed" in plan:
            self.speed = int(plan["speed"])
        for key in ("autofocus", "autoiris", "backlight"):
            if key in plan:
                setattr(self, key, bool(plan[key]))
        if "ircutfilter" in plan:
            self.ircutfilter = str(plan["ircutfilter"])
        if "iris" in plan:
            self.iris = int(plan["iris"])
        if "riris" in plan:
            self.iris = min(9999, max(1, self.iris + int(plan["riris"])))
        if "brightness" in plan:
            self.brightness = int(plan["brightness"])
        if "rbrightness" in plan:
            self.brightness = min(9999, max(1, self.brightness + int(plan["rbrightness"])))
        if "focus" in plan or "rfocus" in plan:
            f = float(plan["focus"]) if "focus" in plan else self._focus.pos + float(plan["rfocus"])
            self._focus.target = min(9999.0, max(1.0, f))
            self.autofocus = False
        # Absolute / relative pose.
        new_pan = float(plan["pan"]) if "pan" in plan else None
        new_tilt = float(plan["tilt"]) if "tilt" in plan else None
        new_zoom = float(plan["zoom"]) if "zoom" in plan else None
        if "rpan" in plan:
            new_pan = pan + float(plan["rpan"])
        if "rtilt" in plan:
            new_tilt = tilt + float(plan["rtilt"])
        if "rzoom" in plan:
            new_zoom = zoom + float(plan["rzoom"])
        if "center" in plan or "areazoom" in plan:
            xy = plan.get("center", plan.get("areazoom"))
            assert isinstance(xy, list)
            w = int(plan.get("imagewidth", self.default_image_size[0]))
            h = int(plan.get("imageheight", self.default_image_size[1]))
            intr = self.zoom_model.intrinsics(zoom, w, h)
            p_ros, t_ros = vapix_to_ros(pan, tilt)
            np_ros, nt_ros = center_on_pixel(p_ros, t_ros, xy[0], xy[1], intr)
            new_pan, new_tilt = ros_to_vapix(np_ros, nt_ros)
            if "areazoom" in plan:
                m = self.zoom_model.magnification(zoom) * xy[2] / 100.0
                new_zoom = self.zoom_model.zoom_for_magnification(m)
        if "move" in plan:
            mv = str(plan["move"])
            if mv == "stop":
                self._cancel_continuous()
                self._pan.target = self._tilt.target = None
            elif mv == "home":
                p = self.presets.get(self.home, Preset(0, "Home", 0.0, 0.0, 1.0))
                new_pan, new_tilt, new_zoom = p.pan, p.tilt, p.zoom
            else:
                dx, dy = MOVES[mv]
                step = MOVE_STEP_DEG
                if self.move_step_fov > 0.0:  # v3: "moves the image 25 % of the image field width"
                    step = self.move_step_fov * math.degrees(self.zoom_model.hfov(zoom))
                if dx:
                    new_pan = pan + dx * step
                if dy:
                    new_tilt = tilt + dy * step
        for key in ("gotoserverpresetname", "gotoserverpresetno"):
            if key in plan:
                pre = self._preset_by_name(str(plan[key])) if key.endswith("name") else self.presets[int(plan[key])]
                assert pre is not None
                new_pan, new_tilt, new_zoom = pre.pan, pre.tilt, pre.zoom
        if new_pan is not None or new_tilt is not None or new_zoom is not None:
            self._goto(new_pan, new_tilt, new_zoom)
        # Continuous moves (after absolute ones so that a combined request ends with the velocity).
        if "continuouspantiltmove" in plan:
            vp, vt = plan["continuouspantiltmove"]
            self._pan.target = self._tilt.target = None
            self._pan.velocity = self.speeds.pan_deg_s * vp / 100.0
            self._tilt.velocity = self.speeds.tilt_deg_s * vt / 100.0
        if "continuouszoommove" in plan:
            self._zoom.target = None
            L = self.limits
            self._zoom.velocity = (
                (L.max_zoom - L.min_zoom) / self.speeds.zoom_full_travel_s * float(plan["continuouszoommove"]) / 100.0
            )
        if "continuousfocusmove" in plan:
            self._focus.target = None
            self._focus.velocity = 9998.0 / self.speeds.focus_full_travel_s * float(plan["continuousfocusmove"]) / 100.0
        # Presets (legacy ptz.cgi forms; ptzconfig.cgi uses the same code).
        self._apply_presets(plan, pan, tilt, zoom)
        # Replies.
        if "query" in plan:
            if plan["query"] == "attributes":
                as_json = plan.get("format") == "json"
                return attributes_reply(self.limits, self.zoom_model, self.speeds.pan_deg_s, as_json)
            return self._query(str(plan["query"]))
        if "info" in plan:
            return info_reply(self.attributes)
        if "whoami" in plan:
            return self.whoami + "\n"
        return None

    def _apply_presets(self, plan: Plan, pan: float, tilt: float, zoom: float) -> None:
        if "setserverpresetname" in plan:
            name = str(plan["setserverpresetname"])
            old = self._preset_by_name(name)
            num = old.number if old else next(n for n in range(1, 1002) if n not in self.presets)
            self.presets[num] = Preset(num, name, pan, tilt, zoom)
            if plan.get("home") is True:
                self.home = num
        if "setserverpresetno" in plan:
            num = int(plan["setserverpresetno"])
            name = self.presets[num].name if num in self.presets else f"Preset {num}"
            self.presets[num] = Preset(num, name, pan, tilt, zoom)
            if plan.get("home") is True:
                self.home = num
        if "removeserverpresetname" in plan:
            pre = self._preset_by_name(str(plan["removeserverpresetname"]))
            if pre is not None:
                del self.presets[pre.number]
        if "removeserverpresetno" in plan:
            self.presets.pop(int(plan["removeserverpresetno"]), None)

    def handle_config(self, args: list[tuple[str, str]]) -> None:
        """``ptzconfig.cgi`` (vapix.md §4.6): preset management; raises
        :class:`~axis_ptz_ros2.sim.ptz_args.PtzCommandError` without changing anything."""
        with self._lock:
            self._update()
            plan = parse_ptzconfig(args, self._facts())
            self._apply_presets(plan, self._pan.pos, self._tilt.pos, self._zoom.pos)
            if "rename" in plan:
                self.presets[int(plan["rename"])].name = str(plan["newname"])
            if "removeall" in plan:
                self.presets.clear()

    def _query(self, what: str) -> str:
        if what == "position":
            lines = [
                f"pan={format_number(self._pan.pos)}",
                f"tilt={format_number(self._tilt.pos)}",
                f"zoom={int(round(self._zoom.pos))}",
                f"iris={self.iris}",
                f"focus={int(round(self._focus.pos))}",
                f"brightness={self.brightness}",
                f"autofocus={'on' if self.autofocus else 'off'}",
                f"autoiris={'on' if self.autoiris else 'off'}",
            ]
        elif what == "limits":
            return limits_reply(self.limits, self.zoom_model)
        elif what == "speed":
            lines = [f"speed={self.speed}"]
        elif what == "mode":
            lines = ["mode=normal"]  # the only value seen from real cameras (vapix.md §4.4)
        else:  # presetposcam / presetposall
            lines = ["Preset Positions for camera 1"]
            lines += [f"presetposno{n}={p.name}" for n, p in sorted(self.presets.items())]
        return "\n".join(lines) + "\n"

    def presets_snapshot(self) -> list[Preset]:
        """Copies of the presets, by number."""
        with self._lock:
            return [Preset(p.number, p.name, p.pan, p.tilt, p.zoom) for _, p in sorted(self.presets.items())]
