"""Correspondence file format axis_ptz_ros2/correspondences/v1: round trip, validation, append_view."""

import math
import textwrap

import pytest

from axis_ptz_ros2.calibration.correspondences import (
    CORRESPONDENCES_FORMAT,
    Correspondence,
    CorrespondenceError,
    CorrespondenceSet,
    View,
    append_view,
    dump_correspondences,
    load_correspondences,
    parse_correspondences,
    save_correspondences,
)
from axis_ptz_ros2.config import default_config_path

pytestmark = pytest.mark.unit

GOOD = textwrap.dedent(
    """\
    format: axis_ptz_ros2/correspondences/v1
    camera_model: axis214.yaml
    views:
      - name: left
        pan: 0.5
        tilt: -0.1
        zoom: 1
        image_width: 704
        image_height: 576
        points:
          - pixel: [100.5, 200.25]
            point: [3.0, 1.0, 0.25]
            label: table corner
          - pixel: [600, 50]
            point: [4, -1, 1]
    """
)


def _view(name: str = "v", n: int = 3) -> View:
    pts = tuple(Correspondence((10.125 + i, 20.5 + 2 * i), (1.0 + i, -0.5 * i, 0.25), f"pt{i}") for i in range(n))
    return View(name, 0.25, -0.125, 1234.5, 704, 576, pts, image="img/v.jpg")


def test_parse_good_file():
    cs = parse_correspondences(GOOD, "good.yaml")
    assert cs.camera_model == "axis214.yaml"
    assert len(cs.views) == 1
    assert cs.n_points == 2
    v = cs.views[0]
    assert (v.name, v.pan, v.tilt, v.zoom, v.image_width, v.image_height) == (
        "left",
        0.5,
        -0.1,
        1.0,
        704,
        576,
    )
    assert v.points[0] == Correspondence((100.5, 200.25), (3.0, 1.0, 0.25), "table corner")
    assert v.points[1].label == ""


def test_round_trip_through_file(tmp_path):
    cs = CorrespondenceSet((_view("a"), _view("b", 5)), "axis214.yaml", "two views")
    path = tmp_path / "c.yaml"
    save_correspondences(cs, path)
    loaded = load_correspondences(path)
    assert loaded == cs  # `source` is excluded from equality
    assert loaded.source == path.resolve()
    assert dump_correspondences(loaded) == dump_correspondences(cs)
    assert CORRESPONDENCES_FORMAT in path.read_text()


def test_camera_model_resolves_relative_to_file(tmp_path):
    path = tmp_path / "sub" / "c.yaml"
    path.parent.mkdir()
    save_correspondences(CorrespondenceSet((_view(),), "../models/cam.yaml"), path)
    assert load_correspondences(path).resolve_camera_model() == (tmp_path / "models" / "cam.yaml").resolve()


def test_append_view_creates_then_extends(tmp_path):
    path = tmp_path / "capture.yaml"
    append_view(path, _view("first"), camera_model="axis214.yaml")
    cs = append_view(path, _view("second", 4))
    loaded = load_correspondences(path)
    assert [v.name for v in loaded.views] == ["first", "second"]
    assert loaded.camera_model == "axis214.yaml"
    assert loaded.n_points == 7 == cs.n_points
    with pytest.raises(CorrespondenceError, match="already exists"):
        append_view(path, _view("first"))


@pytest.mark.parametrize(
    ("old", "new", "line", "pattern"),
    [
        ("format: axis_ptz_ros2/correspondences/v1", "format: v0", 1, r"format.*expected format"),
        ("    pan: 0.5", "    pan: 45.0", 5, r"views\[0\]\.pan: .*degrees given instead of radians"),
        ("    tilt: -0.1", "    tilt: low", 6, r"views\[0\]\.tilt: expected a number"),
        (
            "    image_width: 704",
            "    image_width: -3",
            8,
            r"views\[0\]\.image_width: expected a positive integer",
        ),
        (
            "        point: [3.0, 1.0, 0.25]",
            "        point: [3.0, 1.0]",
            12,
            r"views\[0\]\.points\[0\]\.point",
        ),
        (
            "      - pixel: [600, 50]",
            "      - pixel: [900, 50]",
            14,
            r"points\[1\]\.pixel.*outside the 704x576",
        ),
        ("        label: table corner", "        lable: table corner", 13, r"unknown field.*lable"),
        ("    zoom: 1", "    zom: 1", 7, r"unknown field.*zom"),
        ("      - pixel: [100.5, 200.25]", "      - pixel: [100.5, .nan]", 11, r"pixel\[1\].*finite"),
    ],
)
def test_validation_errors_name_line_and_field(old, new, line, pattern):
    assert old in GOOD
    with pytest.raises(CorrespondenceError, match=pattern) as exc:
        parse_correspondences(GOOD.replace(old, new), "bad.yaml")
    assert str(exc.value).startswith(f"bad.yaml:{line}:"), str(exc.value)


def test_missing_fields_and_duplicates():
    with pytest.raises(CorrespondenceError, match=r"views\[0\].*missing required field 'zoom'"):
        parse_correspondences(GOOD.replace("    zoom: 1\n", ""), "x.yaml")
    dup = GOOD + textwrap.indent(GOOD.split("views:\n", 1)[1], "")
    with pytest.raises(CorrespondenceError, match="duplicate view name 'left'"):
        parse_correspondences(dup, "x.yaml")
    with pytest.raises(CorrespondenceError, match="not valid YAML"):
        parse_correspondences("views: [", "x.yaml")
    with pytest.raises(CorrespondenceError, match="expected a list of views"):
        parse_correspondences(f"format: {CORRESPONDENCES_FORMAT}\n", "x.yaml")


def test_view_constructor_validates():
    with pytest.raises(CorrespondenceError, match="degrees"):
        View("v", math.radians(30) * 57.3, 0.0, 1.0, 704, 576)
    with pytest.raises(CorrespondenceError, match="outside"):
        View("v", 0.0, 0.0, 1.0, 704, 576, (Correspondence((-5.0, 3.0), (1.0, 0.0, 0.0)),))


def test_missing_file_is_a_correspondence_error(tmp_path):
    with pytest.raises(CorrespondenceError, match="cannot read"):
        load_correspondences(tmp_path / "nope.yaml")
    (tmp_path / "latin1.yaml").write_bytes(b"format: axis_ptz_correspondences/1\ncomment: caf\xe9\n")
    with pytest.raises(CorrespondenceError, match="latin1.yaml: not a UTF-8 text file"):
        load_correspondences(tmp_path / "latin1.yaml")


def test_shipped_example_loads():
    cs = load_correspondences(default_config_path("calibration_example.yaml"))
    assert len(cs.views) >= 3
    assert cs.n_points >= 24
    model = cs.resolve_camera_model()
    assert model is not None
    assert model.exists()


def test_calibration_package_is_ros_free():
    import subprocess
    import sys

    code = (
        "import sys\n"
        "import axis_ptz_ros2.calibration as c\n"
        "import axis_ptz_ros2.calibration.cli, axis_ptz_ros2.calibration.synthetic\n"
        "assert callable(c.calibrate) and callable(c.append_view)\n"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('rclpy', 'sensor_msgs', 'geometry_msgs')]\n"
        "assert not bad, bad\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)
