"""A self-signed TLS certificate for the simulated camera's HTTPS (ROS-free).

Current Axis cameras serve HTTPS by default with a self-signed certificate (vapix.md §3). The simulator
generates one at start-up (:func:`axis_ptz_ros2.tls.self_signed`, the helper the web console uses too) into a
private temporary directory: an RSA-2048 key and an X.509 certificate for the bind address (IP or DNS
subjectAltName, plus ``localhost`` and 127.0.0.1), valid for 30 days, usable as its own CA. Clients verify it by
using :attr:`SelfSignedCertificate.cert_file` as their CA.
"""

from __future__ import annotations

import ipaddress
import shutil
import ssl
import tempfile
from dataclasses import dataclass
from pathlib import Path

from axis_ptz_ros2.tls import self_signed, server_context, write_private


@dataclass(frozen=True)
class SelfSignedCertificate:
    """Key and certificate files in a private temporary directory (removed by :meth:`cleanup`)."""

    directory: Path
    cert_file: Path
    key_file: Path

    @staticmethod
    def generate(host: str, serial: str) -> SelfSignedCertificate:
        """Generate a certificate for ``host`` (CN ``AXIS_<serial>``, as an Axis camera names itself)."""
        dns, ips = ["localhost"], ["127.0.0.1"]
        try:
            ipaddress.ip_address(host)
        except ValueError:
            dns.append(host)
        else:
            if host not in ips:
                ips.append(host)
        cert_pem, key_pem = self_signed(
            f"AXIS_{serial}", dns, ips, days=30, organization="Axis Communications AB", ca=True, rsa_bits=2048
        )
        directory = Path(tempfile.mkdtemp(prefix="axis_sim_tls_"))
        cert, key = directory / "camera-cert.pem", directory / "camera-key.pem"
        cert.write_bytes(cert_pem)
        write_private(key, key_pem)
        return SelfSignedCertificate(directory, cert, key)

    def server_context(self) -> ssl.SSLContext:
        """A TLS server context with this certificate."""
        return server_context(self.cert_file, self.key_file)

    def cleanup(self) -> None:
        """Delete the key and certificate."""
        shutil.rmtree(self.directory, ignore_errors=True)
