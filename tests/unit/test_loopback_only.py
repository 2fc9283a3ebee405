"""Nothing we ship points anywhere but loopback by default (the real camera's address lives in user config)."""

import ipaddress
import re
from pathlib import Path

import pytest
import yaml

from axis_ptz_ros2.vapix import CameraConfig
from tests.support.link import LINK_SUBNET

pytestmark = pytest.mark.unit

ROOT = Path(__file__).resolve().parents[2]
IPV4 = re.compile(r"(?<![\d.])(\d{1,3}\.\d{1,3}\.\d{1,3}\.\d{1,3})(?![\d.])")
# The thesis camera's factory address may be *documented* (README, the example parameter file), never a default.
DOCUMENTED_ONLY = {"192.168.0.90"}


def _addresses(text: str) -> set[str]:
    found = set()
    for m in IPV4.findall(text):
        try:
            ipaddress.IPv4Address(m)
        except ValueError:
            continue
        found.add(m)
    return found


# The two-host link (tests/netns, bench_link) gives its network namespaces addresses of one private subnet and
# routes multicast onto their veth; those exist only inside namespaces we create, and only that module names them.
NAMESPACE_ONLY = {"tests/support/link.py": (LINK_SUBNET, ipaddress.IPv4Network("224.0.0.0/4"))}


def _allowed(addr: str, path: Path | None = None) -> bool:
    ip = ipaddress.IPv4Address(addr)
    if path is not None and any(ip in net for net in NAMESPACE_ONLY.get(str(path.relative_to(ROOT)), ())):
        return True
    return ip.is_loopback or ip.is_unspecified


@pytest.mark.parametrize(
    "path",
    sorted(
        p
        for d in ("axis_ptz_ros2", "scripts", "bench", ".ci", "tests/netns", "tests/support")  # the two-host support
        for p in (ROOT / d).rglob("*")
        if p.is_file() and p.suffix in ("", ".py", ".sh", ".js", ".html")
    ),
    ids=lambda p: str(p.relative_to(ROOT)),
)
def test_code_contacts_only_loopback(path):
    bad = {a for a in _addresses(path.read_text(encoding="utf-8", errors="replace")) if not _allowed(a, path)}
    assert not bad, f"{path}: non-loopback address literal(s) {sorted(bad)}"


def test_config_files_default_to_loopback():
    for p in (ROOT / "config").glob("*.yaml"):
        text = p.read_text(encoding="utf-8")
        data = yaml.safe_load(text)
        bad = {a for a in _addresses(text) if not _allowed(a)} - DOCUMENTED_ONLY
        assert not bad, f"{p.name}: {sorted(bad)}"
        # the documented real-camera address may only appear in a file that is clearly a user example
        if _addresses(text) & DOCUMENTED_ONLY:
            assert "example" in p.name, f"{p.name} names the real camera's address but is not an example file"
        assert data is not None


def test_client_default_host_is_loopback():
    assert CameraConfig().host == "127.0.0.1"
    assert CameraConfig().base_url.startswith("http://127.0.0.1")
