"""camera_info_manager semantics without ROS: URL resolution, the standard YAML, atomic stores, refusals."""

from __future__ import annotations

import os
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml

from axis_ptz_ros2.camera_info import CameraInfoData, CameraInfoError, load_camera_info
from axis_ptz_ros2.camera_info_store import (
    CameraInfoStore,
    CameraInfoUrlError,
    calibration_from_msg,
    parse_calibration,
    resolve_url,
)
from axis_ptz_ros2.config import load_camera_model

K = (800.0, 0.0, 351.5, 0.0, 810.0, 287.5, 0.0, 0.0, 1.0)
D = (-0.2, 0.05, 0.001, -0.002, 0.0)
R = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
P = (790.0, 0.0, 350.0, 0.0, 0.0, 800.0, 286.0, 0.0, 0.0, 0.0, 1.0, 0.0)
# The file camera_calibration writes (camera_calibration_parsers' YAML), verbatim in form
STANDARD_YAML = """image_width: 704
image_height: 576
camera_name: axis_ptz
camera_matrix:
  rows: 3
  cols: 3
  data: [800.0, 0.0, 351.5, 0.0, 810.0, 287.5, 0.0, 0.0, 1.0]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.2, 0.05, 0.001, -0.002, 0.0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
projection_matrix:
  rows: 3
  cols: 4
  data: [790.0, 0.0, 350.0, 0.0, 0.0, 800.0, 286.0, 0.0, 0.0, 0.0, 1.0, 0.0]
"""


def msg(**kw: object) -> SimpleNamespace:
    base = {"width": 704, "height": 576, "distortion_model": "plumb_bob", "d": list(D), "k": list(K), "r": list(R),
            "p": list(P)}  # fmt: skip
    return SimpleNamespace(**{**base, **kw})


def no_share(pkg: str) -> Path:
    raise AssertionError(f"package lookup not expected ({pkg})")


# ---- URL resolution ------------------------------------------------------------------------------------
def test_empty_url_is_the_default_location_under_ros_home():
    env = {"ROS_HOME": "/data/ros", "HOME": "/home/u"}
    assert resolve_url("", "axis_ptz", env=env) == Path("/data/ros/camera_info/axis_ptz.yaml")
    assert resolve_url("", "axis_ptz", env={"HOME": "/home/u"}) == Path("/home/u/.ros/camera_info/axis_ptz.yaml")


def test_file_url_with_variables_and_case_insensitive_scheme():
    env = {"ROS_HOME": "/r"}
    assert resolve_url("file:///calib/${NAME}.yaml", "front", env=env) == Path("/calib/front.yaml")
    assert resolve_url("FILE://${ROS_HOME}/c/${NAME}.yaml", "front", env=env) == Path("/r/c/front.yaml")


def test_package_url_resolves_under_the_share_directory(tmp_path):
    seen = []

    def share(pkg: str) -> Path:
        seen.append(pkg)
        return tmp_path / "share" / pkg

    got = resolve_url("package://my_robot/calib/${NAME}.yaml", "axis_ptz", find_share=share)
    assert got == tmp_path / "share" / "my_robot" / "calib" / "axis_ptz.yaml"
    assert seen == ["my_robot"]


def test_package_url_through_ament_index_when_it_is_installed(tmp_path, monkeypatch):
    pytest.importorskip("ament_index_python")
    prefix = tmp_path / "prefix"
    (prefix / "share" / "ament_index" / "resource_index" / "packages").mkdir(parents=True)
    (prefix / "share" / "ament_index" / "resource_index" / "packages" / "calib_pkg").write_text("")
    (prefix / "share" / "calib_pkg").mkdir()
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(prefix))
    assert resolve_url("package://calib_pkg/c/x.yaml", "x") == prefix / "share" / "calib_pkg" / "c" / "x.yaml"
    with pytest.raises(CameraInfoUrlError, match="package 'no_such_pkg' not found"):
        resolve_url("package://no_such_pkg/c/x.yaml", "x")


@pytest.mark.parametrize(
    ("url", "reason"),
    [
        ("http://host/calib.yaml", "unsupported scheme 'http://'"),
        ("flash:///calib.yaml", "unsupported scheme 'flash://'"),
        ("/calib/x.yaml", "no scheme"),
        ("file://relative/x.yaml", "absolute path"),
        ("file:///calib/", "directory"),
        ("package://only_pkg", "package://<package>/<file>"),
        ("package://pkg/../../etc/x.yaml", "'..'"),
        ("file:///c/${CAMERA}.yaml", "unknown variable"),
    ],
)
def test_bad_urls_are_refused_with_the_reason(url, reason):
    with pytest.raises(CameraInfoUrlError, match=None) as e:
        resolve_url(url, "axis_ptz", env={"ROS_HOME": "/r"}, find_share=no_share)
    assert reason in str(e.value)


