"""Property-based tests of the web console's HTTP API (issue 25): every route, method, header, body shape and
number range, generated from the API's own table (:mod:`axis_ptz_ros2.web.api`) against a real
``axis_web_console`` node over loopback HTTP and DDS, with recording stand-ins for the PTZ and stream nodes.

The property, for every generated request: an answer at once; never a 5xx; a 4xx carries a reason; no
traceback and no failed request in the node's log; what reaches the PTZ and stream services is valid and is
exactly what was asked for (no wrapped numbers); a well-formed command is accepted and a malformed one refused;
and the node still works afterwards.

Examples per property test: the tier's hypothesis profile (``tests/fuzz/conftest.py``: ``ci`` by default, part of
``./scripts/test``; ``AXIS_FUZZ=long`` for the nightly count; ``AXIS_FUZZ_EXAMPLES=N`` sets it), e.g.
``AXIS_FUZZ=long AXIS_FUZZ_EXAMPLES=5000 python -m pytest -p no:cacheprovider tests/fuzz/test_console_api.py``
(about 4 minutes). Each test writes what it tried to ``artifacts/fuzz/console_api.json`` (for the README
table). The regression tests at the end pin the defects found by hand and by this tier.
"""

from __future__ import annotations

import http.client
import json
import math
import socket
import struct
import threading
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import quote

import pytest

pytest.importorskip("rclpy")

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import CompressedImage  # noqa: E402

from axis_ptz_ros2.nodes.web_console import WebConsole  # noqa: E402
from axis_ptz_ros2.teleop import keymap  # noqa: E402
from axis_ptz_ros2.web import api  # noqa: E402
from axis_ptz_ros2.web.h264relay import CONTENT_TYPE as H264_RELAY_TYPE  # noqa: E402
from axis_ptz_ros2.web.view import FROM_BROWSER  # noqa: E402
from tests.ros.test_web_console import FakePtz, jpeg  # noqa: E402
from tests.support.harness import RosHarness  # noqa: E402

pytestmark = pytest.mark.fuzz

# the profile of tests/fuzz/conftest.py sets the examples, the deadline and the database; one console serves the
# whole module (a module fixture, which hypothesis would flag), and raw bodies may be large
FUZZ = settings(
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture, HealthCheck.data_too_large],
)
TOKEN = "fuzz-token-0123456789abcdef"
REPORT = Path(__file__).resolve().parents[2] / "artifacts" / "fuzz" / "console_api.json"


# ---------------------------------------------------------------------------------------------------------
# one console for the module: a token (so auth headers are part of the input), fake PTZ and stream services,
# and frames on every image topic (snapshots answer at once)
# ---------------------------------------------------------------------------------------------------------
class Env:
    def __init__(self, ros: RosHarness, fake: FakePtz, console: WebConsole) -> None:
        self.ros, self.fake, self.console = ros, fake, console
        self.port = console.server.port
        self.tried: Counter[str] = Counter()

    def recorded(self) -> dict[str, int]:
        return {k: len(v) for k, v in self.fake.requests.items()}


@pytest.fixture(scope="module")
def env(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Env]:
    ros = RosHarness()
    stop = threading.Event()
    try:
        fake = FakePtz(ros)
        token_file = tmp_path_factory.mktemp("fuzz") / "token"
        token_file.write_text(TOKEN + "\n")
        overrides = [
            Parameter("port", value=0),
            Parameter("service_timeout", value=5.0),
            Parameter("token_file", value=str(token_file)),
            Parameter("auth_max_failures", value=1000),  # wrong tokens are part of the input: do not lock out
            Parameter("auth_window", value=1.0),
        ]
        console = ros.add(WebConsole(context=ros.context, parameter_overrides=overrides))
        probe = ros.probe("fuzz_frames")
        pubs = [probe.create_publisher(CompressedImage, t, 10) for t in
                ("image_raw/compressed", "panorama/image_raw/compressed", "axis_visualizer/compressed")]  # fmt: skip
        frame = jpeg(1, 64, 48)

        def publish() -> None:
            while not stop.wait(0.05):
                for p in pubs:
                    msg = CompressedImage(format="jpeg", data=frame)
                    msg.header.stamp = probe.get_clock().now().to_msg()
                    p.publish(msg)

        threading.Thread(target=publish, daemon=True).start()
        ros.wait_for(lambda: console.state()["video"] is not None, 10.0)
        e = Env(ros, fake, console)
        yield e
        _write_report(e)
    finally:
        stop.set()
        ros.close()


