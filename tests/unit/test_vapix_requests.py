"""Request dataclasses: wire encoding and validation (vapix.md §4.1, §4.2, §4.6)."""

import math

import pytest

from axis_ptz_ros2.vapix.errors import InvalidArgument
from axis_ptz_ros2.vapix.models import PtzLimits, PtzPosition
from axis_ptz_ros2.vapix.requests import (
    PTZ_CGI,
    PTZCONFIG_CGI,
    AbsoluteMove,
    AreaZoom,
    Center,
    ContinuousMove,
    GotoPreset,
    Move,
    MoveDirection,
    RelativeMove,
    RemovePreset,
    SetPreset,
    SetSpeed,
)
from tests.unit import fixtures_vapix as fx

pytestmark = pytest.mark.unit

LIMITS_214 = PtzLimits(-170, 170, -30, 90, 1, 9999)


def test_absolute_move_keeps_sub_degree_precision():
    cmd = AbsoluteMove(pan_deg=10.12345, tilt_deg=-15.5, zoom=3000, speed=50)
    cmd.validate(LIMITS_214)
    assert cmd.query() == {"pan": "10.1235", "tilt": "-15.5000", "zoom": "3000", "speed": "50"}
    assert AbsoluteMove(pan_deg=0.4).query() == {"pan": "0.4000"}  # never int()-truncated to 0
    assert AbsoluteMove(pan_deg=-0.00001).query() == {"pan": "0.0000"}
    assert AbsoluteMove(pan_deg=1.0).path == PTZ_CGI


@pytest.mark.parametrize(
    ("cmd", "reason"),
    [
        (AbsoluteMove(), "at least one"),
        (AbsoluteMove(pan_deg=500.0), "pan 500 outside the protocol range -180..180"),
        (AbsoluteMove(pan_deg=175.0), "pan 175 outside the camera limits -170..170"),
        (AbsoluteMove(tilt_deg=-60.0), "tilt -60 outside the camera limits -30..90"),
        (AbsoluteMove(zoom=0), "zoom 0 outside the protocol range"),
        (AbsoluteMove(zoom=12000), "zoom 12000 outside the camera limits 1..9999"),
        (AbsoluteMove(zoom=10.5), "zoom must be an integer"),  # type: ignore[arg-type]
        (AbsoluteMove(pan_deg=math.nan), "pan must be a finite number"),
        (AbsoluteMove(pan_deg=1.0, speed=0), "speed 0 outside"),
        (RelativeMove(), "at least one"),
        (RelativeMove(rpan_deg=400.0), "rpan 400 outside the protocol range -360..360"),
        (RelativeMove(rzoom=10000), "rzoom 10000 outside"),
        (ContinuousMove(101, 0), "pan speed 101 outside"),
        (ContinuousMove(0, -101), "tilt speed -101 outside"),
        (ContinuousMove(0, 0, 200), "zoom speed 200 outside"),
        (Center(704, 10, 704, 576), r"pixel \(704, 10\) outside the 704x576 image"),
        (Center(1, 1, 0, 576), "image size must be positive"),
        (AreaZoom(10, 10, 0, 704, 576), "z must be >= 1"),
        (GotoPreset(), "exactly one"),
        (GotoPreset(name="a", number=1), "exactly one"),
        (GotoPreset(number=0), "preset number must be >= 1"),
        (SetPreset("x" * 32), "longer than 31"),
        (SetPreset("a:b"), "forbidden characters"),
        (RemovePreset(""), "non-empty"),
        (SetSpeed(101), "speed 101 outside"),
        (Move("sideways"), "unknown move direction"),  # type: ignore[arg-type]
    ],
)
def test_validation_refuses_with_reason(cmd, reason):
    with pytest.raises(InvalidArgument, match=reason):
        cmd.validate(LIMITS_214)


def test_invalid_argument_is_also_value_error():
    with pytest.raises(ValueError, match="pan"):
        AbsoluteMove(pan_deg=1000.0).validate(None)


def test_limits_from_real_fixture_used_for_validation():
    limits = PtzLimits.parse(fx.LIMITS_RESPONSE)
    AbsoluteMove(tilt_deg=-20.0).validate(limits)
    with pytest.raises(InvalidArgument, match="tilt -25 outside the camera limits -20..90"):
        AbsoluteMove(tilt_deg=-25.0).validate(limits)


def test_without_limits_only_protocol_range_applies():
    AbsoluteMove(pan_deg=180.0, tilt_deg=-180.0, zoom=9999).validate(None)


def test_relative_move_target_checked_against_current_position():
    current = PtzPosition(pan_deg=160.0, tilt_deg=0.0, zoom=9000)
    RelativeMove(rpan_deg=10.0).validate(LIMITS_214, current=current)
    with pytest.raises(InvalidArgument, match="target pan 175 outside the camera limits"):
        RelativeMove(rpan_deg=15.0).validate(LIMITS_214, current=current)
    with pytest.raises(InvalidArgument, match="target zoom 10000"):
        RelativeMove(rzoom=1000).validate(LIMITS_214, current=current)
    assert RelativeMove(rpan_deg=-2.25, rtilt_deg=0.5, rzoom=-100).query() == {
        "rpan": "-2.2500",
        "rtilt": "0.5000",
        "rzoom": "-100",
    }


def test_continuous_move_always_sends_pan_tilt_even_zero():
    assert ContinuousMove(0, 0).query() == {"continuouspantiltmove": "0,0"}
    assert ContinuousMove(0, 0, 0).query() == {"continuouspantiltmove": "0,0", "continuouszoommove": "0"}
    assert ContinuousMove(-100, 50, 10).query() == {
        "continuouspantiltmove": "-100,50",
        "continuouszoommove": "10",
    }


def test_center_and_areazoom_send_image_size():
    assert Center(150, 275, 704, 576).query() == {
        "center": "150,275",
        "imagewidth": "704",
        "imageheight": "576",
    }
    assert AreaZoom(352, 288, 300, 704, 576).query() == {
        "areazoom": "352,288,300",
        "imagewidth": "704",
        "imageheight": "576",
    }


def test_move_vocabulary_is_strenum():
    assert [d.value for d in MoveDirection] == [
        "home",
        "up",
        "down",
        "left",
        "right",
        "upleft",
        "upright",
        "downleft",
        "downright",
        "stop",
    ]
    assert Move(MoveDirection.HOME).query() == {"move": "home"}
    Move(MoveDirection.STOP).validate(None)


def test_presets_paths_and_args():
    assert GotoPreset(name="Home").query() == {"gotoserverpresetname": "Home"}
    assert GotoPreset(number=2).query() == {"gotoserverpresetno": "2"}
    assert GotoPreset(name="Home").path == PTZ_CGI
    assert SetPreset("Door").path == PTZCONFIG_CGI
    assert SetPreset("Door", home=True).query() == {"setserverpresetname": "Door", "home": "yes"}
    assert RemovePreset("Door").path == PTZCONFIG_CGI
    assert RemovePreset("Door").query() == {"removeserverpresetname": "Door"}
    assert SetSpeed(100).query() == {"speed": "100"}
