"""Models and lenient parsing of real VAPIX replies (vapix.md §4.4, §4.7, §5.5, §6, §12)."""

import pytest

from axis_ptz_ros2.vapix.errors import InvalidArgument, ResponseParseError
from axis_ptz_ros2.vapix.models import (
    Preset,
    PtzLimits,
    PtzPosition,
    Resolution,
    VideoParams,
    parse_bool,
    parse_key_values,
)
from tests.unit import fixtures_vapix as fx

pytestmark = pytest.mark.unit


def test_position_real_fixture_all_fields():
    pos = PtzPosition.parse(fx.POSITION_RESPONSE)
    assert pos == PtzPosition(
        pan_deg=51.2891,
        tilt_deg=46.1914,
        zoom=1,
        focus=8265,
        iris=6427,
        brightness=4999,
        autofocus=False,
        autoiris=True,
    )


def test_position_crlf_negative_and_two_decimals():
    pos = PtzPosition.parse(fx.POSITION_RESPONSE_CLEARPATH)
    assert pos.pan_deg == pytest.approx(-0.01)
    assert pos.tilt_deg == pytest.approx(-45.03)
    assert pos.autofocus is True
    assert pos.iris == 5748


def test_position_optional_fields_are_none():
    pos = PtzPosition.parse(fx.POSITION_RESPONSE_MINIMAL)
    assert (pos.pan_deg, pos.tilt_deg, pos.zoom) == (10.0, -15.0, 3000)
    assert pos.focus is None
    assert pos.iris is None
    assert pos.brightness is None


def test_position_missing_pan_is_parse_error():
    with pytest.raises(ResponseParseError, match="pan"):
        PtzPosition.parse("tilt=1\nzoom=1\n")


def test_position_bad_number_is_parse_error():
    with pytest.raises(ResponseParseError, match="pan"):
        PtzPosition.parse("pan=abc\ntilt=1\nzoom=1\n")


def test_limits_fixture_field_angle_in_tenths():
    lim = PtzLimits.parse(fx.LIMITS_RESPONSE)
    assert (lim.min_pan_deg, lim.max_pan_deg, lim.min_tilt_deg, lim.max_tilt_deg) == (-170, 170, -20, 90)
    assert (lim.min_zoom, lim.max_zoom) == (1, 9999)
    assert (lim.min_focus, lim.max_focus, lim.min_iris, lim.max_iris) == (770, 9999, 1, 9999)
    assert lim.min_field_angle_deg == pytest.approx(2.2)
    assert lim.max_field_angle_deg == pytest.approx(62.3)


def test_limits_from_param_listing_with_root_prefix():
    lim = PtzLimits.from_params(parse_key_values(fx.P5512_PTZ_LIMIT_PARAMS), camera=1)
    assert (lim.min_tilt_deg, lim.max_tilt_deg, lim.max_zoom) == (-180, 0, 19999)
    assert lim.min_field_angle_deg == pytest.approx(4.4)
    assert lim.max_field_angle_deg == pytest.approx(51.6)
    assert lim.min_iris is None


def test_limits_inverted_is_parse_error():
    with pytest.raises(ResponseParseError, match="minimum above maximum"):
        PtzLimits.parse("MinPan=10\nMaxPan=-10\nMinTilt=0\nMaxTilt=1\nMinZoom=1\nMaxZoom=9999\n")


def test_presets_header_ignored_and_sorted():
    assert Preset.parse_list(fx.PRESETPOSCAM_RESPONSE) == (Preset(1, "Home"),)
    assert Preset.parse_list(fx.PRESETPOSCAM_RESPONSE_TWO) == (Preset(1, "Home"), Preset(2, "Door"))


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("a=1\nb=2\n", {"a": "1", "b": "2"}),
        ("  a = 1 \r\n\r\nno equals here\r\nb=x=y\r\n", {"a": "1", "b": "x=y"}),
        (
            "root.Brand.ProdNbr=P5512\nBrand.ProdShortName=AXIS P5512",
            {"Brand.ProdNbr": "P5512", "Brand.ProdShortName": "AXIS P5512"},
        ),
        ("Preset Positions for camera 1\n", {}),
    ],
)
def test_parse_key_values_lenient(text, expected):
    assert parse_key_values(text) == expected


@pytest.mark.parametrize(
    ("value", "expected"),
    [("on", True), ("OFF", False), ("yes", True), ("no", False), ("true", True), ("False", False)],
)
def test_parse_bool_vocabulary(value, expected):
    assert parse_bool(value) is expected


def test_parse_bool_rejects_other_words():
    with pytest.raises(ResponseParseError, match="maybe"):
        parse_bool("maybe")


@pytest.mark.parametrize(
    ("text", "ntsc", "size"),
    [
        ("704x576", False, (704, 576)),
        ("4CIF", False, (704, 576)),
        ("2CIFEXP", False, (704, 576)),
        ("2CIF", False, (704, 288)),
        ("cif", False, (352, 288)),
        ("QCIF", False, (176, 144)),
        ("4CIF", True, (704, 480)),
        ("2CIF", True, (704, 240)),
        ("QCIF", True, (176, 120)),
    ],
)
def test_resolution_parse_names_and_wxh(text, ntsc, size):
    res = Resolution.parse(text, ntsc=ntsc)
    assert (res.width, res.height) == size
    assert str(res) == f"{size[0]}x{size[1]}"


def test_resolution_unknown_name_refused():
    with pytest.raises(InvalidArgument, match="unknown resolution 'HD'"):
        Resolution.parse("HD")


PAL = (Resolution(704, 576), Resolution(352, 288), Resolution(176, 144))


def test_video_params_query_uses_documented_fps():
    params = VideoParams(Resolution(704, 576), fps=24, compression=30)
    assert params.query() == {"resolution": "704x576", "fps": "24", "compression": "30"}
    assert "req_fps" not in params.query()
    assert VideoParams(Resolution(704, 576), 5, 0, camera=2, squarepixel=True).query() == {
        "resolution": "704x576",
        "fps": "5",
        "compression": "0",
        "camera": "2",
        "squarepixel": "1",
    }


@pytest.mark.parametrize(
    ("params", "reason"),
    [
        (VideoParams(Resolution(704, 576), 0, 30), "fps 0 outside 1..30"),
        (VideoParams(Resolution(704, 576), 31, 30), "fps 31 outside 1..30"),
        (VideoParams(Resolution(704, 576), 10, -1), "compression -1 outside 0..100"),
        (VideoParams(Resolution(704, 576), 10, 101), "compression 101 outside 0..100"),
        (VideoParams(Resolution(1920, 1080), 10, 30), "resolution 1920x1080 not supported"),
    ],
)
def test_video_params_validation_reasons(params, reason):
    with pytest.raises(InvalidArgument, match=reason):
        params.validate(PAL)


def test_video_params_valid_and_unknown_list_skips_resolution_check():
    VideoParams(Resolution(352, 288), 30, 100).validate(PAL)
    VideoParams(Resolution(1920, 1080), 1, 0).validate(None)
