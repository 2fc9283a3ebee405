"""Forward kinematics of a URDF for the tests: a small reader of our own (``xml.etree`` + numpy).

Moved here from the package (issue 24: the URDF is generated from urdf/axis_214.urdf.xacro by xacro; only
tests need to read it back). tests/unit/test_urdf_yourdfpy.py checks the same chain with an independent
library (yourdfpy).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from axis_ptz_ros2.config import MountConfig, save_mount
from axis_ptz_ros2.transforms import FloatArray, Transform, rpy_to_matrix

ROOT = Path(__file__).resolve().parents[2]


@dataclass(frozen=True, slots=True)
class UrdfJoint:
    """One joint as written in the URDF."""

    name: str
    kind: str  # fixed | revolute | continuous | prismatic
    parent: str
    child: str
    origin: Transform
    axis: FloatArray
    lower: float | None
    upper: float | None
    velocity: float | None


def _floats(text: str | None, default: tuple[float, float, float]) -> tuple[float, float, float]:
    if text is None:
        return default
    v = [float(s) for s in text.split()]
    if len(v) != 3:
        raise ValueError(f"expected three numbers, got {text!r}")
    return v[0], v[1], v[2]


def parse_urdf(text: str) -> dict[str, UrdfJoint]:
    """Joints of a URDF by name (raises ValueError on a malformed joint)."""
    root = ET.fromstring(text)
    if root.tag != "robot":
        raise ValueError(f"not a URDF: root element <{root.tag}>")
    joints: dict[str, UrdfJoint] = {}
    for j in root.findall("joint"):
        parent, child = j.find("parent"), j.find("child")
        if parent is None or child is None:
            raise ValueError(f"joint {j.get('name')!r} needs <parent> and <child>")
        o = j.find("origin")
        xyz = _floats(o.get("xyz") if o is not None else None, (0.0, 0.0, 0.0))
        rpy = _floats(o.get("rpy") if o is not None else None, (0.0, 0.0, 0.0))
        a = j.find("axis")
        axis = np.array(_floats(a.get("xyz") if a is not None else None, (1.0, 0.0, 0.0)), dtype=np.float64)
        lim = j.find("limit")

        def attr(name: str, el: ET.Element | None = lim) -> float | None:
            v = el.get(name) if el is not None else None
            return None if v is None else float(v)

        joints[str(j.get("name"))] = UrdfJoint(
            name=str(j.get("name")),
            kind=str(j.get("type")),
            parent=str(parent.get("link")),
            child=str(child.get("link")),
            origin=Transform(rpy_to_matrix(*rpy), np.array(xyz, dtype=np.float64)),
            axis=axis / np.linalg.norm(axis),
            lower=attr("lower"),
            upper=attr("upper"),
            velocity=attr("velocity"),
        )
    return joints


def _axis_angle(axis: FloatArray, angle: float) -> FloatArray:
    """Rodrigues: rotation by ``angle`` about the unit vector ``axis``."""
    k = axis
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.asarray(np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K), dtype=np.float64)


def forward_kinematics(joints: dict[str, UrdfJoint], root: str, tip: str, positions: dict[str, float]) -> Transform:
    """``T_root_tip`` through the joint tree at the given joint positions (radians / metres)."""
    by_child = {j.child: j for j in joints.values()}
    chain: list[UrdfJoint] = []
    link = tip
    while link != root:
        if link not in by_child:
            raise ValueError(f"no joint chain from {root!r} to {tip!r} (stuck at {link!r})")
        j = by_child[link]
        chain.append(j)
        link = j.parent
    T = Transform()
    for j in reversed(chain):
        T = T @ j.origin
        if j.kind in ("revolute", "continuous"):
            T = T @ Transform(_axis_angle(j.axis, float(positions[j.name])), np.zeros(3))
        elif j.kind == "prismatic":
            T = T @ Transform(np.eye(3), j.axis * float(positions[j.name]))
        elif j.kind != "fixed":
            raise ValueError(f"joint {j.name!r}: unsupported type {j.kind!r}")
    return T


def write_unusual_configuration(directory: Path, limits_deg: tuple[float, float, float, float]) -> tuple[Path, Path]:
    """(camera model, mount) files in ``directory`` where every term of the chain is non-zero: a rolled, pitched
    and yawed mount with encoder offsets, a ceiling-mounted ccw camera with an offset optical centre, and the pan
    and tilt limits ``(min_pan, max_pan, min_tilt, max_tilt)`` in degrees."""
    mount = directory / "mount.yaml"
    save_mount(
        MountConfig(
            transform=Transform.from_xyz_rpy(0.31, -0.12, 0.62, 0.05, -0.08, 0.9), pan_offset=0.02, tilt_offset=-0.01
        ),
        mount,
    )
    raw = yaml.safe_load((ROOT / "config" / "axis214.yaml").read_text())
    raw["convention"] = {"pan_direction": "ccw", "mount": "ceiling"}
    raw["head"] = {"h_tilt": 0.081, "d_opt": [0.035, 0.004, -0.006]}
    lo_pan, hi_pan, lo_tilt, hi_tilt = limits_deg
    raw["limits"].update(min_pan_deg=lo_pan, max_pan_deg=hi_pan, min_tilt_deg=lo_tilt, max_tilt_deg=hi_tilt)
    model = directory / "model.yaml"
    model.write_text(yaml.safe_dump(raw))
    return model, mount
