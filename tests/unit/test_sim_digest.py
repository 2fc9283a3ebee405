"""The simulated camera's authentication (:mod:`axis_ptz_ros2.sim.digest`), without HTTP.

``CameraAuth`` is what both the HTTP and the RTSP listeners ask. The expected Digest responses are computed here
with :mod:`hashlib` after RFC 7616 §3.4.1 / RFC 2617 §3.2.2 (the helper is itself checked against the RFCs'
published examples), and httpx's own ``DigestAuth``/``BasicAuth`` clients are run against it through a
``MockTransport`` (no sockets).
"""

from __future__ import annotations

import base64
import hashlib
import re

import httpx
import pytest

from axis_ptz_ros2.sim.digest import NONCE_LIFETIME_S, CameraAuth

pytestmark = pytest.mark.unit

USER, PASSWORD, REALM = "root", "s3cret:with colon", "AXIS_00408C1A2B3C"
URI = "/axis-cgi/com/ptz.cgi?query=position"
CNONCE, NC = "0a4f113b", "00000001"


def md5(text: str) -> str:
    return hashlib.md5(text.encode("utf-8")).hexdigest()  # noqa: S324 - HTTP Digest is MD5 by definition


def digest_response(
    user: str, realm: str, password: str, method: str, uri: str, nonce: str, qop: str | None, nc: str, cnonce: str
) -> str:
    """request-digest of RFC 7616 §3.4.1 (qop=auth) or RFC 2069 (no qop), MD5."""
    ha1 = md5(f"{user}:{realm}:{password}")
    ha2 = md5(f"{method}:{uri}")
    if qop is None:
        return md5(f"{ha1}:{nonce}:{ha2}")
    return md5(f"{ha1}:{nonce}:{nc}:{cnonce}:{qop}:{ha2}")


def digest_header(
    nonce: str,
    *,
    method: str = "GET",
    uri: str = URI,
    signed_uri: str | None = None,
    user: str = USER,
    realm: str = REALM,
    password: str = PASSWORD,
    qop: str | None = "auth",
    algorithm: str | None = "MD5",
    response: str | None = None,
) -> str:
    """An ``Authorization: Digest …`` value as a client would send it (``signed_uri``: the target it hashed)."""
    signed = uri if signed_uri is None else signed_uri
    resp = response or digest_response(user, realm, password, method, signed, nonce, qop, NC, CNONCE)
    fields = [f'username="{user}"', f'realm="{realm}"', f'nonce="{nonce}"', f'uri="{uri}"', f'response="{resp}"']
    if algorithm is not None:
        fields.append(f"algorithm={algorithm}")
    if qop is not None:
        fields += [f"qop={qop}", f"nc={NC}", f'cnonce="{CNONCE}"']
    return "Digest " + ", ".join(fields)


def basic_header(user: str, password: str) -> str:
    return "Basic " + base64.b64encode(f"{user}:{password}".encode()).decode()


def challenge_fields(challenge: str) -> dict[str, str]:
    scheme, _, rest = challenge.partition(" ")
    fields = {k: a if a else b for k, a, b in re.findall(r'(\w+)=(?:"([^"]*)"|([^,\s]*))', rest)}
    fields["scheme"] = scheme
    return fields


def fresh_nonce(auth: CameraAuth) -> str:
    """The nonce of the Digest challenge a 401 would carry now."""
    return challenge_fields(auth.challenges()[0])["nonce"]


@pytest.fixture
def auth() -> CameraAuth:
    return CameraAuth("digest", REALM, USER, PASSWORD)


