"""Which H.264 encoder settings keep the picture from breathing, offline (issue 39, item 4; not in ``./scripts/bench``).

The simulated 214's compression-0 JPEGs of its home view, as its camera model sends them (softness, sensor noise:
each picture is a new noisy JPEG of the same still view), go through
:class:`~axis_ptz_ros2.media.transcoder.MjpegTranscoder` (the stream node's transcoder) once per setting and
bitrate, encode only (no link), and are decoded again with the node's decoder
(:class:`~axis_ptz_ros2.media.decoder.H264Decoder`). Printed per setting: PSNR of every decoded picture after the
first second against the view before noise and compression (median, 5th percentile, their gap), the largest
picture (kbit), the rate reached, and the CPU of one ``transcode()`` call (JPEG decode + x264; process CPU, x264 on
one thread) as ms and as % of one core at 704×576 @ 25. Last, what a viewer that reports nothing sees after one
lost P-picture (an access unit a keep-last history replaced before its repair) with no IDR asked for: the same
access units but that one go through a plain FFmpeg h264 decoder (default options, as the ``ffmpeg``
image_transport plugin decodes), and "healed" is the number of pictures after the loss until its pictures are
identical to the loss-free decoder's again (or ``never`` within the run). The settings:

* ``today``: what the stream node did until issue 39: Constrained Baseline, ``superfast``, an IDR every 25 pictures
  (one second), VBV buffer 60 ms of a 2 Mbit/s link budget (``h264_vbv_kbit``: the smaller of 0.15 s of the bitrate
  and 60 ms of the budget);
* candidates: x264's periodic intra refresh (``intra``: one wave a second, IDRs only on request) or a long GOP
  (``gop``: one IDR at the start), each Constrained Baseline or High, under the same VBV rule;
* ``node``: the stream node's defaults now (``H264Settings()``), under the same VBV rule, with a viewer that does
  not report its losses (the wave at most one second); ``node-psy``: the same with x264's psychovisual
  optimisations on (x264's default, and the node's until ``H264Settings.psy``);
* ``node-reported``: the same while every viewer reports its losses (``long_wave``: the wave
  ``h264_reported_wave`` 100 pictures, 4 s); ``reported-veryfast``: that wave with ``veryfast``;
* ``reference``: x264 ``medium`` (its psychovisual optimisations on, as x264 ships it; AQ off, no B-frames, as every
  setting here), High, long GOP, VBV 150 ms of the bitrate: "what the bits allow". Psy off, ``medium`` measured
  0.2 dB lower here: the stricter of the two is the reference.

Targets (issue 39): 5th percentile within 1.5 dB of the median; median within 0.5 dB of the reference at the same
bitrate; CPU ≤ 30 % of a core at 704×576 @ 25 (``bench/bench_transcode.py`` measures that paced, as the node runs).
On a shared machine the CPU figures carry some of the other processes' load (cache, frequency); the load average
is printed with them.

    .venv/bin/python bench/encoder_tradeoff.py [--kbps 1500 1000] [--pictures 250] [--link-kbps 2000] [--only NAME ...]
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import av
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from link_h264_roles import psnr_db  # noqa: E402  (bench/ is on sys.path when run)
from machine import cpu_s, loadavg  # noqa: E402  (bench/machine.py)

from axis_ptz_ros2.media.decoder import H264Decoder  # noqa: E402
from axis_ptz_ros2.media.h264_settings import H264Settings  # noqa: E402
from axis_ptz_ros2.media.transcoder import MjpegTranscoder  # noqa: E402
from axis_ptz_ros2.sim.camera import SimulatedCamera  # noqa: E402
from axis_ptz_ros2.streaming.h264_policy import h264_vbv_kbit  # noqa: E402

W, H, FPS = 704, 576, 25
SKIP = FPS  # pictures left out at the start (the first IDR and the rate control settling)
LONG_GOP = 600  # frames: longer than any run here, so one IDR at the start
LOSS = SKIP + 2 * FPS + 3  # the access unit a silent viewer loses (a P-picture in every setting here)


@dataclass(frozen=True)
class Setting:
    name: str
    preset: str
    profile: str
    refresh: str  # "idr" (periodic, keyframe_interval) or "intra"
    keyframe_interval: int
    link_vbv: bool  # VBV by the node's rule under the link budget; else 0.15 s of the bitrate
    psy: bool = False  # x264's psychovisual optimisations (H264Settings.psy; x264's own default is on)


def settings() -> list[Setting]:
    node = H264Settings(fps=FPS)  # a viewer that does not report: the wave at most a second
    reported = H264Settings(
        fps=FPS, long_wave=True, reported_wave=4 * FPS
    )  # every viewer reports its losses: the wave as set
    return [
        Setting("today", "superfast", "baseline", "idr", FPS, True, psy=True),
        Setting("gop-baseline", "superfast", "baseline", "idr", LONG_GOP, True),
        Setting("gop-high", "superfast", "high", "idr", LONG_GOP, True),
        Setting("intra-baseline", "superfast", "baseline", "intra", FPS, True),
        Setting("intra-high", "superfast", "high", "intra", FPS, True),
        Setting("intra-high-veryfast", "veryfast", "high", "intra", FPS, True),
        Setting("intra-high-faster", "faster", "high", "intra", FPS, True),
        Setting("node", node.preset, node.profile, node.refresh, node.effective_keyframe_interval, True, node.psy),
        Setting("node-psy", node.preset, node.profile, node.refresh, node.effective_keyframe_interval, True, True),
        Setting(
            "node-reported",
            reported.preset,
            reported.profile,
            reported.refresh,
            reported.effective_keyframe_interval,
            True,
        ),
        Setting("reported-veryfast", "veryfast", "high", "intra", reported.effective_keyframe_interval, True),
        Setting("reference", "medium", "high", "idr", LONG_GOP, False, psy=True),
    ]


def run(s: Setting, jpegs: list[bytes], view: np.ndarray, kbps: int, link_kbps: float) -> dict[str, float]:
    vbv_kbit = h264_vbv_kbit(kbps, link_kbps, s.refresh) if s.link_vbv else 0
    tc = MjpegTranscoder(
        H264Settings(
            fps=FPS,
            bitrate_kbps=kbps,
            keyframe_interval=s.keyframe_interval,
            preset=s.preset,
            profile=s.profile,
            refresh=s.refresh,
            vbv_kbit=vbv_kbit,
            psy=s.psy,
        ),
        stamp_sei=False,
    )
    dec = H264Decoder()
    plain = av.VideoCodecContext.create("h264", "r")  # the lossy viewer's decoder, and its loss-free twin
    plain.thread_count = 1
    twin = av.VideoCodecContext.create("h264", "r")
    twin.thread_count = 1
    healed_at = -1
    scores: list[float] = []
    sizes: list[int] = []
    cpu: list[float] = []
    idrs = 0
    for k, jpeg in enumerate(jpegs):
        c0 = cpu_s()
        out = tc.transcode(jpeg)
        c1 = cpu_s()
        pic = dec.decode(out.data)
        if k >= LOSS - 1:
            (ref,) = twin.decode(av.Packet(out.data))
            if k != LOSS:
                got = plain.decode(av.Packet(out.data))
                same = bool(got) and np.array_equal(got[-1].to_ndarray(), ref.to_ndarray())
                if k > LOSS and same and healed_at < 0:
                    healed_at = k
                elif not same:
                    healed_at = -1
        else:
            twin.decode(av.Packet(out.data))
            plain.decode(av.Packet(out.data))
        if k == LOSS and out.keyframe:
            raise SystemExit(f"{s.name}: picture {LOSS} is an IDR; the loss test needs a P-picture")
        if k < SKIP:
            continue
        cpu.append(c1 - c0)
        sizes.append(len(out.data) * 8)
        idrs += int(out.keyframe)
        if pic is not None:
            scores.append(psnr_db(pic.image, view))
    if len(scores) != len(jpegs) - SKIP:
        raise SystemExit(f"{s.name}: {len(jpegs) - SKIP - len(scores)} pictures did not decode")
    med, p5 = float(np.median(scores)), float(np.percentile(scores, 5))
    ms = 1e3 * float(np.mean(cpu))
    return {
        "median": med,
        "p5": p5,
        "largest_kbit": max(sizes) / 1e3,
        "kbps": float(np.mean(sizes)) * FPS / 1e3,
        "cpu_ms": ms,
        "cpu_pct": ms * FPS / 10.0,
        "idrs": idrs,
        "vbv_kbit": vbv_kbit or kbps * 0.15,
        "codec": tc.codec_string or "",
        "healed": healed_at - LOSS if healed_at > 0 else math.inf,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--kbps", type=int, nargs="+", default=[1500, 1000], help="bitrates (kbit/s)")
    ap.add_argument("--pictures", type=int, default=250, help="pictures per run (the first second is left out)")
    a_min = LOSS + 2 * FPS
    ap.add_argument("--link-kbps", type=float, default=2000.0, help="the link budget the VBV rule sees (0 = none)")
    ap.add_argument("--only", nargs="+", default=[], help="run only these settings (names as printed)")
    a = ap.parse_args()
    if a.pictures < a_min:
        ap.error(f"--pictures must be at least {a_min} (a lost picture at {LOSS} and two seconds after it)")
    chosen = [s for s in settings() if not a.only or s.name in a.only]
    cam = SimulatedCamera(host="127.0.0.1", port=0)  # not started: its pictures only
    pan, tilt, zoom = cam.position()
    view = cam.persona.picture.soften(cam.frames.renderer.render(pan, tilt, zoom, W, H), zoom).astype(np.float32)
    jpegs = [cam.frame_jpeg(W, H, 0) for _ in range(a.pictures)]
    print(
        f"simulated 214, home view (pan {pan:g}, tilt {tilt:g}, zoom {zoom:g}), still, {W}x{H} @ {FPS}, "
        f"{a.pictures} compression-0 JPEGs (mean {np.mean([len(j) for j in jpegs]) / 1e3:.0f} kB), first {SKIP} "
        f"left out; VBV rule under a {a.link_kbps:g} kbit/s link budget; load average {loadavg()}"
    )
    head = f"{'setting':20} {'preset':9} {'profile':8} {'refresh':8} {'psy':3} {'kbit/s':>6} {'VBV':>4} "
    head += f"{'median':>6} {'p5':>5} {'gap':>4} {'vs ref':>6} {'largest':>7} {'IDRs':>4} {'CPU ms':>6} {'%core':>5}"
    head += f" {'healed':>6}"
    for kbps in a.kbps:
        results = {s.name: run(s, jpegs, view, kbps, a.link_kbps) for s in chosen}
        ref = results.get("reference")
        print(f"\n{kbps} kbit/s (PSNR in dB against the view before noise; CPU of transcode(): JPEG decode + x264)")
        print(head)
        for s in chosen:
            r = results[s.name]
            vs = f"{r['median'] - ref['median']:+6.2f}" if ref else "     -"
            print(
                f"{s.name:20} {s.preset:9} {s.profile:8} {s.refresh:8} {'on' if s.psy else 'off':3} {r['kbps']:6.0f} "
                f"{r['vbv_kbit']:4.0f} "
                f"{r['median']:6.2f} {r['p5']:5.2f} {r['median'] - r['p5']:4.2f} {vs} {r['largest_kbit']:7.0f} "
                f"{r['idrs']:4d} {r['cpu_ms']:6.2f} {r['cpu_pct']:5.1f} "
                + (f"{r['healed']:6.0f}" if math.isfinite(r["healed"]) else " never")
            )
        print(f"load average {loadavg()}")


if __name__ == "__main__":
    main()