def _write_report(e: Env) -> None:
    """Merge this run's counts into artifacts/fuzz/console_api.json (one entry per test)."""
    REPORT.parent.mkdir(parents=True, exist_ok=True)
    old = json.loads(REPORT.read_text()) if REPORT.exists() else {}
    old.update({k: {"inputs": v, "max_examples": settings.default.max_examples} for k, v in e.tried.items()})
    REPORT.write_text(json.dumps(old, indent=2, sort_keys=True) + "\n")


# ---------------------------------------------------------------------------------------------------------
# strategies, from the API table
# ---------------------------------------------------------------------------------------------------------
#: classes of hostile values, each drawn as often as the others (so a rare class is still tried in CI)
HOSTILE: dict[str, st.SearchStrategy[Any]] = {
    "huge int": st.sampled_from([10**400, -(10**400), 10**309, 2**1024]),
    "int64 edge": st.sampled_from([2**63, 2**63 - 1, -(2**63), 2**64, 2**64 + 5, 2**31, -(2**31) - 1]),
    "uint32 wrap": st.sampled_from([2**32, 2**32 + 352, 2**32 + 288, 2**32 - 1, -1, -(2**32)]),
    "huge float": st.sampled_from([1e300, -1e300, 1e30, 2.0**63, 1.7976931348623157e308]),
    "not finite": st.sampled_from([math.inf, -math.inf, math.nan]),
    "tiny or fraction": st.sampled_from([-0.0, 0.5, 1e-300, 5e-324, 0.9999999999999999]),
    "any int": st.integers(),
    "any float": st.floats(),
    "wrong type": st.one_of(
        st.text(max_size=20),
        st.booleans(),
        st.none(),
        st.lists(st.integers(), max_size=3),
        st.dictionaries(st.text(max_size=5), st.integers(), max_size=2),
    ),  # fmt: skip
    "long text": st.text(min_size=30, max_size=200),
}
RESOLUTIONS = ["176x144", "352x288", "704x576", "1920x1080", "", "x", "0x0", "704x576\x00", "\u00e9"]
KEYS = ["\x1b", "ArrowLeft", "ArrowUp", "ArrowDown", "ArrowRight", "a", "d", "w", "s", "+", "-", "h", "Escape",
        "1", "9", "x", " ", "q", "Q", "F13", "\u00e9"]  # fmt: skip


def good_value(f: api.Field) -> st.SearchStrategy[Any]:
    """A value the table accepts (keep values included)."""
    if f.kind == "str":
        return st.sampled_from(KEYS if f.name == "key" else RESOLUTIONS)
    lo = f.lo if math.isfinite(f.lo) else 0.0
    hi = f.hi if math.isfinite(f.hi) else 1e6
    edges = [lo, hi] + ([f.keep] if f.keep is not None else [])
    inside = st.integers(int(lo), int(hi)) if f.kind == "int" else st.floats(lo, hi, allow_nan=False)
    return st.one_of(inside, st.sampled_from(edges))


def bad_value(f: api.Field) -> st.SearchStrategy[Any]:
    """A value just beyond the field's range, or of one hostile class."""
    beyond = []
    if f.kind != "str":
        beyond = [v for v in (f.lo - 1, f.hi + 1, f.lo - 0.5) if math.isfinite(v)]
    classes = [*HOSTILE.values(), st.sampled_from(beyond)] if beyond else list(HOSTILE.values())
    return st.sampled_from(classes).flatmap(lambda c: c)


