"""The keyboard teleop key map (thesis Table 5.3): every key, signs against the VAPIX convention, parsing."""

import math

import pytest

from axis_ptz_ros2.geometry import VapixConvention
from axis_ptz_ros2.teleop import keymap as km
from axis_ptz_ros2.teleop.keymap import (
    GoHome,
    Notice,
    Quit,
    RelativeMove,
    SetVideo,
    StopMotion,
    TeleopState,
    ToggleHelp,
    apply,
)

pytestmark = pytest.mark.unit

VIDEO = TeleopState(step=1, fps=15, resolution="352x288", compression=30)


def _move(key: str, step: int) -> RelativeMove:
    cmds, state = apply(key, TeleopState(step=step))
    assert state.step == step
    assert len(cmds) == 1
    assert isinstance(cmds[0], RelativeMove)
    return cmds[0]


@pytest.mark.parametrize(
    ("key", "pan_deg_thesis", "fast"),
    [("a", -1, False), ("d", +1, False), ("A", -1, True), ("D", +1, True), ("<left>", -1, False)]
    + [("<right>", +1, False)],
)
@pytest.mark.parametrize("step", [1, 4, 9])
def test_pan_keys_follow_the_thesis_in_axis_degrees_and_turn_the_view_the_right_way(key, pan_deg_thesis, fast, step):
    m = _move(key, step)
    factor = 5 if fast else 1
    assert math.isnan(m.tilt)
    assert math.isnan(m.zoom)
    # Thesis: "A: turn by -x deg in pan axis" (Axis pan, + = right) on the Axis 214 (cw, upright).
    vapix_pan, _ = VapixConvention().to_vapix(m.pan, 0.0)
    assert vapix_pan == pytest.approx(pan_deg_thesis * factor * step)
    # REP-103: + = left (CCW). A/left turn the view left.
    assert (m.pan > 0) == (pan_deg_thesis < 0)
    assert abs(m.pan) == pytest.approx(math.radians(factor * step))


@pytest.mark.parametrize(
    ("key", "sign", "fast"),
    [("w", +1, False), ("s", -1, False), ("W", +1, True), ("S", -1, True), ("<up>", +1, False)]
    + [("<down>", -1, False)],
)
@pytest.mark.parametrize("step", [1, 3, 9])
def test_tilt_keys(key, sign, fast, step):
    m = _move(key, step)
    assert math.isnan(m.pan)
    assert math.isnan(m.zoom)
    assert m.tilt == pytest.approx(sign * math.radians(step * (5 if fast else 1)))
    _, vapix_tilt = VapixConvention().to_vapix(0.0, m.tilt)
    assert vapix_tilt == pytest.approx(sign * step * (5 if fast else 1))


@pytest.mark.parametrize(("key", "units_per_step"), [("q", -10), ("e", +10), ("Q", -100), ("E", +100)])
@pytest.mark.parametrize("step", [1, 2, 9])
def test_zoom_keys(key, units_per_step, step):
    m = _move(key, step)
    assert math.isnan(m.pan)
    assert math.isnan(m.tilt)
    assert m.zoom == units_per_step * step


@pytest.mark.parametrize("digit", range(1, 10))
def test_digits_set_the_step_size_and_send_nothing(digit):
    cmds, st = apply(str(digit), VIDEO)
    assert cmds == []
    assert st.step == digit
    assert st.fps == VIDEO.fps  # nothing else changes
    (m,), _ = apply("d", st)
    assert m.pan == pytest.approx(-math.radians(digit))


def test_space_goes_home_and_stop_keys_stop():
    assert apply(" ", VIDEO) == ([GoHome()], VIDEO)
    for k in ("x", "X", km.ESC):
        assert apply(k, VIDEO) == ([StopMotion()], VIDEO)


def test_help_and_quit():
    assert apply("?", VIDEO) == ([ToggleHelp()], VIDEO)
    for k in (km.CTRL_C, km.CTRL_Q):
        cmds, _ = apply(k, VIDEO)
        assert cmds == [StopMotion(), Quit()]


