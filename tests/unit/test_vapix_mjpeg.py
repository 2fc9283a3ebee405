"""MJPEG multipart parser (vapix.md §5.1, §12): splits, garbage, truncation, wrong lengths, boundaries."""

import pytest

from axis_ptz_ros2.vapix.errors import ResponseParseError
from axis_ptz_ros2.vapix.mjpeg import MjpegParser, boundary_from_content_type, multipart_content_type, part_header
from tests.unit.fixtures_vapix import jpeg, part

pytestmark = pytest.mark.unit

F1, F2, F3 = jpeg(b"one" * 20), jpeg(b"\x00two\r\n--my" * 7), jpeg(b"three" * 9)


def feed_all(data: bytes, chunk: int = 1 << 16, boundary: bytes = b"myboundary") -> tuple[list[bytes], MjpegParser]:
    parser = MjpegParser(boundary)
    frames: list[bytes] = []
    for i in range(0, len(data), chunk):
        frames += parser.feed(data[i : i + chunk])
    frames += parser.close()
    return frames, parser


@pytest.mark.parametrize(
    ("content_type", "boundary"),
    [
        ("multipart/x-mixed-replace;boundary=myboundary", b"myboundary"),
        ("multipart/x-mixed-replace; boundary=myboundary", b"myboundary"),
        ('multipart/x-mixed-replace; boundary="myboundary"', b"myboundary"),
        ("multipart/x-mixed-replace; boundary=--myboundary", b"myboundary"),
        ('Multipart/X-Mixed-Replace; charset=x; BOUNDARY="--b0und"', b"b0und"),
    ],
)
def test_boundary_variants(content_type, boundary):
    assert boundary_from_content_type(content_type) == boundary


@pytest.mark.parametrize("content_type", ["multipart/x-mixed-replace", "image/jpeg", 'multipart/x; boundary=""'])
def test_boundary_missing_is_parse_error(content_type):
    with pytest.raises(ResponseParseError, match="boundary"):
        boundary_from_content_type(content_type)


def test_thesis_wire_layout_three_frames():
    frames, parser = feed_all(part(F1) + part(F2) + part(F3))
    assert frames == [F1, F2, F3]
    stats = parser.stats
    assert (
        stats.frames,
        stats.garbage_bytes,
        stats.resyncs,
        stats.dropped_corrupt,
        stats.dropped_truncated,
    ) == (
        3,
        0,
        0,
        0,
        0,
    )
    assert stats.bytes == len(part(F1) + part(F2) + part(F3))


@pytest.mark.parametrize("boundary", ["myboundary", "axisframe"])
def test_part_writer_is_the_axis_wire_layout_and_parses_back(boundary):
    written = b"".join(part_header(boundary, len(f)) + f + b"\r\n" for f in (F1, F2))
    assert written == part(F1, boundary=boundary.encode()) + part(F2, boundary=boundary.encode())
    parser = MjpegParser(boundary_from_content_type(multipart_content_type(boundary)))
    assert parser.feed(written) == [F1, F2]


def test_frame_emitted_as_soon_as_content_length_bytes_arrive():
    parser = MjpegParser(b"myboundary")
    assert parser.feed(part(F1)[:-2]) == [F1]  # no need to wait for the next boundary
    assert parser.feed(b"\r\n") == []


STREAMS = {
    "clean": part(F1) + part(F2) + part(F3),
    "no_content_length": part(F1, length=None) + part(F2, length=None) + part(F3, length=None),
    "garbage_between": b"junk\r\n" + part(F1) + b"\x00garbage bytes!\r\n" + part(F2) + b"xx" + part(F3),
    "length_too_short": part(F1) + part(F2, length=len(F2) - 9) + part(F3),
    "length_too_long": part(F1) + part(F2, length=len(F2) + 40) + part(F3),
    "boundary_with_leading_dashes": part(F1, boundary=b"myboundary") + part(F2) + part(F3),
}


@pytest.mark.parametrize("name", sorted(STREAMS))
def test_split_at_every_byte_offset_gives_same_frames_and_stats(name):
    data = STREAMS[name]
    reference, ref_parser = feed_all(data)
    assert reference == [F1, F2, F3]
    for cut in range(1, len(data)):
        parser = MjpegParser(b"myboundary")
        frames = parser.feed(data[:cut]) + parser.feed(data[cut:]) + parser.close()
        assert frames == reference, f"split at {cut}"
        assert parser.stats == ref_parser.stats, f"split at {cut}"


@pytest.mark.parametrize("name", sorted(STREAMS))
def test_byte_by_byte(name):
    frames, _ = feed_all(STREAMS[name], chunk=1)
    assert frames == [F1, F2, F3]


