"""The state poll's quick path reads the camera's reply straight off the socket (``vapix/keepalive.py``,
``_read_reply``): generated replies — status lines, headers of every framing and coding, lying or repeated
``Content-Length``, bodies cut anywhere, garbage, delivered in any chunks — are answered with a reply, a
decline (``None``: the full ``httpx`` path asks again) or an ``httpx.TransportError``, never another exception;
a reply it returns has exactly the body its ``Content-Length`` announced (issue 25: the boundary as it lands).
"""

from __future__ import annotations

import socket
import threading
import time

import httpx
import pytest
from hypothesis import given
from hypothesis import strategies as st

from axis_ptz_ros2.vapix.keepalive import _read_reply

pytestmark = pytest.mark.fuzz

_valid_status = st.tuples(
    st.sampled_from([b"HTTP/1.1", b"HTTP/1.0"]),
    st.integers(100, 599).map(lambda n: str(n).encode()),
    st.sampled_from([b" OK", b"", b" Unauthorized"]),
).map(lambda t: t[0] + b" " + t[1] + t[2])
_odd_status = st.one_of(
    st.tuples(
        st.sampled_from([b"HTTP/2", b"http/1.1", b"HTTP/1.1 ", b"", b"ICY"]),
        st.one_of(st.integers(0, 9999).map(lambda n: str(n).encode()), st.binary(max_size=5)),
        st.sampled_from([b" OK", b"", b"\tX"]),
    ).map(lambda t: t[0] + b" " + t[1] + t[2]),
    st.binary(max_size=40),
)
_status_line = st.one_of(_valid_status, _valid_status, _valid_status, _odd_status)  # mostly past the status line
_numbers = st.one_of(
    st.integers(-5, 10**30).map(lambda n: str(n).encode()),
    st.sampled_from([b"", b" 12 ", b"1e3", b"0x10", b"+3", b"-1", b"1_0", b"\xd9\xa3", b"12, 12", b"nan"]),
)
_header = st.one_of(
    st.tuples(st.sampled_from([b"Content-Length", b"content-length", b"CONTENT-LENGTH "]), _numbers),
    st.tuples(
        st.sampled_from(
            [b"Transfer-Encoding", b"Content-Encoding", b"Content-Type", b"Connection", b"WWW-Authenticate", b"X-Junk"]
        ),
        st.one_of(
            st.sampled_from(
                [
                    b"chunked",
                    b"gzip",
                    b"identity",
                    b"close",
                    b"keep-alive",
                    b"multipart/x-mixed-replace",
                    b"text/plain",
                    b"",
                ]
            ),  # fmt: skip
            st.binary(max_size=20).filter(lambda b: b"\r" not in b and b"\n" not in b),
        ),
    ),
).map(lambda kv: kv[0] + b": " + kv[1])
_line = st.one_of(_header, _header, _header, st.binary(max_size=30).filter(lambda b: b"\r\n" not in b))


@st.composite
def replies(draw: st.DrawFn) -> tuple[bytes, list[int]]:
    head = draw(_status_line) + b"".join(b"\r\n" + h for h in draw(st.lists(_line, max_size=8)))
    body = draw(st.binary(max_size=300))
    if draw(st.booleans()):  # an honest length most of the time, so the reading past the head is exercised
        head += b"\r\nContent-Length: " + str(len(body) + draw(st.sampled_from([0, 0, 0, -1, 1, 50]))).encode()
    data = head + draw(st.sampled_from([b"\r\n\r\n", b"\r\n\r\n", b"\n\n", b"\r\n"])) + body
    data = data[: draw(st.integers(0, len(data)))] if draw(st.booleans()) else data  # cut anywhere, or not
    cuts = sorted(draw(st.lists(st.integers(0, len(data)), max_size=6)))
    return data, cuts


def read(data: bytes, cuts: list[int]) -> httpx.TransportError | object:
    a, b = socket.socketpair()
    a.settimeout(1.0)

    def send() -> None:
        last = 0
        for c in [*cuts, len(data)]:
            if c > last:
                b.sendall(data[last:c])
                last = c
        b.shutdown(socket.SHUT_WR)  # the camera hangs up after its reply

    t = threading.Thread(target=send)
    t.start()
    try:
        return _read_reply(a, max_bytes=1 << 16, deadline=time.monotonic() + 5.0)
    except httpx.TransportError as err:  # a typed refusal (RemoteProtocolError, ReadError, ReadTimeout)
        return err
    finally:
        t.join()
        a.close()
        b.close()


@given(replies())
def test_any_reply_is_read_declined_or_refused(reply: tuple[bytes, list[int]]) -> None:
    data, cuts = reply
    out = read(data, cuts)
    if out is None or isinstance(out, httpx.TransportError):
        return
    status, body = out.status, out.body  # type: ignore[attr-defined]
    assert 200 <= status <= 599
    assert status not in (204, 304)
    if 200 <= status < 300:  # a returned 2xx body is exactly the announced length, taken from after the head
        end = data.find(b"\r\n\r\n")
        assert end >= 0
        assert data[end + 4 : end + 4 + len(body)] == body
        lengths = {
            line.partition(b":")[2].strip()
            for line in data[:end].split(b"\r\n")[1:]
            if line.partition(b":")[0].strip().lower() == b"content-length"
        }
        assert lengths == {str(len(body)).encode()}


def test_the_generator_reaches_every_outcome() -> None:
    """The strategy is not blind: hand-made members of each class come out as expected."""
    ok = read(b"HTTP/1.1 200 OK\r\nContent-Length: 3\r\n\r\nabc", [5, 20])
    assert getattr(ok, "body", None) == b"abc"
    assert read(b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n3\r\nabc\r\n0\r\n\r\n", []) is None
    assert isinstance(read(b"HTTP/1.1 200 OK\r\nContent-Length: 9\r\n\r\nabc", []), httpx.ReadError)
    assert isinstance(read(b"garbage\r\n\r\n", []), httpx.RemoteProtocolError)