@st.composite
def command_body(draw: st.DrawFn, command: str) -> dict[str, Any]:
    """A well-formed body (pixel inside the image) with none, one or two fields spoiled, dropped or added."""
    fields = api.COMMANDS[command]
    body: dict[str, Any] = {f.name: draw(good_value(f)) for f in fields if f.default is None or draw(st.booleans())}
    xk, yk = ("u", "v") if command == "center" else ("x", "y")
    w, h = body.get("width", 1), body.get("height", 1)
    if command in ("center", "look_panorama"):
        body[xk] = draw(st.one_of(st.floats(0, float(w)), st.sampled_from([0, w])))
        body[yk] = draw(st.one_of(st.floats(0, float(h)), st.sampled_from([0, h])))
    names = [f.name for f in fields] + (["extra", "__proto__"] if fields else [])
    for name in draw(st.lists(st.sampled_from(names), max_size=2, unique=True)) if names else []:
        how = draw(st.sampled_from(["bad", "bad", "bad", "drop", "null", "outside"]))
        f = next((g for g in fields if g.name == name), api.Field(name, "float"))
        if how == "drop":
            body.pop(name, None)
        elif how == "null":
            body[name] = None
        elif how == "outside" and name in (xk, yk) and command in ("center", "look_panorama"):
            size = w if name == xk else h  # the size drawn above, even if it was spoiled since
            body[name] = draw(st.sampled_from([-1, -1e-9, size + 1, size + 1e-6]))
        else:
            body[name] = draw(bad_value(f))
    return body


PATHS = sorted({r.path for r in api.ROUTES}) + [
    "/api/launch", "/api/", "/api", "/static/../README.md", "/static/%2e%2e/x.js", "/static/.hidden.js",
    "/video/none.mjpg", "/video/ptz.png", "/video/ptz.jpg?fresh", "//", "/index.html?x=1", "/login?next=//evil",
    "/api/state#frag", "/" + "a" * 3000, "/\u00e9", "*",
]  # fmt: skip
CONTENT_TYPES = ["application/json", "application/json", "application/json; charset=utf-8", "text/plain",
                 "application/x-www-form-urlencoded", "", "APPLICATION/JSON"]  # fmt: skip
ANY_JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=6), c, max_size=3),
    max_leaves=8,
)
METHODS = ["GET", "POST", "HEAD", "PUT", "DELETE", "OPTIONS", "PATCH", "TRACE", "CONNECT", "BREW"]


@st.composite
def http_request(draw: st.DrawFn) -> tuple[str, str, dict[str, str], bytes]:
    method = draw(st.sampled_from(METHODS) | st.text("ABCDEFGHIJKLMNOPQRSTUVWXYZ", min_size=1, max_size=12))
    path = draw(st.sampled_from(PATHS) | st.text(min_size=1, max_size=40).map(lambda t: "/" + quote(t, safe="/?&=%.*")))
    path = quote(path, safe="/?&=%.*#:")
    headers: dict[str, str] = {}
    auth = draw(st.sampled_from(["bearer", "bearer", "bearer", "header", "cookie", "wrong", "none", "garbage"]))
    if auth == "bearer":
        headers["Authorization"] = f"Bearer {TOKEN}"
    elif auth == "header":
        headers["X-Axis-Token"] = TOKEN
    elif auth == "cookie":
        headers["Cookie"] = f"axis_token={TOKEN}"
    elif auth == "wrong":
        headers["Authorization"] = "Bearer " + draw(st.text("abcdef0123456789", max_size=30))
    elif auth == "garbage":
        headers["Cookie"] = draw(st.text(st.characters(min_codepoint=32, max_codepoint=126), max_size=40))
    host = draw(st.sampled_from(["ok", "ok", "ok", "evil", "none", "ipv6"]))
    if host == "evil":
        headers["Host"] = "attacker.example"
    elif host == "ipv6":
        headers["Host"] = "[::1]"
    elif host == "none":
        headers["Host"] = ""
    ctype = draw(st.sampled_from(CONTENT_TYPES))
    if ctype:
        headers["Content-Type"] = ctype
    origin = draw(st.sampled_from(["none", "none", "same", "other", "null"]))
    if origin != "none":
        headers["Origin"] = {"same": "http://127.0.0.1:{port}", "other": "http://evil.example", "null": "null"}[origin]
    command = path[len("/api/") :] if path.startswith("/api/") else ""
    kind = draw(st.sampled_from(["schema", "schema", "schema", "json", "raw", "empty"]))
    if kind == "schema" and command in api.COMMANDS:
        body = _dumps(draw(command_body(command)))
    elif kind == "json":
        body = _dumps(draw(ANY_JSON))
    elif kind == "raw":
        body = draw(st.binary(max_size=200) | st.sampled_from([b"[" * 5000, b"{" + b"9" * 5000 + b"}", b"\xff\xfe{}"]))
    else:
        body = b""
    return method, path, headers, body


