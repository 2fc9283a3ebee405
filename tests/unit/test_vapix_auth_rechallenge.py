"""Digest logins that last (issue 10): real challenge forms, re-challenge on 401, one retry, counters.

The cameras here are ``httpx.MockTransport`` servers that check Digest the way an Axis does (RFC 2617/2069
response over the request target as sent) and hand out nonces that they can expire or forget.
"""

from __future__ import annotations

import hashlib
import secrets

import httpx
import pytest

from axis_ptz_ros2.vapix import AuthError, CameraConfig, VapixClient
from axis_ptz_ros2.vapix.auth import parse_challenges
from tests.unit import fixtures_vapix as fx

pytestmark = pytest.mark.unit

USER, PASSWORD = "root", "s3cr3t-Pa55"
REALM = "AXIS_00408CFB6888"

# Challenge forms recorded from real Axis firmware (vapix.md §3, S8) and the older form.
CURRENT = 'Digest realm="{realm}", nonce="{nonce}", algorithm=MD5, qop="auth"'
LEGACY = 'Digest realm="{realm}", nonce="{nonce}", stale=FALSE, qop="auth"'
NO_QOP = 'Digest realm="{realm}", nonce="{nonce}", algorithm=MD5'
BARE = 'Digest realm="{realm}", nonce="{nonce}"'


def _md5(s: str) -> str:
    return hashlib.md5(s.encode()).hexdigest()  # noqa: S324 - Digest is MD5


def _params(header: str) -> dict[str, str]:
    (challenge,) = parse_challenges(httpx.Response(401, headers={"WWW-Authenticate": header}))
    return challenge.params


class DigestCamera:
    """Issues nonces; ``expire()`` makes them stale, ``restart()`` forgets them; counts requests by outcome."""

    def __init__(self, form: str = CURRENT, password: str = PASSWORD) -> None:
        self.form = form
        self.password = password
        self.live: set[str] = set()
        self.expired: set[str] = set()
        self.log: list[str] = []  # "anon" | "ok" | "stale" | "unknown" | "bad"
        self.stale_word = "true"

    def expire(self) -> None:
        self.expired |= self.live
        self.live.clear()

    def restart(self) -> None:
        self.live.clear()
        self.expired.clear()

    def _challenge(self, stale: bool) -> httpx.Response:
        nonce = secrets.token_urlsafe(16) + "="
        self.live.add(nonce)
        header = self.form.format(realm=REALM, nonce=nonce)
        if stale:
            header = header.replace("stale=FALSE", "stale=TRUE") if "stale=" in header else header + ", stale=true"
        return httpx.Response(401, headers={"WWW-Authenticate": header})

    def __call__(self, request: httpx.Request) -> httpx.Response:
        header = request.headers.get("authorization", "")
        if not header.startswith("Digest "):
            self.log.append("anon")
            return self._challenge(False)
        p = fx.parse_auth_params(header)
        uri = request.url.raw_path.decode()
        ha1 = _md5(f"{USER}:{REALM}:{self.password}")
        ha2 = _md5(f"{request.method}:{p.get('uri')}")
        if "qop" in p:
            expected = _md5(f"{ha1}:{p['nonce']}:{p['nc']}:{p['cnonce']}:{p['qop']}:{ha2}")
        else:
            expected = _md5(f"{ha1}:{p['nonce']}:{ha2}")
        if p.get("uri") != uri or p.get("response") != expected or p.get("username") != USER:
            self.log.append("bad")
            return self._challenge(False)
        if p["nonce"] in self.expired:
            self.log.append("stale")
            return self._challenge(True)
        if p["nonce"] not in self.live:
            self.log.append("unknown")
            return self._challenge(False)
        self.log.append("ok")
        return httpx.Response(200, text=fx.POSITION_RESPONSE)


def _client(camera: DigestCamera, auth: str = "auto") -> VapixClient:
    config = CameraConfig(username=USER, password=PASSWORD, auth=auth)
    return VapixClient(config, transport=httpx.MockTransport(camera))


@pytest.mark.parametrize(
    ("header", "expected"),
    [
        (CURRENT.format(realm="R", nonce="n=="), {"realm": "R", "nonce": "n==", "algorithm": "MD5", "qop": "auth"}),
        (LEGACY.format(realm="R", nonce="a+b="), {"realm": "R", "nonce": "a+b=", "stale": "FALSE", "qop": "auth"}),
        ('Digest realm="R",nonce="x",stale=true', {"realm": "R", "nonce": "x", "stale": "true"}),
        ('Digest realm="a, b", nonce="x"', {"realm": "a, b", "nonce": "x"}),
    ],
)
def test_parse_real_challenge_forms(header, expected):
    assert _params(header) == expected