# --------------------------------------------------------------------------------------------------------
# the test's own arithmetic, against the RFCs' examples
# --------------------------------------------------------------------------------------------------------
def test_the_helper_reproduces_rfc_2617_and_rfc_7616_examples() -> None:
    # RFC 2617 §3.5
    assert (
        digest_response("Mufasa", "testrealm@host.com", "Circle Of Life", "GET", "/dir/index.html",
                        "dcd98b7102dd2f0e8b11d0f600bfb0c093", "auth", "00000001", "0a4f113b")
        == "6629fae49393a05397450978507c4ef1"
    )  # fmt: skip
    # RFC 7616 §3.9.1 (MD5)
    assert (
        digest_response("Mufasa", "http-auth@example.org", "Circle of Life", "GET", "/dir/index.html",
                        "7ypf/xlj9XXwfDPEoM4URrv/xwf94BcCAzFZH4GiTo0v", "auth", "00000001",
                        "f2/wE4q74E6zIJEtWaHKaf5wv/H5QzzpXusqGemxURZJ")
        == "8ca523f5e9506fed4657c9700eebdbec"
    )  # fmt: skip


# --------------------------------------------------------------------------------------------------------
# Digest check
# --------------------------------------------------------------------------------------------------------
def test_a_correct_digest_response_to_an_issued_nonce_is_accepted(auth: CameraAuth) -> None:
    nonce = fresh_nonce(auth)
    assert auth.check(digest_header(nonce), "GET", URI) == "ok"
    # the same nonce serves later requests too (a client reuses the challenge with nc counting up)
    again = digest_header(nonce, method="POST", uri="/axis-cgi/param.cgi")
    assert auth.check(again, "POST", "/axis-cgi/param.cgi") == "ok"


def test_rfc_2069_digest_without_qop_is_accepted(auth: CameraAuth) -> None:
    nonce = fresh_nonce(auth)
    assert auth.check(digest_header(nonce, qop=None), "GET", URI) == "ok"


def test_algorithm_may_be_omitted_and_the_response_hex_may_be_upper_case(auth: CameraAuth) -> None:
    nonce = fresh_nonce(auth)
    upper = digest_response(USER, REALM, PASSWORD, "GET", URI, nonce, "auth", NC, CNONCE).upper()
    assert auth.check(digest_header(nonce, algorithm=None), "GET", URI) == "ok"
    assert auth.check(digest_header(nonce, response=upper), "GET", URI) == "ok"
    assert auth.check(digest_header(nonce).replace("Digest ", "digest ", 1), "GET", URI) == "ok"  # scheme: any case


def test_quoted_and_unquoted_field_values_are_both_read(auth: CameraAuth) -> None:
    nonce = fresh_nonce(auth)
    header = digest_header(nonce).replace("qop=auth", 'qop="auth"').replace("algorithm=MD5", 'algorithm="MD5"')
    assert 'qop="auth"' in header
    assert auth.check(header, "GET", URI) == "ok"


@pytest.mark.parametrize(
    ("what", "header_kw"),
    [
        ("wrong password", {"password": "wrong"}),
        ("wrong user", {"user": "admin"}),
        ("wrong realm", {"realm": "AXIS_000000000000"}),
        ("other algorithm", {"algorithm": "SHA-256"}),
        ("qop auth-int (not offered)", {"qop": "auth-int"}),
        ("a garbage response", {"response": "0" * 32}),
    ],
)
def test_wrong_digest_answers_fail(auth: CameraAuth, what: str, header_kw: dict[str, str]) -> None:
    nonce = fresh_nonce(auth)
    assert auth.check(digest_header(nonce, **header_kw), "GET", URI) == "fail", what


def test_username_and_realm_fields_must_name_the_camera_s_own(auth: CameraAuth) -> None:
    nonce = fresh_nonce(auth)
    good = digest_header(nonce)  # hashed over the camera's user and realm
    assert auth.check(good, "GET", URI) == "ok"
    assert auth.check(good.replace(f'username="{USER}"', 'username="admin"'), "GET", URI) == "fail"
    assert auth.check(good.replace(f'realm="{REALM}"', 'realm="elsewhere"'), "GET", URI) == "fail"


