"""The web console's H.264 relay (ROS-free): real libx264 access units through :class:`H264Slot` and over the
console's real HTTP server, decoded again with FFmpeg's decoder."""

from __future__ import annotations

import http.client
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

av = pytest.importorskip("av")

from axis_ptz_ros2.media.encoder import H264Encoder  # noqa: E402
from axis_ptz_ros2.media.frame import EncodedFrame  # noqa: E402
from axis_ptz_ros2.media.h264_settings import H264Settings  # noqa: E402
from axis_ptz_ros2.web.backend import CommandResult  # noqa: E402
from axis_ptz_ros2.web.h264relay import (  # noqa: E402
    CONTENT_TYPE,
    MAX_CLIENT_QUEUE,
    MAX_GOP_FRAMES,
    H264Slot,
    RelayRecord,
    decode_records,
    encode_record,
)
from axis_ptz_ros2.web.relay import FrameSlot  # noqa: E402
from axis_ptz_ros2.web.server import ConsoleServer  # noqa: E402
from tests.support.waiting import wait_until  # noqa: E402

pytestmark = pytest.mark.unit

W, H = 160, 96


def _frames(n: int, gop: int = 10, refresh: str = "idr") -> list[EncodedFrame]:
    enc = H264Encoder(
        H264Settings(
            fps=30, bitrate_kbps=300, keyframe_interval=gop, preset="ultrafast", refresh=refresh, profile="baseline"
        ),
        W,
        H,
    )
    out = []
    for i in range(n):
        img = np.zeros((H, W, 3), np.uint8)
        img[:, :, 1] = 40
        img[20:60, (i * 3) % (W - 40) : (i * 3) % (W - 40) + 40] = (0, 0, 230)
        out.append(enc.encode_bgr(img))
    return out


@pytest.fixture(scope="module")
def frames() -> list[EncodedFrame]:
    return _frames(25)


def _decode(aus: list[bytes]) -> int:
    ctx = av.CodecContext.create("h264", "r")
    n = 0
    for a in aus:
        n += len(ctx.decode(av.Packet(a)))
    return n


def test_record_round_trip(frames: list[EncodedFrame]) -> None:
    au = RelayRecord(frames[0].data, True, 1764170000.123456, "avc1.42C00B")
    rec = encode_record(au, catch_up=True) + encode_record(RelayRecord(frames[1].data, False, 2.5, "avc1.42C00B"))
    got, rest = decode_records(rec[:-3])
    assert len(got) == 1
    assert got[0] == (au, True)
    assert rest == rec[len(encode_record(au)) : -3]
    got, rest = decode_records(rec)
    assert [g[0].key for g in got] == [True, False]
    assert rest == b""
    assert got[1][0].stamp_s == 2.5
    assert not got[1][1]


def test_codec_string_from_the_sps_and_refusals(frames: list[EncodedFrame]) -> None:
    slot = H264Slot("ptz")
    assert not slot.publish(frames[1].data, False, 1.0)
    assert slot.last_refusal == "no key frame yet"
    assert not slot.publish(frames[1].data, True, 1.0)  # flagged key, but a P-frame: never a start point
    assert "without an IDR" in slot.last_refusal
    assert not slot.publish(b"", False, 1.0)
    assert slot.publish(frames[0].data, True, 1.0)
    assert slot.codec.startswith("avc1.42")  # Constrained Baseline from x264's SPS
    assert len(slot.codec) == len("avc1.PPCCLL")
    c = slot.counters()
    assert (c["received"], c["keys"], c["refused"]) == (4, 1, 3)