@pytest.mark.parametrize(("key", "fps"), [("r", 18), ("R", 18), ("f", 12), ("F", 12)])
def test_fps_keys(key, fps):
    assert apply(key, VIDEO) == ([SetVideo(fps=fps)], VIDEO)


def test_fps_clamps_to_range_and_says_so_at_the_limit():
    assert apply("r", TeleopState(fps=29)) == ([SetVideo(fps=30)], TeleopState(fps=29))
    assert apply("f", TeleopState(fps=2)) == ([SetVideo(fps=1)], TeleopState(fps=2))
    (n,), _ = apply("r", TeleopState(fps=30))
    assert isinstance(n, Notice)
    assert "limit" in n.text
    (n,), _ = apply("f", TeleopState(fps=1))
    assert isinstance(n, Notice)


@pytest.mark.parametrize(("key", "c"), [("y", 40), ("Y", 40), ("h", 20), ("H", 20)])
def test_compression_keys(key, c):
    assert apply(key, VIDEO) == ([SetVideo(compression=c)], VIDEO)


def test_compression_clamps():
    assert apply("y", TeleopState(compression=95))[0] == [SetVideo(compression=100)]
    assert apply("h", TeleopState(compression=5))[0] == [SetVideo(compression=0)]
    assert isinstance(apply("h", TeleopState(compression=0))[0][0], Notice)


@pytest.mark.parametrize(
    ("key", "current", "expected"),
    [
        ("t", "352x288", "704x288"),
        ("T", "704x288", "704x576"),
        ("g", "704x576", "704x288"),
        ("G", "352x288", "176x144"),
        ("t", "640x480", "704x576"),  # not in the list: nearest larger
        ("g", "640x480", "704x288"),  # nearest smaller by pixel count (202752 < 307200)
    ],
)
def test_resolution_keys_walk_the_camera_list(key, current, expected):
    st = TeleopState(resolution=current)
    assert apply(key, st) == ([SetVideo(resolution=expected)], st)


def test_resolution_ends_of_list_and_custom_list():
    (n,), _ = apply("t", TeleopState(resolution="704x576"))
    assert isinstance(n, Notice)
    assert "top" in n.text
    (n,), _ = apply("g", TeleopState(resolution="176x144"))
    assert "bottom" in n.text
    st = TeleopState(resolution="640x480", resolutions=("1920x1080", "640x480", "1280x720", "bogus"))
    assert apply("t", st)[0] == [SetVideo(resolution="1280x720")]
    assert apply("T", TeleopState(resolution="1280x720", resolutions=st.resolutions))[0] == [
        SetVideo(resolution="1920x1080")
    ]


@pytest.mark.parametrize("key", ["r", "f", "t", "g", "y", "h"])
def test_video_keys_before_the_stream_reported_its_params_send_nothing(key):
    (n,), st = apply(key, TeleopState())
    assert isinstance(n, Notice)
    assert "not known" in n.text
    assert st == TeleopState()


def test_unknown_keys_do_nothing():
    for k in ("z", "0", "\r", "<unknown>", "é"):
        assert apply(k, VIDEO) == ([], VIDEO)


H264 = TeleopState(
    step=1,
    fps=15,
    resolution="704x576",
    compression=0,
    codec="h264",
    h264_bitrate_kbps=1000,
    h264_max_bitrate_kbps=1500,
)


@pytest.mark.parametrize(
    ("key", "start", "top"),
    [("h", 1500, 2000), ("H", 1500, 2000), ("y", 700, 1000), ("Y", 700, 1000)],
)
def test_quality_keys_step_both_h264_bitrates_in_h264_mode(key, start, top):
    """With H.264, Y/H never touch the compression: the bitrate without feedback and the ceiling move together."""
    assert apply(key, H264) == ([SetVideo(h264_bitrate_kbps=start, h264_max_bitrate_kbps=top)], H264)