def _dumps(obj: Any) -> bytes:
    return json.dumps(obj).encode()  # NaN / Infinity as JavaScript would not, but Python's parser accepts


# ---------------------------------------------------------------------------------------------------------
# the property
# ---------------------------------------------------------------------------------------------------------
def send(env: Env, method: str, path: str, headers: dict[str, str], body: bytes) -> tuple[int, dict[str, str], bytes]:
    headers = {k: v.replace("{port}", str(env.port)) for k, v in headers.items()}
    conn = http.client.HTTPConnection("127.0.0.1", env.port, timeout=15)
    try:
        conn.putrequest(method, path, skip_host="Host" in headers, skip_accept_encoding=True)
        for k, v in headers.items():
            if v or k != "Host":
                conn.putheader(k, v)
        if body or method in ("POST", "PUT", "PATCH"):
            conn.putheader("Content-Length", str(len(body)))
        conn.endheaders(body or None)
        r = conn.getresponse()
        hdrs = {k.lower(): v for k, v in r.getheaders()}
        ctype = hdrs.get("content-type", "")
        if ctype.startswith("multipart/") or ctype == H264_RELAY_TYPE:
            return r.status, hdrs, b""  # a video stream (MJPEG or the H.264 relay): the answer started; hang up
        return r.status, hdrs, r.read()
    finally:
        conn.close()


def check_answer(status: int, headers: dict[str, str], data: bytes, what: object, head: bool = False) -> None:
    assert 200 <= status < 500, f"HTTP {status} for {what!r}: {data[:300]!r}"
    if status >= 400 and not head:
        ctype = headers.get("content-type", "")
        if ctype.startswith("application/json"):
            ans = json.loads(data) if data else {}
            assert ans.get("ok") is False, f"4xx not marked as a failure for {what!r}: {data[:200]!r}"
            assert ans.get("message"), f"4xx without a reason for {what!r}: {data[:200]!r}"
        else:  # the sign-in page (401/429 on the page routes)
            assert ctype.startswith("text/html"), f"{status} {ctype} for {what!r}"
            assert b"<form" in data, f"{status} without the sign-in form for {what!r}"


def check_sent(env: Env, before: dict[str, int]) -> None:
    """Everything the console sent to the stand-ins since ``before`` is valid."""
    reqs = env.fake.requests
    for r in reqs.get("center", [])[before.get("center", 0) :]:
        t = r.target
        assert 1 <= t.image_width <= api.UINT32_MAX
        assert 1 <= t.image_height <= api.UINT32_MAX
        assert all(math.isfinite(x) for x in (t.u, t.v, t.zoom_delta))
        assert 0 <= t.u <= t.image_width
        assert 0 <= t.v <= t.image_height
        assert abs(t.zoom_delta) <= api.MAX_ZOOM_DELTA
    for r in reqs.get("look_at", [])[before.get("look_at", 0) :]:
        p = r.target.point
        assert all(math.isfinite(x) for x in (p.x, p.y, p.z, r.zoom))
    for r in reqs.get("video", [])[before.get("video", 0) :]:
        assert r.fps == 0 or 1 <= r.fps <= 30
        assert r.compression == -1 or 0 <= r.compression <= 100
        assert len(r.resolution) <= api.MAX_TEXT
    budget = env.fake.node.get_parameter("max_bitrate_kbps").value
    assert 0 <= budget <= 1_000_000


