"""The joystick teleop's parameter table is the one source of its map: :class:`JoyMap` is a frozen snapshot of it,
the parameters' defaults are JoyMap's, the speed ranges the ones JoyMap accepts."""

from __future__ import annotations

import dataclasses

import pytest

pytest.importorskip("rclpy")

from axis_ptz_ros2.nodes.joy_teleop import PARAMS, joy_map_from_params  # noqa: E402
from axis_ptz_ros2.teleop.joy import MAX_PAN_TILT_SPEED, MAX_ZOOM_SPEED, JoyMap  # noqa: E402

pytestmark = pytest.mark.ros

DEFAULTS = {s.name: s.default for s in PARAMS}


def test_defaults_make_the_default_map_and_every_field_is_a_parameter():
    assert joy_map_from_params(DEFAULTS) == JoyMap()
    filled = {s.field for s in PARAMS if s.config is JoyMap}
    assert filled == {f.name for f in dataclasses.fields(JoyMap)}
    assert DEFAULTS["preset_buttons"] == [0, 1, 2]  # a list, as a parameter file writes it
    assert DEFAULTS["preset_names"] == ["1", "2", "3"]


def test_values_land_in_their_fields_and_lists_become_tuples():
    values = {**DEFAULTS, "joy_timeout": 2.0, "pan_speed": -3.0, "preset_buttons": [5], "preset_names": ["door"]}
    assert joy_map_from_params(values) == JoyMap(
        timeout=2.0, pan_speed=-3.0, preset_buttons=(5,), preset_names=("door",)
    )


def test_a_map_that_makes_no_sense_is_refused_with_the_reason():
    with pytest.raises(ValueError, match="dead-man button 9"):
        joy_map_from_params({**DEFAULTS, "home_button": 9})
    with pytest.raises(ValueError, match="preset_buttons must be a list of integers"):
        joy_map_from_params({**DEFAULTS, "preset_buttons": ["a"]})


def test_speed_ranges_are_the_ones_the_map_accepts():
    specs = {s.name: s for s in PARAMS}
    turn = (-MAX_PAN_TILT_SPEED, MAX_PAN_TILT_SPEED)
    assert specs["pan_speed"].float_range == specs["tilt_speed"].float_range == turn
    assert specs["zoom_speed"].float_range == (-MAX_ZOOM_SPEED, MAX_ZOOM_SPEED)
    assert joy_map_from_params({**DEFAULTS, "pan_speed": MAX_PAN_TILT_SPEED}).pan_speed == MAX_PAN_TILT_SPEED
    with pytest.raises(ValueError, match="pan_speed"):
        joy_map_from_params({**DEFAULTS, "pan_speed": MAX_PAN_TILT_SPEED + 0.1})
