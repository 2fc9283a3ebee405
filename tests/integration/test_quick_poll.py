"""The state poll's quick path (``KeepAliveTransport.quick_get`` under ``VapixClient``'s queries) keeps every rule of
the full path: one request per poll on one kept-alive connection, Digest/Basic signed ahead and re-challenged on a
stale nonce, the same typed errors (statuses, ``Error:`` bodies, timeouts) without credentials, recovery after a
reboot, and any reply it does not read (chunked, coded, a stream) answered by the full path from then on. Against
the simulated camera; the reply framings the simulator never sends come from a scripted HTTP server."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator

import httpx
import pytest

from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.vapix import (
    AuthError,
    AxisPtzError,
    CameraConfig,
    CameraTimeout,
    CameraUnreachable,
    CommandRejected,
    HttpStatusError,
    VapixClient,
)
from axis_ptz_ros2.vapix.keepalive import KeepAliveTransport, _read_reply
from tests.support.waiting import wait_until

pytestmark = pytest.mark.integration
POSITION_BODY = b"pan=12.5\r\ntilt=-3.25\r\nzoom=7\r\n"


def _quick(port: int, *, https: bool = False, **kw: object) -> VapixClient:
    config = CameraConfig(port=port, use_https=https, verify_tls=not https, **kw)  # type: ignore[arg-type]
    return VapixClient(config, transport=KeepAliveTransport(config.ssl_verify() if https else True))


def _full(port: int, **kw: object) -> VapixClient:
    """The same camera through httpx's own transport (no quick path): the reference for errors."""
    return VapixClient(CameraConfig(port=port, **kw))  # type: ignore[arg-type]


def _socket(client: VapixClient) -> socket.socket:
    (connection,) = client._pool._idle  # noqa: SLF001 - which connection was used is the point
    return connection.conn.sock


def _counts(cam: SimulatedCamera, replies: int):
    """The simulator's counters once it has counted ``replies`` replies (it counts a reply after sending it)."""
    wait_until(lambda: sum(cam.request_counts.status.values()) >= replies, 2.0, scaled=False, raises=False)
    return cam.request_counts


def _reset_counts(cam: SimulatedCamera) -> None:
    """Reset the simulator's counters once the replies so far are counted (no count for 0.2 s)."""
    seen = {"n": -1, "since": time.monotonic()}

    def quiet() -> bool:
        n, now = sum(cam.request_counts.status.values()), time.monotonic()
        if n != seen["n"]:
            seen["n"], seen["since"] = n, now
        return now - seen["since"] >= 0.2

    wait_until(quiet, 30.0, 0.02, what="the simulator's counters to stay put for 0.2 s")
    cam.reset_counts()


def _error(call) -> AxisPtzError:
    with pytest.raises(AxisPtzError) as err:
        call()
    return err.value


@pytest.fixture
def sim() -> Iterator[SimulatedCamera]:
    cam = SimulatedCamera().start()
    try:
        yield cam
    finally:
        cam.stop()


# -- against the simulated camera --------------------------------------------------------------------------------
def test_one_request_per_poll_on_one_connection(sim):
    with _quick(sim.port) as c:
        first = c.query_position()
        sock = _socket(c)
        _reset_counts(sim)
        sim.teleport(33.0, -12.0, 500)
        for _ in range(30):
            p = c.query_position()
        assert (p.pan_deg, p.tilt_deg, p.zoom) == (33.0, -12.0, 500) != (first.pan_deg, first.tilt_deg, first.zoom)
        counts = _counts(sim, 30)
        assert sum(counts.status.values()) == 30
        assert counts.status[200] == 30
        assert c.quick_replies == 31
        assert c.quick_declined == ""
        assert _socket(c) is sock
        assert c.query_limits().max_zoom == 9999  # the limits refresh of the poll loop takes it too
        assert c.quick_replies == 32


@pytest.mark.parametrize("mode", ["digest", "basic_digest"])
def test_digest_signed_ahead_and_rechallenged(mode):
    cam = SimulatedCamera(auth=mode, user="operator", password="s3cret-pw").start()
    try:
        with _quick(cam.port, username="operator", password="s3cret-pw") as c:
            c.query_position()  # negotiates (the full path answers the first 401)
            sock = _socket(c)
            _reset_counts(cam)
            for _ in range(10):
                c.query_position()
            counts = _counts(cam, 10)
            assert counts.status[200] == 10
            assert counts.status[401] == 0
            assert counts.auth["digest"] == 10
            quick = c.quick_replies
            cam.forget_nonces()  # a restarted web server: the next signed request gets a 401
            c.query_position()
            assert c.auth_counters.rechallenges == 1
            assert c.auth_counters.refusals == 0
            assert _socket(c) is sock  # the 401's body was read: the connection kept
            c.query_position()
            assert c.quick_replies == quick + 1  # quick again with the new nonce
            cam.set_auth_options(nonce_lifetime_s=0.2)  # nonces expire (stale=true) while polling
            wait_until(lambda: (c.query_position(), c.auth_counters.stale >= 2)[1], 1.5, 0.05)
            assert c.auth_counters.stale >= 2
            assert c.auth_counters.refusals == 0
        with _quick(cam.port, username="operator", password="wrong-pw") as c:
            err = _error(c.query_position)
            assert isinstance(err, AuthError)
            assert "wrong-pw" not in str(err)
            assert c.auth_counters.refusals == 1
    finally:
        cam.stop()