def check_log_clean(env: Env, capfd: pytest.CaptureFixture[str]) -> None:
    err = capfd.readouterr().err
    assert "Traceback" not in err, err[-3000:]
    assert env.console.server.counters()["errors"] == 0


def check_still_works(env: Env) -> None:
    auth = {"Authorization": f"Bearer {TOKEN}", "Content-Type": "application/json"}
    n = len(env.fake.requests.get("center", []))
    body = _dumps({"u": 10, "v": 10, "width": 20, "height": 20})
    status, _, data = send(env, "POST", "/api/center", auth, body)
    assert status == 200, data
    assert len(env.fake.requests["center"]) == n + 1
    assert send(env, "GET", "/api/state", auth, b"")[0] == 200


@FUZZ
@given(req=http_request())
def test_every_route_method_header_and_body(env: Env, capfd: pytest.CaptureFixture[str], req: Any) -> None:
    method, path, headers, body = req
    before = env.recorded()
    status, hdrs, data = send(env, method, path, headers, body)
    env.tried["console HTTP: routes x methods x headers x bodies"] += 1
    check_answer(status, hdrs, data, req, head=method == "HEAD")
    check_sent(env, before)
    check_log_clean(env, capfd)


def expected_ok(command: str, body: dict[str, Any]) -> bool:
    """An oracle written independently of the console: is this body well-formed by the API table?"""

    def num(v: Any) -> float | None:
        if isinstance(v, bool) or not isinstance(v, int | float):
            return None
        if isinstance(v, int):
            return v if abs(v) < 10**300 else None
        return v if math.isfinite(v) else None

    values: dict[str, Any] = {}
    for f in api.COMMANDS[command]:
        v = body.get(f.name)
        if v is None or (f.kind == "str" and v == ""):
            if f.default is None:
                return False
            values[f.name] = f.default
            continue
        if f.kind == "str":
            if not isinstance(v, str) or len(v) > f.hi or not v.isprintable():
                return False
            values[f.name] = v
            continue
        n = num(v)
        if n is None or (f.kind == "int" and n != int(n)):
            return False
        if n != f.keep and not f.lo <= n <= f.hi:
            return False
        values[f.name] = n
    if command in ("center", "look_panorama"):
        xk, yk = ("u", "v") if command == "center" else ("x", "y")
        return 0 <= values[xk] <= values["width"] and 0 <= values[yk] <= values["height"]
    if command == "key":  # the key map is the specification of this command
        action = keymap.KEYMAP.get(FROM_BROWSER.get(values["key"], values["key"]))
        return action is not None and action.kind is not keymap.Kind.QUIT
    if command == "video":
        return bool(
            values["fps"] or values["resolution"] or values["compression"] >= 0 or values["max_bitrate_kbps"] >= 0
        )
    return True


