"""HTTP authentication of the simulated camera: Basic and Digest (MD5, qop=auth), as an Axis camera does them.

One :class:`CameraAuth` per camera, independent of the protocol: the HTTP server uses it for VAPIX and an RTSP
server can share it (``check(header, method, uri)`` for any method and request target; the same nonces, realm
and 401 challenges). Reference: vapix.md §3. ROS-free, stdlib only. The password is never logged or shown.
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import re
import secrets
import threading
import time
from typing import Literal

AUTH_MODES = ("none", "basic", "digest", "basic_digest")
CHALLENGE_STYLES = ("current", "legacy")
NONCE_LIFETIME_S = 600.0  #: default Digest nonce lifetime (a guess: real Axis lifetimes are not documented)

Verdict = Literal["ok", "stale", "fail"]

_DIGEST_FIELD = re.compile(r'(\w+)=("([^"]*)"|([^,\s]*))')
_MAX_NONCES = 2000


def _md5(s: str) -> str:
    return hashlib.md5(s.encode("utf-8")).hexdigest()  # noqa: S324 - HTTP Digest is MD5 by definition


class CameraAuth:
    """Credentials, Digest nonces and 401 challenges of one camera (thread-safe).

    ``mode``: ``none`` (anonymous), ``basic``, ``digest`` or ``basic_digest``. Nonces are remembered with the
    time they were issued; a correct answer to one older than ``nonce_lifetime_s`` is ``stale``, to one never
    issued (or forgotten by :meth:`forget_nonces`, what a restart does) ``fail``.
    """

    def __init__(
        self,
        mode: str,
        realm: str,
        user: str,
        password: str,
        *,
        nonce_lifetime_s: float = NONCE_LIFETIME_S,
        challenge_style: str = "current",
    ) -> None:
        """Validate ``mode`` and the options."""
        if mode not in AUTH_MODES:
            raise ValueError(f"auth must be one of {AUTH_MODES}")
        self.mode = mode
        self.realm = realm
        self.user = user
        self._password = password
        self._nonces: dict[str, float] = {}
        self._lock = threading.Lock()
        self.nonce_lifetime_s = NONCE_LIFETIME_S
        self.challenge_style = "current"
        self.set_options(nonce_lifetime_s=nonce_lifetime_s, challenge_style=challenge_style)

    def __repr__(self) -> str:
        return f"CameraAuth(mode={self.mode!r}, realm={self.realm!r}, user={self.user!r})"

    def set_options(self, *, nonce_lifetime_s: float | None = None, challenge_style: str | None = None) -> None:
        """Digest nonce lifetime (seconds, > 0) and the 401 form: ``current`` (``algorithm=MD5, qop="auth"``,
        HTML body, ``stale=true`` only for an expired nonce) or ``legacy`` (older firmware: empty body,
        ``stale=FALSE`` or ``stale=TRUE`` always present, ``qop="auth"``, no ``algorithm``)."""
        if nonce_lifetime_s is not None:
            if not nonce_lifetime_s > 0:
                raise ValueError("nonce_lifetime_s must be > 0")
            self.nonce_lifetime_s = float(nonce_lifetime_s)
        if challenge_style is not None:
            if challenge_style not in CHALLENGE_STYLES:
                raise ValueError(f"challenge_style must be one of {CHALLENGE_STYLES}")
            self.challenge_style = challenge_style

    def forget_nonces(self) -> None:
        """What a restart does: every nonce handed out so far becomes unknown."""
        with self._lock:
            self._nonces.clear()

    def age_nonces(self, seconds: float) -> None:
        """Make every nonce issued so far ``seconds`` older (a test hook: expire them without waiting)."""
        with self._lock:
            for nonce in self._nonces:
                self._nonces[nonce] -= seconds

    def new_nonce(self) -> str:
        """A fresh nonce, remembered as issued now."""
        nonce = base64.b64encode(secrets.token_bytes(12)).decode() + hashlib.sha1(secrets.token_bytes(8)).hexdigest()
        now = time.monotonic()
        with self._lock:
            if len(self._nonces) > _MAX_NONCES:
                for k in [k for k, t in self._nonces.items() if now - t > self.nonce_lifetime_s]:
                    del self._nonces[k]
            self._nonces[nonce] = now
        return nonce

    def challenges(self, stale: bool = False) -> list[str]:
        """``WWW-Authenticate`` values for the mode (``stale``: the nonce sent had expired)."""
        out = []
        if self.mode in ("digest", "basic_digest"):
            nonce = self.new_nonce()
            if self.challenge_style == "legacy":
                flag = "TRUE" if stale else "FALSE"
                out.append(f'Digest realm="{self.realm}", nonce="{nonce}", stale={flag}, qop="auth"')
            else:
                tail = ", stale=true" if stale else ""
                out.append(f'Digest realm="{self.realm}", nonce="{nonce}", algorithm=MD5, qop="auth"{tail}')
        if self.mode in ("basic", "basic_digest"):
            out.append(f'Basic realm="{self.realm}"')
        return out

    def check(self, header: str | None, method: str, uri: str) -> Verdict:
        """``ok``, ``stale`` (a correct Digest response to an expired nonce) or ``fail`` for an ``Authorization``
        header of a request (``uri``: the request target exactly as sent, which is what a Digest client signs)."""
        if self.mode == "none":
            return "ok"
        if not header:
            return "fail"
        scheme, _, rest = header.partition(" ")
        scheme = scheme.lower()
        if scheme == "basic" and self.mode in ("basic", "basic_digest"):
            return self._check_basic(rest)
        if scheme == "digest" and self.mode in ("digest", "basic_digest"):
            return self._check_digest(rest, method, uri)
        return "fail"

    def _check_basic(self, rest: str) -> Verdict:
        try:
            user, _, pw = base64.b64decode(rest.strip(), validate=True).decode("utf-8").partition(":")
        except (ValueError, UnicodeDecodeError):
            return "fail"
        good = hmac.compare_digest(user, self.user) and hmac.compare_digest(pw.encode(), self._password.encode())
        return "ok" if good else "fail"

    def _check_digest(self, rest: str, method: str, uri: str) -> Verdict:
        f = {
            m.group(1).lower(): m.group(3) if m.group(3) is not None else m.group(4)
            for m in _DIGEST_FIELD.finditer(rest)
        }
        nonce = f.get("nonce", "")
        # The signed uri must be the request target as sent (e.g. "//axis-cgi/com/ptz.cgi?…"), not a
        # normalised path: that is what the client hashed.
        if f.get("username") != self.user or f.get("realm") != self.realm or f.get("uri") != uri:
            return "fail"
        algorithm = (f.get("algorithm") or "MD5").upper()
        if algorithm != "MD5":
            return "fail"
        ha1 = _md5(f"{self.user}:{self.realm}:{self._password}")
        ha2 = _md5(f"{method}:{uri}")
        qop = f.get("qop")
        if qop == "auth":
            expected = _md5(f"{ha1}:{nonce}:{f.get('nc', '')}:{f.get('cnonce', '')}:auth:{ha2}")
        elif qop is None:
            expected = _md5(f"{ha1}:{nonce}:{ha2}")
        else:
            return "fail"
        if not hmac.compare_digest(expected, f.get("response", "").lower()):
            return "fail"
        with self._lock:
            issued = self._nonces.get(nonce)
        if issued is None:
            return "fail"  # never issued, or forgotten by a restart
        if time.monotonic() - issued > self.nonce_lifetime_s:
            return "stale"
        return "ok"
