"""The web console's H.264 relay (ROS-free): access units of ``image_raw/ffmpeg`` to browsers that decode them
with WebCodecs.

Transport: ``GET /video/<stream>.h264`` answers ``application/x-axis-h264-au`` and then streams, until either
side goes, one record per access unit (no HTTP chunk framing is needed: the response ends with the connection)::

    u32 record length (big endian, bytes after this field)
    u8  flags        bit 0: key (an IDR with its SPS/PPS: a decoder can start here)
                     bit 1: catch-up (a frame older than the newest one: decode it, do not draw it)
    u8  codec length n
    f64 capture stamp (s since the epoch, big endian; the message header's stamp = the camera's capture time)
    n   codec string (ASCII, WebCodecs ``avc1.PPCCLL`` from the stream's SPS)
    ... the access unit, Annex B, exactly as published (the browser configures without ``description``)

Every client starts on a key frame. A client that joins mid-GOP gets the current GOP (its IDR and every frame
since, flagged catch-up but the newest) so it shows the present picture at once instead of waiting up to a
keyframe interval; the first watcher causes the console's subscription, and the stream node sends an IDR for a
new H.264 subscriber. A later client when no GOP is kept (the stream node makes IDRs only on demand, so a GOP can
last for minutes: one longer than :data:`MAX_GOP_FRAMES` is not kept) waits for the next key frame and
:attr:`H264Slot.on_need_idr` asks for one. Each client has a bounded queue: a client that falls behind loses its
queue, waits for the next key frame (nothing is ever drawn from a broken reference chain) and
:attr:`H264Slot.on_need_idr` asks for one. Frames flagged key without an IDR, frames without a decodable start (no
SPS known) and empty frames are refused and counted, never relayed.
"""

from __future__ import annotations

import struct
import threading
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from axis_ptz_ros2.media.annexb import find_sps, is_idr

CONTENT_TYPE = "application/x-axis-h264-au"
FLAG_KEY = 0x01
FLAG_CATCH_UP = 0x02
_HEAD = struct.Struct(">IBBd")  # length, flags, codec length, stamp
#: access units a client may lag behind before it is cut back to the next key frame
MAX_CLIENT_QUEUE = 90
#: the longest GOP kept for late joiners (frames; it must fit a client's queue); a longer one is not cached (they
#: ask for an IDR and wait for it)
MAX_GOP_FRAMES = 60


@dataclass(frozen=True)
class RelayRecord:
    """One access unit as relayed, the fields of its wire record: Annex B bytes, key flag, capture stamp (s, as
    the record's f64 carries it) and the codec string of the SPS in force when it arrived.

    Not :class:`axis_ptz_ros2.media.frame.EncodedFrame`: the codec string belongs to each record, not only to the
    stream, because a client's queue can hold the tail of one GOP and the start of the next after an SPS change,
    and the browser must not configure the new codec for an old frame; the stamp is the ROS header's seconds as
    sent; the frame's pts and size are not known here (it comes off the ``image_raw/ffmpeg`` topic).
    """

    data: bytes
    key: bool
    stamp_s: float
    codec: str


def encode_record(au: RelayRecord, catch_up: bool = False) -> bytes:
    """The wire record of ``au`` (see the module docstring)."""
    codec = au.codec.encode("ascii")
    if len(codec) > 255:
        raise ValueError("codec string longer than 255 bytes")
    flags = (FLAG_KEY if au.key else 0) | (FLAG_CATCH_UP if catch_up else 0)
    length = _HEAD.size - 4 + len(codec) + len(au.data)
    return _HEAD.pack(length, flags, len(codec), au.stamp_s) + codec + au.data


def decode_records(buf: bytes) -> tuple[list[tuple[RelayRecord, bool]], bytes]:
    """Parse complete records from ``buf``: ([(access unit, catch-up)], the incomplete rest). For tests and tools."""
    out: list[tuple[RelayRecord, bool]] = []
    while len(buf) >= _HEAD.size:
        length, flags, clen, stamp = _HEAD.unpack_from(buf)
        end = 4 + length
        if len(buf) < end:
            break
        codec = buf[_HEAD.size : _HEAD.size + clen].decode("ascii")
        out.append((RelayRecord(buf[_HEAD.size + clen : end], bool(flags & FLAG_KEY), stamp, codec),
                    bool(flags & FLAG_CATCH_UP)))  # fmt: skip
        buf = buf[end:]
    return out, buf


