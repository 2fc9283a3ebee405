"""``axis_calibrate capture --picker``: the automatic picker is a plug-in named ``MODULE:NAME`` or ``PATH.py:NAME``
(the product's calibration tool never imports the simulator; the tests pass the simulated boards' picker in).
Bad plug-in names and options are refused with the reason before anything is captured (exit 1)."""

from __future__ import annotations

from pathlib import Path

import pytest

from axis_ptz_ros2.calibration.capture import load_picker_factory, parse_picker_options
from axis_ptz_ros2.calibration.cli import main as cli_main
from axis_ptz_ros2.config import load_camera_model, load_mount
from tests.support import sim_picker

pytestmark = pytest.mark.unit

ROOT = Path(__file__).resolve().parents[2]
PICKER_FILE = ROOT / "tests" / "support" / "sim_picker.py"


def test_a_picker_is_found_by_module_or_by_file() -> None:
    assert load_picker_factory("tests.support.sim_picker:SimBoardPicker") is sim_picker.SimBoardPicker
    by_file = load_picker_factory(f"{PICKER_FILE}:SimBoardPicker")
    picker = by_file(load_camera_model(None), load_mount(None).transform, mode="plane", max_angle_deg="2.5")
    assert picker.mode == "plane"
    assert picker.max_angle_deg == 2.5
    # the simulated world's calibration boards: 4 dots each
    labels = sorted(f.label for f in picker.features)
    assert len(labels) >= 8
    assert all("/dot_" in lab for lab in labels)
    assert len(labels) % 4 == 0


@pytest.mark.parametrize(
    ("spec", "reason"),
    [
        ("tests.support.sim_picker", "expected MODULE:NAME"),
        (":SimBoardPicker", "expected MODULE:NAME"),
        ("tests.support.sim_picker:not a name", "expected MODULE:NAME"),
        ("no_such_module_xyz:Picker", "cannot import 'no_such_module_xyz'"),
        ("tests.support.sim_picker:NoSuchPicker", "has no callable 'NoSuchPicker'"),
        ("tests.support.sim_picker:__doc__", "has no callable '__doc__'"),
        ("/nonexistent/picker.py:Picker", "no file /nonexistent/picker.py"),
    ],
)
def test_bad_picker_names_are_refused_with_the_reason(spec: str, reason: str) -> None:
    with pytest.raises(ValueError, match="picker") as err:
        load_picker_factory(spec)
    assert reason in str(err.value)


def test_picker_options() -> None:
    assert parse_picker_options(["world_file=a=b.yaml", " mode_x =1", "empty="]) == {
        "world_file": "a=b.yaml",
        "mode_x": "1",
        "empty": "",
    }
    for bad in ("novalue", "=x", "not a key=1"):
        with pytest.raises(ValueError, match="KEY=VALUE"):
            parse_picker_options([bad])


@pytest.mark.parametrize(
    ("args", "reason"),
    [
        (["--picker", "no_such_module_xyz:Picker"], "cannot import"),
        (["--picker", "tests.support.sim_picker:SimBoardPicker", "--picker-arg", "colour=red"], "colour"),
        (["--picker", "tests.support.sim_picker:SimBoardPicker", "--picker-arg", "world_file"], "KEY=VALUE"),
    ],
)
def test_the_cli_refuses_a_bad_picker_before_capturing(
    args: list[str], reason: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "views.yaml"
    assert cli_main(["capture", str(out), "--poses", "0,0", *args]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: ")
    assert reason in err
    assert not out.exists()


def test_the_ros_free_command_line_refuses_capture_without_its_ros_side(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``capture`` needs the ROS side the ``axis_calibrate`` executable plugs in (nodes/calibration_capture.py)."""
    out = tmp_path / "views.yaml"
    assert cli_main(["capture", str(out), "--poses", "0,0"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: capture needs the ROS side")
    assert not out.exists()
