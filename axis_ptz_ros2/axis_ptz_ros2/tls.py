"""Self-signed TLS certificates and server contexts, shared by the web console and the simulated camera (ROS-free).

One helper on the ``cryptography`` library: :func:`self_signed` makes a certificate + key (PEM) for a set of DNS
names and IP addresses, :func:`server_context` loads a pair into a TLS 1.2+ server context, :func:`write_private`
writes a key readable by its owner only, :func:`fingerprint_sha256` is what browsers show. Policy (which names,
how long, where a certificate is kept) stays with the caller (``web/tls.py``, ``sim/tls.py``).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import ipaddress
import os
import ssl
from collections.abc import Sequence
from pathlib import Path

__all__ = ["fingerprint_sha256", "self_signed", "server_context", "write_private"]


def fingerprint_sha256(cert_pem_or_der: bytes) -> str:
    """``AB:CD:…`` SHA-256 of the certificate's DER encoding (what browsers show as the fingerprint)."""
    der = cert_pem_or_der
    if cert_pem_or_der.lstrip().startswith(b"-----BEGIN"):
        der = ssl.PEM_cert_to_DER_cert(cert_pem_or_der.decode("ascii"))
    return ":".join(f"{b:02X}" for b in hashlib.sha256(der).digest())


def self_signed(
    common_name: str,
    dns: Sequence[str],
    ips: Sequence[str],
    *,
    days: int,
    organization: str = "",
    ca: bool = False,
    rsa_bits: int = 0,
) -> tuple[bytes, bytes]:
    """A new self-signed server certificate: (cert PEM, unencrypted PKCS#8 key PEM).

    Names ``dns`` + ``ips`` (subjectAltName), valid from 5 minutes ago for ``days``, SHA-256 signature, EC P-256
    key (``rsa_bits`` > 0: an RSA key of that size, as cameras use). ``ca``: the certificate may also sign (a
    client can then use it as its CA bundle directly).
    """
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec, rsa
    from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

    key: ec.EllipticCurvePrivateKey | rsa.RSAPrivateKey
    key = rsa.generate_private_key(65537, rsa_bits) if rsa_bits > 0 else ec.generate_private_key(ec.SECP256R1())
    attrs = [x509.NameAttribute(NameOID.ORGANIZATION_NAME, organization)] if organization else []
    name = x509.Name([*attrs, x509.NameAttribute(NameOID.COMMON_NAME, common_name)])
    now = dt.datetime.now(dt.UTC)
    san = [x509.DNSName(d) for d in dns] + [x509.IPAddress(ipaddress.ip_address(i)) for i in ips]
    cert = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=days))
        .add_extension(x509.SubjectAlternativeName(san), critical=False)
        .add_extension(x509.BasicConstraints(ca=ca, path_length=None), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True,
                content_commitment=False,
                key_encipherment=rsa_bits > 0,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=ca,
                crl_sign=False,
                encipher_only=False,
                decipher_only=False,
            ),  # fmt: skip
            critical=True,
        )
        .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH]), critical=False)
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .add_extension(x509.AuthorityKeyIdentifier.from_issuer_public_key(key.public_key()), critical=False)
        .sign(key, hashes.SHA256())
    )
    cert_pem = cert.public_bytes(serialization.Encoding.PEM)
    key_pem = key.private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
    )
    return cert_pem, key_pem


def server_context(cert_path: Path, key_path: Path) -> ssl.SSLContext:
    """A TLS (1.2 or newer) server context with this certificate and key (PEM files)."""
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    ctx.minimum_version = ssl.TLSVersion.TLSv1_2
    ctx.load_cert_chain(str(cert_path), str(key_path))
    return ctx


def write_private(path: Path, data: bytes) -> None:
    """Write a key readable by its owner only (created 0600, never world-readable even briefly)."""
    tmp = path.with_name(path.name + ".tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    tmp.replace(path)
