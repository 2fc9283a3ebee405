"""TLS for the web console (ROS-free): the server context, a generated self-signed certificate, fingerprints.

Off loopback the console serves HTTPS. The operator either gives a certificate + key (files, PEM) or lets the
console generate a self-signed one (EC P-256, SHA-256 signature) whose SHA-256 fingerprint is logged, so it can
be compared with what the browser shows before trusting it. A generated certificate is kept in a directory when
one is given (the fingerprint then survives restarts), else it lives only as long as the process (a new one,
with a new fingerprint, at every start).
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import socket
import ssl
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from axis_ptz_ros2.tls import fingerprint_sha256, self_signed, server_context, write_private

__all__ = ["TlsIdentity", "fingerprint_sha256", "generate_self_signed", "load_identity"]

#: a generated certificate is renewed when it expires within this many days
RENEW_DAYS = 7
#: validity of a generated certificate (days)
VALID_DAYS = 365


@dataclass(frozen=True)
class TlsIdentity:
    """A loaded server certificate: the SSL context, its PEM (public part only) and SHA-256 fingerprint."""

    context: ssl.SSLContext
    cert_pem: bytes
    fingerprint: str
    generated: bool
    cert_path: Path | None


def _names_for(bind: str) -> tuple[list[str], list[str]]:
    """(DNS names, IP addresses) a generated certificate covers for a bind address."""
    dns = ["localhost"]
    ips = ["127.0.0.1", "::1"]
    host = socket.gethostname()
    if host and host not in dns:
        dns.append(host)
    b = bind.strip("[]")
    try:
        ip = ipaddress.ip_address(b)
    except ValueError:
        if b and b not in dns:
            dns.append(b)
    else:
        if not ip.is_unspecified and str(ip) not in ips:
            ips.append(str(ip))
    return dns, ips


def generate_self_signed(bind: str) -> tuple[bytes, bytes]:
    """A new self-signed server certificate for ``bind`` (+ localhost): (cert PEM, unencrypted key PEM)."""
    dns, ips = _names_for(bind)
    return self_signed(f"axis_web_console {dns[-1]}", dns, ips, days=VALID_DAYS)


def _expires(cert: Any) -> dt.datetime:
    """The certificate's end of validity, aware (UTC). ``not_valid_after_utc`` is cryptography 42+; Ubuntu 24.04
    ships 41, whose naive ``not_valid_after`` is UTC (and deprecated from 42 on)."""
    utc = getattr(cert, "not_valid_after_utc", None)
    if isinstance(utc, dt.datetime):
        return utc
    naive: dt.datetime = cert.not_valid_after
    return naive.replace(tzinfo=dt.UTC)


def _still_valid(cert_pem: bytes, bind: str) -> bool:
    """True when a kept certificate is not about to expire and still names ``bind``."""
    from cryptography import x509

    try:
        cert = x509.load_pem_x509_certificate(cert_pem)
        san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    except (ValueError, x509.ExtensionNotFound):
        return False
    if _expires(cert) - dt.datetime.now(dt.UTC) < dt.timedelta(days=RENEW_DAYS):
        return False
    dns, ips = _names_for(bind)
    have_ips = {str(i) for i in san.get_values_for_type(x509.IPAddress)}
    have_dns = set(san.get_values_for_type(x509.DNSName))
    return set(ips) <= have_ips and set(dns) <= have_dns


def _context(cert_path: Path, key_path: Path) -> ssl.SSLContext:
    try:
        return server_context(cert_path, key_path)
    except (ssl.SSLError, OSError) as err:
        # never echo file contents; the paths are the operator's own parameters
        raise ValueError(f"cannot load the TLS certificate {cert_path} / key {key_path}: {err}") from None


def load_identity(cert_file: str, key_file: str, bind: str, keep_dir: str = "") -> TlsIdentity:
    """The server's TLS identity: the operator's files, or a generated self-signed certificate.

    ``cert_file`` + ``key_file`` (PEM) take precedence (both or neither). Otherwise a certificate is generated;
    with ``keep_dir`` it is stored there (``console-cert.pem``, ``console-key.pem`` mode 0600) and reused while
    valid, else it is written to a private temporary directory that is removed once loaded.
    """
    if bool(cert_file) != bool(key_file):
        raise ValueError("tls_cert_file and tls_key_file go together: give both or neither")
    if cert_file:
        cert_path, key_path = Path(cert_file).expanduser(), Path(key_file).expanduser()
        ctx = _context(cert_path, key_path)
        pem = cert_path.read_bytes()
        return TlsIdentity(ctx, pem, fingerprint_sha256(pem), False, cert_path)
    if keep_dir:
        d = Path(keep_dir).expanduser()
        d.mkdir(parents=True, exist_ok=True, mode=0o700)
        cert_path, key_path = d / "console-cert.pem", d / "console-key.pem"
        if not (cert_path.is_file() and key_path.is_file() and _still_valid(cert_path.read_bytes(), bind)):
            cert_pem, key_pem = generate_self_signed(bind)
            write_private(key_path, key_pem)
            cert_path.write_bytes(cert_pem)
        pem = cert_path.read_bytes()
        return TlsIdentity(_context(cert_path, key_path), pem, fingerprint_sha256(pem), True, cert_path)
    cert_pem, key_pem = generate_self_signed(bind)
    with tempfile.TemporaryDirectory(prefix="axis_console_tls_") as tmp:
        cert_path, key_path = Path(tmp) / "cert.pem", Path(tmp) / "key.pem"
        cert_path.write_bytes(cert_pem)
        write_private(key_path, key_pem)
        ctx = _context(cert_path, key_path)
    return TlsIdentity(ctx, cert_pem, fingerprint_sha256(cert_pem), True, None)