def test_basic_and_digest_over_https():
    cam = SimulatedCamera(model="q6075").start()
    try:
        assert cam.base_url.startswith("https://")
        with _quick(cam.port, https=True, username="root", password="pass") as c:
            c.query_position()
            _reset_counts(cam)
            for _ in range(5):
                assert c.query_position().zoom >= 1
            assert _counts(cam, 5).status[200] == 5
            assert c.quick_declined == ""
    finally:
        cam.stop()
    cam = SimulatedCamera(auth="basic", user="root", password="pa:ss w").start()
    try:
        with _quick(cam.port, username="root", password="pa:ss w", auth="basic") as c:
            c.query_position()
            _reset_counts(cam)
            for _ in range(5):
                c.query_position()
            counts = _counts(cam, 5)
            assert counts.status[200] == 5
            assert counts.auth["basic"] == 5
            assert c.quick_replies == 5  # the first poll went unsigned (no scheme yet): the full path negotiated
    finally:
        cam.stop()


@pytest.mark.parametrize("status", [500, 503, 401])
def test_error_statuses_raise_what_the_full_path_raises(sim, status):
    with _quick(sim.port, timeout_s=2.0) as c, _full(sim.port, timeout_s=2.0) as ref:
        c.query_position()
        sim.set_faults(http_error=status)
        got, want = _error(c.query_position), _error(ref.query_position)
        assert type(got) is type(want)
        assert str(got) == str(want)
        assert isinstance(got, AuthError if status == 401 else HttpStatusError)
        sim.set_faults(http_error=0)
        quick = c.quick_replies
        c.query_position()
        assert c.quick_replies == quick + 1
        assert c.quick_declined == ""


def test_error_body_raises_command_rejected(sim):
    with _quick(sim.port, camera=2) as c, _full(sim.port, camera=2) as ref:
        got, want = _error(c.query_position), _error(ref.query_position)
        assert isinstance(got, CommandRejected)
        assert str(got) == str(want)
        assert got.camera_message == want.camera_message
        assert c.quick_replies == 0
        assert c.quick_declined == ""


@pytest.mark.parametrize("auth", ["digest", "basic"])
def test_a_stalled_camera_times_out_and_recovers(auth):
    sim = SimulatedCamera(auth=auth, user="operator", password="s3cret-pw").start()
    try:
        with _quick(sim.port, timeout_s=0.4, connect_timeout_s=0.4, username="operator", password="s3cret-pw",
                    auth=auth) as c:  # fmt: skip
            c.query_position()
            c.query_position()
            assert c.quick_replies == 1  # signed ahead
            sim.set_faults(latency_ms=1500)
            t0 = time.monotonic()
            err = _error(c.query_position)
            assert isinstance(err, CameraTimeout)
            assert time.monotonic() - t0 < 1.0
            assert "query=position" in str(err)
            assert "s3cret" not in str(err)
            assert "operator" not in str(err)
            sim.set_faults(latency_ms=0)
            deadline = time.monotonic() + 5.0
            while True:
                try:
                    c.query_position()
                    break
                except CameraTimeout:
                    assert time.monotonic() < deadline, "no recovery after the stall"
            assert c.quick_declined == ""
            assert c.quick_replies >= 2
    finally:
        sim.stop()


def test_reboot_with_errors_then_recovery_on_the_quick_path(sim):
    with _quick(sim.port, timeout_s=1.0) as c:
        c.query_position()
        sim.reboot(0.4, errors_s=0.4, error_kind="503")
        seen: set[type] = set()

        def answered_after_errors() -> bool:
            try:
                c.query_position()
            except AxisPtzError as err:
                seen.add(type(err))
                return False
            return bool(seen)

        recovered = wait_until(answered_after_errors, 8.0, 0.05, scaled=False, raises=False)
        assert seen, "no error during the reboot"
        assert recovered, f"no recovery after {seen}"
        quick = c.quick_replies
        c.query_position()
        assert c.quick_replies == quick + 1