def test_late_joiner_gets_the_gop_and_decodes_it(frames: list[EncodedFrame]) -> None:
    events: list[tuple[str, int]] = []
    slot = H264Slot("ptz", on_watchers=lambda n, c: events.append((n, c)))
    for f in frames[:14]:  # IDR at 0 and 10
        slot.publish(f.data, f.keyframe, 0.0)
    with slot.watch() as client:
        assert events == [("ptz", 1)]
        got = []
        while (r := slot.next(client, 0.01)) is not None:
            got.append(r)
        assert [g[0].data for g in got] == [f.data for f in frames[10:14]]
        assert got[0][0].key
        assert [g[1] for g in got] == [True, True, True, False]
        slot.publish(frames[14].data, False, 0.0)
        live = slot.next(client, 1.0)
        assert live is not None
        assert live[0].data == frames[14].data
        assert not live[1]
        assert _decode([g[0].data for g in got] + [live[0].data]) == 5
    assert events == [("ptz", 1), ("ptz", 0)]
    with slot.watch() as client:  # after the last watcher left, nothing old is replayed
        assert slot.next(client, 0.01) is None


def test_a_new_client_without_a_gop_starts_at_the_next_key_frame(frames: list[EncodedFrame]) -> None:
    slot = H264Slot("ptz")
    with slot.watch() as client:
        slot.publish(frames[0].data, True, 0.0)  # sets the codec; the client is synced on it
        first = slot.next(client, 0.1)
        assert first is not None
        assert first[0].key
    with slot.watch() as client:  # GOP was dropped with the last watcher: P-frames are not for this client
        for f in frames[1:10]:
            slot.publish(f.data, f.keyframe, 0.0)
        assert slot.next(client, 0.01) is None
        slot.publish(frames[10].data, True, 0.0)
        r = slot.next(client, 0.1)
        assert r is not None
        assert r[0].key


def test_a_slow_client_is_cut_back_to_the_next_key_frame_and_an_idr_is_asked_for() -> None:
    frames = _frames(MAX_CLIENT_QUEUE + 30, gop=MAX_CLIENT_QUEUE + 20)
    asked = []
    slot = H264Slot("ptz", on_need_idr=lambda: asked.append(1))
    with slot.watch() as client:
        for f in frames[: MAX_CLIENT_QUEUE + 5]:
            slot.publish(f.data, f.keyframe, 0.0)
        assert asked, "an IDR is asked for when a client loses frames"
        assert slot.next(client, 0.01) is None  # nothing from a broken chain
        assert slot.counters()["dropped"] == MAX_CLIENT_QUEUE + 1  # the queue and the frame that overflowed it
        idr = MAX_CLIENT_QUEUE + 20
        for f in frames[MAX_CLIENT_QUEUE + 5 : idr + 3]:
            slot.publish(f.data, f.keyframe, 0.0)
        got = []
        while (r := slot.next(client, 0.01)) is not None:
            got.append(r[0].data)
        assert got == [f.data for f in frames[idr : idr + 3]]
        assert _decode(got) == 3


def test_a_later_client_without_a_gop_kept_asks_for_an_idr() -> None:
    """IDRs only on demand (intra refresh): past MAX_GOP_FRAMES no GOP is kept, so a page joining a stream that
    others watch (no new subscription, no IDR of its own) asks for one and starts there."""
    frames = _frames(MAX_GOP_FRAMES + 10, gop=30, refresh="intra")
    assert [i for i, f in enumerate(frames) if f.keyframe] == [0]
    asked = []
    slot = H264Slot("ptz", on_need_idr=lambda: asked.append(1))
    with slot.watch() as first:
        for f in frames[: MAX_GOP_FRAMES + 2]:
            slot.publish(f.data, f.keyframe, 0.0)
            assert slot.next(first, 0.1) is not None
        assert not asked
        with slot.watch() as late:
            assert asked == [1]
            slot.publish(frames[MAX_GOP_FRAMES + 2].data, False, 0.0)
            assert slot.next(late, 0.01) is None  # nothing from the middle of a chain
            key = _frames(1)[0]
            slot.publish(key.data, True, 0.0)
            r = slot.next(late, 0.1)
            assert r is not None
            assert r[0].key
    with slot.watch() as short:  # a GOP shorter than MAX_GOP_FRAMES is replayed, nothing asked
        asked.clear()
        slot.publish(frames[0].data, True, 0.0)
        with slot.watch() as second:
            assert not asked
            r = slot.next(second, 0.1)
            assert r is not None
            assert r[0].key
        assert slot.next(short, 0.1) is not None