def test_a_qop_other_than_auth_fails_whatever_else_is_sent(auth: CameraAuth) -> None:
    nonce = fresh_nonce(auth)
    no_response = f'Digest username="{USER}", realm="{REALM}", nonce="{nonce}", uri="{URI}"'
    for qop in ("auth-int", "auth,auth-int", ""):
        assert auth.check(f"{no_response}, qop={qop}", "GET", URI) == "fail", qop
        assert auth.check(f'{no_response}, qop={qop}, response=""', "GET", URI) == "fail", qop


def test_the_signature_covers_method_and_the_request_target_exactly_as_sent(auth: CameraAuth) -> None:
    nonce = fresh_nonce(auth)
    assert auth.check(digest_header(nonce), "POST", URI) == "fail"  # signed for GET
    # the uri field must be the target on the request line, byte for byte (no normalising "//" or the query away)
    assert auth.check(digest_header(nonce), "GET", "/axis-cgi/com/ptz.cgi") == "fail"
    double = "//axis-cgi/com/ptz.cgi?query=position"
    assert auth.check(digest_header(nonce, uri=double), "GET", double) == "ok"
    assert auth.check(digest_header(nonce, uri=double), "GET", URI) == "fail"
    # the right target hashed, but another one named in the uri field (RFC 7616 §3.4.6: they must match)
    assert auth.check(digest_header(nonce, uri="/other", signed_uri=URI), "GET", URI) == "fail"


def test_rtsp_requests_are_checked_the_same_way(auth: CameraAuth) -> None:
    nonce = fresh_nonce(auth)
    url = "rtsp://127.0.0.1:554/axis-media/media.amp?videocodec=h264"
    assert auth.check(digest_header(nonce, method="DESCRIBE", uri=url), "DESCRIBE", url) == "ok"
    assert auth.check(digest_header(nonce, method="DESCRIBE", uri=url), "SETUP", url) == "fail"


def test_a_nonce_never_issued_or_forgotten_by_a_restart_fails(auth: CameraAuth) -> None:
    assert auth.check(digest_header("bm90IGlzc3VlZA=="), "GET", URI) == "fail"
    nonce = fresh_nonce(auth)
    assert auth.check(digest_header(nonce), "GET", URI) == "ok"
    auth.forget_nonces()
    assert auth.check(digest_header(nonce), "GET", URI) == "fail"


def test_an_expired_nonce_is_stale_only_for_a_correct_answer(auth: CameraAuth) -> None:
    auth.set_options(nonce_lifetime_s=30.0)
    nonce = fresh_nonce(auth)
    auth.age_nonces(29.0)
    assert auth.check(digest_header(nonce), "GET", URI) == "ok"
    auth.age_nonces(2.0)
    assert auth.check(digest_header(nonce), "GET", URI) == "stale"
    assert auth.check(digest_header(nonce, password="wrong"), "GET", URI) == "fail"  # never "stale" for a wrong one
    assert auth.check(digest_header(fresh_nonce(auth)), "GET", URI) == "ok"  # a new challenge's nonce works again


def test_expired_nonces_are_pruned_once_thousands_were_issued(auth: CameraAuth) -> None:
    old = fresh_nonce(auth)
    auth.age_nonces(NONCE_LIFETIME_S + 1.0)
    assert auth.check(digest_header(old), "GET", URI) == "stale"
    recent = [auth.new_nonce() for _ in range(2001)]
    assert len(set(recent)) == len(recent)
    assert auth.check(digest_header(old), "GET", URI) == "fail"  # forgotten: memory stays bounded
    assert auth.check(digest_header(recent[0]), "GET", URI) == "ok"  # unexpired ones are kept


