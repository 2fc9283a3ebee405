"""The camera's replies, generated: every parser of the VAPIX layer answers any byte string with a typed value
or a typed refusal (``ResponseParseError`` / ``InvalidArgument``, both ``AxisPtzError``), never another exception,
never a number the ROS messages cannot hold (issue 25: "no number wraps").

Boundaries: ``key=value`` listings (``param.cgi``, ``Properties``, ``Brand``), ``query=position|limits``,
``presetposcam``, resolution names / ``WxH`` (``imagesize.cgi``, ``Properties.Image.Resolution``), the MJPEG
``multipart/x-mixed-replace`` stream (boundary header, parts, lengths, truncation, garbage).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TypeVar

import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from axis_ptz_ros2.vapix.errors import AxisPtzError
from axis_ptz_ros2.vapix.mjpeg import MjpegParser, boundary_from_content_type
from axis_ptz_ros2.vapix.models import (
    INT_RANGE,
    MAX_IMAGE_SIDE,
    Preset,
    PtzLimits,
    PtzPosition,
    Resolution,
    parse_float,
    parse_int,
    parse_key_values,
)
from tests.unit.fixtures_vapix import part

pytestmark = pytest.mark.fuzz
T = TypeVar("T")

INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1

# Values a camera (or something pretending to be one) may put after '=': numbers of every shape and size,
# words, empty, unicode, control characters.
_number_text = st.one_of(
    st.integers().map(str),
    st.integers(min_value=-(10**500), max_value=10**500).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.floats().map(lambda f: f"{f:.12e}"),
    st.sampled_from(["nan", "inf", "-inf", "1e400", "-1e400", "0x10", "1_000", " 7 ", "", "1.", ".5", "+3", "٣"]),
)
_value_text = st.one_of(_number_text, st.text(max_size=40))


def _listing(keys: list[str]) -> st.SearchStrategy[str]:
    line = st.tuples(st.sampled_from(keys), _value_text).map(lambda kv: f"{kv[0]}={kv[1]}")
    noise = st.text(max_size=30).filter(lambda s: "\n" not in s and "\r" not in s)
    eol = st.sampled_from(["\n", "\r\n"])
    return st.lists(st.tuples(st.one_of(line, noise), eol), max_size=20).map(
        lambda parts: "".join(a + b for a, b in parts)
    )


_POSITION_KEYS = ["pan", "tilt", "zoom", "focus", "iris", "brightness", "autofocus", "autoiris", "root.pan", "x"]
_LIMIT_KEYS = [
    "MinPan", "MaxPan", "MinTilt", "MaxTilt", "MinZoom", "MaxZoom", "MinFocus", "MaxFocus",
    "MinIris", "MaxIris", "MinFieldAngle", "MaxFieldAngle",
]  # fmt: skip


def _parsed(parse: Callable[..., T], *args: object, **kwargs: object) -> T | None:
    """The parser's value, or None when it refused with a typed error that says why."""
    try:
        return parse(*args, **kwargs)
    except AxisPtzError as err:
        if not str(err):
            pytest.fail(f"{parse.__qualname__} refused {args!r} without a reason")
        return None


def _within_int32(value: int | None) -> bool:
    return value is None or INT32_MIN <= value <= INT32_MAX


@given(st.text())
def test_key_value_listing_never_raises(text: str) -> None:
    values = parse_key_values(text)
    assert all(isinstance(k, str) and k and isinstance(v, str) for k, v in values.items())
    assert all("\n" not in k and "\n" not in v for k, v in values.items())


@given(_number_text)
def test_numbers_are_finite_and_bounded_or_refused(text: str) -> None:
    try:
        value = parse_float(text)
    except AxisPtzError:
        value = None
    assert value is None or math.isfinite(value)
    try:
        integer = parse_int(text)
    except AxisPtzError:
        return
    assert INT_RANGE[0] <= integer <= INT_RANGE[1], integer


@given(_listing(_POSITION_KEYS))
def test_position_reply(text: str) -> None:
    position = _parsed(PtzPosition.parse, text)
    if position is None:
        return
    assert math.isfinite(position.pan_deg)
    assert math.isfinite(position.tilt_deg)
    for value in (position.zoom, position.focus, position.iris, position.brightness):
        assert _within_int32(value)


@given(_listing(_LIMIT_KEYS))
def test_limits_reply(text: str) -> None:
    limits = _parsed(PtzLimits.parse, text)
    if limits is None:
        return
    assert limits.min_pan_deg <= limits.max_pan_deg
    assert limits.min_tilt_deg <= limits.max_tilt_deg
    assert limits.min_zoom <= limits.max_zoom
    for value in (limits.min_zoom, limits.max_zoom, limits.min_focus, limits.max_focus):
        assert _within_int32(value)
    for angle in (limits.min_field_angle_deg, limits.max_field_angle_deg):
        assert angle is None or math.isfinite(angle)


