"""Throughput of :class:`axis_ptz_ros2.vapix.mjpeg.MjpegParser` (pure Python, one core).

Builds an in-memory multipart stream exactly as an Axis camera sends it (VAPIX §5.1) and feeds it
in fixed-size chunks, as ``httpx.Response.iter_raw()`` would. Prints frames/s and MB/s.

    .venv/bin/python bench/bench_mjpeg_parser.py [--seconds 1.0]
"""

from __future__ import annotations

import argparse
import os
import time

from report import inputs, row  # bench/report.py (bench/ is on sys.path when run)

from axis_ptz_ros2.vapix.mjpeg import MjpegParser


def fake_jpeg(size: int) -> bytes:
    """SOI + random payload without 0xFF bytes (as in entropy-coded data) + EOI, ``size`` bytes."""
    body = bytes(b % 0xFF for b in os.urandom(max(0, size - 4)))
    return b"\xff\xd8" + body + b"\xff\xd9"


def build_stream(frame_size: int, n_frames: int, boundary: bytes = b"myboundary") -> bytes:
    """``n_frames`` parts with Content-Type and Content-Length headers."""
    parts = []
    for _ in range(min(n_frames, 64)):
        jpeg = fake_jpeg(frame_size)
        parts.append(
            b"--"
            + boundary
            + b"\r\nContent-Type: image/jpeg\r\nContent-Length: "
            + str(len(jpeg)).encode()
            + b"\r\n\r\n"
            + jpeg
            + b"\r\n"
        )
    return b"".join(parts[k % len(parts)] for k in range(n_frames))


def run(frame_size: int, chunk_size: int, seconds: float) -> tuple[float, float]:
    """Return (frames/s, MB/s) over at least ``seconds`` of parsing."""
    n_frames = max(200, (4 * 1024 * 1024) // frame_size)
    stream = build_stream(frame_size, n_frames)
    chunks = [stream[i : i + chunk_size] for i in range(0, len(stream), chunk_size)]
    frames = 0
    total = 0
    start = time.perf_counter()
    elapsed = 0.0
    while elapsed < seconds:
        parser = MjpegParser(b"myboundary")
        for chunk in chunks:
            frames += len(parser.feed(chunk))
        total += len(stream)
        stats = parser.stats
        if stats.frames != n_frames or stats.resyncs:
            raise RuntimeError(f"parser lost sync on a clean stream: {stats}")
        elapsed = time.perf_counter() - start
    return frames / elapsed, total / elapsed / 1e6


def main() -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seconds", type=float, default=1.0)
    args = ap.parse_args()
    inputs("axis_ptz_ros2/axis_ptz_ros2/vapix/mjpeg.py", "bench/bench_mjpeg_parser.py")
    print(f"{'frame':>8} {'chunk':>8} {'frames/s':>12} {'MB/s':>8}")
    rates = {}
    for frame_size, chunk_size in ((3 * 1024, 64 * 1024), (50 * 1024, 64 * 1024), (3 * 1024, 4 * 1024)):
        fps, mbps = run(frame_size, chunk_size, args.seconds)
        rates[(frame_size, chunk_size)] = fps
        print(f"{frame_size:>8} {chunk_size:>8} {fps:>12,.0f} {mbps:>8.1f}")
    row(
        "MJPEG parser (pure Python), 3 KB / 50 KB frames",
        f"{rates[(3072, 65536)]:,.0f} / {rates[(51200, 65536)]:,.0f} frames/s",
    )


if __name__ == "__main__":
    main()
