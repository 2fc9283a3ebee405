"""The joystick mapping (pure): dead zone, dead-man, edges, repeats, timeout stop, map validation."""

from __future__ import annotations

import pytest

from axis_ptz_ros2.teleop.joy import GotoPreset, Home, JoyMap, JoyTeleop, Stop, Velocity, shape

pytestmark = pytest.mark.unit

M = JoyMap(
    pan_axis=0,
    tilt_axis=1,
    zoom_axis=3,
    pan_speed=2.0,
    tilt_speed=1.0,
    zoom_speed=0.5,
    deadzone=0.2,
    deadman_button=4,
    home_button=3,
    preset_buttons=(0, 1),
    preset_names=("door", "plate"),
    timeout=0.5,
)
HELD = [0, 0, 0, 0, 1, 0]
FREE = [0, 0, 0, 0, 0, 0]


def buttons(*pressed: int, deadman: bool = True) -> list[int]:
    b = list(HELD if deadman else FREE)
    for i in pressed:
        b[i] = 1
    return b


def test_shape_dead_zone_and_rescale():
    assert shape(0.1, 0.2) == 0.0
    assert shape(-0.2, 0.2) == 0.0
    assert shape(1.0, 0.2) == pytest.approx(1.0)
    assert shape(-0.6, 0.2) == pytest.approx(-0.5)
    assert shape(0.6, 0.0) == pytest.approx(0.6)


def test_stick_moves_only_with_deadman_and_scales_in_rest103():
    t = JoyTeleop(M)
    assert t.on_joy([1.0, 0.0, 0.0, 0.0], buttons(deadman=False), 0.0) == []
    assert not t.moving
    out = t.on_joy([1.0, -0.6, 0.0, 0.6], buttons(), 0.1)
    assert out == [Velocity(2.0, pytest.approx(-0.5), pytest.approx(0.25))]
    assert t.moving
    # same stick again: nothing new now, the tick repeats it
    assert t.on_joy([1.0, -0.6, 0.0, 0.6], buttons(), 0.2) == []
    assert t.tick(0.25) == [Velocity(2.0, pytest.approx(-0.5), pytest.approx(0.25))]


def test_deadman_release_stops_once():
    t = JoyTeleop(M)
    t.on_joy([0.5, 0.0, 0.0, 0.0], buttons(), 0.0)
    out = t.on_joy([0.5, 0.0, 0.0, 0.0], buttons(deadman=False), 0.1)
    assert out == [Stop("dead-man button released")]
    assert t.on_joy([0.5, 0.0, 0.0, 0.0], buttons(deadman=False), 0.2) == []
    assert t.tick(0.3) == []


def test_centred_stick_stops_once():
    t = JoyTeleop(M)
    t.on_joy([0.0, 0.9, 0.0, 0.0], buttons(), 0.0)
    assert t.on_joy([0.0, 0.1, 0.0, 0.0], buttons(), 0.1) == [Stop("sticks centred")]
    assert t.on_joy([0.0, 0.0, 0.0, 0.0], buttons(), 0.2) == []


def test_joy_silence_stops_once_then_nothing():
    t = JoyTeleop(M)
    t.on_joy([0.9, 0.0, 0.0, 0.0], buttons(), 0.0)
    assert t.tick(0.4) != []  # fresh: repeats
    out = t.tick(0.51)
    assert len(out) == 1
    assert isinstance(out[0], Stop)
    assert "no Joy message" in out[0].reason
    assert t.tick(0.6) == []
    assert not t.moving
    # Joy comes back with the stick still pushed: motion resumes
    assert t.on_joy([0.9, 0.0, 0.0, 0.0], buttons(), 1.0) != []


def test_buttons_fire_on_press_only_and_need_deadman():
    t = JoyTeleop(M)
    assert t.on_joy([0.0] * 4, buttons(3, deadman=False), 0.0) == []  # no dead-man: nothing
    assert t.on_joy([0.0] * 4, FREE, 0.05) == []
    assert t.on_joy([0.0] * 4, buttons(3), 0.1) == [Home()]
    assert t.on_joy([0.0] * 4, buttons(3), 0.2) == []  # held: no repeat
    assert t.on_joy([0.0] * 4, buttons(), 0.3) == []
    assert t.on_joy([0.0] * 4, buttons(1), 0.4) == [GotoPreset("plate")]
    assert t.on_joy([0.0] * 4, buttons(1, 0), 0.5) == [GotoPreset("door")]


def test_goto_wins_over_sticks_and_is_not_stopped():
    t = JoyTeleop(M)
    t.on_joy([0.9, 0.0, 0.0, 0.0], buttons(), 0.0)
    out = t.on_joy([0.9, 0.0, 0.0, 0.0], buttons(3), 0.1)
    assert out == [Home()]
    assert not t.moving
    assert t.tick(0.15) == []


def test_zoom_buttons_and_short_messages():
    m = JoyMap(
        zoom_axis=-1,
        zoom_in_button=5,
        zoom_out_button=6,
        deadman_button=-1,
        home_button=-1,
        preset_buttons=(),
        preset_names=(),
        zoom_speed=0.7,
    )
    t = JoyTeleop(m)
    b = [0] * 8
    b[5] = 1
    assert t.on_joy([0.0, 0.0], b, 0.0) == [Velocity(0.0, 0.0, 0.7)]
    b[5], b[6] = 0, 1
    assert t.on_joy([0.0, 0.0], b, 0.1) == [Velocity(0.0, 0.0, -0.7)]
    # a message with fewer axes/buttons than the map: those read as released, with a warning
    t2 = JoyTeleop(M)
    assert t2.on_joy([0.5], [1], 0.0) == []
    assert any("tilt_axis=1" in w for w in t2.warnings)
    assert any("deadman_button=4" in w for w in t2.warnings)


def test_non_finite_axis_is_ignored():
    t = JoyTeleop(M)
    # garbage from a driver reads as a centred stick, never as full deflection
    assert t.on_joy([float("nan"), float("inf"), 0.0, 0.0], buttons(), 0.0) == []
    assert t.on_joy([float("nan"), 1.5, 0.0, 0.0], buttons(), 0.1) == [Velocity(0.0, 1.0, 0.0)]  # clipped


@pytest.mark.parametrize(
    ("changes", "reason"),
    [
        ({"preset_buttons": (0, 1), "preset_names": ("a",)}, "one name per button"),
        ({"home_button": 0}, "must differ"),
        ({"deadman_button": 3}, "dead-man"),
        ({"pan_axis": 1}, "axes"),
        ({"deadzone": 1.0}, "deadzone"),
        ({"pan_speed": float("nan")}, "pan_speed"),
        ({"timeout": 0.0}, "timeout"),
        ({"preset_names": ("a:b", "c", "d")}, "preset name"),
        ({"home_button": -2}, "home_button"),
    ],
)
def test_bad_maps_are_refused_with_the_reason(changes, reason):
    base = {f: getattr(JoyMap(), f) for f in JoyMap.__dataclass_fields__}
    base.update(changes)
    with pytest.raises(ValueError, match=reason):
        JoyMap(**base)


def test_the_mapping_imports_without_ros():
    """teleop/joy.py belongs to the ROS-free layer (a fresh interpreter with rclpy blocked)."""
    import subprocess
    import sys

    probe = (
        "import sys\n"
        "for m in ('rclpy', 'sensor_msgs', 'std_msgs', 'axis_ptz_interfaces'):\n"
        "    sys.modules[m] = None\n"
        "import axis_ptz_ros2.teleop.joy\n"
        "print('ok')\n"
    )
    r = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, check=False)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "ok"
