"""The shipped weak-link Fast DDS profile (``config/fastdds_weak_link.xml``) keeps the settings the weak-link
benches measured for the H.264 writers. ROS-free: the XML is read, not loaded into Fast DDS."""

from __future__ import annotations

import xml.etree.ElementTree as ET

from tests.support.fastdds_profile import NS, PROFILE, flow_controllers, pace

H264_WRITERS = ("/image_raw/ffmpeg", "/image_raw/foxglove")  # the stream node's H.264 topics (nodes/stream_node.py)


def _writer(name: str) -> ET.Element:
    root = ET.parse(PROFILE).getroot()
    found = [w for w in root.iterfind(".//f:data_writer", NS) if w.get("profile_name") == name]
    assert len(found) == 1, f"{name}: {len(found)} data_writer profiles"
    return found[0]


def _duration(parent: ET.Element, path: str) -> tuple[str | None, str | None]:
    """(sec, nanosec) of the duration element at ``path`` under ``parent``."""
    el = parent.find(path, NS)
    assert el is not None, path
    return el.findtext("f:sec", namespaces=NS), el.findtext("f:nanosec", namespaces=NS)


def test_h264_writers_repair_on_a_50_ms_heartbeat_without_piggybacked_heartbeats():
    """A heartbeat on every sample of a full keep-last history made the reader NACK fragments still queued on the
    link, and the re-sends swamped it (README, "First picture after a viewer starts"); the periodic 50 ms heartbeat
    alone asks for repairs in time."""
    for name in H264_WRITERS:
        w = _writer(name)
        assert w.findtext("f:qos/f:disable_heartbeat_piggyback", namespaces=NS) == "true", name
        assert _duration(w, "f:times/f:heartbeatPeriod") == ("0", "50000000"), name


def test_service_requests_and_replies_repair_on_a_50_ms_heartbeat():
    """rmw_fastrtps applies the profile ``client`` to every client's request writer and ``service`` to every server's
    reply writer (unless one is named after the mangled topic): a request datagram lost on the link otherwise waited
    for the default 3 s heartbeat (one still call in each of two six-still runs answered 3.0 s late)."""
    for name in ("client", "service"):
        assert _duration(_writer(name), "f:times/f:heartbeatPeriod") == ("0", "50000000"), name


def test_participants_announce_themselves_every_half_second():
    """A participant's one announcement to a newcomer lost on the link left the newcomer waiting for the next
    periodic one (3 s by default): first pictures up to 3.5 s after a viewer's start (README, "First picture after
    a viewer starts"). The default participant profile announces every 0.5 s."""
    root = ET.parse(PROFILE).getroot()
    defaults = [p for p in root.iterfind(".//f:participant", NS) if p.get("is_default_profile") == "true"]
    assert len(defaults) == 1
    assert _duration(defaults[0], "f:rtps/f:builtin/f:discovery_config/f:leaseAnnouncement") == ("0", "500000000")


def test_only_the_still_writer_is_paced_and_its_pace_leaves_the_live_video_room():
    """With ``RMW_FASTRTPS_PUBLICATION_MODE=AUTO`` every writer publishes as the profile says: only still/compressed
    names a publish mode (asynchronous, behind a flow controller declared in the default participant profile); the
    others keep Fast DDS's synchronous default. The pace is under a 2 Mbit/s link (the live video keeps room)."""
    root = ET.parse(PROFILE).getroot()
    modes = {w.get("profile_name"): w.find("f:qos/f:publishMode", NS) for w in root.iterfind(".//f:data_writer", NS)}
    assert {name for name, mode in modes.items() if mode is not None} == {"/still/compressed"}
    mode = modes["/still/compressed"]
    assert mode is not None
    assert mode.findtext("f:kind", namespaces=NS) == "ASYNCHRONOUS"
    controllers = flow_controllers()
    assert [c.findtext("f:name", namespaces=NS) for c in controllers] == [
        mode.findtext("f:flow_controller_name", namespaces=NS)
    ]
    nbytes, period_s = pace(controllers[0])
    assert nbytes >= 1400, "a period must carry at least one datagram (maxMessageSize 1400)"
    assert 0.5e6 <= nbytes * 8 / period_s < 2.0e6