class Client:
    """One watching HTTP client: its queue of (access unit, catch-up) records."""

    def __init__(self) -> None:
        self.queue: deque[tuple[RelayRecord, bool]] = deque()
        self.synced = False  # False: waiting for a key frame
        self.dropped = 0  # access units this client lost by falling behind


class H264Slot:
    """The H.264 stream of one camera, shared by every browser watching it (thread-safe).

    ``on_watchers(name, count)`` is called (outside the lock) when the watcher count goes 0 → 1 or 1 → 0;
    ``on_need_idr()`` when a client lost sync and waits for a key frame.
    """

    def __init__(
        self,
        name: str,
        on_watchers: Callable[[str, int], None] | None = None,
        on_need_idr: Callable[[], None] | None = None,
    ) -> None:
        self.name = name
        self.on_watchers = on_watchers
        self.on_need_idr = on_need_idr
        self._cond = threading.Condition()
        self._clients: set[Client] = set()
        self._gop: list[RelayRecord] = []
        self._codec = ""
        self._closed = False
        self.received = 0
        self.keys = 0
        self.refused = 0
        self.last_refusal = ""

    @property
    def codec(self) -> str:
        """The codec string of the newest SPS seen ('' before the first key frame)."""
        with self._cond:
            return self._codec

    @property
    def watchers(self) -> int:
        """Clients currently watching."""
        with self._cond:
            return len(self._clients)

    def counters(self) -> dict[str, object]:
        """Received, key, refused access units, dropped ones (slow clients), codec, last refusal reason."""
        with self._cond:
            return {
                "received": self.received,
                "keys": self.keys,
                "refused": self.refused,
                "dropped": sum(c.dropped for c in self._clients),
                "codec": self._codec,
                "last_refusal": self.last_refusal,
            }

    def publish(self, data: bytes, key_flag: bool, stamp_s: float) -> bool:
        """One access unit from the topic; False (counted, with a reason) when refused."""
        reason = ""
        key = False
        codec = ""
        if not data:
            reason = "empty access unit"
        elif key_flag:
            sps = find_sps(data) if is_idr(data) else None
            if sps is None:
                reason = "frame flagged key without an IDR and its SPS"
            else:
                key, codec = True, sps.codec_string
        need_idr = False
        with self._cond:
            self.received += 1
            if not reason and not key and not self._codec:
                reason = "no key frame yet"
            if reason:
                self.refused += 1
                self.last_refusal = reason
                return False
            if key:
                self.keys += 1
                self._codec = codec
            au = RelayRecord(data, key, stamp_s, self._codec)
            if key:
                self._gop = [au]
            elif self._gop:
                self._gop.append(au)
                if len(self._gop) > MAX_GOP_FRAMES:
                    self._gop = []
            for c in self._clients:
                if not c.synced:
                    if not key:
                        continue
                    c.synced = True
                if len(c.queue) >= MAX_CLIENT_QUEUE:
                    c.dropped += len(c.queue) + 1
                    c.queue.clear()
                    c.synced = False
                    need_idr = True
                    continue
                c.queue.append((au, False))
            self._cond.notify_all()
        if need_idr and self.on_need_idr:
            self.on_need_idr()
        return True

    @contextmanager
    def watch(self) -> Iterator[Client]:
        """Count one watching client for the ``with`` block; it starts with the current GOP (if any)."""
        c = Client()
        with self._cond:
            if self._gop:
                c.synced = True
                last = len(self._gop) - 1
                c.queue.extend((au, i < last) for i, au in enumerate(self._gop))
            self._clients.add(c)
            n = len(self._clients)
        if n == 1 and self.on_watchers:
            self.on_watchers(self.name, n)  # a new subscription: the stream node sends an IDR for it
        if n > 1 and not c.synced and self.on_need_idr:
            self.on_need_idr()  # subscribed already, and no GOP to start from
        try:
            yield c
        finally:
            with self._cond:
                self._clients.discard(c)
                n = len(self._clients)
                if n == 0:
                    self._gop = []  # unsubscribed from now on: a later GOP would have a hole
            if n == 0 and self.on_watchers:
                self.on_watchers(self.name, n)

    def next(self, client: Client, timeout: float) -> tuple[RelayRecord, bool] | None:
        """The client's next record (waits up to ``timeout``; None on timeout or close)."""
        with self._cond:
            if not client.queue and not self._closed:
                self._cond.wait(timeout)
            if client.queue:
                return client.queue.popleft()
            return None

    def close(self) -> None:
        """Wake every waiter for good (server shutdown)."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()