def test_garbage_counted_and_resynced():
    garbage = b"\x00garbage bytes!\r\n"
    frames, parser = feed_all(part(F1) + garbage + part(F2))
    assert frames == [F1, F2]
    assert parser.stats.garbage_bytes == len(garbage)
    assert parser.stats.resyncs == 1


@pytest.mark.parametrize("chunk", [1, 7, 1 << 16])
def test_wrong_content_length_detected_and_frame_salvaged(chunk):
    frames, parser = feed_all(part(F1, length=len(F1) - 5) + part(F2, length=len(F2) + 100) + part(F3), chunk)
    assert frames == [F1, F2, F3]
    assert parser.stats.resyncs == 2


def test_implausible_length_does_not_hold_the_frames_behind_it():
    # A plausible length is checked once its bytes are in; one of megabytes is searched for the boundary as the
    # bytes arrive, so the frames after a corrupt header come out as they arrive, not megabytes later.
    parser = MjpegParser(b"myboundary")
    assert parser.feed(part(F1)) == [F1]
    assert parser.feed(part(F2, length=5_000_000)) == []  # the part might really be that long
    assert parser.feed(part(F3)) == [F2, F3]
    assert parser.stats.resyncs == 1
    assert parser.buffered_bytes < len(part(F3))


def test_truncated_frame_dropped_never_emitted():
    truncated = F2[: len(F2) // 2]
    # Camera announced the full length but the part ends early (connection hiccup) and the next part starts.
    data = part(F1) + b"--myboundary\r\nContent-Type: image/jpeg\r\nContent-Length: %d\r\n\r\n" % len(F2)
    data += truncated + b"\r\n" + part(F3)
    frames, parser = feed_all(data, chunk=7)
    assert frames == [F1, F3]
    assert parser.stats.dropped_truncated == 1


def test_corrupt_frame_without_soi_dropped():
    frames, parser = feed_all(part(F1) + part(b"not a jpeg at all\xff\xd9") + part(F3))
    assert frames == [F1, F3]
    assert parser.stats.dropped_corrupt == 1


def test_truncated_at_end_of_stream_counted_on_close():
    parser = MjpegParser(b"myboundary")
    assert parser.feed(part(F1) + part(F2)[:-20]) == [F1]
    assert parser.close() == []
    assert parser.stats.dropped_truncated == 1
    assert parser.stats.frames == 1


def test_frame_never_repeated_and_never_stale():
    parser = MjpegParser(b"myboundary")
    assert parser.feed(part(F1)) == [F1]
    # A malformed header part must not cause F1 to be handed out again.
    assert parser.feed(b"--myboundary\r\nContent-Le") == []
    assert parser.feed(b"ngth: banana\r\n\r\n\xff\xd8oops") == []
    assert parser.feed(b"\r\n" + part(F2)) == [F2]
    assert parser.feed(b"") == []
    assert parser.stats.frames == 2


def test_longer_token_is_not_our_boundary():
    frames, _ = feed_all(b"--myboundary2\r\nContent-Length: 3\r\n\r\nabc\r\n" + part(F1))
    assert frames == [F1]


def test_part_without_headers_and_lf_only_lines():
    data = b"--myboundary\r\n\r\n" + F1 + b"\r\n" + b"--myboundary\nContent-Length: %d\n\n" % len(F2) + F2 + b"\n"
    data += part(F3)
    frames, _ = feed_all(data, chunk=3)
    assert frames == [F1, F2, F3]


def test_oversized_frame_dropped():
    big = jpeg(b"x" * 5000)
    parser = MjpegParser(b"myboundary", max_frame_bytes=1000)
    frames = parser.feed(part(F1) + part(big) + part(F3))
    assert frames == [F1, F3]
    assert parser.stats.dropped_corrupt == 1


def test_close_delimiter_and_boundary_with_dashes_in_constructor():
    parser = MjpegParser(b"--myboundary")
    assert parser.feed(part(F1) + b"--myboundary--\r\n") == [F1]


def test_buffer_does_not_grow_on_clean_stream():
    parser = MjpegParser(b"myboundary")
    data = (part(F1) + part(F2)) * 200
    for i in range(0, len(data), 1000):
        parser.feed(data[i : i + 1000])
    assert parser.buffered_bytes < len(part(F2)) + 1000
    assert parser.stats.frames == 400


def test_last_part_without_length_completed_by_end_of_stream():
    parser = MjpegParser(b"myboundary")
    assert parser.feed(part(F1, length=None) + part(F2, length=None)) == [F1]  # F2 ends at next boundary...
    assert parser.close() == [F2]  # ...or at end of stream
    assert parser.close() == []  # never twice
