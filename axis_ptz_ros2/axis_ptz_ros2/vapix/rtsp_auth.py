"""Digest for RTSP: :class:`~axis_ptz_ros2.vapix.auth.NegotiatingAuth` signing the absolute request URL.

An RTSP request line carries the absolute URL (``DESCRIBE rtsp://host:554/axis-media/media.amp?… RTSP/1.0``,
RFC 2326 §6.1) and RTSP clients (FFmpeg, live555, GStreamer) put that URL in the Digest ``uri`` field; a server
that checks ``uri`` against the request (the simulated camera does, as on its HTTP side) refuses a response
signed over the path alone. :class:`NegotiatingAuth` signs ``request.url.raw_path`` (right for HTTP); this
subclass signs :attr:`RtspDigestAuth.rtsp_uri` instead. Everything else (scheme choice, stale nonces, one retry)
is the HTTP side's.
"""

from __future__ import annotations

import httpx

from axis_ptz_ros2.vapix.auth import Challenge, NegotiatingAuth


class _RawUrl:
    """Just enough of :class:`httpx.URL` for the Digest signer: ``raw_path`` is the whole RTSP URL."""

    def __init__(self, uri: str) -> None:
        self.raw_path = uri.encode("ascii")
        self.scheme = "rtsp"


class RtspDigestAuth(NegotiatingAuth):
    """Set :attr:`rtsp_uri` to the request's URL before each ``auth_flow``."""

    rtsp_uri = ""

    def _digest_header(self, request: httpx.Request, challenge: Challenge) -> str | None:
        signed = httpx.Request(request.method, "http://rtsp.invalid/")
        signed.url = _RawUrl(self.rtsp_uri)  # type: ignore[assignment]
        return super()._digest_header(signed, challenge)
