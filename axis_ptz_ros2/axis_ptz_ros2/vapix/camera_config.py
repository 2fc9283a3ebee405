"""Where and how to reach one camera (ROS-free): host, port, TLS, credentials, timeouts (reference ``vapix.md`` §2,
§3). The password is never shown in ``repr``."""

from __future__ import annotations

import os
import ssl
from dataclasses import dataclass, field

import httpx

from axis_ptz_ros2.vapix.auth import AuthMode
from axis_ptz_ros2.vapix.errors import InvalidArgument

__all__ = ["CameraConfig"]


@dataclass(frozen=True, slots=True)
class CameraConfig:
    """Where and how to reach the camera. ``password`` is never shown in ``repr``."""

    host: str = "127.0.0.1"
    port: int | None = None
    use_https: bool = False
    verify_tls: bool | str = True
    username: str | None = None
    password: str | None = field(default=None, repr=False)
    camera: int = 1
    timeout_s: float = 5.0
    connect_timeout_s: float = 2.0
    auth: str = "auto"

    def __post_init__(self) -> None:
        """Refuse configurations that cannot work (the request would never be sent)."""
        if not self.host or any(c in self.host for c in "/@?# "):
            raise InvalidArgument(f"host must be a bare host name or address, got {self.host!r}")
        if self.port is not None and not 0 < self.port < 65536:
            raise InvalidArgument(f"port must be 1..65535, got {self.port}")
        if self.camera < 1:
            raise InvalidArgument(f"camera must be >= 1, got {self.camera}")
        if self.timeout_s <= 0 or self.connect_timeout_s <= 0:
            raise InvalidArgument("timeouts must be positive")
        try:
            AuthMode(self.auth)
        except ValueError as err:
            modes = ", ".join(m.value for m in AuthMode)
            raise InvalidArgument(f"auth must be one of {modes}, got {self.auth!r}") from err
        if (self.username is None) != (self.password is None):
            raise InvalidArgument("username and password must be given together")

    @property
    def base_url(self) -> str:
        """``http://host[:port]`` without credentials (IPv6 literals bracketed)."""
        scheme = "https" if self.use_https else "http"
        host = f"[{self.host}]" if ":" in self.host and not self.host.startswith("[") else self.host
        return f"{scheme}://{host}" + (f":{self.port}" if self.port is not None else "")

    @property
    def tcp_port(self) -> int:
        """The TCP port the requests go to: ``port``, else the scheme's default (443 for HTTPS, else 80)."""
        if self.port is not None:
            return self.port
        return 443 if self.use_https else 80

    def ssl_verify(self) -> ssl.SSLContext | bool:
        """``verify_tls`` for httpx: a bool, or a CA file/directory turned into an SSL context."""
        if isinstance(self.verify_tls, bool):
            return self.verify_tls
        try:
            if os.path.isdir(self.verify_tls):
                return ssl.create_default_context(capath=self.verify_tls)
            return ssl.create_default_context(cafile=self.verify_tls)
        except (OSError, ssl.SSLError) as err:
            raise InvalidArgument(f"verify_tls: cannot load CA bundle {self.verify_tls!r} ({err})") from err

    def timeout(self, read_timeout_s: float | None = None) -> httpx.Timeout:
        """httpx timeout: connect from ``connect_timeout_s``, the rest from ``timeout_s``."""
        read = self.timeout_s if read_timeout_s is None else read_timeout_s
        return httpx.Timeout(self.timeout_s, connect=self.connect_timeout_s, read=read)