def test_h264_bitrate_keys_keep_the_ceiling_at_least_the_start_and_stop_at_the_range():
    # values between two steps move to the next step that way; the ceiling never below the start
    odd = TeleopState(codec="h264", h264_bitrate_kbps=1200, h264_max_bitrate_kbps=1250)
    assert apply("h", odd)[0] == [SetVideo(h264_bitrate_kbps=1500, h264_max_bitrate_kbps=1500)]
    assert apply("y", odd)[0] == [SetVideo(h264_bitrate_kbps=1000, h264_max_bitrate_kbps=1000)]
    top = TeleopState(codec="h264", h264_bitrate_kbps=15000, h264_max_bitrate_kbps=20000)
    assert apply("h", top)[0] == [SetVideo(h264_bitrate_kbps=20000, h264_max_bitrate_kbps=20000)]
    (n,), _ = apply("h", TeleopState(codec="h264", h264_bitrate_kbps=20000, h264_max_bitrate_kbps=20000))
    assert isinstance(n, Notice)
    assert "limit" in n.text
    bottom = TeleopState(codec="h264", h264_bitrate_kbps=100, h264_max_bitrate_kbps=150)
    assert apply("y", bottom)[0] == [SetVideo(h264_bitrate_kbps=100, h264_max_bitrate_kbps=100)]
    (n,), _ = apply("y", TeleopState(codec="h264", h264_bitrate_kbps=100, h264_max_bitrate_kbps=100))
    assert isinstance(n, Notice)
    (n,), _ = apply("h", TeleopState(codec="h264"))  # no video/params yet
    assert isinstance(n, Notice)
    assert "not known" in n.text


def test_bitrate_steps_span_the_stream_nodes_range():
    from axis_ptz_ros2.media.limits import BITRATE_RANGE_KBPS  # noqa: PLC0415

    assert (km.BITRATE_STEPS_KBPS[0], km.BITRATE_STEPS_KBPS[-1]) == BITRATE_RANGE_KBPS
    assert list(km.BITRATE_STEPS_KBPS) == sorted(set(km.BITRATE_STEPS_KBPS))


def test_help_says_what_the_quality_keys_do_in_each_mode():
    lines = {line.split()[0]: line for line in km.help_lines() if line.split()}
    for key in ("Y", "H"):
        assert "MJPEG: compression" in lines[key]
        assert "H.264: bitrate one step" in lines[key]


def test_other_video_keys_act_the_same_in_h264_mode():
    assert apply("r", H264)[0] == [SetVideo(fps=18)]
    assert apply("g", H264)[0] == [SetVideo(resolution="704x288")]


def test_every_mapped_key_has_a_description_and_is_handled():
    for key, action in km.KEYMAP.items():
        assert action.description, key
        cmds, _ = apply(key, VIDEO)
        assert cmds or action.kind is km.Kind.STEP, key
    assert len(km.help_lines()) >= 30


def test_split_keys_decodes_escape_sequences_instead_of_typing_their_letters():
    assert km.split_keys("ad") == ["a", "d"]
    assert km.split_keys("\x1b[A\x1b[D") == ["<up>", "<left>"]
    assert km.split_keys("\x1bOB\x1bOC") == ["<down>", "<right>"]
    assert km.split_keys("\x1b[1;2A") == ["<unknown>"]  # SHIFT+up: not mapped (never a stray "A")
    assert km.split_keys("\x1b[15~w") == ["<unknown>", "w"]  # F5 then w
    assert km.split_keys("\x1b") == [km.ESC]
    assert km.split_keys("x\x1b") == ["x", km.ESC]
    assert km.split_keys("\x1bq") == [km.ESC, "q"]


def test_resolution_parsing():
    assert km.parse_resolution(" 704X576 ") == (704, 576)
    for bad in ("704", "ax5", "0x10", "4CIF"):
        with pytest.raises(ValueError, match=r"."):
            km.parse_resolution(bad)
    assert km.sort_resolutions(["704x576", "176x144", "704x288", "352x288", "176x144"]) == (
        "176x144",
        "352x288",
        "704x288",
        "704x576",
    )
    assert km.next_resolution("352x288", [], 1) is None
