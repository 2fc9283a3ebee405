"""Which picture size reads best at a low bitrate, offline (issue 21's current-Axis case; not in ``./scripts/bench``).

The current-Axis persona's view (its camera model: softness and a new draw of sensor noise per picture, as its RTSP
side makes them) at several sizes, encoded by :class:`~axis_ptz_ros2.media.encoder.H264Encoder` with one
``--preset`` for every size (a camera has one encoder; the persona itself uses ``ultrafast`` above 704x576 to spare
the simulator's CPU), VBV and an IDR every 30 pictures, at each bitrate; decoded, upscaled to 1920x1080 (bilinear)
and compared with the persona's 1920x1080 view before noise and compression: PSNR median and 5th percentile of
every third picture after the first second, and the rate reached. Also printed: each smaller view itself, upscaled,
without coding (what that size can reach at best).

    .venv/bin/python bench/resolution_tradeoff.py [--kbps 600,1000,1500] [--preset veryfast]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from link_h264_roles import psnr_db  # noqa: E402  (bench/ is on sys.path when run)

from axis_ptz_ros2.media.decoder import H264Decoder  # noqa: E402
from axis_ptz_ros2.media.encoder import H264Encoder  # noqa: E402
from axis_ptz_ros2.media.h264_settings import H264Settings  # noqa: E402
from axis_ptz_ros2.sim.camera import SimulatedCamera  # noqa: E402

SIZES = ((1920, 1080), (1280, 720), (800, 450), (640, 360))
FPS, PICTURES = 30, 120


def noisy(soft: np.ndarray, noise: tuple[np.ndarray, np.ndarray] | None, rng: np.random.Generator) -> np.ndarray:
    """``soft`` with a window of the persona's noise field (``noise_field``'s positive and negative parts) at a
    random offset drawn from ``rng``, as the simulator adds it per picture; ``soft`` itself without noise."""
    if noise is None:
        return soft
    pos, neg = noise
    h, w = soft.shape[:2]
    dy = int(rng.integers(0, pos.shape[0] - h + 1))
    dx = int(rng.integers(0, pos.shape[1] - w + 1))
    return cv2.subtract(cv2.add(soft, pos[dy : dy + h, dx : dx + w]), neg[dy : dy + h, dx : dx + w])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--kbps", default="600,1000,1500", help="bitrates to try (kbit/s, comma-separated)")
    ap.add_argument("--preset", default="veryfast", help="x264 preset for every size")
    a = ap.parse_args()
    cam = SimulatedCamera(host="127.0.0.1", port=0, model="q6075", rtsp_port=None)  # not started: its pictures
    pan, tilt, zoom = cam.position()
    model = cam.persona.picture
    views = {(w, h): model.soften(cam.frames.renderer.render(pan, tilt, zoom, w, h), zoom) for w, h in SIZES}
    ref = views[SIZES[0]].astype(np.float32)
    rng = np.random.default_rng(1)

    def psnr(img: np.ndarray) -> float:
        return psnr_db(img, ref)  # upscaled (bilinear) to the reference's size first

    print(f"current-Axis persona (q6075), home view, {FPS} fps, x264 {a.preset}; PSNR against its 1920x1080 view")
    for w, h in SIZES[1:]:
        print(f"{w}x{h} view itself, upscaled, no coding: {psnr(views[(w, h)]):.1f} dB")
    for kbps in (int(k) for k in a.kbps.split(",")):
        for w, h in SIZES:
            soft = views[(w, h)]
            noise = model.noise_field(w, h) if model.noisy else None
            cfg = H264Settings(
                fps=FPS,
                bitrate_kbps=kbps,
                keyframe_interval=FPS,
                preset=a.preset,
                profile="baseline",
                refresh="idr",  # a camera's own H.264: an IDR every second
            )
            enc = H264Encoder(cfg, w, h)
            dec = H264Decoder()
            scores: list[float] = []
            bits = 0
            for k in range(PICTURES):
                out = enc.encode_bgr(np.ascontiguousarray(noisy(soft, noise, rng), dtype=np.uint8), 1)
                pic = dec.decode(out.data)
                if k < FPS:
                    continue
                bits += len(out.data) * 8
                if pic is not None and k % 3 == 0:
                    scores.append(psnr(pic.image))
            print(
                f"{kbps:5d} kbit/s asked, {w}x{h}: {bits * FPS / (PICTURES - FPS) / 1e3:4.0f} kbit/s, "
                f"PSNR median {np.median(scores):.1f}, 5th pct {np.percentile(scores, 5):.1f} dB"
            )


if __name__ == "__main__":
    main()