# -- reply framings the simulator never sends (a scripted HTTP server) -------------------------------------------
class Scripted:
    """An HTTP/1.1 server on loopback answering request ``n`` (from 1) with ``reply(n)``: bytes, or a list of bytes,
    pauses (float seconds) and None (close the connection)."""

    def __init__(self, reply) -> None:
        self.reply = reply
        self.requests: list[bytes] = []
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.port = self._listener.getsockname()[1]
        self._stop = False
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while not self._stop:
            try:
                conn, _ = self._listener.accept()
            except OSError:
                return
            threading.Thread(target=self._serve, args=(conn,), daemon=True).start()

    def _serve(self, conn: socket.socket) -> None:
        data = b""
        with conn:
            while True:
                while b"\r\n\r\n" not in data:
                    chunk = conn.recv(4096)
                    if not chunk:
                        return
                    data += chunk
                head, data = data.split(b"\r\n\r\n", 1)
                self.requests.append(head)
                reply = self.reply(len(self.requests))
                for part in reply if isinstance(reply, list) else [reply]:
                    if part is None:  # close the connection
                        return
                    if isinstance(part, float):
                        time.sleep(part)  # the scripted server: a reply that comes this late
                        continue
                    try:
                        conn.sendall(part)
                    except OSError:  # the client gave up (a timeout)
                        return

    def close(self) -> None:
        self._stop = True
        self._listener.close()


def _plain(body: bytes = POSITION_BODY, extra: bytes = b"") -> bytes:
    return b"HTTP/1.1 200 OK\r\nContent-Type: text/plain\r\nContent-Length: %d\r\n%s\r\n%s" % (len(body), extra, body)


def _chunked(body: bytes = POSITION_BODY) -> bytes:
    return b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n%x\r\n%s\r\n0\r\n\r\n" % (len(body), body)


def _gzip(body: bytes = POSITION_BODY) -> bytes:
    import gzip  # noqa: PLC0415

    z = gzip.compress(body)
    return b"HTTP/1.1 200 OK\r\nContent-Encoding: gzip\r\nContent-Length: %d\r\n\r\n%s" % (len(z), z)


@pytest.fixture
def scripted() -> Iterator[list[Scripted]]:
    servers: list[Scripted] = []
    yield servers
    for s in servers:
        s.close()


def _serve(scripted: list[Scripted], reply) -> Scripted:
    server = Scripted(reply)
    scripted.append(server)
    return server


def test_the_request_sent(scripted):
    server = _serve(scripted, lambda n: _plain())
    with _quick(server.port) as c:
        c.query_position()
    (head,) = server.requests
    lines = head.split(b"\r\n")
    assert lines[0] == b"GET /axis-cgi/com/ptz.cgi?query=position HTTP/1.1"
    headers = {k.lower(): v.strip() for k, _, v in (ln.partition(b":") for ln in lines[1:])}
    assert headers[b"host"] == b"127.0.0.1:%d" % server.port
    assert headers[b"accept-encoding"] == b"identity"
    assert headers[b"user-agent"].startswith(b"axis_ptz_ros2/")
    assert b"authorization" not in headers


@pytest.mark.parametrize("framing", [_chunked, _gzip])
def test_a_reply_it_does_not_read_goes_the_full_path_from_then_on(scripted, framing):
    server = _serve(scripted, lambda n: framing())
    with _quick(server.port) as c:
        p = c.query_position()
        assert (p.pan_deg, p.tilt_deg, p.zoom) == (12.5, -3.25, 7)
        assert "query=position" in c.quick_declined
        assert c.quick_replies == 0
        assert len(server.requests) == 2  # asked once more on the full path
        c.query_position()
        assert len(server.requests) == 3  # the full path only
        assert server.requests[-1].lower().count(b"accept-encoding: identity") == 0


def test_connection_close_and_http_1_0_open_a_new_connection(scripted):
    closing = {1: _plain(extra=b"Connection: close\r\n"), 2: _plain().replace(b"HTTP/1.1", b"HTTP/1.0")}
    server = _serve(scripted, lambda n: [closing[n], None] if n in closing else _plain())
    with _quick(server.port) as c:
        for _ in range(4):
            c.query_position()
            if len(server.requests) <= 2:
                assert c._pool._idle == []  # noqa: SLF001 - not kept after a closing reply
        assert c.quick_replies == 4
        assert c.quick_declined == ""
        assert len(server.requests) == 4


