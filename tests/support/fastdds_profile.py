"""The shipped weak-link Fast DDS profile (``config/fastdds_weak_link.xml``) as the tests read it: the XML, not
loaded into Fast DDS."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

PROFILE = Path(__file__).resolve().parents[2] / "config" / "fastdds_weak_link.xml"
NS = {"f": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}


def root() -> ET.Element:
    """The profile's root element."""
    return ET.parse(PROFILE).getroot()


def flow_controllers() -> list[ET.Element]:
    """The flow controllers declared in the default participant profile."""
    defaults = [p for p in root().iterfind(".//f:participant", NS) if p.get("is_default_profile") == "true"]
    assert len(defaults) == 1, f"{len(defaults)} default participant profiles"
    return defaults[0].findall(".//f:flow_controller_descriptor", NS)


def pace(controller: ET.Element) -> tuple[int, float]:
    """A flow controller's (bytes per period, period in s)."""
    nbytes = int(controller.findtext("f:max_bytes_per_period", namespaces=NS) or 0)
    return nbytes, int(controller.findtext("f:period_ms", namespaces=NS) or 0) / 1000
