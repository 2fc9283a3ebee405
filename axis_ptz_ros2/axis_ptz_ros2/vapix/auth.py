"""HTTP authentication negotiated the way Axis cameras expect it.

Implements reference ``vapix.md`` §3 "Authentication": the first request goes out without
credentials; a protected resource answers ``401`` with one or more ``WWW-Authenticate`` headers
(``Digest realm="AXIS_…", nonce=…, algorithm=MD5, qop="auth"`` and/or ``Basic realm="AXIS"``,
per ``Network.HTTP.AuthenticationPolicy``). Real challenges vary by firmware: ``stale=true`` or
``stale=FALSE``, ``qop`` or ``algorithm`` missing, both schemes in one header or in two.

Rules:

* Mode ``auto`` prefers Digest. It uses Basic only over HTTPS: over plain HTTP a camera that offers
  only Basic is refused with an explanation (choose ``auth: basic`` explicitly, or HTTPS), so the
  password never crosses the network in clear by accident. A Basic choice made by ``auto`` is kept
  only for HTTPS requests.
* Digest keeps the camera's last challenge and signs every request pre-emptively (``nc`` counts up).
  A ``401`` to a signed request (nonce expired — ``stale=true`` — or the camera restarted and forgot
  it) takes the new challenge and retries exactly once; that retry is counted
  (:attr:`AuthCounters.rechallenges`). A ``401`` to the retry is a real refusal and is returned; so is a
  ``401`` to a challenge that never authenticated anything (a refused login is tried once per call).
* Digest is signed over the request target exactly as sent (``request.url.raw_path``).
"""

from __future__ import annotations

import base64
import hashlib
import os
import re
import threading
import time
from collections.abc import Callable, Generator
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import httpx

from axis_ptz_ros2.vapix.errors import ResponseParseError, describe_request

__all__ = [
    "AuthCounters",
    "AuthMode",
    "AuthScheme",
    "Challenge",
    "NegotiatingAuth",
    "offered_schemes",
    "parse_challenges",
    "read_challenge_body",
]


class AuthMode(StrEnum):
    """What the client may use: negotiate, force one scheme, or never send credentials."""

    AUTO = "auto"
    BASIC = "basic"
    DIGEST = "digest"
    NONE = "none"


class AuthScheme(StrEnum):
    """An HTTP authentication scheme the camera offers."""

    BASIC = "Basic"
    DIGEST = "Digest"


@dataclass(frozen=True, slots=True)
class Challenge:
    """One parsed ``WWW-Authenticate`` challenge (scheme name capitalised, parameter names lower-case)."""

    scheme: str
    params: dict[str, str]

    @property
    def stale(self) -> bool:
        """``stale=true`` (any case, quoted or not): the nonce expired, the credentials were fine."""
        return self.params.get("stale", "").strip().lower() == "true"


# auth-param = token "=" ( token / quoted-string ); a new challenge starts with a bare token.
_TOKEN = r"[!#$%&'*+.^_`|~0-9A-Za-z-]+"
_PARAM = re.compile(rf'\s*({_TOKEN})\s*=\s*("(?:[^"\\]|\\.)*"|[^,\s]*)\s*(?:,|$)')
_SCHEME = re.compile(rf"\s*({_TOKEN})(?:\s+|\s*,|\s*$)")


def _unquote(value: str) -> str:
    if len(value) >= 2 and value[0] == value[-1] == '"':
        return re.sub(r"\\(.)", r"\1", value[1:-1])
    return value


def _parse_header(header: str) -> list[Challenge]:
    out: list[Challenge] = []
    pos, n = 0, len(header)
    current: Challenge | None = None
    while pos < n:
        if header[pos] in ", \t":
            pos += 1
            continue
        param = _PARAM.match(header, pos)
        if param is not None and current is not None:
            current.params[param.group(1).lower()] = _unquote(param.group(2))
            pos = param.end()
            continue
        scheme = _SCHEME.match(header, pos)
        if scheme is None:
            break  # unparseable rest: keep what we have
        current = Challenge(scheme.group(1).capitalize(), {})
        out.append(current)
        pos = scheme.end()
    return out


def parse_challenges(response: httpx.Response) -> list[Challenge]:
    """Every challenge of every ``WWW-Authenticate`` header (several headers or one combined)."""
    out: list[Challenge] = []
    for header in response.headers.get_list("www-authenticate"):
        out.extend(_parse_header(header))
    return out