@FUZZ
@given(
    command=st.sampled_from(["center", "look_panorama", "video", "key"]),
    data=st.data(),
)
def test_command_bodies_are_accepted_exactly_when_well_formed(
    env: Env, capfd: pytest.CaptureFixture[str], command: str, data: st.DataObject
) -> None:
    body = data.draw(command_body(command))
    before = env.recorded()
    headers = {"Authorization": f"Bearer {TOKEN}", "Content-Type": "application/json"}
    status, hdrs, ans = send(env, "POST", f"/api/{command}", headers, _dumps(body))
    env.tried[f"console HTTP: /api/{command} bodies (oracle)"] += 1
    check_answer(status, hdrs, ans, body)
    ok = expected_ok(command, body)
    if command == "key" and ok:
        assert status in (200, 409), (body, status, ans)  # 409: a notice such as "already at the top"
    elif (
        command == "video"
        and ok
        and body.get("resolution") not in (None, "", "176x144", "352x288", "704x288", "704x576")
    ):
        assert status == 409, (body, ans)  # the stand-in refuses resolutions its camera does not list
    else:
        assert (status == 200) == ok, (body, status, ans)
    check_sent(env, before)
    check_log_clean(env, capfd)
    if status == 200 and command == "center":
        t = env.fake.requests["center"][-1].target
        assert (t.image_width, t.image_height) == (int(body["width"]), int(body["height"]))  # nothing wrapped
        assert (t.u, t.v) == (float(body["u"]), float(body["v"]))
    if (
        status == 200
        and command == "video"
        and "max_bitrate_kbps" in body
        and body["max_bitrate_kbps"] not in (None, -1)
    ):
        assert env.fake.node.get_parameter("max_bitrate_kbps").value == int(body["max_bitrate_kbps"])


REQUEST_LINES = st.one_of(
    st.binary(max_size=120),
    st.builds(
        lambda m, p, v: m + b" " + p + b" " + v,
        st.sampled_from([b"GET", b"POST", b"HEAD", b"get", b"G\x00T", b""]),
        st.sampled_from([b"/", b"/api/state", b"*", b"http://127.0.0.1/", b"/\xff", b"/" + b"a" * 70000]),
        st.sampled_from([b"HTTP/1.1", b"HTTP/1.0", b"HTTP/2.0", b"HTTP/0.9", b"HTTP/1.1.1", b"HTTP/x", b""]),
    ),
)


@FUZZ
@given(line=REQUEST_LINES, headers=st.lists(st.binary(max_size=60), max_size=5), body=st.binary(max_size=60))
def test_raw_request_heads_get_an_answer_at_once(
    env: Env, capfd: pytest.CaptureFixture[str], line: bytes, headers: list[bytes], body: bytes
) -> None:
    data = (
        line + b"\r\n" + b"".join(h.replace(b"\r", b"").replace(b"\n", b"") + b"\r\n" for h in headers) + b"\r\n" + body
    )
    answer = raw(env.port, data, shutdown=True, timeout=10.0)
    env.tried["console HTTP: raw request lines and headers"] += 1
    if answer:  # a connection closed without a request line gets nothing, like any HTTP server
        assert answer.startswith(b"HTTP/1."), (data[:200], answer[:200])
        status = int(answer.split(b" ", 2)[1])
        assert 200 <= status < 500, (data[:200], answer[:300])
    check_log_clean(env, capfd)


def test_the_node_still_works_after_the_fuzzing(env: Env) -> None:
    """Runs after the fuzz tests of this module (pytest keeps file order)."""
    check_still_works(env)


