"""A self-signed TLS certificate for the simulated camera's HTTPS (ROS-free).

Current Axis cameras serve HTTPS by default with a self-signed certificate (vapix.md §3). The simulator
generates one at start-up with the ``openssl`` command-line tool into a private temporary directory: an
RSA-2048 key and an X.509 certificate for the bind address (IP and DNS subjectAltName, plus ``localhost`` and
127.0.0.1), valid for 30 days. Clients verify it by using :attr:`SelfSignedCertificate.cert_file` as their CA.
"""

from __future__ import annotations

import ipaddress
import shutil
import ssl
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class SelfSignedCertificate:
    """Key and certificate files in a private temporary directory (removed by :meth:`cleanup`)."""

    directory: Path
    cert_file: Path
    key_file: Path

    @staticmethod
    def generate(host: str, serial: str) -> SelfSignedCertificate:
        """Generate a certificate for ``host`` (CN ``AXIS_<serial>``, as an Axis camera names itself)."""
        openssl = shutil.which("openssl")
        if openssl is None:
            raise RuntimeError("HTTPS needs the 'openssl' command (Debian package openssl) to make a certificate")
        names = {"DNS:localhost", "IP:127.0.0.1"}
        try:
            ipaddress.ip_address(host)
            names.add(f"IP:{host}")
        except ValueError:
            names.add(f"DNS:{host}")
        directory = Path(tempfile.mkdtemp(prefix="axis_sim_tls_"))
        cert, key = directory / "camera-cert.pem", directory / "camera-key.pem"
        cmd = [
            openssl,
            "req",
            "-x509",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-sha256",
            "-days",
            "30",
            "-subj",
            f"/O=Axis Communications AB/CN=AXIS_{serial}",
            "-addext",
            "subjectAltName=" + ",".join(sorted(names)),
            "-addext",
            "basicConstraints=critical,CA:TRUE",
            "-keyout",
            str(key),
            "-out",
            str(cert),
        ]
        try:
            subprocess.run(cmd, check=True, capture_output=True, timeout=60)  # noqa: S603 - fixed argv
        except (OSError, subprocess.SubprocessError) as err:
            shutil.rmtree(directory, ignore_errors=True)
            raise RuntimeError(f"could not generate the simulator's TLS certificate: {err}") from err
        return SelfSignedCertificate(directory, cert, key)

    def server_context(self) -> ssl.SSLContext:
        """A TLS server context with this certificate."""
        ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
        ctx.minimum_version = ssl.TLSVersion.TLSv1_2
        ctx.load_cert_chain(str(self.cert_file), str(self.key_file))
        return ctx

    def cleanup(self) -> None:
        """Delete the key and certificate."""
        shutil.rmtree(self.directory, ignore_errors=True)