def offered_schemes(response: httpx.Response) -> tuple[str, ...]:
    """Scheme names from every ``WWW-Authenticate`` header, in order, without repeats."""
    names: list[str] = []
    for challenge in parse_challenges(response):
        if challenge.scheme not in names:
            names.append(challenge.scheme)
    return tuple(names)


def _digest_challenge(response: httpx.Response) -> Challenge | None:
    for challenge in parse_challenges(response):
        if challenge.scheme == AuthScheme.DIGEST.value and "nonce" in challenge.params:
            return challenge
    return None


_HASHES: dict[str, Callable[[bytes], Any]] = {
    "MD5": hashlib.md5,
    "MD5-SESS": hashlib.md5,
    "SHA-256": hashlib.sha256,
    "SHA-256-SESS": hashlib.sha256,
}


MAX_CHALLENGE_BODY_BYTES = 64 << 10  #: a 401 page bigger than this is not a camera's challenge page


def read_challenge_body(response: httpx.Response) -> None:
    """Read the body of a 401 we answer with another request, capped: httpx would otherwise read all of it
    (to reuse the connection) and an endless 401 body would grow without bound."""
    if hasattr(response, "_content"):
        return
    chunks: list[bytes] = []
    size = 0
    for chunk in response.iter_bytes():
        size += len(chunk)
        if size > MAX_CHALLENGE_BODY_BYTES:
            response.close()
            raise ResponseParseError(
                f"{describe_request(response.request)}: 401 reply larger than {MAX_CHALLENGE_BODY_BYTES} bytes: "
                "not a camera's challenge (check the port)"
            )
        chunks.append(chunk)
    response._content = b"".join(chunks)  # noqa: SLF001 - httpx then re-uses it instead of reading again


class AuthCounters:
    """What authentication did so far (shared by a client and the streams it opens; thread-safe)."""

    def __init__(self) -> None:
        """All zero."""
        self._lock = threading.Lock()
        self.rechallenges = 0  #: 401 to a signed request → new challenge taken, retried once
        self.stale = 0  #: … of which the camera said ``stale=true``
        self.refusals = 0  #: final 401/403 after credentials were sent
        self.basic_refused = 0  #: ``auto`` over HTTP refused to send Basic (the camera offered nothing else)

    def add(self, name: str) -> None:
        """Count one event (``rechallenges``, ``stale``, ``refusals``, ``basic_refused``)."""
        with self._lock:
            setattr(self, name, getattr(self, name) + 1)

    def as_dict(self) -> dict[str, int]:
        """For diagnostics."""
        with self._lock:
            return {
                "auth rechallenges": self.rechallenges,
                "auth stale nonces": self.stale,
                "auth refusals": self.refusals,
                "auth basic refused (plain HTTP)": self.basic_refused,
            }


BASIC_OVER_HTTP_HINT = (
    "the camera offers only Basic authentication over plain HTTP; auth 'auto' never sends a password in "
    "clear: set auth: basic explicitly (accepting that risk) or use HTTPS"
)