def test_a_camera_name_that_is_not_a_file_name_is_refused():
    with pytest.raises(CameraInfoUrlError, match="only letters, digits"):
        resolve_url("", "../axis", env={"ROS_HOME": "/r"})


# ---- reading ---------------------------------------------------------------------------------------------
def test_loads_the_standard_calibration_yaml(tmp_path):
    f = tmp_path / "axis_ptz.yaml"
    f.write_text(STANDARD_YAML)
    s = CameraInfoStore(f"file://{f}", "axis_ptz")
    assert s.calibration is None
    assert s.load() is True
    ci = s.calibration
    assert ci is not None
    assert (ci.width, ci.height, ci.K, ci.D, ci.R, ci.P) == (704, 576, K, D, R, P)
    assert ci.distortion_model == "plumb_bob"
    assert s.zoom is None  # a file from camera_calibration records no zoom: the wide end


def test_a_missing_file_is_no_calibration_yet(tmp_path):
    s = CameraInfoStore(f"file://{tmp_path}/none.yaml", "axis_ptz")
    assert s.load() is False
    assert s.calibration is None


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("image_width: [704\n", "expected"),  # YAML syntax
        (STANDARD_YAML.replace("rows: 3\n  cols: 4", "rows: 3\n  cols: 3", 1), "rows 3 x cols 3 does not match 12"),
        (STANDARD_YAML.replace("image_width: 704", "image_width: 704\nimage_width: 640"), "duplicate"),
        (STANDARD_YAML.replace("camera_name", "camera_nmae"), "unknown field"),
        (STANDARD_YAML.replace("800.0, 0.0, 351.5, ", "800.0, 0.0, "), "rows 3 x cols 3 does not match 8"),
    ],
)
def test_a_malformed_file_is_refused_and_the_previous_calibration_kept(tmp_path, text, reason):
    f = tmp_path / "axis_ptz.yaml"
    f.write_text(STANDARD_YAML)
    s = CameraInfoStore(f"file://{f}", "axis_ptz")
    s.load()
    before = s.calibration
    f.write_text(text)
    with pytest.raises(CameraInfoError) as e:
        s.load()
    assert reason in str(e.value)
    assert s.calibration is before


# ---- storing (set_camera_info) ---------------------------------------------------------------------------
def test_store_writes_the_standard_format_atomically_and_reads_back(tmp_path):
    s = CameraInfoStore("", "axis_ptz", env={"ROS_HOME": str(tmp_path)})
    r = s.store_msg(msg(), (704, 576), zoom=2500.0)
    assert r.success, r.status_message
    path = tmp_path / "camera_info" / "axis_ptz.yaml"  # directory created, as camera_info_manager does
    assert s.path == path
    assert str(path) in r.status_message
    # what any standard parser reads: the plain YAML, every key of the standard format
    doc = yaml.safe_load(path.read_text())
    assert set(doc) == {"image_width", "image_height", "camera_name", "camera_matrix", "distortion_model",
                        "distortion_coefficients", "rectification_matrix", "projection_matrix"}  # fmt: skip
    assert doc["camera_matrix"] == {"rows": 3, "cols": 3, "data": list(K)}
    assert doc["projection_matrix"] == {"rows": 3, "cols": 4, "data": list(P)}
    assert doc["distortion_coefficients"] == {"rows": 1, "cols": 5, "data": list(D)}
    assert doc["camera_name"] == "axis_ptz"
    assert load_camera_info(path).K == K  # the project's own parser too
    fresh = CameraInfoStore("", "axis_ptz", env={"ROS_HOME": str(tmp_path)})
    assert fresh.load()
    assert fresh.calibration == s.calibration
    assert fresh.zoom == 2500.0
    assert [p.name for p in path.parent.iterdir()] == ["axis_ptz.yaml"]  # no temporary file left


