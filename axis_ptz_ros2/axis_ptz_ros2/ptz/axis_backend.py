"""The Axis (VAPIX) implementation of :class:`~axis_ptz_ros2.ptz.backend.PtzBackend` (ROS-free).

Two kept-alive :class:`~axis_ptz_ros2.vapix.VapixClient` connections: one for commands (used by the node's
single command worker) and one for state polling, so a poll never waits behind a move request and vice versa.
Units are converted only through :class:`~axis_ptz_ros2.geometry.VapixConvention`.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import replace

from axis_ptz_ros2.config import CameraModel
from axis_ptz_ros2.geometry import wrap_angle
from axis_ptz_ros2.ptz.backend import PresetInfo, PtzBackendError, PtzLimitsRos, PtzReading
from axis_ptz_ros2.vapix import (
    AbsoluteMove,
    AxisPtzError,
    CameraConfig,
    ContinuousMove,
    GotoPreset,
    Move,
    MoveDirection,
    PtzLimits,
    PtzRequest,
    RemovePreset,
    SetPreset,
    VapixClient,
)
from axis_ptz_ros2.vapix.keepalive import KeepAliveTransport

LIMITS_RETRY_S = 5.0  #: while only fallback limits are known, ask the camera again this often


def speed_to_vapix(rate: float, max_rate: float) -> int:
    """A signed rate as a VAPIX continuous speed −100..100 (a non-zero rate never rounds to a stop)."""
    if rate == 0.0 or not math.isfinite(rate) or max_rate <= 0.0:
        return 0
    s = max(-100.0, min(100.0, 100.0 * rate / max_rate))
    n = int(round(s))
    return n if n != 0 else (1 if s > 0 else -1)


class AxisBackend:
    """A VAPIX PTZ head in ROS units (see :class:`~axis_ptz_ros2.ptz.backend.PtzBackend`)."""

    def __init__(
        self,
        config: CameraConfig,
        model: CameraModel,
        *,
        state_timeout_s: float | None = None,
        command_client: VapixClient | None = None,
        state_client: VapixClient | None = None,
    ) -> None:
        """``state_timeout_s`` bounds one poll (default: the config's timeout); clients may be injected."""
        self._model = model
        self._conv = model.convention
        self._cmd = command_client or VapixClient(config)
        state_cfg = config if state_timeout_s is None else replace(config, timeout_s=state_timeout_s)
        if state_client is None:
            # the poll's 20 requests a second go over http.client (keepalive.py says why, with the figures)
            verify = state_cfg.ssl_verify() if state_cfg.use_https else True
            transport = KeepAliveTransport(verify)
            state_client = VapixClient(state_cfg, auth_counters=self._cmd.auth_counters, transport=transport)
        self._state = state_client
        self.auth_counters = self._cmd.auth_counters  #: Digest re-challenges etc. (for /diagnostics)
        self._lock = threading.Lock()
        self._limits: PtzLimitsRos | None = None
        self._limits_from_camera = False
        self._limits_tried = -math.inf
        self.limits_source = "none"

    def fixed_camera_reason(self) -> str:
        """Non-empty when the camera says it has no mechanical PTZ (``PTZ.ImageSource.I0.PTZEnabled=false``)."""
        try:
            enabled = self._cmd.mechanical_ptz()
        except AxisPtzError:
            return ""
        if enabled is False:
            key = f"PTZ.ImageSource.I{self._cmd.config.camera - 1}.PTZEnabled"
            return f"the camera reports {key}=false (a fixed camera; digital PTZ only)"
        return ""

    def __repr__(self) -> str:
        """No credentials (the client's repr hides them)."""
        return f"AxisBackend({self._cmd!r})"

    # -- limits -----------------------------------------------------------------------------------
    def _to_ros_limits(
        self,
        min_pan: float,
        max_pan: float,
        min_tilt: float,
        max_tilt: float,
        min_zoom: float,
        max_zoom: float,
    ) -> PtzLimitsRos:
        p0, p1, t0, t1 = self._conv.limits_to_ros(min_pan, max_pan, min_tilt, max_tilt)
        return PtzLimitsRos(p0, p1, t0, t1, float(min_zoom), float(max_zoom))

    def limits(self) -> PtzLimitsRos:
        """Camera limits (``query=limits`` / ``PTZ.Limit``), else the camera model's fallback (retried)."""
        with self._lock:
            now = time.monotonic()
            if self._limits_from_camera and self._limits is not None:
                return self._limits
            if self._limits is None or now - self._limits_tried >= LIMITS_RETRY_S:
                self._limits_tried = now
                try:
                    lim: PtzLimits = self._state.query_limits()
                except AxisPtzError:
                    if self._limits is None:
                        fb = self._model.limits
                        self._limits = self._to_ros_limits(
                            fb.min_pan_deg,
                            fb.max_pan_deg,
                            fb.min_tilt_deg,
                            fb.max_tilt_deg,
                            fb.min_zoom,
                            fb.max_zoom,
                        )
                        self.limits_source = "camera_model"
                else:
                    self._limits = self._to_ros_limits(
                        lim.min_pan_deg,
                        lim.max_pan_deg,
                        lim.min_tilt_deg,
                        lim.max_tilt_deg,
                        lim.min_zoom,
                        lim.max_zoom,
                    )
                    self._limits_from_camera = True
                    self.limits_source = "camera"
            assert self._limits is not None
            return self._limits

    # -- state ------------------------------------------------------------------------------------
    def read_state(self) -> PtzReading:
        """``query=position`` on the polling connection; stamped at the middle of the round trip."""
        t0 = time.time_ns()
        try:
            pos = self._state.query_position()
        except AxisPtzError as err:
            raise PtzBackendError(str(err)) from err
        t1 = time.time_ns()
        pan, tilt = self._conv.to_ros(pos.pan_deg, pos.tilt_deg)
        return PtzReading(pan, tilt, float(pos.zoom), (t0 + t1) // 2)

    # -- commands ---------------------------------------------------------------------------------
    def _send(self, request: PtzRequest) -> None:
        try:
            self._cmd.ptz(request)
        except AxisPtzError as err:
            raise PtzBackendError(str(err)) from err

    def move_to(self, pan: float | None, tilt: float | None, zoom: float | None, speed: float | None = None) -> None:
        """``pan=…&tilt=…&zoom=…[&speed=…]`` (degrees rounded to the protocol's 4 decimals). On an endless-pan
        head the pan is wrapped first (an encoder offset may push a wrapped joint target past ±180°)."""
        if pan is not None and self._limits is not None and self._limits.full_turn:
            pan = wrap_angle(pan)
        pan_deg = None if pan is None else round(self._conv.to_vapix(pan, 0.0)[0], 4)
        tilt_deg = None if tilt is None else round(self._conv.to_vapix(0.0, tilt)[1], 4)
        zoom_units = None if zoom is None else int(round(zoom))
        vspeed = None
        if speed is not None and math.isfinite(speed) and speed > 0.0:
            vspeed = max(1, min(100, int(round(100.0 * min(speed, 1.0)))))
        self._send(AbsoluteMove(pan_deg, tilt_deg, zoom_units, vspeed))

    def velocity(self, pan_rate: float, tilt_rate: float, zoom_rate: float) -> None:
        """``continuouspantiltmove=p,t&continuouszoommove=z`` scaled by the camera model's maximum speeds."""
        p = speed_to_vapix(self._conv.pan_rate_to_vapix(math.degrees(pan_rate)), self._model.max_pan_speed_dps)
        t = speed_to_vapix(self._conv.tilt_rate_to_vapix(math.degrees(tilt_rate)), self._model.max_tilt_speed_dps)
        z = speed_to_vapix(zoom_rate, 1.0)
        self._send(ContinuousMove(p, t, z))

    def home(self) -> None:
        """``move=home``."""
        self._send(Move(MoveDirection.HOME))

    def stop(self) -> None:
        """``move=stop``."""
        self._send(Move(MoveDirection.STOP))

    def goto_preset(self, name: str) -> None:
        """``gotoserverpresetname=<name>``."""
        self._send(GotoPreset(name=name))

    def set_preset(self, name: str) -> None:
        """``ptzconfig.cgi?setserverpresetname=<name>``."""
        self._send(SetPreset(name))

    def remove_preset(self, name: str) -> None:
        """``ptzconfig.cgi?removeserverpresetname=<name>``."""
        self._send(RemovePreset(name))

    def list_presets(self) -> list[PresetInfo]:
        """``query=presetposcam``."""
        try:
            presets = self._cmd.query_presets()
        except AxisPtzError as err:
            raise PtzBackendError(str(err)) from err
        return [PresetInfo(p.number, p.name) for p in presets]

    def close(self) -> None:
        """Close both connections."""
        self._cmd.close()
        self._state.close()
