"""Raw MJPEG helpers for the simulator integration tests (independent of the project's VAPIX client)."""

import re
import time

import cv2
import httpx
import numpy as np

PART_HEADER = re.compile(rb"--myboundary\r\nContent-Type: image/jpeg\r\nContent-Length: (\d+)\r\n\r\n")
COM = re.compile(rb"\xff\xd8\xff\xfe..axsim seq=(\d+) t=(\d+)", re.S)


def read_stream(client: httpx.Client, url: str, max_seconds: float = 5.0, max_bytes: int = 50_000_000):
    """GET an MJPEG stream; return (response headers, raw body bytes, [(arrival time, cumulative bytes)])."""
    chunks, marks, total = [], [], 0
    t_end = time.monotonic() + max_seconds
    with client.stream("GET", url) as r:
        headers = r.headers
        status = r.status_code
        try:
            for chunk in r.iter_raw():
                chunks.append(chunk)
                total += len(chunk)
                marks.append((time.monotonic(), total))
                if time.monotonic() > t_end or total > max_bytes:
                    break
        except (httpx.ReadError, httpx.RemoteProtocolError):
            pass
    return status, headers, b"".join(chunks), marks


def parts(body: bytes):
    """Parts as (announced length, start offset of the JPEG) in stream order."""
    return [(int(m.group(1)), m.end()) for m in PART_HEADER.finditer(body)]


def decode(jpeg: bytes):
    return cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)


def blob(img, lo, hi):
    """Centroid (x, y) of the largest connected region with lo <= BGR <= hi."""
    mask = cv2.inRange(img, np.array(lo), np.array(hi))
    n, _, stats, cent = cv2.connectedComponentsWithStats(mask)
    if n <= 1:
        return None
    k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return cent[k]