# --------------------------------------------------------------------------------------------------------
# Basic, modes
# --------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("mode", ["basic", "basic_digest"])
def test_basic_where_the_mode_offers_it(mode: str) -> None:
    auth = CameraAuth(mode, REALM, USER, PASSWORD)
    assert auth.check(basic_header(USER, PASSWORD), "GET", URI) == "ok"  # a ":" in the password is kept
    assert auth.check(basic_header(USER, "wrong"), "GET", URI) == "fail"
    assert auth.check(basic_header("admin", PASSWORD), "GET", URI) == "fail"
    assert auth.check(basic_header(USER, PASSWORD).replace("Basic", "BASIC"), "GET", URI) == "ok"
    assert auth.check("Basic not*base64", "GET", URI) == "fail"
    assert auth.check("Basic " + base64.b64encode(b"\xff\xfe:x").decode(), "GET", URI) == "fail"  # not UTF-8


def test_each_mode_accepts_only_its_own_schemes() -> None:
    basic = basic_header(USER, PASSWORD)
    for mode, basic_ok, digest_ok in (
        ("basic", True, False),
        ("digest", False, True),
        ("basic_digest", True, True),
    ):
        auth = CameraAuth(mode, REALM, USER, PASSWORD)
        nonce = auth.new_nonce()
        assert (auth.check(basic, "GET", URI) == "ok") is basic_ok, mode
        assert (auth.check(digest_header(nonce), "GET", URI) == "ok") is digest_ok, mode
        assert auth.check(None, "GET", URI) == "fail"
        assert auth.check("", "GET", URI) == "fail"
        assert auth.check(f"Bearer {PASSWORD}", "GET", URI) == "fail"


def test_mode_none_lets_everything_through_and_challenges_nothing() -> None:
    auth = CameraAuth("none", REALM, USER, PASSWORD)
    assert auth.check(None, "GET", URI) == "ok"
    assert auth.check(basic_header(USER, "wrong"), "GET", URI) == "ok"
    assert auth.challenges() == []


# --------------------------------------------------------------------------------------------------------
# challenges and options
# --------------------------------------------------------------------------------------------------------
def test_current_style_challenge() -> None:
    auth = CameraAuth("basic_digest", REALM, USER, PASSWORD)
    digest, basic = auth.challenges()
    assert re.fullmatch(rf'Digest realm="{REALM}", nonce="[^"]+", algorithm=MD5, qop="auth"', digest)
    assert basic == f'Basic realm="{REALM}"'
    assert auth.challenges(stale=True)[0].endswith(', qop="auth", stale=true')
    assert challenge_fields(auth.challenges()[0])["nonce"] != challenge_fields(auth.challenges()[0])["nonce"]


def test_legacy_style_challenge() -> None:
    auth = CameraAuth("digest", REALM, USER, PASSWORD, challenge_style="legacy")
    (plain,) = auth.challenges()
    (stale,) = auth.challenges(stale=True)
    assert re.fullmatch(rf'Digest realm="{REALM}", nonce="[^"]+", stale=FALSE, qop="auth"', plain)
    assert re.fullmatch(rf'Digest realm="{REALM}", nonce="[^"]+", stale=TRUE, qop="auth"', stale)
    assert "algorithm" not in plain
    assert auth.check(digest_header(challenge_fields(plain)["nonce"], algorithm=None), "GET", URI) == "ok"


def test_options_and_modes_are_validated_and_the_password_never_shown() -> None:
    with pytest.raises(ValueError, match="auth must be one of"):
        CameraAuth("ntlm", REALM, USER, PASSWORD)
    with pytest.raises(ValueError, match="challenge_style must be one of"):
        CameraAuth("digest", REALM, USER, PASSWORD, challenge_style="modern")
    auth = CameraAuth("digest", REALM, USER, PASSWORD)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="nonce_lifetime_s must be > 0"):
            auth.set_options(nonce_lifetime_s=bad)
    assert auth.nonce_lifetime_s == NONCE_LIFETIME_S
    auth.set_options(nonce_lifetime_s=5, challenge_style="legacy")
    assert (auth.nonce_lifetime_s, auth.challenge_style) == (5.0, "legacy")
    assert isinstance(auth.nonce_lifetime_s, float)
    assert PASSWORD not in repr(auth)
    assert repr(auth) == f"CameraAuth(mode='digest', realm='{REALM}', user='{USER}')"


