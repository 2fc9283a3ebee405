"""Raw MJPEG/image helpers for tests and benchmarks of the simulator (independent of the VAPIX client)."""

from __future__ import annotations

import re
import time

import cv2
import httpx
import numpy as np
import numpy.typing as npt

PART_HEADER = re.compile(rb"--myboundary\r\nContent-Type: image/jpeg\r\nContent-Length: (\d+)\r\n\r\n")
COM = re.compile(rb"\xff\xd8\xff\xfe..axsim seq=(\d+) t=(\d+)", re.S)


def read_stream(
    client: httpx.Client, url: str, max_seconds: float = 5.0, max_bytes: int = 50_000_000
) -> tuple[int, httpx.Headers, bytes, list[tuple[float, int]]]:
    """GET an MJPEG stream → (status, headers, raw body, [(arrival monotonic time, cumulative bytes)])."""
    chunks: list[bytes] = []
    marks: list[tuple[float, int]] = []
    total = 0
    t_end = time.monotonic() + max_seconds
    with client.stream("GET", url) as r:
        headers, status = r.headers, r.status_code
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


def parts(body: bytes) -> list[tuple[int, int]]:
    """Multipart parts as (announced Content-Length, offset of the JPEG) in stream order."""
    return [(int(m.group(1)), m.end()) for m in PART_HEADER.finditer(body)]


def decode(jpeg: bytes) -> npt.NDArray[np.uint8]:
    """Decode a JPEG to BGR."""
    img = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
    if img is None:
        raise ValueError("not a decodable JPEG")
    return np.asarray(img, dtype=np.uint8)


def blob(
    img: npt.NDArray[np.uint8], lo: tuple[int, int, int], hi: tuple[int, int, int]
) -> npt.NDArray[np.float64] | None:
    """Centroid (x, y) of the largest connected region with lo <= BGR <= hi, or None."""
    mask = cv2.inRange(img, np.array(lo), np.array(hi))
    n, _, stats, cent = cv2.connectedComponentsWithStats(mask)
    if n <= 1:
        return None
    k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return np.asarray(cent[k], dtype=np.float64)
