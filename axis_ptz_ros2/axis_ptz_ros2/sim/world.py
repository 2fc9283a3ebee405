"""The simulated robot and its surroundings as configured (``config/sim_world.yaml``), ROS-free.

Frames: everything is expressed in ``base_link`` (REP-103, x forward, y left, z up, metres). :class:`SimWorld`
holds the true poses of the PTZ head, the panorama camera and the laser, the head's kinematics, limits and zoom
model, and the :class:`TargetSpec` s that :mod:`axis_ptz_ros2.sim.scene` turns into textured targets.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from axis_ptz_ros2.config import default_config_path
from axis_ptz_ros2.geometry import AXIS_214_ZOOM, FloatArray, PtzKinematics, Transform, ZoomModel


@dataclass(frozen=True, slots=True)
class PtzLimits:
    """``PTZ.Limit.L1`` of the simulated camera (VAPIX degrees and zoom units)."""

    min_pan: float = -170.0
    max_pan: float = 170.0
    min_tilt: float = -30.0
    max_tilt: float = 90.0
    min_zoom: int = 1
    max_zoom: int = 9999


@dataclass(frozen=True, slots=True)
class TargetSpec:
    """Configuration of one planar target (see ``config/sim_world.yaml``)."""

    name: str
    kind: str
    center: tuple[float, float, float]
    size: tuple[float, float]
    text: str = ""
    color: tuple[int, int, int] = (0, 0, 255)  # BGR
    normal: tuple[float, float, float] | None = None  # None: face the PTZ head, upright
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class SimWorld:
    """Everything the simulator knows about the robot and its surroundings."""

    T_base_ptz: Transform = field(
        default_factory=lambda: Transform.from_xyz_rpy(
            -0.209, -0.047, 0.462, math.radians(0.4), math.radians(-0.3), math.radians(1.1)
        )
    )
    kinematics: PtzKinematics = field(default_factory=lambda: PtzKinematics(0.0687, (0.03, 0.0, 0.0)))
    limits: PtzLimits = field(default_factory=PtzLimits)
    zoom_model: ZoomModel = AXIS_214_ZOOM
    T_base_pano: Transform = field(default_factory=lambda: Transform.from_xyz_rpy(0.216, -0.044, 0.75, 0, 0, 0))
    T_base_laser: Transform = field(default_factory=lambda: Transform.from_xyz_rpy(0.25, 0.0, 0.40, 0, 0, 0))
    targets: tuple[TargetSpec, ...] = ()
    equirect_width: int = 4096

    @property
    def pan_tilt_centre(self) -> FloatArray:
        """The point where the pan and tilt axes meet, in ``base_link``."""
        return self.T_base_ptz.apply(np.array([0.0, 0.0, self.kinematics.h_tilt]))

    def cache_key(self) -> tuple[Any, ...]:
        """A hashable identity of the world (for sharing a built :class:`Scene` between cameras)."""
        return (
            tuple(np.round(self.T_base_ptz.matrix(), 9).ravel()),
            self.kinematics,
            self.targets,
            self.equirect_width,
        )


def _pose(d: dict[str, Any], xyz_default: list[float]) -> Transform:
    xyz = [float(v) for v in d.get("xyz", d.get("mount_xyz", xyz_default))]
    rpy = [math.radians(float(v)) for v in d.get("rpy_deg", d.get("mount_rpy_deg", [0.0, 0.0, 0.0]))]
    return Transform.from_xyz_rpy(*xyz, *rpy)


def world_from_dict(cfg: dict[str, Any]) -> SimWorld:
    """Build a :class:`SimWorld` from a parsed ``sim_world.yaml`` mapping (missing keys take defaults)."""
    default = SimWorld()
    ptz = cfg.get("ptz", {})
    lim = ptz.get("limits", {})
    limits = PtzLimits(
        float(lim.get("min_pan", -170.0)),
        float(lim.get("max_pan", 170.0)),
        float(lim.get("min_tilt", -30.0)),
        float(lim.get("max_tilt", 90.0)),
        int(lim.get("min_zoom", 1)),
        int(lim.get("max_zoom", 9999)),
    )
    zm = ZoomModel.from_dict(ptz["zoom_model"]) if "zoom_model" in ptz else AXIS_214_ZOOM
    targets = []
    for t in cfg.get("targets", []):
        targets.append(
            TargetSpec(
                name=str(t["name"]),
                kind=str(t["kind"]),
                center=(float(t["center"][0]), float(t["center"][1]), float(t["center"][2])),
                size=(float(t["size"][0]), float(t["size"][1])),
                text=str(t.get("text", "")),
                color=tuple(int(c) for c in t.get("color", (0, 0, 255))),  # type: ignore[arg-type]
                normal=tuple(float(c) for c in t["normal"]) if "normal" in t else None,  # type: ignore[arg-type]
                up=tuple(float(c) for c in t.get("up", (0.0, 0.0, 1.0))),  # type: ignore[arg-type]
            )
        )
    d_opt = ptz.get("d_opt", [0.03, 0.0, 0.0])
    return SimWorld(
        T_base_ptz=_pose(ptz, [-0.209, -0.047, 0.462]) if ptz else default.T_base_ptz,
        kinematics=PtzKinematics(float(ptz.get("h_tilt", 0.0687)), (float(d_opt[0]), float(d_opt[1]), float(d_opt[2]))),
        limits=limits,
        zoom_model=zm,
        T_base_pano=_pose(cfg["panorama"], [0.216, -0.044, 0.75]) if "panorama" in cfg else default.T_base_pano,
        T_base_laser=_pose(cfg["laser"], [0.25, 0.0, 0.40]) if "laser" in cfg else default.T_base_laser,
        targets=tuple(targets),
        equirect_width=int(cfg.get("background", {}).get("equirect_width", 4096)),
    )


def load_world(path: str | Path | None = None) -> SimWorld:
    """Load the world from a YAML file (default: the repository's ``config/sim_world.yaml``)."""
    # default: the repository's file, or the installed share/axis_ptz_ros2/config copy (colcon)
    p = Path(path) if path is not None else default_config_path("sim_world.yaml")
    with p.open(encoding="utf-8") as fh:
        cfg = yaml.safe_load(fh) or {}
    return world_from_dict(cfg)