# --------------------------------------------------------------------------------------------------------
# httpx's clients against it
# --------------------------------------------------------------------------------------------------------
def camera_transport(auth: CameraAuth, seen: list[tuple[str, str | None, int]]) -> httpx.MockTransport:
    """A camera that answers 200 after :meth:`CameraAuth.check`, else 401 with its challenges (as sim/http)."""

    def handle(request: httpx.Request) -> httpx.Response:
        target = request.url.raw_path.decode("ascii")
        verdict = auth.check(request.headers.get("Authorization"), request.method, target)
        status = 200 if verdict == "ok" else 401
        seen.append((request.method, request.headers.get("Authorization"), status))
        if status == 200:
            return httpx.Response(200, text="pan=0\n")
        headers = [("WWW-Authenticate", c) for c in auth.challenges(stale=verdict == "stale")]
        return httpx.Response(401, headers=headers)

    return httpx.MockTransport(handle)


@pytest.mark.parametrize(("mode", "style"), [("digest", "current"), ("digest", "legacy"), ("basic_digest", "current")])
def test_httpx_digest_auth_is_accepted(mode: str, style: str) -> None:
    auth = CameraAuth(mode, REALM, USER, PASSWORD, challenge_style=style)
    seen: list[tuple[str, str | None, int]] = []
    with httpx.Client(transport=camera_transport(auth, seen), auth=httpx.DigestAuth(USER, PASSWORD)) as client:
        r = client.get("http://cam" + URI)
        assert r.status_code == 200
        assert r.text == "pan=0\n"
        assert [s for _, _, s in seen] == [401, 200]
        sent = seen[1][1]
        assert sent is not None
        assert sent.startswith("Digest ")
        assert 'uri="/axis-cgi/com/ptz.cgi?query=position"' in sent
        assert "qop=auth" in sent
        # the next request reuses the nonce (nc 2) and is accepted at once
        assert client.post("http://cam/axis-cgi/com/ptz.cgi", data={"move": "home"}).status_code == 200
        assert [s for _, _, s in seen] == [401, 200, 200]
        assert "nc=00000002" in (seen[2][1] or "")


def test_httpx_digest_auth_recovers_from_a_stale_nonce() -> None:
    auth = CameraAuth("digest", REALM, USER, PASSWORD, nonce_lifetime_s=10.0)
    seen: list[tuple[str, str | None, int]] = []
    with httpx.Client(transport=camera_transport(auth, seen), auth=httpx.DigestAuth(USER, PASSWORD)) as client:
        assert client.get("http://cam" + URI).status_code == 200
        auth.age_nonces(11.0)
        assert client.get("http://cam" + URI).status_code == 200
    assert [s for _, _, s in seen] == [401, 200, 401, 200]
    first, renewed = (challenge_fields(h or "")["nonce"] for _, h, s in seen if s == 200)
    assert first != renewed


def test_httpx_with_the_wrong_password_is_refused() -> None:
    auth = CameraAuth("digest", REALM, USER, PASSWORD)
    seen: list[tuple[str, str | None, int]] = []
    with httpx.Client(transport=camera_transport(auth, seen), auth=httpx.DigestAuth(USER, "wrong")) as client:
        assert client.get("http://cam" + URI).status_code == 401
    assert [s for _, _, s in seen] == [401, 401]


def test_httpx_basic_auth_is_accepted_only_where_basic_is_offered() -> None:
    for mode, expected in (("basic", 200), ("basic_digest", 200), ("digest", 401)):
        auth = CameraAuth(mode, REALM, USER, PASSWORD)
        seen: list[tuple[str, str | None, int]] = []
        with httpx.Client(transport=camera_transport(auth, seen), auth=httpx.BasicAuth(USER, PASSWORD)) as client:
            assert client.get("http://cam" + URI).status_code == expected, mode
