"""HTTP authentication negotiated the way Axis cameras expect it.

Implements reference ``vapix.md`` §3 "Authentication": the first request goes out without
credentials; a protected resource answers ``401`` with one or more ``WWW-Authenticate`` headers
(``Digest realm="AXIS_…", nonce=…, algorithm=MD5, qop="auth"`` and/or ``Basic realm="AXIS"``,
per ``Network.HTTP.AuthenticationPolicy``). Mode ``auto`` prefers Digest (delegated to
:class:`httpx.DigestAuth`) and falls back to Basic; the chosen scheme is remembered for later
requests. A ``401`` to credentials ends the exchange (one credentialed try, no hammering) unless
the Digest challenge says ``stale=true`` (expired nonce, RFC 7616), which earns exactly one retry.
"""

from __future__ import annotations

import re
from collections.abc import Generator
from enum import StrEnum

import httpx

__all__ = ["AuthMode", "AuthScheme", "NegotiatingAuth", "offered_schemes"]


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


_SCHEME_TOKEN = re.compile(r"(?:^|,)\s*([A-Za-z][A-Za-z0-9_-]*)(?=\s+[A-Za-z0-9_-]+\s*=|\s*$|\s*,)")
_STALE = re.compile(r'(?i)\bstale\s*=\s*"?true"?')


def offered_schemes(response: httpx.Response) -> tuple[str, ...]:
    """Scheme names from every ``WWW-Authenticate`` header (several headers or one combined)."""
    names: list[str] = []
    for header in response.headers.get_list("www-authenticate"):
        for match in _SCHEME_TOKEN.finditer(header):
            name = match.group(1).capitalize()
            if name not in names:
                names.append(name)
    return tuple(names)


def _digest_is_stale(response: httpx.Response) -> bool:
    return any(
        h.lower().startswith("digest") and _STALE.search(h)
        for h in response.headers.get_list("www-authenticate")
    )


class NegotiatingAuth(httpx.Auth):
    """An :class:`httpx.Auth` that negotiates Digest/Basic with the camera and remembers the result.

    Not shared between threads: give each ``httpx.Client`` its own instance (pass
    ``initial_scheme`` to skip re-negotiating a Basic camera).
    """

    def __init__(
        self,
        username: str | None,
        password: str | None,
        mode: AuthMode | str = AuthMode.AUTO,
        *,
        initial_scheme: AuthScheme | None = None,
    ) -> None:
        """Credentials are kept only inside this object and the ``httpx.DigestAuth`` it owns."""
        self._mode = AuthMode(mode)
        self._username = username
        self._password = password
        self._scheme: AuthScheme | None = initial_scheme if self.has_credentials else None
        self._basic: httpx.BasicAuth | None = None
        self._digest: httpx.DigestAuth | None = None
        if username is not None and password is not None:
            self._basic = httpx.BasicAuth(username, password)
            self._digest = httpx.DigestAuth(username, password)

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

    def _choose(self, offered: tuple[str, ...]) -> AuthScheme | None:
        if not self.has_credentials:
            return None
        digest = AuthScheme.DIGEST.value in offered
        basic = AuthScheme.BASIC.value in offered
        if self._mode is AuthMode.DIGEST:
            return AuthScheme.DIGEST if digest else None
        if self._mode is AuthMode.BASIC:
            return AuthScheme.BASIC if basic else None
        if digest:
            return AuthScheme.DIGEST
        return AuthScheme.BASIC if basic else None

    def _basic_flow(self, request: httpx.Request) -> Generator[httpx.Request, httpx.Response, None]:
        assert self._basic is not None  # noqa: S101 - guarded by has_credentials
        yield from self._basic.auth_flow(request)

    def _digest_flow(
        self, request: httpx.Request, challenge: httpx.Response | None
    ) -> Generator[httpx.Request, httpx.Response, None]:
        """Send with Digest; ``challenge`` is the 401 that just arrived (if any)."""
        assert self._digest is not None  # noqa: S101 - guarded by has_credentials
        inner = self._digest.auth_flow(request)
        outgoing = next(inner)  # carries Authorization if a previous challenge is cached
        if challenge is None:
            if "authorization" in outgoing.headers:
                response = yield outgoing
                if response.status_code != 401 or not _digest_is_stale(response):
                    return  # success, or credentials refused: one try only
            else:
                response = yield outgoing
                if response.status_code != 401:
                    return
            challenge = response
        try:
            retry = inner.send(challenge)
        except StopIteration:
            return  # the 401 carried no Digest challenge
        yield retry

    def auth_flow(self, request: httpx.Request) -> Generator[httpx.Request, httpx.Response, None]:
        """One exchange: at most one unauthenticated and one credentialed request (+1 on stale nonce)."""
        if not self.has_credentials:
            yield request
            return
        if self._scheme is AuthScheme.BASIC:
            yield from self._basic_flow(request)
            return
        if self._scheme is AuthScheme.DIGEST:
            yield from self._digest_flow(request, None)
            return
        response = yield request
        if response.status_code != 401:
            return
        chosen = self._choose(offered_schemes(response))
        if chosen is None:
            return
        self._scheme = chosen
        if chosen is AuthScheme.BASIC:
            yield from self._basic_flow(request)
            return
        yield from self._digest_flow(request, response)

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
        return f"auth mode {self._mode.value!r} not offered by the camera (camera offers {offer_text})"
