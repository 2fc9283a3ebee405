"""Measured intrinsics: the ROS camera calibration YAML, distortion models, the camera model's camera_info and
the strict YAML loader (ROS-free)."""

from __future__ import annotations

import textwrap

import cv2
import numpy as np
import pytest
import yaml

from axis_ptz_ros2.calibration.synthetic import default_camera_model, real_like_camera_info
from axis_ptz_ros2.camera_info import (
    CameraInfoData,
    CameraInfoError,
    camera_info_from_dict,
    dump_camera_info,
    fill_camera_info_msg,
    load_camera_info,
    project,
    undistort_pixels,
)
from axis_ptz_ros2.config import CameraModelError, default_config_path, load_camera_model
from axis_ptz_ros2.strict_yaml import YamlError, loads_strict
from tests.support.models import AXIS_214_ZOOM

pytestmark = pytest.mark.unit

# What the ROS camera_calibration tool writes (camera_calibration_parsers YAML), values of a real 964x724 camera.
OST = textwrap.dedent(
    """\
    image_width: 964
    image_height: 724
    camera_name: narrow_stereo
    camera_matrix:
      rows: 3
      cols: 3
      data: [484.13, 0.0, 457.21, 0.0, 484.55, 366.92, 0.0, 0.0, 1.0]
    distortion_model: plumb_bob
    distortion_coefficients:
      rows: 1
      cols: 5
      data: [-0.2011, 0.0612, 0.0009, -0.0004, -0.0081]
    rectification_matrix:
      rows: 3
      cols: 3
      data: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    projection_matrix:
      rows: 3
      cols: 4
      data: [401.2, 0.0, 452.7, 0.0, 0.0, 440.3, 368.1, 0.0, 0.0, 0.0, 1.0, 0.0]
    """
)


def test_parse_ros_calibration_file(tmp_path):
    p = tmp_path / "ost.yaml"
    p.write_text(OST)
    ci = load_camera_info(p)
    assert (ci.width, ci.height, ci.camera_name) == (964, 724, "narrow_stereo")
    assert (ci.fx, ci.fy, ci.cx, ci.cy) == (484.13, 484.55, 457.21, 366.92)
    assert ci.distortion_model == "plumb_bob"
    assert ci.D == (-0.2011, 0.0612, 0.0009, -0.0004, -0.0081)
    assert ci.P[0] == 401.2
    # round trip through our writer
    again = camera_info_from_dict(loads_strict(dump_camera_info(ci)))
    assert again.K == ci.K
    assert again.D == ci.D
    assert again.P == ci.P
    assert again.R == ci.R


@pytest.mark.parametrize(
    ("old", "new", "match"),
    [
        ("distortion_model: plumb_bob", "distortion_model: kannala", "not supported"),
        ("  cols: 5\n", "  cols: 4\n", "does not match 5 values"),
        ("image_width: 964", "image_widht: 964", r"unknown field\(s\) \['image_widht'\]"),
        ("image_height: 724\n", "", "missing required field 'image_height'"),
        ("data: [484.13, 0.0, 457.21", "data: [-484.13, 0.0, 457.21", "fx and fy must be positive"),
        ("457.21, 0.0, 484.55", "1457.21, 0.0, 484.55", "principal point .* outside"),
        ("camera_name: narrow_stereo", "camera_name: narrow_stereo\nimage_width: 965", "duplicate key 'image_width'"),
        ("  rows: 1\n", "  rows: [1\n", "not valid YAML"),
    ],
)
def test_bad_calibration_files_are_refused_with_a_reason(tmp_path, old, new, match):
    p = tmp_path / "ost.yaml"
    assert old in OST
    p.write_text(OST.replace(old, new, 1))
    with pytest.raises(CameraInfoError, match=match) as exc:
        load_camera_info(p)
    assert str(p) in str(exc.value)


def test_extra_rational_coefficients_must_be_zero():
    base = real_like_camera_info("rational_polynomial")
    CameraInfoData(base.width, base.height, base.K, base.distortion_model, (*base.D, 0.0, 0.0, 0.0, 0.0))
    with pytest.raises(CameraInfoError, match="must be 0"):
        CameraInfoData(base.width, base.height, base.K, base.distortion_model, (*base.D, 0.01, 0.0, 0.0, 0.0))


@pytest.mark.parametrize("model", ["plumb_bob", "rational_polynomial", "equidistant"])
def test_projection_matches_opencv_and_undistortion_inverts_it(model):
    ci = real_like_camera_info(model)
    rng = np.random.default_rng(3)
    P = np.column_stack([rng.uniform(-0.4, 0.4, 50), rng.uniform(-0.3, 0.3, 50), np.ones(50)]) * rng.uniform(
        1, 20, (50, 1)
    )
    K = np.array(ci.K).reshape(3, 3)
    if model == "equidistant":
        ref, _ = cv2.fisheye.projectPoints(P.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, ci.coefficients)
    else:
        ref, _ = cv2.projectPoints(P, np.zeros(3), np.zeros(3), K, ci.coefficients)
    uv = project(P, ci)
    assert np.abs(uv - ref.reshape(-1, 2)).max() < 1e-6
    ideal = undistort_pixels(uv, ci)
    pin = ci.intrinsics().project(P)
    assert np.abs(ideal - pin).max() < 1e-4
    assert np.abs(uv - pin).max() > 5.0  # the distortion is not negligible


