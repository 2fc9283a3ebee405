"""Every file we read, generated: camera models, the mount, the robot, camera calibrations (issue 25).

Each property starts from the shipped, valid file and changes it the way a careless edit would (a value of
another type or size, a missing or unknown key, a list of the wrong length, a NaN); the loader must answer with
a value whose numbers are finite or with a ``ValueError`` that says what is wrong — never a ``TypeError``,
``KeyError``, ``AttributeError`` or any other exception escaping to the node that reads the file.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from axis_ptz_ros2.camera_info import camera_info_from_dict
from axis_ptz_ros2.config import camera_model_from_dict, mount_from_dict, robot_from_dict
from axis_ptz_ros2.strict_yaml import YamlError, loads_strict

pytestmark = pytest.mark.fuzz
CONFIG = Path(__file__).resolve().parents[2] / "config"

_leaf = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(),
    st.integers(min_value=-(10**400), max_value=10**400),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=12),
    st.sampled_from(["nan", "1e999", "0x10", "", "[1, 2]"]),
)
_value = st.recursive(
    _leaf,
    lambda inner: st.one_of(st.lists(inner, max_size=5), st.dictionaries(st.text(max_size=6), inner, max_size=4)),
    max_leaves=8,
)


def _paths(d: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [prefix] if prefix else []
    if isinstance(d, dict):
        for k, v in d.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(d, list):
        for i, v in enumerate(d):
            out += _paths(v, (*prefix, i))
    return out


def _edit(doc: Any, path: tuple[Any, ...], action: str, value: Any) -> Any:
    doc = copy.deepcopy(doc)
    parent = doc
    for key in path[:-1]:
        parent = parent[key]
    last = path[-1]
    if action == "replace":
        parent[last] = value
    elif action == "delete" and isinstance(parent, dict):
        del parent[last]
    elif action == "delete":
        parent.pop(last)
    elif action == "add" and isinstance(parent, dict):
        parent[f"unknown_{last}"] = value
    elif action == "add":
        parent.append(value)
    return doc


def _mutated(doc: Any) -> st.SearchStrategy[Any]:
    paths = _paths(doc)
    edit = st.tuples(st.sampled_from(paths), st.sampled_from(["replace", "delete", "add"]), _value)
    return st.lists(edit, min_size=1, max_size=3).map(lambda edits: _apply(doc, edits))


def _apply(doc: Any, edits: list[tuple[tuple[Any, ...], str, Any]]) -> Any:
    for path, action, value in edits:
        try:
            doc = _edit(doc, path, action, value)
        except (KeyError, IndexError, TypeError, AttributeError):
            continue  # an earlier edit removed or replaced the path's parent
    return doc


def _finite(obj: Any) -> bool:
    if isinstance(obj, float):
        return math.isfinite(obj)
    if isinstance(obj, tuple | list):
        return all(_finite(v) for v in obj)
    return True


def _load_or_refuse(load: Callable[[Any], Any], doc: Any) -> Any:
    try:
        return load(doc)
    except ValueError as err:  # CameraModelError, CameraInfoError, ConfigError, YamlError are ValueErrors
        if not str(err):
            pytest.fail(f"{load.__name__} refused {doc!r} without a reason")
        return None


def _shipped(name: str) -> Any:
    return yaml.safe_load((CONFIG / name).read_text(encoding="utf-8"))


MOUNT = _shipped("mount.yaml")
ROBOT = _shipped("robot.yaml")
MODEL = _shipped("axis214.yaml")
CALIBRATION = _shipped("calibration_example.yaml") if (CONFIG / "calibration_example.yaml").exists() else None


@given(_mutated(MOUNT))
def test_mount_file(doc: Any) -> None:
    mount = _load_or_refuse(mount_from_dict, doc)
    if mount is not None:
        assert _finite((mount.pan_offset, mount.tilt_offset))
        assert _finite(tuple(float(v) for v in mount.transform.t))
        assert mount.covariance is None or _finite(mount.covariance)


@given(_mutated(ROBOT))
def test_robot_file(doc: Any) -> None:
    robot = _load_or_refuse(robot_from_dict, doc)
    if robot is not None:
        assert _finite((robot.ground_z, robot.default_range, robot.depth_cone_deg))
        assert isinstance(robot.base_frame, str)


@given(_mutated(MODEL))
def test_camera_model_file(doc: Any) -> None:
    model = _load_or_refuse(lambda d: camera_model_from_dict(d, "axis214.yaml", CONFIG), doc)
    if model is not None:
        assert _finite((model.max_pan_speed_dps, model.max_tilt_speed_dps))


def _camera_info_doc() -> Any:
    return {
        "image_width": 704,
        "image_height": 576,
        "camera_name": "axis",
        "camera_matrix": {"rows": 3, "cols": 3, "data": [800.0, 0.0, 352.0, 0.0, 800.0, 288.0, 0.0, 0.0, 1.0]},
        "distortion_model": "plumb_bob",
        "distortion_coefficients": {"rows": 1, "cols": 5, "data": [0.01, 0.0, 0.0, 0.0, 0.0]},
        "rectification_matrix": {"rows": 3, "cols": 3, "data": [1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0]},
        "projection_matrix": {"rows": 3, "cols": 4, "data": [800.0, 0, 352.0, 0, 0, 800.0, 288.0, 0, 0, 0, 1.0, 0]},
    }


@given(_mutated(_camera_info_doc()))
def test_camera_calibration_file(doc: Any) -> None:
    info = _load_or_refuse(camera_info_from_dict, doc)
    if info is not None:
        assert _finite(info.K)
        assert _finite(info.D)


@given(st.text(max_size=200))
def test_yaml_text_is_a_document_or_a_yaml_error(text: str) -> None:
    try:
        loads_strict(text, "fuzz.yaml")
    except YamlError as err:
        message = str(err)
    else:
        return
    assert "fuzz.yaml" in message
