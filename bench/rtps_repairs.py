"""Per second, how much of what a DDS writer sent over a link was a *repeat* of a fragment already sent.

A diagnosis tool for the weak-link benches (not a bench: it prints no README row). Capture what the robot sends on
its side of the link while a bench runs, with enough of each packet for the RTPS submessage headers:

    ip netns exec <robot namespace> tcpdump -i <robot veth> -s 200 -Q out -w robot.pcap udp

then

    .venv/bin/python bench/rtps_repairs.py robot.pcap [--port 17911]

prints, for each second of the capture, the kbit/s of RTPS DATA / DATA_FRAG submessages and the part of it whose
(writer, sequence number, fragment) had been sent before (repairs, including the duplicate repairs of fragments
that were still on their way), and the HEARTBEAT and GAP counts. ``--port`` keeps one UDP destination port (the
operator participant's user-traffic port: 7411 + 250 × domain + 2 × participant id; 17911 for ROS_DOMAIN_ID 42 and
the first participant).

What it found at 5c22257 (README, "First picture after a viewer starts"): on the healthy 2 Mbit/s + 2 % link an
H.264 stream of ~870 kbit/s went out at ~1,050 kbit/s with 0-80 kbit/s of repeats; in the starts that showed no
picture for 15 s the robot sent ~1,970 kbit/s (the link's rate) of which ~1,000-1,300 kbit/s were repeats, for as
long as the viewer stayed. Only RTPS over UDPv4 in Ethernet or raw-IP captures; nothing else is decoded.
"""

from __future__ import annotations

import argparse
import struct
import sys
from collections import Counter, defaultdict
from pathlib import Path

#: RTPS submessage ids (RTPS 2.x, 9.4.5.1.1)
HEARTBEAT, GAP, DATA, DATA_FRAG = 0x07, 0x08, 0x15, 0x16


def packets(path: Path) -> list[tuple[float, int, bytes]]:
    """(time [s], original length, IPv4 packet) of every packet of a classic pcap file."""
    raw = path.read_bytes()
    magic = struct.unpack("<I", raw[:4])[0]
    if magic not in (0xA1B2C3D4, 0xA1B23C4D):
        raise SystemExit(f"{path}: not a little-endian classic pcap file (pcapng: convert with tcpdump -r/-w)")
    scale = 1e-9 if magic == 0xA1B23C4D else 1e-6
    linktype = struct.unpack("<I", raw[20:24])[0]
    skip = {1: 14, 101: 0, 113: 16}.get(linktype)  # Ethernet, raw IP, Linux cooked
    if skip is None:
        raise SystemExit(f"{path}: link type {linktype} not handled")
    out, off = [], 24
    while off + 16 <= len(raw):
        sec, frac, caplen, origlen = struct.unpack("<IIII", raw[off : off + 16])
        out.append((sec + frac * scale, origlen, raw[off + 16 + skip : off + 16 + caplen]))
        off += 16 + caplen
    return out


def submessages(rtps: bytes) -> list[tuple[int, bool, bytes]]:
    """(id, little-endian, body) of each submessage present in the captured part of an RTPS message."""
    out, o = [], 20
    while o + 4 <= len(rtps):
        sid, flags = rtps[o], rtps[o + 1]
        little = bool(flags & 1)
        length = struct.unpack("<H" if little else ">H", rtps[o + 2 : o + 4])[0]
        out.append((sid, little, rtps[o + 4 : o + 4 + length] if length else rtps[o + 4 :]))
        if length == 0:  # the last submessage runs to the end of the message
            break
        o += 4 + length
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("pcap", type=Path)
    ap.add_argument("--port", type=int, default=0, help="only this UDP destination port (0 = all)")
    a = ap.parse_args()
    pkts = packets(a.pcap)
    if not pkts:
        print("no packets")
        return 1
    t0 = pkts[0][0]
    sent: defaultdict[int, int] = defaultdict(int)
    repeat: defaultdict[int, int] = defaultdict(int)
    kinds: defaultdict[int, Counter[int]] = defaultdict(Counter)
    seen: set[tuple[bytes, int, int]] = set()
    for t, origlen, ip in pkts:
        if len(ip) < 20 or ip[0] >> 4 != 4 or ip[9] != 17:
            continue
        ihl = (ip[0] & 15) * 4
        if a.port and struct.unpack(">H", ip[ihl + 2 : ihl + 4])[0] != a.port:
            continue
        rtps = ip[ihl + 8 :]
        if rtps[:4] != b"RTPS":
            continue
        second = int(t - t0)
        for sid, little, body in submessages(rtps):
            kinds[second][sid] += 1
            if sid not in (DATA, DATA_FRAG) or len(body) < 24:
                continue
            e = "<" if little else ">"
            writer = body[8:12]
            high, low = struct.unpack(e + "iI", body[12:20])
            frag = struct.unpack(e + "I", body[20:24])[0] if sid == DATA_FRAG else 0
            key = (writer, (high << 32) | low, frag)
            sent[second] += origlen
            if key in seen:
                repeat[second] += origlen
            seen.add(key)
    print("second  data kbit/s  repeated kbit/s  HEARTBEAT  GAP")
    for s in sorted(kinds):
        k = kinds[s]
        print(f"{s:6d}  {sent[s] * 8 / 1000:11.0f}  {repeat[s] * 8 / 1000:15.0f}  {k[HEARTBEAT]:9d}  {k[GAP]:3d}")
    total, dup = sum(sent.values()), sum(repeat.values())
    rate = total * 8 / 1000 / max(1, len(kinds))
    print(f"over the seconds with traffic: {rate:.0f} kbit/s of data, {100 * dup / max(1, total):.1f} % of it repeats")
    return 0


if __name__ == "__main__":
    sys.exit(main())
