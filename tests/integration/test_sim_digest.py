"""The simulator's Digest behaves like a real camera's (issue 10): nonces expire (``stale=true``), a restart
forgets them, the older 401 form is available, and the signature is checked over the request target as sent."""

from __future__ import annotations

import hashlib
import http.client
import re

import pytest

from axis_ptz_ros2.sim import SimulatedCamera
from axis_ptz_ros2.vapix import CameraConfig, VapixClient
from axis_ptz_ros2.vapix.auth import parse_challenges
from tests.support.waiting import wait_until

pytestmark = pytest.mark.integration
USER, PASSWORD = "root", "s3cret"
POSITION = "/axis-cgi/com/ptz.cgi?query=position"


def _md5(s: str) -> str:
    return hashlib.md5(s.encode()).hexdigest()  # noqa: S324 - Digest is MD5


def _get(cam: SimulatedCamera, target: str, authorization: str | None = None) -> tuple[int, dict[str, str], bytes]:
    """GET with the request target sent byte for byte (http.client does not normalise it)."""
    conn = http.client.HTTPConnection(cam.host, cam.port, timeout=5)
    try:
        conn.putrequest("GET", target, skip_host=False, skip_accept_encoding=True)
        if authorization:
            conn.putheader("Authorization", authorization)
        conn.endheaders()
        r = conn.getresponse()
        return r.status, {k.lower(): v for k, v in r.getheaders()}, r.read()
    finally:
        conn.close()


def _challenge(headers: dict[str, str]) -> dict[str, str]:
    import httpx  # noqa: PLC0415

    (c,) = parse_challenges(httpx.Response(401, headers={"WWW-Authenticate": headers["www-authenticate"]}))
    return c.params


def _sign(params: dict[str, str], target: str, nc: int = 1) -> str:
    ha1 = _md5(f"{USER}:{params['realm']}:{PASSWORD}")
    ha2 = _md5(f"GET:{target}")
    cnonce = "0a4f113b"
    ncs = f"{nc:08x}"
    resp = _md5(f"{ha1}:{params['nonce']}:{ncs}:{cnonce}:auth:{ha2}")
    return (
        f'Digest username="{USER}", realm="{params["realm"]}", nonce="{params["nonce"]}", uri="{target}", '
        f'response="{resp}", qop=auth, nc={ncs}, cnonce="{cnonce}"'
    )


def _expire_nonces(cam: SimulatedCamera) -> None:
    """Expire every nonce handed out so far: the simulator's clock moves past their lifetime (its test hook
    ``age_nonces``), no real time is waited and the lifetime stays long, so a nonce handed out after this (the
    fresh one) cannot expire between its challenge and the signed request on a loaded machine."""
    cam.authenticator.age_nonces(cam.nonce_lifetime_s + 1.0)


def test_nonce_expires_with_stale_true_then_fresh_nonce_works():
    with SimulatedCamera(auth="digest", password=PASSWORD, nonce_lifetime_s=600.0) as cam:
        status, headers, _ = _get(cam, POSITION)
        assert status == 401
        assert "stale" not in headers["www-authenticate"]
        params = _challenge(headers)
        assert _get(cam, POSITION, _sign(params, POSITION))[0] == 200
        _expire_nonces(cam)
        status, headers, _ = _get(cam, POSITION, _sign(params, POSITION, 2))
        assert status == 401
        fresh = _challenge(headers)
        assert fresh["stale"] == "true"
        assert fresh["nonce"] != params["nonce"]
        # A wrong password on an expired nonce is not "stale": the credentials are wrong.
        bad = _sign(params, POSITION, 3).replace('response="', 'response="0')
        assert "stale" not in _get(cam, POSITION, bad)[1]["www-authenticate"]
        # the fresh nonce works (issued after the ageing, within its long lifetime)
        assert _get(cam, POSITION, _sign(fresh, POSITION))[0] == 200


def test_restart_and_reboot_forget_every_nonce():
    with SimulatedCamera(auth="digest", password=PASSWORD) as cam:
        params = _challenge(_get(cam, POSITION)[1])
        assert _get(cam, POSITION, _sign(params, POSITION))[0] == 200
        cam.reboot(0.2)
        wait_until(lambda: not cam.rebooting, 10.0, 0.05, scaled=False, raises=False)
        status, headers, _ = _get(cam, POSITION, _sign(params, POSITION, 2))
        assert status == 401
        assert "stale" not in headers["www-authenticate"]
        params = _challenge(headers)
        cam.stop()
        cam.start()
        assert _get(cam, POSITION, _sign(params, POSITION))[0] == 401


def test_nonce_lifetime_and_challenge_style_over_sim_control():
    with SimulatedCamera(auth="digest", password=PASSWORD) as cam:
        status, _, body = _get(cam, "/sim/control?nonce_lifetime=2.5&challenge_style=legacy")
        assert status == 200
        assert b'"nonce_lifetime_s": 2.5' in body
        assert cam.nonce_lifetime_s == 2.5
        assert cam.challenge_style == "legacy"
        assert _get(cam, "/sim/control?nonce_lifetime=0")[0] == 400
        assert _get(cam, "/sim/control?challenge_style=weird")[0] == 400


def test_legacy_401_form():
    with SimulatedCamera(auth="digest", password=PASSWORD, challenge_style="legacy", nonce_lifetime_s=600.0) as cam:
        status, headers, body = _get(cam, POSITION)
        assert status == 401
        assert body == b""
        value = headers["www-authenticate"]
        assert re.fullmatch(r'Digest realm="AXIS_[0-9A-F]{12}", nonce="[^"]+", stale=FALSE, qop="auth"', value)
        params = _challenge(headers)
        assert _get(cam, POSITION, _sign(params, POSITION))[0] == 200
        _expire_nonces(cam)
        status, headers, _ = _get(cam, POSITION, _sign(params, POSITION, 2))
        assert status == 401
        assert "stale=TRUE" in headers["www-authenticate"]


def test_double_slash_target_is_signed_and_served_as_sent():
    target = "//axis-cgi/com/ptz.cgi?query=position"
    with SimulatedCamera() as open_cam:
        status, _, body = _get(open_cam, target)
        assert status == 200
        assert body.startswith(b"pan=")
    with SimulatedCamera(auth="digest", password=PASSWORD) as cam:
        params = _challenge(_get(cam, target)[1])
        status, _, body = _get(cam, target, _sign(params, target))
        assert status == 200
        assert body.startswith(b"pan=")
        # Signed for the normalised path but sent as "//…": not the target the client signed.
        assert _get(cam, target, _sign(params, POSITION, 2))[0] == 401


def test_vapix_client_survives_expiry_and_restart_against_the_simulator():
    # The client takes the stale challenge and retries at once: the fresh nonce must outlive that round trip,
    # so the lifetime stays long and the nonces handed out so far are aged past it instead (the camera's clock).
    with (
        SimulatedCamera(auth="digest", password=PASSWORD, nonce_lifetime_s=600.0) as cam,
        VapixClient(CameraConfig(cam.host, cam.port, username=USER, password=PASSWORD)) as vapix,
    ):
        for i in range(8):
            vapix.query_position()
            if i == 2:
                cam.authenticator.age_nonces(601.0)  # expire every nonce issued so far
            if i == 4:
                cam.stop()
                cam.start()
        counters = vapix.auth_counters
        assert counters.stale == 1  # the expiry
        assert counters.rechallenges == 2  # the expiry and the restart
        assert counters.refusals == 0