def test_parse_combined_header_and_stale_flag():
    response = httpx.Response(
        401,
        headers={"WWW-Authenticate": f'{fx.BASIC_CHALLENGE}, Digest realm="R", nonce="x", stale=TRUE, qop="auth"'},
    )
    basic, digest = parse_challenges(response)
    assert (basic.scheme, basic.params) == ("Basic", {"realm": "AXIS"})
    assert digest.scheme == "Digest"
    assert digest.stale
    assert not parse_challenges(httpx.Response(401, headers={"WWW-Authenticate": LEGACY}))[0].stale


@pytest.mark.parametrize("form", [CURRENT, LEGACY, NO_QOP, BARE], ids=["current", "legacy", "no-qop", "bare"])
def test_login_with_each_challenge_form_and_preemptive_reuse(form):
    camera = DigestCamera(form)
    with _client(camera) as vapix:
        vapix.query_position()
        vapix.query_position()
        assert vapix.auth_counters.rechallenges == 0
    assert camera.log == ["anon", "ok", "ok"]


@pytest.mark.parametrize("form", [CURRENT, LEGACY], ids=["current", "legacy"])
def test_expired_nonce_takes_new_challenge_and_retries_once(form):
    camera = DigestCamera(form)
    with _client(camera) as vapix:
        vapix.query_position()
        camera.expire()
        vapix.query_position()  # no exception: the stale 401 was answered with the fresh nonce
        assert camera.log == ["anon", "ok", "stale", "ok"]
        assert vapix.auth_counters.rechallenges == 1
        assert vapix.auth_counters.stale == 1
        vapix.query_position()
    assert camera.log[-1] == "ok"
    assert len(camera.log) == 5


def test_camera_restart_forgets_nonce_without_stale_flag():
    camera = DigestCamera(CURRENT)
    with _client(camera) as vapix:
        vapix.query_position()
        camera.restart()  # 401 without stale=true: still worth exactly one retry with the new challenge
        vapix.query_position()
        assert vapix.auth_counters.rechallenges == 1
        assert vapix.auth_counters.stale == 0
    assert camera.log == ["anon", "ok", "unknown", "ok"]


def test_second_401_is_a_refusal_not_a_loop():
    camera = DigestCamera(CURRENT)
    with _client(camera) as vapix:
        vapix.query_position()
        camera.password = "changed-on-the-camera"
        with pytest.raises(AuthError, match="Digest credentials rejected") as excinfo:
            vapix.query_position()
        assert PASSWORD not in str(excinfo.value)
        assert camera.log == ["anon", "ok", "bad", "bad"]  # one retry, then the refusal
        assert vapix.auth_counters.rechallenges == 1
        assert vapix.auth_counters.refusals == 1
        camera.password = PASSWORD  # fixed on the camera: the next call works again
        vapix.query_position()
    assert camera.log[-1] == "ok"


def test_many_expiries_in_a_row_never_fail_a_call():
    camera = DigestCamera(LEGACY)
    with _client(camera) as vapix:
        for i in range(20):
            if i % 3 == 0:
                camera.expire()
            if i % 7 == 0:
                camera.restart()
            vapix.query_position()
    assert "bad" not in camera.log


def test_digest_signs_the_request_target_as_sent():
    """``//axis-cgi/…`` (sent by a released ROS driver) must be signed as ``//axis-cgi/…``."""
    camera = DigestCamera(CURRENT)
    config = CameraConfig(username=USER, password=PASSWORD)
    with VapixClient(config, transport=httpx.MockTransport(camera)) as vapix:
        http = vapix._http  # noqa: SLF001 - the raw request target is the point of this test
        url = httpx.URL(config.base_url + "//axis-cgi/com/ptz.cgi?query=position")
        assert url.raw_path == b"//axis-cgi/com/ptz.cgi?query=position"
        response = http.send(http.build_request("GET", url))
        assert response.status_code == 200
        assert fx.parse_auth_params(response.request.headers["authorization"])["uri"] == (
            "//axis-cgi/com/ptz.cgi?query=position"
        )
    assert camera.log == ["anon", "ok"]


def test_stream_auth_shares_the_client_counters():
    camera = DigestCamera(CURRENT)
    with _client(camera) as vapix:
        vapix.query_position()
        assert set(vapix.auth_counters.as_dict()) >= {"auth rechallenges", "auth refusals"}
        camera.expire()
        vapix.query_position()
        assert vapix.auth_counters.as_dict()["auth rechallenges"] == 1
