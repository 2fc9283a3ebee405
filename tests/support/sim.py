"""Raw MJPEG/image helpers for tests and benchmarks of the simulator.

:func:`frames` splits a stream with the driver's own parser (:class:`axis_ptz_ros2.vapix.mjpeg.MjpegParser`), which
hides what a fault did on the wire. The fault tests need exactly that, so :func:`parts` and :data:`PART_HEADER`
find the part headers as written (:func:`axis_ptz_ros2.vapix.mjpeg.part_header`, with the simulator's boundary)
and report each announced ``Content-Length`` with its offset, even when it is wrong.
"""

from __future__ import annotations

import re
import time

import cv2
import httpx
import numpy as np
import numpy.typing as npt

from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.sim.faults import FaultConfig
from axis_ptz_ros2.sim.http.mjpeg import BOUNDARY
from axis_ptz_ros2.vapix.mjpeg import MjpegParser, boundary_from_content_type, multipart_content_type, part_header
from tests.support.waiting import wait_until

#: the simulator's ``Content-Type`` for video.cgi
CONTENT_TYPE = multipart_content_type(BOUNDARY)


def part_header_pattern(boundary: str) -> re.Pattern[bytes]:
    """A pattern of the part headers :func:`part_header` writes, the ``Content-Length`` value as group 1."""
    prefix, _, suffix = part_header(boundary, 0).rpartition(b"0")
    return re.compile(re.escape(prefix) + rb"(\d+)" + re.escape(suffix))


PART_HEADER = part_header_pattern(BOUNDARY)
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


def frames(body: bytes, content_type: str = CONTENT_TYPE) -> list[bytes]:
    """The complete, valid JPEGs of a stream body, as the driver's parser finds them."""
    parser = MjpegParser(boundary_from_content_type(content_type))
    return parser.feed(body) + parser.close()


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


#: Stream-node timing for tests: reconnect and notice stalls quickly (defaults are for real cameras).
FAST_STREAM_PARAMS = {
    "backoff_initial": 0.05,
    "backoff_max": 0.3,
    "stall_timeout": 0.4,
    "auth_retry": 1.0,
    "read_timeout": 2.0,
}


def reset_camera(cam: SimulatedCamera, reboot_wait_s: float = 5.0) -> SimulatedCamera:
    """A shared simulator as a test expects it: not rebooting, no faults, head at home, counters cleared."""
    wait_until(lambda: not cam.rebooting, reboot_wait_s, 0.05, scaled=False, raises=False)
    cam.set_faults(FaultConfig())
    cam.teleport(0.0, 0.0, 1.0)
    cam.reset_counts()
    return cam