@given(_listing(["presetposno1", "presetposno2", "presetposnoX", "presetposno", "presetposno99999999999999"]))
def test_preset_listing(text: str) -> None:
    presets = _parsed(Preset.parse_list, text)
    if presets is None:
        return
    numbers = [p.number for p in presets]
    assert numbers == sorted(numbers)
    assert all(_within_int32(n) and n >= 0 for n in numbers)


_resolution_text = st.one_of(
    st.text(max_size=30),
    st.tuples(st.integers(-5, 10**12), st.sampled_from(["x", "X", "*", " x "]), st.integers(-5, 10**12)).map(
        lambda t: f"{t[0]}{t[1]}{t[2]}"
    ),
    st.sampled_from(["4CIF", "2cifexp", "CIF", "QCIF", "D1", "0x0", "4294967648x288", "99999999999999999999x1"]),
)


@given(_resolution_text, st.booleans())
def test_resolution_is_a_real_image_size_or_refused(text: str, ntsc: bool) -> None:
    size = _parsed(Resolution.parse, text, ntsc=ntsc)
    if size is None:
        return
    assert 1 <= size.width <= MAX_IMAGE_SIDE
    assert 1 <= size.height <= MAX_IMAGE_SIDE


def test_sizes_that_would_wrap_a_uint32_are_refused() -> None:
    """Regression: 2^32 + 352 must not become 352 anywhere downstream."""
    for text in ("4294967648x288", "352x4294967584", f"{10**30}x{10**30}"):
        with pytest.raises(AxisPtzError, match="1..|outside"):
            Resolution.parse(text)


@given(st.text(max_size=120))
def test_content_type_boundary(content_type: str) -> None:
    try:
        boundary = boundary_from_content_type(content_type)
    except AxisPtzError:
        return
    except UnicodeEncodeError:  # pragma: no cover - reported as a finding if it ever happens
        pytest.fail(f"UnicodeEncodeError escaped for {content_type!r}")
    assert boundary
    assert not boundary.startswith(b"--")


_JPEG = st.binary(max_size=300).map(lambda body: b"\xff\xd8" + body.replace(b"\xff\xd9", b"") + b"\xff\xd9")


def _split(data: bytes, cuts: list[int]) -> list[bytes]:
    points = sorted({c % (len(data) + 1) for c in cuts})
    edges = [0, *points, len(data)]
    return [data[a:b] for a, b in zip(edges, edges[1:], strict=False)]


@given(st.lists(_JPEG, min_size=1, max_size=6), st.lists(st.integers(0, 10**6), max_size=12))
def test_valid_stream_in_any_chunking_gives_every_frame_once(frames: list[bytes], cuts: list[int]) -> None:
    stream = b"".join(part(f) for f in frames)
    parser = MjpegParser(b"myboundary")
    out: list[bytes] = []
    for chunk in _split(stream, cuts):
        out += parser.feed(chunk)
    out += parser.close()
    assert out == frames


@given(
    st.lists(st.one_of(_JPEG.map(lambda f: part(f)), st.binary(max_size=200)), max_size=10),
    st.lists(st.integers(0, 10**6), max_size=12),
)
def test_garbage_truncation_and_lies_never_yield_a_non_jpeg(parts: list[bytes], cuts: list[int]) -> None:
    stream = b"".join(parts)
    parser = MjpegParser(b"myboundary", max_frame_bytes=4096)
    out: list[bytes] = []
    for chunk in _split(stream, cuts):
        out += parser.feed(chunk)
    out += parser.close()
    for frame in out:
        assert frame.startswith(b"\xff\xd8")
        assert frame.endswith(b"\xff\xd9")
        assert len(frame) <= 4096
    assert parser.stats.bytes == len(stream)


@given(st.binary(min_size=1, max_size=40), st.integers(0, 2**64), st.binary(max_size=200))
def test_content_length_of_any_size_is_bounded_by_the_frame_cap(boundary: bytes, length: int, body: bytes) -> None:
    assume(not boundary.startswith(b"--") and b"\r" not in boundary and b"\n" not in boundary)
    head = b"--" + boundary + b"\r\nContent-Type: image/jpeg\r\nContent-Length: " + str(length).encode() + b"\r\n\r\n"
    parser = MjpegParser(boundary, max_frame_bytes=1024)
    out = parser.feed(head + body) + parser.close()
    assert all(len(f) <= 1024 for f in out)
    assert parser.buffered_bytes <= len(head) + len(body)
