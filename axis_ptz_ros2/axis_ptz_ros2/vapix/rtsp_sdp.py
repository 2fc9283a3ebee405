"""What an Axis camera's RTSP answers describe, parsed (ROS-free): the H.264 media of a DESCRIBE's SDP, the
``Transport`` of a SETUP reply, the ``RTP-Info`` of a PLAY reply; and the errors for what this driver cannot play
(no H.264 video offered, UDP transport), which name what the camera offered instead.
"""

from __future__ import annotations

from typing import Final

from axis_ptz_ros2.vapix.errors import ResponseParseError

UDP_TRANSPORT: Final = "camera answered SETUP with UDP transport; only RTP over the RTSP TCP connection is supported"
_STATIC_PAYLOADS: Final = {0: "PCMU/8000", 8: "PCMA/8000", 14: "MPA/90000", 26: "JPEG/90000", 32: "MPV/90000"}


class RtspUnsupportedError(ResponseParseError):
    """The camera answered, but with something this client cannot play (retrying does not help)."""


class NoH264VideoError(RtspUnsupportedError):
    """The SDP holds no H.264 video media (``m=video`` with ``a=rtpmap:<pt> H264/90000``); the message names
    what the camera offers."""


class UdpTransportError(RtspUnsupportedError):
    """The camera answered SETUP with UDP transport (no ``interleaved=``)."""


def rtp_info_seq(rtp_info: str) -> int | None:
    """``seq=`` of the first stream in an ``RTP-Info`` header (None if absent)."""
    for item in rtp_info.split(",")[0].split(";"):
        k, _, v = item.strip().partition("=")
        if k.lower() == "seq" and v.isascii() and v.isdigit() and len(v) <= 5 and int(v) <= 0xFFFF:
            return int(v)  # a 16-bit sequence number; anything else is not one (and is not wrapped into one)
    return None


def udp_transport(transport: str) -> bool:
    """Whether a SETUP reply's ``Transport`` is UDP: no ``interleaved=``, and no ``/TCP`` profile (or ports)."""
    t = transport.lower().replace(" ", "")
    if not t or "interleaved=" in t:
        return False
    return not t.split(";")[0].endswith("/tcp") or "client_port=" in t or "server_port=" in t


def interleaved_channels(transport: str) -> tuple[int, int]:
    """The RTP and RTCP channels the server chose (``interleaved=a-b``; default 0-1)."""
    for item in transport.split(";"):
        k, _, v = item.strip().partition("=")
        a, _, b = v.partition("-")
        if k.lower() == "interleaved":
            rtp = int(a) if a.isascii() and a.isdigit() and len(a) <= 3 else -1
            rtcp = (int(b) if b.isascii() and b.isdigit() and len(b) <= 3 else -1) if b else rtp + 1
            if not (0 <= rtp <= 255 and 0 <= rtcp <= 255):  # one byte in the '$' framing (RFC 2326 §10.12)
                raise ResponseParseError(f"Transport: interleaved={v[:20]!r} is not a channel pair in 0..255")
            return rtp, rtcp
    return 0, 1


def h264_media(sdp: str, where: str) -> tuple[str, int]:
    """``(a=control, payload type)`` of the first H.264 video media of an SDP (``m=video`` with
    ``a=rtpmap:<pt> H264/90000``); :class:`NoH264VideoError` naming what the SDP offers instead."""
    sections: list[tuple[str, list[str], dict[str, str], str]] = []  # (media, payload types, rtpmaps, control)
    for line in sdp.splitlines():
        line = line.strip()
        if line.startswith("m="):
            fields = line[2:].split()
            sections.append((fields[0] if fields else "?", fields[3:], {}, ""))
        elif sections and line.startswith("a=rtpmap:"):
            pt, _, encoding = line[len("a=rtpmap:") :].partition(" ")
            sections[-1][2][pt.strip()] = encoding.strip()
        elif sections and line.startswith("a=control:"):
            media, pts, maps, _ = sections[-1]
            sections[-1] = (media, pts, maps, line[len("a=control:") :].strip())
    offers = []
    for media, pts, maps, control in sections:
        for pt in pts:
            encoding = maps.get(pt, "")
            name, _, rate = encoding.partition("/")
            if media == "video" and name.upper() == "H264" and rate.split("/")[0] == "90000" and pt.isdigit():
                return control, int(pt) & 0x7F
        kinds = [maps.get(pt) or (_STATIC_PAYLOADS.get(int(pt), "") if pt.isdigit() else "") for pt in pts]
        what = " ".join(dict.fromkeys(k for k in kinds if k)) or ("payload " + ",".join(pts) if pts else "")
        note = " (event stream)" if media == "application" else ""
        offers.append(f"m={media}" + (f" {what}" if what else "") + note)
    offered = "; ".join(offers)[:300] if offers else "no media at all (an empty or non-SDP DESCRIBE answer)"
    raise NoH264VideoError(f"{where}: the camera offers no H.264 video: {offered}")


def sdp_control(sdp: str, *, video: bool) -> str:
    """The ``a=control`` of the first video media section (``video``) or of the session ("" if none)."""
    section = "session"
    for line in sdp.splitlines():
        if line.startswith("m="):
            if section == "video" or not video:
                break
            section = "video" if line.startswith("m=video") else "other"
        elif line.startswith("a=control:") and section == ("video" if video else "session"):
            return line[len("a=control:") :].strip()
    return ""