class _Backend:
    """The ConsoleBackend protocol's minimum for the HTTP side (the real node is tested in tests/browser)."""

    def __init__(self) -> None:
        self.h264 = H264Slot("ptz")

    def slot(self, name: str) -> FrameSlot | None:
        return None

    def h264_slot(self, name: str) -> H264Slot | None:
        return self.h264 if name == "ptz" else None

    def state(self) -> dict[str, Any]:
        return {}

    def keymap(self) -> dict[str, Any]:
        return {}

    def command(self, name: str, body: dict[str, Any]) -> CommandResult:
        return CommandResult(True, "")


@pytest.fixture
def served() -> Iterator[tuple[ConsoleServer, _Backend]]:
    backend = _Backend()
    srv = ConsoleServer(backend, port=0)
    srv.start()
    try:
        yield srv, backend
    finally:
        srv.stop()


def test_http_stream_delivers_decodable_access_units(
    served: tuple[ConsoleServer, _Backend], frames: list[EncodedFrame]
) -> None:
    srv, backend = served
    conn = http.client.HTTPConnection("127.0.0.1", srv.port, timeout=5)
    conn.request("GET", "/video/ptz.h264")
    res = conn.getresponse()
    assert res.status == 200
    assert res.getheader("Content-Type") == CONTENT_TYPE
    wait_until(lambda: backend.h264.watchers > 0, 5.0, scaled=False, raises=False)

    def feed() -> None:
        for i, f in enumerate(frames):
            backend.h264.publish(f.data, f.keyframe, 100.0 + i / 30)
            time.sleep(0.005)  # a paced stream (200 frames/s), not one burst into the client's bounded queue

    t = threading.Thread(target=feed)
    t.start()
    buf = b""
    got: list[tuple[RelayRecord, bool]] = []
    while len(got) < len(frames):
        chunk = res.read1(65536)
        assert chunk, "stream ended early"
        buf += chunk
        recs, buf = decode_records(buf)
        got += recs
    t.join()
    assert [g[0].data for g in got] == [f.data for f in frames]
    assert got[0][0].key
    assert got[0][0].codec == backend.h264.codec
    assert [g[0].stamp_s for g in got] == [100.0 + i / 30 for i in range(len(frames))]
    assert _decode([g[0].data for g in got]) == len(frames)
    res.close()
    conn.close()
    wait_until(lambda: backend.h264.watchers == 0, 5.0, 0.05, scaled=False, raises=False)
    assert backend.h264.watchers == 0, "the client left: the relay stops watching (the node unsubscribes)"


def test_http_refuses_other_streams(served: tuple[ConsoleServer, _Backend]) -> None:
    srv, _ = served
    conn = http.client.HTTPConnection("127.0.0.1", srv.port, timeout=5)
    conn.request("GET", "/video/panorama.h264")
    res = conn.getresponse()
    assert res.status == 404
    assert b"no H.264 stream" in res.read()
    conn.close()


def test_decoder_report_is_bounded_and_summed_over_pages() -> None:
    from axis_ptz_ros2.web import api  # noqa: PLC0415
    from axis_ptz_ros2.web.api import BadRequest  # noqa: PLC0415
    from axis_ptz_ros2.web.view import ConsoleModel  # noqa: PLC0415

    for body, words in (
        ({"decoded": -1}, "'decoded'"),
        ({"errors": 2**60}, "'errors'"),
        ({"errors": 1.5}, "integer"),
        ({"codec": "x" * 33}, "at most 32"),
        ({"note": "n" * 201}, "at most 200"),
        ({"mode": "h264\x00"}, "printable"),
    ):
        with pytest.raises(BadRequest, match=words):
            api.decoder_request(body)
    model = ConsoleModel()
    for page in ({"mode": "h264", "decoded": 30, "errors": 1, "codec": "avc1.42C01E"}, {"decoded": 5, "errors": 2}):
        r = api.decoder_request(page)
        model.decoder(r.mode, r.decoded, r.errors, r.codec, r.note)
    d = model.state(True, {})["decoder"]
    assert (d["decoded"], d["errors"], d["reports"]) == (35, 3, 2)
    assert d["mode"] == ""
    assert d["age_s"] is not None