@pytest.mark.parametrize(
    ("kw", "reason"),
    [
        ({"k": [800.0, 0.0, 351.5, 0.0, 810.0, 287.5, 0.0, 0.0]}, "k needs 9 values, got 8"),
        ({"r": [1.0] * 4}, "r needs 9 values, got 4"),
        ({"p": [1.0] * 9}, "p needs 12 values, got 9"),
        ({"distortion_model": "fisheye_xyz"}, "not supported"),
        ({"k": [-800.0, 0.0, 351.5, 0.0, 810.0, 287.5, 0.0, 0.0, 1.0]}, "must be positive"),
        ({"width": 640, "height": 480, "k": [600.0, 0, 319.5, 0, 600.0, 239.5, 0, 0, 1]}, "stream is 704x576"),
    ],
)
def test_bad_calibrations_are_refused_with_the_reason_and_nothing_lost(tmp_path, kw, reason):
    s = CameraInfoStore(f"file://{tmp_path}/axis_ptz.yaml", "axis_ptz")
    assert s.store_msg(msg(), (704, 576), zoom=1.0).success
    before_text = s.path.read_text()
    before = (s.calibration, s.zoom)
    r = s.store_msg(msg(**kw), (704, 576), zoom=5000.0)
    assert not r.success
    assert reason in r.status_message
    assert "kept the previous" in r.status_message
    assert (s.calibration, s.zoom) == before
    assert s.path.read_text() == before_text


def test_an_unwritable_location_is_refused_with_the_reason_and_the_calibration_kept(tmp_path):
    """A location that cannot be written (here: its directory is a file, which stops root too)."""
    blocker = tmp_path / "calib"
    blocker.write_text("not a directory")
    s = CameraInfoStore(f"file://{blocker}/axis_ptz.yaml", "axis_ptz")
    r = s.store_msg(msg(), (704, 576), zoom=None)
    assert not r.success
    assert "cannot write" in r.status_message
    assert str(blocker) in r.status_message
    assert s.calibration is None
    assert blocker.read_text() == "not a directory"


def test_a_failed_rename_leaves_the_old_file_whole_and_no_temporary(tmp_path, monkeypatch):
    """The write goes to a temporary file that is renamed over the old one: a failure at the rename (e.g. the
    disk full or the target a directory) leaves the previous file byte for byte and removes the temporary."""
    s = CameraInfoStore(f"file://{tmp_path}/axis_ptz.yaml", "axis_ptz")
    assert s.store_msg(msg(), (704, 576), zoom=None).success
    before = s.path.read_text()

    def boom(src: str, dst: str) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", boom)
    r = s.store_msg(msg(k=[900.0, 0.0, 351.5, 0.0, 910.0, 287.5, 0.0, 0.0, 1.0]), (704, 576), zoom=None)
    assert not r.success
    assert "No space left on device" in r.status_message
    assert s.path.read_text() == before
    assert [p.name for p in tmp_path.iterdir()] == ["axis_ptz.yaml"]


# ---- feeding the zoom-aware camera_info ------------------------------------------------------------------
def test_a_stored_calibration_is_k_and_d_at_its_zoom_and_scales_from_there(tmp_path):
    model = load_camera_model()  # the installed Axis 214 model: its zoom curve
    s = CameraInfoStore(f"file://{tmp_path}/axis_ptz.yaml", "axis_ptz")
    z0 = 3000.0
    assert s.store_msg(msg(), (704, 576), zoom=z0).success
    reloaded = CameraInfoStore(f"file://{tmp_path}/axis_ptz.yaml", "axis_ptz")
    assert reloaded.load()
    assert reloaded.calibration is not None
    m = model.with_camera_info(reloaded.calibration, reloaded.zoom)
    at = m.camera_info_at(z0, 704, 576)  # at the zoom it was taken at: exactly the stored K and D
    assert pytest.approx(K) == at.K
    assert at.D == D
    z1 = 6000.0
    ratio = model.zoom.magnification(z1) / model.zoom.magnification(z0)
    assert ratio > 1.2  # the check below would not notice a calibration pinned to one zoom otherwise
    far = m.camera_info_at(z1, 704, 576)
    assert far.fx == pytest.approx(K[0] * ratio)
    assert far.fy == pytest.approx(K[4] * ratio)
    assert (far.cx, far.cy, far.D) == (K[2], K[5], D)
    half = m.camera_info_at(z0, 352, 288)  # another resolution of the same sensor area
    assert half.fx == pytest.approx(K[0] / 2)


def test_parse_refuses_a_bad_zoom_record():
    with pytest.raises(CameraInfoError, match="is not a number"):
        parse_calibration("# axis_ptz_ros2 camera_info_zoom: wide\n" + STANDARD_YAML, "x.yaml")


def test_calibration_from_msg_builds_the_data():
    ci = calibration_from_msg(msg(), "axis_ptz")
    assert isinstance(ci, CameraInfoData)
    assert (ci.K, ci.P, ci.camera_name) == (K, P, "axis_ptz")
