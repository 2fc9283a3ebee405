"""Auth negotiation against the real Axis challenges (vapix.md §3), over httpx.MockTransport."""

import base64

import httpx
import pytest

from axis_ptz_ros2.vapix import AuthError, CameraConfig, VapixClient
from axis_ptz_ros2.vapix.auth import AuthScheme, NegotiatingAuth, offered_schemes
from tests.unit import fixtures_vapix as fx

pytestmark = pytest.mark.unit

USER, PASSWORD = "root", "s3cr3t-Pa55"
REALM, NONCE = "AXIS_ACCC8EF7DE6B", "h20V+wGvBQA=b6c0ce8666d2d4b2688858d7a31386d9d337e072"


class Camera:
    """A protected camera: Digest and/or Basic per policy; counts credentialed attempts."""

    def __init__(self, policy: str = "basic_digest", password: str = PASSWORD) -> None:
        self.policy = policy
        self.password = password
        self.sent: list[str] = []  # Authorization scheme at the time of each request

    def challenge(self) -> httpx.Response:
        headers = []
        if "digest" in self.policy:
            headers.append(("WWW-Authenticate", fx.DIGEST_CHALLENGE))
        if "basic" in self.policy:
            headers.append(("WWW-Authenticate", fx.BASIC_CHALLENGE))
        return httpx.Response(401, headers=headers, text="401 Unauthorized")

    def __call__(self, request: httpx.Request) -> httpx.Response:
        header = request.headers.get("authorization", "")
        self.sent.append(header.split(" ")[0] if header else "none")  # httpx re-uses the Request object
        ok = False
        if header.startswith("Digest ") and "digest" in self.policy:
            ok = fx.digest_is_valid(request, USER, self.password, REALM, NONCE)
        elif header.startswith("Basic ") and "basic" in self.policy:
            ok = header == "Basic " + base64.b64encode(f"{USER}:{self.password}".encode()).decode()
        if not ok:
            return self.challenge()
        return httpx.Response(200, text=fx.POSITION_RESPONSE)

    @property
    def schemes_sent(self) -> list[str]:
        return list(self.sent)


def client(camera: Camera, *, auth: str = "auto", password: str | None = PASSWORD) -> VapixClient:
    config = CameraConfig(username=USER if password else None, password=password, auth=auth)
    return VapixClient(config, transport=httpx.MockTransport(camera))


def test_offered_schemes_reads_all_headers_and_combined_header():
    response = Camera().challenge()
    assert offered_schemes(response) == ("Digest", "Basic")
    combined = httpx.Response(401, headers={"WWW-Authenticate": f"{fx.BASIC_CHALLENGE}, {fx.DIGEST_CHALLENGE}"})
    assert offered_schemes(combined) == ("Basic", "Digest")


def test_digest_preferred_when_both_offered_and_remembered():
    camera = Camera("basic_digest")
    with client(camera) as vapix:
        assert vapix.query_position().pan_deg == pytest.approx(51.2891)
        vapix.query_position()
    # First request anonymous, then Digest; the second call re-uses the challenge (no extra 401).
    assert camera.schemes_sent == ["none", "Digest", "Digest"]


def test_digest_only_camera():
    camera = Camera("digest")
    with client(camera) as vapix:
        vapix.query_position()
    assert camera.schemes_sent == ["none", "Digest"]


def test_auto_never_sends_basic_over_plain_http():
    camera = Camera("basic")
    with client(camera) as vapix:
        for _ in range(2):
            with pytest.raises(AuthError) as excinfo:
                vapix.query_position()
            message = str(excinfo.value)
            assert "offers only Basic" in message
            assert "auth: basic" in message
            assert "HTTPS" in message
            assert PASSWORD not in message
        assert vapix.auth_counters.basic_refused == 2
    # Basic was never sent, and nothing was "remembered" between the two calls.
    assert camera.schemes_sent == ["none", "none"]


def test_explicit_basic_mode_over_http_then_preemptive():
    camera = Camera("basic")
    with client(camera, auth="basic") as vapix:
        vapix.query_position()
        vapix.query_position()
    assert camera.schemes_sent == ["none", "Basic", "Basic"]


def test_auto_uses_basic_over_https():
    camera = Camera("basic")
    config = CameraConfig(username=USER, password=PASSWORD, use_https=True, verify_tls=False)
    with VapixClient(config, transport=httpx.MockTransport(camera)) as vapix:
        vapix.query_position()
        vapix.query_position()
    assert camera.schemes_sent == ["none", "Basic", "Basic"]