class NegotiatingAuth(httpx.Auth):
    """An :class:`httpx.Auth` that negotiates Digest/Basic with the camera (see the module rules).

    Not shared between threads: give each ``httpx.Client`` its own instance (``counters`` may be shared).
    """

    def __init__(
        self,
        username: str | None,
        password: str | None,
        mode: AuthMode | str = AuthMode.AUTO,
        *,
        initial_scheme: AuthScheme | None = None,
        counters: AuthCounters | None = None,
    ) -> None:
        """Credentials are kept only inside this object."""
        self._mode = AuthMode(mode)
        self._username = username
        self._password = password
        self._scheme: AuthScheme | None = initial_scheme if self.has_credentials else None
        self._challenge: Challenge | None = None
        self._nc = 0
        self._proven = False  # the current challenge has authenticated a request at least once
        self.counters = counters if counters is not None else AuthCounters()
        self.last_problem = ""  #: why the last exchange could not authenticate (no secrets), "" if it could

    def __repr__(self) -> str:
        """No credentials in the representation."""
        return f"NegotiatingAuth(mode={self._mode.value!r}, scheme={self._scheme!r})"

    @property
    def mode(self) -> AuthMode:
        """The configured mode."""
        return self._mode

    @property
    def scheme(self) -> AuthScheme | None:
        """The scheme negotiated so far (``None``: anonymous so far, or not yet challenged)."""
        return self._scheme

    @property
    def has_credentials(self) -> bool:
        """Whether a username and password were configured and the mode allows sending them."""
        return self._mode is not AuthMode.NONE and self._username is not None and self._password is not None

    # -- scheme choice ----------------------------------------------------------------------------------------
    def _basic_allowed(self, request: httpx.Request) -> bool:
        if self._mode is AuthMode.BASIC:
            return True
        return self._mode is AuthMode.AUTO and request.url.scheme == "https"

    def _choose(self, offered: tuple[str, ...], request: httpx.Request) -> AuthScheme | None:
        digest = AuthScheme.DIGEST.value in offered
        basic = AuthScheme.BASIC.value in offered
        if self._mode is AuthMode.DIGEST:
            return AuthScheme.DIGEST if digest else None
        if self._mode is AuthMode.BASIC:
            return AuthScheme.BASIC if basic else None
        if digest:
            return AuthScheme.DIGEST
        if basic:
            if self._basic_allowed(request):
                return AuthScheme.BASIC
            self.counters.add("basic_refused")
            self.last_problem = BASIC_OVER_HTTP_HINT
        return None

    # -- header construction ------------------------------------------------------------------------------------
    def _basic_header(self) -> str:
        assert self._username is not None
        assert self._password is not None
        token = base64.b64encode(f"{self._username}:{self._password}".encode()).decode("ascii")
        return f"Basic {token}"

    def _digest_header(self, request: httpx.Request, challenge: Challenge) -> str | None:
        """``Authorization: Digest …`` for ``request`` (None: algorithm/qop we cannot do)."""
        assert self._username is not None
        assert self._password is not None
        p = challenge.params
        algorithm = p.get("algorithm", "MD5")
        hash_func = _HASHES.get(algorithm.upper())
        if hash_func is None:
            return None

        def h(text: str) -> str:
            return str(hash_func(text.encode("utf-8")).hexdigest())

        qops = [q.strip().lower() for q in p["qop"].split(",")] if "qop" in p else []
        if qops and "auth" not in qops:
            return None  # auth-int only
        realm, nonce = p.get("realm", ""), p["nonce"]
        uri = request.url.raw_path.decode("ascii")  # the request target exactly as sent
        self._nc += 1
        nc = f"{self._nc:08x}"
        cnonce = hashlib.sha1(os.urandom(16) + str(time.time()).encode()).hexdigest()[:16]  # noqa: S324
        ha1 = h(f"{self._username}:{realm}:{self._password}")
        if algorithm.upper().endswith("-SESS"):
            ha1 = h(f"{ha1}:{nonce}:{cnonce}")
        ha2 = h(f"{request.method}:{uri}")
        # RFC 2617 with qop, else the RFC 2069 form
        response = h(f"{ha1}:{nonce}:{nc}:{cnonce}:auth:{ha2}") if qops else h(f"{ha1}:{nonce}:{ha2}")
        parts = [
            f'username="{self._username}"',
            f'realm="{realm}"',
            f'nonce="{nonce}"',
            f'uri="{uri}"',
            f'response="{response}"',
        ]
        if "algorithm" in p:
            parts.append(f"algorithm={algorithm}")
        if "opaque" in p:
            parts.append(f'opaque="{p["opaque"]}"')
        if qops:
            parts += ["qop=auth", f"nc={nc}", f'cnonce="{cnonce}"']
        return "Digest " + ", ".join(parts)

    def _take_challenge(self, challenge: Challenge) -> None:
        self._challenge = challenge
        self._nc = 0
        self._proven = False

    def _sign(self, request: httpx.Request, scheme: AuthScheme) -> bool:
        if scheme is AuthScheme.BASIC:
            request.headers["Authorization"] = self._basic_header()
            return True
        if self._challenge is None:
            return False
        header = self._digest_header(request, self._challenge)
        if header is None:
            self.last_problem = f"unsupported Digest challenge (algorithm/qop) {self._challenge.params!r}"
            return False
        request.headers["Authorization"] = header
        return True

    # -- without a flow (the state poll's quick path) ---------------------------------------------------------
    def preemptive(self, request: httpx.Request) -> str | None:
        """The ``Authorization`` value the first request of :meth:`auth_flow` would carry for ``request``
        (``""``: it goes unsigned), or None when only the flow can go on (no Digest challenge to sign with, or
        one we cannot sign). ``request`` is not changed; a Digest signature counts its ``nc`` as the flow's."""
        if not self.has_credentials:
            return ""
        scheme = self._scheme
        if scheme is AuthScheme.BASIC and not self._basic_allowed(request):
            scheme = None
        if scheme is None:
            return ""
        if scheme is AuthScheme.BASIC:
            return self._basic_header()
        if self._challenge is None:
            return None
        return self._digest_header(request, self._challenge)

    def accepted(self, *, signed: bool) -> None:
        """A 2xx reply to a request sent with :meth:`preemptive`'s value: noted as the flow notes it."""
        if signed:
            self._proven = True
            self.last_problem = ""

    # -- the exchange ---------------------------------------------------------------------------------------------
    def auth_flow(self, request: httpx.Request) -> Generator[httpx.Request, httpx.Response, None]:
        """At most: one unauthenticated request, one signed request, and one re-challenged retry."""
        if not self.has_credentials:
            yield request
            return
        scheme = self._scheme
        if scheme is AuthScheme.BASIC and not self._basic_allowed(request):
            scheme = None
        if scheme is not None and self._sign(request, scheme):
            response = yield request
            if response.status_code != 401:
                self._note_final(response, signed=True)
                return
            if scheme is AuthScheme.DIGEST:
                challenge = _digest_challenge(response)
                proven = self._proven
                if challenge is None:  # the camera now offers no Digest: never downgrade
                    self._note_final(response, signed=True)
                    return
                self._take_challenge(challenge)  # the next request signs with the freshest nonce either way
                if not proven:  # this challenge never worked: the credentials are refused, no second try
                    self._note_final(response, signed=True)
                    return
                self.counters.add("rechallenges")
                if challenge.stale:
                    self.counters.add("stale")
                del request.headers["Authorization"]
                if not self._sign(request, AuthScheme.DIGEST):
                    return
                read_challenge_body(response)
                retry = yield request
                self._note_final(retry, signed=True)
                return
            self._note_final(response, signed=True)
            return
        response = yield request
        if response.status_code != 401:
            return
        chosen = self._choose(offered_schemes(response), request)
        if chosen is None:
            return
        if chosen is AuthScheme.DIGEST:
            challenge = _digest_challenge(response)
            if challenge is None:
                self.last_problem = "the camera's Digest challenge carries no nonce"
                return
            self._take_challenge(challenge)
        if not self._sign(request, chosen):
            return
        self._scheme = chosen
        read_challenge_body(response)
        retry = yield request
        self._note_final(retry, signed=True)

    def _note_final(self, response: httpx.Response, *, signed: bool) -> None:
        if signed and response.status_code in (401, 403):
            self.counters.add("refusals")
            return
        if signed and response.status_code != 401:
            self._proven = True
        if 200 <= response.status_code < 300:
            self.last_problem = ""

    def failure_hint(self, response: httpx.Response) -> str:
        """Explain a final 401/403 without secrets: what was sent, what the camera offers."""
        offered = offered_schemes(response)
        offer_text = ", ".join(offered) if offered else "no scheme"
        sent = response.request.headers.get("authorization")
        if response.status_code == 403:
            who = f"{sent.split(' ', 1)[0]} credentials" if sent else "anonymous request"
            return f"{who} accepted but not allowed this resource (needs a user with more rights)"
        if sent:
            scheme = sent.split(" ", 1)[0]
            return f"{scheme} credentials rejected (camera offers {offer_text}); check username/password"
        if self._mode is AuthMode.NONE:
            return f"auth mode 'none' but the camera requires authentication ({offer_text})"
        if self._username is None or self._password is None:
            return f"camera requires authentication ({offer_text}) but no username/password configured"
        if (
            self._mode is AuthMode.AUTO
            and offered
            and AuthScheme.DIGEST.value not in offered
            and AuthScheme.BASIC.value in offered
            and response.request.url.scheme != "https"
        ):
            return BASIC_OVER_HTTP_HINT
        if self.last_problem:
            return self.last_problem
        return f"auth mode {self._mode.value!r} not offered by the camera (camera offers {offer_text})"
