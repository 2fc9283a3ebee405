"""A camera's facts live in its YAML file only (issue 38, item 5): the code has no camera's name, optics or head
geometry as defaults, a camera-model file that lacks one is refused naming the file and the key, and the shipped
files give every user the figures it had."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest
import yaml

from axis_ptz_ros2.camera_models import Optics, generic_model, load_generic_base
from axis_ptz_ros2.config import (
    CAMERA_MODEL_REQUIRED,
    CameraModel,
    CameraModelError,
    camera_model_from_dict,
    default_config_path,
    load_camera_model,
)
from axis_ptz_ros2.geometry import PtzKinematics
from axis_ptz_ros2.optics import ZoomModel
from axis_ptz_ros2.sim.persona import AXIS_Q6075
from axis_ptz_ros2.sim.world import SimWorld, load_world, world_from_dict

pytestmark = pytest.mark.unit

CONFIG = default_config_path("axis214.yaml").parent
SHIPPED = sorted(p for p in CONFIG.glob("*.yaml") if "axis_ptz_ros2/camera_model/v1" in p.read_text(encoding="utf-8"))


def _doc(name: str = "axis214.yaml") -> dict:
    return yaml.safe_load((CONFIG / name).read_text(encoding="utf-8"))


def _write(tmp_path: Path, doc: dict) -> Path:
    p = tmp_path / "my_camera.yaml"
    p.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return p


def test_a_model_file_without_head_is_refused_naming_the_file_and_the_key(tmp_path: Path) -> None:
    doc = _doc()
    del doc["head"]
    p = _write(tmp_path, doc)
    with pytest.raises(
        CameraModelError, match=r"missing key 'head' \(the head geometry: h_tilt, d_opt in metres\)"
    ) as e:
        load_camera_model(p)
    assert str(e.value).startswith(f"{p}: ")


@pytest.mark.parametrize(
    ("section", "key"),
    [(s, k) for s, keys in CAMERA_MODEL_REQUIRED.items() for k in (keys or (None,))],
)
def test_every_required_key_is_required(tmp_path: Path, section: str, key: str | None) -> None:
    doc = _doc()
    if key is None:
        del doc[section]
        match = rf"^{tmp_path}/my_camera\.yaml: missing key '{section}'"
    else:
        del doc[section][key]
        match = rf"^{tmp_path}/my_camera\.yaml: {section}: missing key '{key}'"
    with pytest.raises(CameraModelError, match=match):
        load_camera_model(_write(tmp_path, doc))


def test_an_empty_head_is_refused_too() -> None:
    doc = _doc()
    doc["head"] = None
    with pytest.raises(CameraModelError, match=r"^robot\.yaml: missing key 'head'"):
        camera_model_from_dict(doc, "robot.yaml")
    doc["head"] = {"d_opt": [0.0, 0.0, 0.0]}
    with pytest.raises(CameraModelError, match=r"^robot\.yaml: head: missing key 'h_tilt'"):
        camera_model_from_dict(doc, "robot.yaml")


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_every_shipped_model_file_carries_what_the_code_needs(path: Path) -> None:
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    for section, keys in CAMERA_MODEL_REQUIRED.items():
        assert doc.get(section) is not None, f"{path.name}: {section}"
        for key in keys or ():
            assert key in doc[section], f"{path.name}: {section}.{key}"
    load_camera_model(path)


def test_the_shipped_files_are_the_ones_expected() -> None:
    assert {p.name for p in SHIPPED} >= {"axis214.yaml", "q6075.yaml", "generic.yaml", "virtual_camera.yaml"}


def test_the_code_holds_no_camera_as_a_default() -> None:
    with pytest.raises(TypeError):
        CameraModel()  # type: ignore[call-arg]
    with pytest.raises(TypeError):
        ZoomModel()  # type: ignore[call-arg]
    with pytest.raises(ValueError, match=r"missing key\(s\) \['max_magnification'\]"):
        ZoomModel.from_dict({"hfov_wide_deg": 50.0})
    assert PtzKinematics() == PtzKinematics(0.0, (0.0, 0.0, 0.0))  # neutral: optical centre at the pan origin


def test_the_214_users_get_the_figures_they_had() -> None:
    """config/axis214.yaml (what the nodes, the calibration and the simulator's driver side load) gives the
    figures the code defaults used to give (name, optics, head, limits, speeds)."""
    m = load_camera_model()
    assert m.name == "AXIS 214 PTZ"
    assert (m.zoom.hfov_wide_deg, m.zoom.max_magnification, m.zoom.min_zoom, m.zoom.max_zoom) == (47.98, 18.88, 1, 9999)
    assert m.zoom.image_aspect == pytest.approx(4.0 / 3.0, rel=1e-10)
    assert (m.head.h_tilt, m.head.d_opt) == (0.0687, (0.03, 0.0, 0.0))
    assert dataclasses.astuple(m.limits) == (-170.0, 170.0, -30.0, 90.0, 1, 9999)
    assert (m.max_pan_speed_dps, m.max_tilt_speed_dps) == (100.0, 90.0)
    # a world without ptz.zoom_model takes the file's, exactly (its image_aspect 1.3333333333 too: no copy in code)
    assert world_from_dict({}).zoom_model == m.zoom
    assert SimWorld().zoom_model == m.zoom
    # the simulated 214's head (config/sim_world.yaml) is the file's; its optics are the file's (the world file
    # has no zoom_model of its own)
    world = load_world()
    assert world.kinematics == m.head
    assert world.zoom_model == m.zoom
    assert "zoom_model" not in yaml.safe_load((CONFIG / "sim_world.yaml").read_text(encoding="utf-8"))["ptz"]


def test_the_simulated_q6075_is_its_model_file() -> None:
    m = load_camera_model(CONFIG / "q6075.yaml")
    assert AXIS_Q6075.zoom_model == m.zoom  # read from the file, exactly (its image_aspect 1.7777777778 too)
    assert AXIS_Q6075.kinematics == m.head
    lim = AXIS_Q6075.limits
    assert lim is not None
    assert (lim.min_pan, lim.max_pan, lim.min_tilt, lim.max_tilt, lim.min_zoom, lim.max_zoom) == dataclasses.astuple(
        m.limits
    )
    assert (AXIS_Q6075.speeds.pan_deg_s, AXIS_Q6075.speeds.tilt_deg_s) == (m.max_pan_speed_dps, m.max_tilt_speed_dps)


def test_an_unknown_camera_starts_from_generic_yaml() -> None:
    base = load_generic_base()
    assert base == load_camera_model(CONFIG / "generic.yaml")
    assert (base.head.h_tilt, base.head.d_opt) == (0.0, (0.0, 0.0, 0.0))
    built = generic_model(Optics())
    assert built.name == "generic Axis PTZ"
    assert (built.zoom.hfov_wide_deg, built.zoom.max_magnification) == (60.0, 10.0)
    assert math.isclose(built.zoom.image_aspect, 4.0 / 3.0)