def test_auto_does_not_downgrade_from_digest_to_basic():
    """A Digest camera that suddenly offers only Basic (e.g. an impostor on the link) gets no password."""
    camera = Camera("digest")
    with client(camera) as vapix:
        vapix.query_position()
        camera.policy = "basic"
        with pytest.raises(AuthError):
            vapix.query_position()
    assert camera.schemes_sent == ["none", "Digest", "Digest"]


def test_basic_mode_uses_basic_even_if_digest_offered():
    camera = Camera("basic_digest")
    with client(camera, auth="basic") as vapix:
        vapix.query_position()
    assert camera.schemes_sent == ["none", "Basic"]


def test_digest_mode_never_falls_back_to_basic():
    camera = Camera("basic")
    with (
        client(camera, auth="digest") as vapix,
        pytest.raises(AuthError, match="auth mode 'digest' not offered"),
    ):
        vapix.query_position()
    assert camera.schemes_sent == ["none"]


def test_wrong_password_exactly_one_credentialed_try_and_no_secret_leak():
    camera = Camera("basic_digest", password="the-real-one")
    with client(camera) as vapix:
        with pytest.raises(AuthError) as excinfo:
            vapix.query_position()
        assert camera.schemes_sent == ["none", "Digest"]
        message = str(excinfo.value)
        assert "Digest credentials rejected" in message
        assert "401" in message
        assert PASSWORD not in message
        assert PASSWORD not in repr(vapix)
        assert PASSWORD not in repr(vapix.config)
        # A later call tries once more (one credentialed request), it does not loop.
        with pytest.raises(AuthError):
            vapix.query_position()
        assert camera.schemes_sent == ["none", "Digest", "Digest"]


def test_wrong_password_basic_one_try():
    camera = Camera("basic", password="other")
    with (
        client(camera, auth="basic") as vapix,
        pytest.raises(AuthError, match="Basic credentials rejected") as excinfo,
    ):
        vapix.query_position()
    assert camera.schemes_sent == ["none", "Basic"]
    assert PASSWORD not in str(excinfo.value)
    assert base64.b64encode(f"{USER}:{PASSWORD}".encode()).decode() not in str(excinfo.value)


def test_no_credentials_configured_message():
    camera = Camera("digest")
    with (
        client(camera, password=None) as vapix,
        pytest.raises(AuthError, match="no username/password configured"),
    ):
        vapix.query_position()
    assert camera.schemes_sent == ["none"]


def test_anonymous_camera_never_gets_credentials():
    seen: list[str | None] = []

    def anonymous(request: httpx.Request) -> httpx.Response:
        seen.append(request.headers.get("authorization"))
        return httpx.Response(200, text=fx.POSITION_RESPONSE)

    with VapixClient(CameraConfig(username=USER, password=PASSWORD), transport=httpx.MockTransport(anonymous)) as v:
        v.query_position()
        v.query_position()
    assert seen == [None, None]


def test_stale_nonce_gets_exactly_one_retry():
    fresh = "bmV3bm9uY2U="
    state = {"nonce": NONCE, "calls": 0}

    def camera(request: httpx.Request) -> httpx.Response:
        state["calls"] += 1
        header = request.headers.get("authorization", "")
        if header and fx.digest_is_valid(request, USER, PASSWORD, REALM, state["nonce"]):
            return httpx.Response(200, text=fx.POSITION_RESPONSE)
        stale = ", stale=true" if header else ""
        challenge = f'Digest realm="{REALM}", nonce="{state["nonce"]}", algorithm=MD5, qop="auth"{stale}'
        return httpx.Response(401, headers={"WWW-Authenticate": challenge})

    auth = NegotiatingAuth(USER, PASSWORD, "auto")
    with httpx.Client(auth=auth, transport=httpx.MockTransport(camera), base_url="http://127.0.0.1") as http:
        assert http.get("/axis-cgi/com/ptz.cgi?query=position").status_code == 200
        assert auth.scheme is AuthScheme.DIGEST
        state["nonce"] = fresh  # camera expires the nonce
        state["calls"] = 0
        assert http.get("/axis-cgi/com/ptz.cgi?query=position").status_code == 200
        assert state["calls"] == 2  # stale 401, then one retry with the fresh nonce


def test_repr_of_auth_and_config_hide_password():
    auth = NegotiatingAuth(USER, PASSWORD, "auto")
    assert PASSWORD not in repr(auth)
    config = CameraConfig(username=USER, password=PASSWORD)
    assert PASSWORD not in repr(config)
    assert PASSWORD not in config.base_url
    assert USER not in config.base_url