def test_adapted_keeps_principal_point_and_distortion():
    ci = real_like_camera_info("plumb_bob", 704, 576)
    z = ci.adapted(704, 576, 3.0)
    assert (z.fx, z.fy) == pytest.approx((3 * ci.fx, 3 * ci.fy))
    assert (z.cx, z.cy) == (ci.cx, ci.cy)
    assert z.D == ci.D
    assert z.P[0] == pytest.approx(3 * ci.P[0])
    half = ci.adapted(352, 288)
    assert half.fx == pytest.approx(ci.fx / 2)
    assert half.cx == pytest.approx((ci.cx + 0.5) / 2 - 0.5)  # pixel-centre convention
    assert ci.adapted(704, 576) is ci


def test_camera_model_with_measured_camera_info(tmp_path):
    measured = real_like_camera_info("plumb_bob", 704, 576)
    (tmp_path / "ost.yaml").write_text(dump_camera_info(measured))
    model = tmp_path / "model.yaml"
    model.write_text(default_config_path("axis214.yaml").read_text() + "camera_info: ost.yaml\n")
    cm = load_camera_model(model)
    assert cm.camera_info is not None
    at1 = cm.camera_info_at(1.0, 704, 576)
    assert at1.K == measured.K
    assert at1.D == measured.D
    assert at1.P == measured.P
    m = AXIS_214_ZOOM.magnification(6000.0)
    at6 = cm.camera_info_at(6000.0, 704, 576)
    assert at6.fx == pytest.approx(measured.fx * m)
    assert (at6.cx, at6.cy, at6.D) == (measured.cx, measured.cy, measured.D)
    assert cm.intrinsics(6000.0, 704, 576).fx == pytest.approx(at6.fx)
    # another aspect ratio (a different crop of the sensor) cannot be derived: nominal values
    wide = cm.camera_info_at(1.0, 1280, 720)
    assert not wide.has_distortion
    assert wide.fx == pytest.approx(AXIS_214_ZOOM.intrinsics(1.0, 1280, 720).fx)
    # inline camera_info, measured at another zoom
    inline = tmp_path / "inline.yaml"
    inline.write_text(
        default_config_path("axis214.yaml").read_text()
        + "camera_info_zoom: 2000\ncamera_info:\n"
        + textwrap.indent(dump_camera_info(measured), "  ")
    )
    cm2 = load_camera_model(inline)
    assert cm2.camera_info_at(2000.0, 704, 576).fx == pytest.approx(measured.fx)
    assert cm2.camera_info_at(1.0, 704, 576).fx == pytest.approx(measured.fx / AXIS_214_ZOOM.magnification(2000.0))
    # no camera_info: the nominal model, unchanged (the default config files load)
    nominal = default_camera_model()
    assert nominal.intrinsics(1.0, 704, 576) == nominal.zoom.intrinsics(1.0, 704, 576)
    load_camera_model()


def test_fill_camera_info_msg_copies_the_measured_values():
    class Msg:  # stands for sensor_msgs/CameraInfo (the ROS test checks the real one)
        pass

    ci = real_like_camera_info("equidistant", 704, 576)
    m = fill_camera_info_msg(Msg(), ci)
    assert (m.width, m.height, m.distortion_model) == (704, 576, "equidistant")
    assert m.k == list(ci.K)
    assert m.d == list(ci.D)
    assert m.p == list(ci.P)
    assert m.r == list(ci.R)


def _shipped_model_with(change: dict) -> str:
    """``config/axis214.yaml`` with ``change`` applied (a mapping section updated, anything else replaced)."""
    doc = yaml.safe_load(default_config_path("axis214.yaml").read_text(encoding="utf-8"))
    for key, value in change.items():
        if isinstance(value, dict) and isinstance(doc.get(key), dict):
            doc[key] = {**doc[key], **value}
        else:
            doc[key] = value
    return yaml.safe_dump(doc, sort_keys=False)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"zoom": {"hfov_wide_degs": 40}}, r"zoom\.hfov_wide_degs: unknown field"),
        ({"zooom": {}}, r"unknown field\(s\) \['zooom'\]"),
        ("head:\n  h_tilt: 0.1\n  h_tilt: 0.2\n", "duplicate key 'h_tilt'"),
        ("head: {h_tilt: [0.1\n", "not valid YAML"),
        ({"convention": {"pan_direction": "left"}}, "convention: 'left' is not a valid PanDirection"),
        ({"zoom": {"hfov_wide_deg": 400}}, "zoom: hfov_wide_deg must be in"),
        ({"camera_info": "missing.yaml"}, "camera_info: .*missing.yaml: cannot read"),
        ({"head": {"d_opt": [0.1, 0.0]}}, "d_opt needs three values"),
    ],
)
def test_camera_model_errors_name_the_file_and_field(tmp_path, change, match):
    p = tmp_path / "model.yaml"
    if isinstance(change, str):  # broken YAML: refused before any field is read
        p.write_text(f"format: axis_ptz_ros2/camera_model/v1\n{change}")
    else:
        p.write_text(_shipped_model_with(change))
    with pytest.raises(CameraModelError, match=match) as exc:
        load_camera_model(p)
    assert str(p) in str(exc.value)


def test_strict_yaml_names_both_lines_of_a_duplicate_key():
    with pytest.raises(YamlError, match=r"x.yaml:3: .*duplicate key 'a' \(first on line 1, again on line 3\)"):
        loads_strict("a: 1\nb: 2\na: 3\n", "x.yaml")
    assert loads_strict("a: {b: 1}\nc: [1, 2]\n") == {"a": {"b": 1}, "c": [1, 2]}


def test_every_shipped_camera_model_loads():
    """The strict loader accepts every camera model in config/ (a new field must be added to
    CAMERA_MODEL_KEYS, not silently ignored)."""
    models = [
        p for p in default_config_path("axis214.yaml").parent.glob("*.yaml") if "camera_model/v1" in p.read_text()
    ]
    assert len(models) >= 2
    for p in models:
        load_camera_model(p)
