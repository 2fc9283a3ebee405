"""Exceptions of the VAPIX client and the one place that maps HTTP failures onto them.

Implements the error handling of VAPIX (reference ``vapix.md`` §4.3 "Error responses", §3
"Authentication", §6 param.cgi ``# Error:`` lines and §12 "Driver robustness checklist")::

    AxisPtzError                      (base: the ROS layer catches only this)
     +-- CameraUnreachable            connection refused / reset / DNS / dropped mid-response
     +-- CameraTimeout                connect, read, write or pool timeout
     +-- AuthError                    401/403 after scheme negotiation (never contains the password)
     +-- CommandRejected              2xx whose body is an ``Error:`` text; ``camera_message``
     +-- HttpStatusError              any other non-2xx status; ``status_code``
     +-- ResponseParseError           a reply that does not have the documented shape
     +-- InvalidArgument(ValueError)  client-side validation failed; the request was never sent

Messages name the request only by method and path+query (never scheme, host userinfo or
credentials); :func:`redact` additionally removes configured secrets from any text we forward.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

import httpx

__all__ = [
    "AuthError",
    "AxisPtzError",
    "CameraTimeout",
    "CameraUnreachable",
    "CommandRejected",
    "HttpStatusError",
    "InvalidArgument",
    "ResponseParseError",
    "check_status",
    "describe_request",
    "map_httpx_error",
    "redact",
]


class AxisPtzError(Exception):
    """Base class of every error raised by :mod:`axis_ptz_ros2.vapix`."""


class CameraUnreachable(AxisPtzError):  # noqa: N818 - names fixed by the project API
    """The camera could not be reached (refused, reset, unknown host, connection dropped)."""


class CameraTimeout(AxisPtzError):  # noqa: N818 - names fixed by the project API
    """The camera did not answer in time (connect, read, write or pool timeout)."""


class AuthError(AxisPtzError):
    """The camera refused our credentials (401) or our rights (403) after negotiation."""


class CommandRejected(AxisPtzError):  # noqa: N818 - names fixed by the project API
    """The camera answered 2xx with an ``Error:`` body (VAPIX §4.3) or a ``# Error:`` line (§6)."""

    def __init__(self, message: str, *, camera_message: str) -> None:
        """Keep the camera's own text in :attr:`camera_message`."""
        super().__init__(message)
        self.camera_message = camera_message


class HttpStatusError(AxisPtzError):
    """A non-2xx status other than 401/403 (e.g. 404 for a CGI the firmware lacks)."""

    def __init__(self, message: str, *, status_code: int) -> None:
        """Keep the HTTP status in :attr:`status_code`."""
        super().__init__(message)
        self.status_code = status_code


class ResponseParseError(AxisPtzError):
    """The reply does not have the documented shape (missing keys, bad numbers, wrong type)."""


class InvalidArgument(AxisPtzError, ValueError):  # noqa: N818 - names fixed by the project API
    """Client-side validation failed; the request was not sent to the camera."""


_USERINFO = re.compile(r"(?i)\b([a-z][a-z0-9+.-]*://)[^/@\s]*@")


def redact(text: str, secrets: Iterable[str | None] = ()) -> str:
    """Remove ``user:pass@`` URL userinfo and every non-empty secret from ``text``."""
    text = _USERINFO.sub(r"\1", text)
    for secret in secrets:
        if secret:
            text = text.replace(secret, "***")
    return text


def describe_request(request: httpx.Request) -> str:
    """``"GET /axis-cgi/com/ptz.cgi?query=position"``: method plus path+query, nothing else."""
    return f"{request.method} {request.url.raw_path.decode('ascii', 'replace')}"


def _target(request: httpx.Request | None) -> str:
    if request is None:
        return "request"
    port = request.url.port
    host = request.url.host + (f":{port}" if port is not None else "")
    return f"{describe_request(request)} (camera {host})"


def map_httpx_error(err: httpx.HTTPError, secrets: Iterable[str | None] = ()) -> AxisPtzError:
    """Translate an httpx exception into our hierarchy (raise the result ``from err``)."""
    try:
        request: httpx.Request | None = err.request
    except RuntimeError:  # httpx raises when the exception carries no request
        request = None
    detail = redact(f"{type(err).__name__}: {err}", secrets)
    where = _target(request)
    if isinstance(err, httpx.TimeoutException):
        return CameraTimeout(f"{where}: camera did not answer in time ({detail})")
    if isinstance(err, httpx.DecodingError):
        return ResponseParseError(f"{where}: undecodable reply ({detail})")
    if isinstance(err, httpx.ProtocolError | httpx.NetworkError | httpx.ProxyError):
        return CameraUnreachable(f"{where}: camera unreachable ({detail})")
    if isinstance(err, httpx.UnsupportedProtocol):
        return InvalidArgument(f"{where}: unsupported URL scheme ({detail})")
    return AxisPtzError(f"{where}: HTTP failure ({detail})")


def check_status(response: httpx.Response, *, auth_hint: str = "") -> None:
    """Raise :class:`AuthError` for 401/403 and :class:`HttpStatusError` for other non-2xx.

    ``auth_hint`` is appended to authentication failures (which scheme was tried, which ones
    the camera offers); it must never contain a password.
    """
    status = response.status_code
    if 200 <= status < 300:
        return
    where = describe_request(response.request)
    if status in (401, 403):
        reason = "authentication failed" if status == 401 else "access forbidden for this user"
        hint = f": {auth_hint}" if auth_hint else ""
        raise AuthError(f"{where}: HTTP {status}, {reason}{hint}")
    raise HttpStatusError(f"{where}: HTTP {status} {response.reason_phrase}".rstrip(), status_code=status)