def test_a_trickling_reply_times_out(scripted):
    head = b"HTTP/1.1 200 OK\r\nContent-Length: 400\r\n\r\n"
    server = _serve(scripted, lambda n: [head, *[b"x" * 10, 0.1] * 40])
    with _quick(server.port, timeout_s=0.5) as c:
        t0 = time.monotonic()
        err = _error(c.query_position)
        assert isinstance(err, CameraTimeout), err
        assert time.monotonic() - t0 < 1.5
        assert len(server.requests) == 1


def test_a_reply_cut_short_or_garbled_is_camera_unreachable(scripted):
    replies = {1: [b"HTTP/1.1 200 OK\r\nContent-Length: 50\r\n\r\npan=1", None], 2: [b"SPDY/9 200\r\n\r\n", None]}
    server = _serve(scripted, lambda n: replies[n])
    with _quick(server.port, timeout_s=1.0) as c:
        for _ in replies:
            err = _error(c.query_position)
            assert isinstance(err, CameraUnreachable), err
            assert "query=position" in str(err)


# -- the reply reader on a socket pair ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("wire", "expected"),
    [
        (_plain(), (200, POSITION_BODY, True)),
        (_plain(extra=b"Connection: close\r\n"), (200, POSITION_BODY, False)),
        (_plain().replace(b"HTTP/1.1", b"HTTP/1.0"), (200, POSITION_BODY, False)),
        (_plain(extra=b"Connection: Keep-Alive\r\n").replace(b"HTTP/1.1", b"HTTP/1.0"), (200, POSITION_BODY, True)),
        (_plain() + b"junk", (200, POSITION_BODY, False)),
        (_plain(b""), (200, b"", True)),
        (b"HTTP/1.1 401 Unauthorized\r\nContent-Length: 5\r\n\r\nnope!", (401, b"nope!", True)),
        (b"HTTP/1.1 503 Busy\r\nContent-Length: 999999\r\n\r\n", (503, b"", False)),
        (_chunked(), None),
        (_gzip(), None),
        (
            b"HTTP/1.1 200 OK\r\nContent-Type: multipart/x-mixed-replace; boundary=x\r\nContent-Length: 3\r\n\r\nabc",
            None,
        ),
        (b"HTTP/1.1 200 OK\r\nContent-Length: 3\r\nContent-Length: 4\r\n\r\nabcd", None),
        (b"HTTP/1.1 200 OK\r\n\r\n", None),
        (b"HTTP/1.1 204 No Content\r\n\r\n", None),
        (b"HTTP/1.1 100 Continue\r\n\r\n", None),
    ],
)
def test_read_reply(wire, expected):
    a, b = socket.socketpair()
    with a, b:
        a.settimeout(1.0)
        for i in range(0, len(wire), 7):  # arrives in small pieces
            b.sendall(wire[i : i + 7])
        reply = _read_reply(a, 1 << 20, time.monotonic() + 5.0)
    assert (None if reply is None else (reply.status, reply.body, reply.reusable)) == expected


@pytest.mark.parametrize(
    ("wire", "error"),
    [
        (b"", httpx.RemoteProtocolError),  # closed before any reply
        (b"HTTP/1.1 200 OK\r\nContent-Le", httpx.RemoteProtocolError),
        (b"HTTP/1.1 2x0 OK\r\n\r\n", httpx.RemoteProtocolError),
        (b"ICY 200 OK\r\n\r\n", httpx.RemoteProtocolError),
        (b"HTTP/1.1 200 OK\r\nno colon here\r\n\r\n", httpx.RemoteProtocolError),
        (b"HTTP/1.1 200 OK\r\nX: " + b"y" * (70 << 10), httpx.RemoteProtocolError),
        (b"HTTP/1.1 200 OK\r\nContent-Length: 10\r\n\r\nabc", httpx.ReadError),
    ],
)
def test_read_reply_refusals(wire, error):
    a, b = socket.socketpair()
    with a:
        a.settimeout(1.0)
        with b:
            b.sendall(wire)
        with pytest.raises(error):
            _read_reply(a, 1 << 20, time.monotonic() + 5.0)


def test_read_reply_times_out():
    a, b = socket.socketpair()
    with a, b:
        a.settimeout(0.2)
        b.sendall(b"HTTP/1.1 200 OK\r\n")
        with pytest.raises(httpx.ReadTimeout):
            _read_reply(a, 1 << 20, time.monotonic() + 5.0)
        with pytest.raises(httpx.ReadTimeout):
            _read_reply(a, 1 << 20, time.monotonic() - 1.0)  # past its deadline


def test_a_2xx_body_over_the_cap_is_left_to_the_full_path():
    a, b = socket.socketpair()
    with a, b:
        a.settimeout(1.0)
        b.sendall(_plain(b"x" * 100))
        assert _read_reply(a, 99, time.monotonic() + 5.0) is None