# ---------------------------------------------------------------------------------------------------------
# regression tests: the defects of issue 25, each pinned
# ---------------------------------------------------------------------------------------------------------
def raw(port: int, data: bytes, shutdown: bool, timeout: float, source: str = "127.0.0.1") -> bytes:
    """Send bytes; everything answered until the server closes (or ``timeout``)."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout, source_address=(source, 0)) as s:
        try:
            s.sendall(data)
            if shutdown:
                s.shutdown(socket.SHUT_WR)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the server answered and closed before reading everything (a request line too long)
        chunks = []
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                c = s.recv(65536)
            except (TimeoutError, ConnectionResetError):
                break
            if not c:
                break
            chunks.append(c)
        return b"".join(chunks)


def _post(env: Env, command: str, body: Any) -> tuple[int, dict[str, Any]]:
    headers = {"Authorization": f"Bearer {TOKEN}", "Content-Type": "application/json"}
    status, _, data = send(env, "POST", f"/api/{command}", headers, body if isinstance(body, bytes) else _dumps(body))
    return status, json.loads(data)


@pytest.mark.parametrize(
    ("command", "body", "words"),
    [
        ("center", b'{"u": ' + b"9" * 400 + b', "v": 1, "width": 10, "height": 10}', "'u' is out of range"),
        ("center", {"u": 1, "v": 1, "width": 1e300, "height": 10}, "'width'"),
        ("center", {"u": 1, "v": 1, "width": 10, "height": 1e300}, "'height'"),
        ("center", {"u": 300, "v": 200, "width": 2**32 + 352, "height": 2**32 + 288}, "'width'"),
        ("look_panorama", {"x": 1, "y": 1, "width": 2**32 + 352, "height": 10}, "'width'"),
        ("video", {"max_bitrate_kbps": 1e30}, "'max_bitrate_kbps'"),
        ("video", {"max_bitrate_kbps": 2**63}, "'max_bitrate_kbps'"),
        ("video", {"fps": 2**64 + 5}, "'fps'"),
    ],
)
def test_regression_numbers_beyond_their_range_are_refused_not_500_or_wrapped(
    env: Env, command: str, body: Any, words: str
) -> None:
    before = env.recorded()
    budget = env.fake.node.get_parameter("max_bitrate_kbps").value
    status, ans = _post(env, command, body)
    assert status == 400, ans
    assert words in ans["message"], ans
    assert "out of range" in ans["message"] or "must be" in ans["message"], ans
    assert env.recorded() == before  # nothing sent to the camera
    assert env.fake.node.get_parameter("max_bitrate_kbps").value == budget


def test_regression_http09_request_is_answered_at_once(env: Env) -> None:
    t0 = time.monotonic()
    answer = raw(env.port, b"GET /\r\n", shutdown=False, timeout=5.0)  # the client keeps its side open
    assert time.monotonic() - t0 < 3.0, "the HTTP/0.9 request waited for headers"
    assert answer.startswith((b"HTTP/1.1 400", b"HTTP/1.0 400")), answer[:200]
    assert b"HTTP/0.9" in answer


def test_regression_clients_that_hang_up_are_counted_not_traced(env: Env, capfd: pytest.CaptureFixture[str]) -> None:
    capfd.readouterr()
    gone = env.console.server.counters()["clients_gone"]
    req = f"GET /video/ptz.jpg?fresh HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer {TOKEN}\r\n\r\n".encode()
    for _ in range(20):  # ask for the next frame, then reset the connection before it comes
        s = socket.create_connection(("127.0.0.1", env.port))
        s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        s.sendall(req)
        time.sleep(0.01)  # let the request reach the server (no per-request counter to wait on), then reset
        s.close()
    env.ros.wait_for(lambda: env.console.server.counters()["clients_gone"] >= gone + 10, 10.0)
    time.sleep(0.3)  # a window for a (wrong) late traceback of the last resets: the thing under test is none comes
    assert "Traceback" not in capfd.readouterr().err
    assert env.console.server.counters()["errors"] == 0
    check_still_works(env)


def test_regression_rotating_loopback_addresses_share_one_allowance(tmp_path: Path) -> None:
    ros = RosHarness()
    try:
        token_file = tmp_path / "token"
        token_file.write_text(TOKEN + "\n")
        overrides = [Parameter("port", value=0), Parameter("token_file", value=str(token_file)),
                     Parameter("auth_max_failures", value=3), Parameter("auth_window", value=60.0)]  # fmt: skip
        console = ros.add(WebConsole(context=ros.context, parameter_overrides=overrides))
        port = console.server.port

        def status(source: str, token: str) -> int:
            req = f"GET /api/state HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer {token}\r\n\r\n".encode()
            return int(raw(port, req, shutdown=True, timeout=10.0, source=source).split(b" ", 2)[1])

        assert [status(f"127.0.{i}.{i + 2}", "guess") for i in range(3)] == [401, 401, 401]
        for source in ("127.0.0.1", "127.9.9.9", "127.200.1.77"):  # a fresh loopback address is no fresh start
            assert status(source, "guess") == 429
            assert status(source, TOKEN) == 429
    finally:
        ros.close()
