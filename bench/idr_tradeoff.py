"""What an IDR costs on a slow link against what it buys, offline (issue 21's step case; not in ``./scripts/bench``).

The simulated 214's compression-0 JPEGs of its home view (``--pan``: the head moving 0.4° per picture, 10°/s at
25 fps, back and forth) go through :class:`~axis_ptz_ros2.media.transcoder.MjpegTranscoder` at one bitrate for
each x264 VBV buffer (seconds of the bitrate, the encoder's ``VBV_BUFFER_S``) and IDR interval, and are decoded
again. Printed per setting: the mean IDR size in kbit and in milliseconds of a 1 Mbit/s link (the time the pictures
behind it wait), the mean P-picture, the rate reached, and the PSNR of every decoded picture against the camera's
view before noise and compression (median, 5th percentile, IDRs alone). Last, x264's periodic intra refresh
(``intra-refresh=1``: a column of intra blocks sweeps the picture once per interval, no periodic IDR after the
first picture; not what the encoder does today, opened here with PyAV directly and otherwise the encoder's
options): the largest picture, which is what the link must carry in one go.

    .venv/bin/python bench/idr_tradeoff.py [--pan] [--kbps 600] [--pictures 150]
"""

from __future__ import annotations

import argparse
import sys
from fractions import Fraction
from pathlib import Path

import av
import numpy as np
from av.video.frame import PictureType

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from link_h264_roles import psnr_db as psnr  # noqa: E402  (bench/ is on sys.path when run)

import axis_ptz_ros2.media.encoder as encoder  # noqa: E402
from axis_ptz_ros2.media.decoder import H264Decoder  # noqa: E402
from axis_ptz_ros2.media.h264_settings import H264Settings  # noqa: E402
from axis_ptz_ros2.media.transcoder import MjpegTranscoder  # noqa: E402
from axis_ptz_ros2.sim.camera import SimulatedCamera  # noqa: E402

W, H, FPS = 704, 576, 25
SKIP = 10  # pictures left out at the start (the encoder's first GOP)


def intra_refresh(pictures: list[tuple[bytes, np.ndarray]], kbps: int, vbv: float) -> None:
    """The encoder's options with ``intra-refresh=1`` (wave = one second) instead of periodic IDRs."""
    ctx = av.VideoCodecContext.create("libx264", "w")
    ctx.width, ctx.height, ctx.pix_fmt = W, H, "yuv420p"
    ctx.time_base, ctx.framerate = Fraction(1, FPS), Fraction(FPS, 1)
    ctx.bit_rate, ctx.max_b_frames, ctx.thread_count = kbps * 1000, 0, 1
    ctx.options = {
        "preset": "superfast",
        "tune": "zerolatency",
        "profile": "baseline",
        "maxrate": str(kbps * 1000),
        "bufsize": str(int(kbps * 1000 * vbv)),
        "x264-params": f"keyint={FPS}:min-keyint={FPS}:scenecut=0:bframes=0:aq-mode=0:intra-refresh=1",
    }
    ctx.open()
    jpeg_decoder = av.VideoCodecContext.create("mjpeg", "r")
    dec = H264Decoder()
    sizes: list[int] = []
    scores: list[float] = []
    for k, (jpeg, view) in enumerate(pictures):
        frame = jpeg_decoder.decode(av.Packet(jpeg))[0]
        frame = frame.reformat(format="yuv420p", src_color_range="JPEG", dst_color_range="MPEG")
        frame.pts, frame.time_base, frame.pict_type = k, ctx.time_base, PictureType.NONE  # a JPEG's own type is I
        for packet in ctx.encode(frame):
            pic = dec.decode(bytes(packet))
            if k >= SKIP:
                sizes.append(packet.size * 8)
                if pic is not None:
                    scores.append(psnr(pic.image, view))
    print(
        f"VBV {vbv:.2f} s, intra refresh every 1 s, no periodic IDR: largest picture {max(sizes) / 1e3:3.0f} kbit = "
        f"{max(sizes) / 1e3:3.0f} ms of a 1 Mbit/s link; mean {np.mean(sizes) / 1e3:4.1f} kbit; "
        f"{np.mean(sizes) * FPS / 1e3:3.0f} kbit/s; PSNR median {np.median(scores):.1f}, "
        f"5th pct {np.percentile(scores, 5):.1f} dB"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pan", action="store_true", help="the head moving 10°/s (else still)")
    ap.add_argument("--kbps", type=int, default=600, help="the encoder's bitrate (kbit/s)")
    ap.add_argument("--pictures", type=int, default=150)
    a = ap.parse_args()
    cam = SimulatedCamera(host="127.0.0.1", port=0)  # not started: its pictures only
    pan0, tilt, zoom = cam.position()
    pictures = []
    for k in range(a.pictures):
        step = k % 75 if (k // 75) % 2 == 0 else 75 - k % 75
        pan = pan0 + 0.4 * step if a.pan else pan0
        cam.teleport(pan, tilt, zoom)
        view = cam.persona.picture.soften(cam.frames.renderer.render(pan, tilt, zoom, W, H), zoom)
        pictures.append((cam.frame_jpeg(W, H, 0), view.astype(np.float32)))
    print(f"{'panning 10°/s' if a.pan else 'still'}, {a.kbps} kbit/s, {FPS} fps, {a.pictures} pictures")
    for vbv in (0.05, 0.08, 0.10, 0.15):
        for gop in (FPS, 2 * FPS):
            encoder.VBV_BUFFER_S = vbv  # read when the encoder opens
            tc = MjpegTranscoder(
                H264Settings(
                    preset="superfast",
                    bitrate_kbps=a.kbps,
                    fps=FPS,
                    keyframe_interval=gop,
                    profile="baseline",
                    refresh="idr",  # periodic IDRs are what this bench weighs
                )
            )
            dec = H264Decoder()
            idr: list[int] = []
            other: list[int] = []
            scores: list[float] = []
            idr_scores: list[float] = []
            for k, (jpeg, view) in enumerate(pictures):
                out = tc.transcode(jpeg, 1)
                pic = dec.decode(out.data)
                if k < SKIP:
                    continue
                (idr if out.keyframe else other).append(len(out.data) * 8)
                if pic is not None:
                    scores.append(psnr(pic.image, view))
                    if out.keyframe:
                        idr_scores.append(scores[-1])
            kbps = (sum(idr) + sum(other)) * FPS / (len(pictures) - SKIP) / 1e3
            print(
                f"VBV {vbv:.2f} s, IDR every {gop / FPS:.0f} s: IDR {np.mean(idr) / 1e3:3.0f} kbit = "
                f"{np.mean(idr) / 1e3:3.0f} ms of a 1 Mbit/s link; P {np.mean(other) / 1e3:4.1f} kbit; "
                f"{kbps:3.0f} kbit/s; "
                f"PSNR median {np.median(scores):.1f}, 5th pct {np.percentile(scores, 5):.1f}, "
                f"IDRs {np.mean(idr_scores):.1f} dB"
            )
    for vbv in (0.10, 0.15):
        intra_refresh(pictures, a.kbps, vbv)


if __name__ == "__main__":
    main()
