"""Which picture size reads best at a given H.264 bitrate, by acuity rows (issue 39 item 6; offline, no link).

The current-Axis persona (q6075: its camera model's softness and a new draw of sensor noise per picture) looks at
the demo world's acuity chart (``acuity_35m``, zoomed as far as the whole chart stays in the 1920x1080 view, at most
the tele limit: the camera's limit) at each size the camera lists in 16:9; each size is encoded by
:class:`~axis_ptz_ros2.media.encoder.H264Encoder` (one ``--preset`` for every size: the camera has one encoder of
its own, unknown to us), a VBV of the bitrate × the encoder's default buffer and IDRs every ``--gop`` pictures, at
each bitrate, decoded, and read by ``bench/acuity.py`` with the chart's true homography at that size (so a small
picture is not penalised for a marker it cannot find). Reported per (size, bitrate): rows read (median and worst
of the pictures read after the first second), the rate reached and the **bits per pixel per picture**
(bitrate / (w·h·fps)): the quantity the driver's size choice uses (``streaming/passthrough_size.py``).

``--pan-deg-s``: the head sweeps at that speed across the chart, reversing each time it has moved one view width (the
chart goes from one edge of the view to the other, as ``bench/bench_acuity_link.py``'s panning sessions do). Each
picture is rendered at its own pose and read through the chart's homography at that pose, and only pictures whose
uncoded picture reads at least one row count (the chart in view); beside the rows read, the rows the uncoded pictures
read. A still chart costs an encoder few bits after its first pictures, whatever the size; a moving one costs every
picture's worth, which is where the size asked for decides what can be read. (No motion blur: the simulator renders
each picture at an instant; a real camera's shutter smears a pan, the more the larger the picture.)

    .venv/bin/python bench/resolution_acuity.py [--kbps 300,500,800,1200,2000] [--fps 25] [--preset veryfast]
        [--pan-deg-s 0]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import acuity  # noqa: E402
from report import SIM_CONFIG, inputs, row  # noqa: E402  (bench/report.py)
from resolution_tradeoff import noisy  # noqa: E402  (bench/resolution_tradeoff.py)

from axis_ptz_ros2.media.decoder import H264Decoder  # noqa: E402
from axis_ptz_ros2.media.encoder import H264Encoder  # noqa: E402
from axis_ptz_ros2.media.h264_settings import H264Settings  # noqa: E402
from axis_ptz_ros2.sim.camera import SimulatedCamera  # noqa: E402
from axis_ptz_ros2.streaming.passthrough_size import bits_per_pixel  # noqa: E402
from axis_ptz_ros2.vapix.models import Resolution  # noqa: E402

SIZES = ((1920, 1080), (1280, 720), (1024, 576), (800, 450), (640, 360), (480, 270))
CHART = "acuity_35m"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kbps", default="300,500,800,1200,2000", help="bitrates (kbit/s, comma-separated)")
    ap.add_argument("--fps", type=int, default=25)
    ap.add_argument("--seconds", type=float, default=3.0, help="coded seconds per setting (the first is not read)")
    ap.add_argument("--gop", type=int, default=0, help="pictures between IDRs (0: one IDR a second)")
    ap.add_argument("--preset", default="veryfast", help="x264 preset for every size")
    ap.add_argument("--pan-deg-s", type=float, default=0.0, help="the head sweeps across the chart at this speed")
    ap.add_argument("--sizes", default="", help="WxH sizes to code (comma-separated; '' = all the 16:9 sizes)")
    args = ap.parse_args(argv)
    if args.pan_deg_s < 0:
        ap.error("--pan-deg-s must be >= 0")
    sizes = tuple(tuple(int(v) for v in s.split("x")) for s in args.sizes.split(",") if s) or SIZES
    inputs(
        "bench/resolution_acuity.py",
        "bench/resolution_tradeoff.py",  # noisy()
        "bench/acuity.py",
        "bench/acuity_chart.py",
        "axis_ptz_ros2/axis_ptz_ros2/media/encoder.py",
        "axis_ptz_ros2/axis_ptz_ros2/sim",
        *SIM_CONFIG,
        "config/sim_world.yaml",
    )
    fps, gop = args.fps, args.gop or args.fps
    pictures = round(args.seconds * fps)
    cam = SimulatedCamera(host="127.0.0.1", port=0, model="q6075", rtsp_port=None)  # not started: its pictures
    renderer = cam.renderer
    model = cam.persona.picture
    target = renderer.scene.target(CHART)
    pan, tilt = acuity.aim(renderer.world, target.center)
    zoom = acuity.fit_zoom(renderer, target, pan, tilt, *SIZES[0])
    distance = float(np.linalg.norm(target.center - renderer.camera_pose(pan, tilt).t))
    print(f"current-Axis persona (q6075), {CHART} at {distance:.1f} m, zoom {zoom:.0f}; {fps} fps, x264 {args.preset}, "
          f"IDR every {gop}; rows read median/worst of every 5th picture after the first second")  # fmt: skip
    rng = np.random.default_rng(1)
    if args.pan_deg_s:
        view_deg = float(np.degrees(renderer.world.zoom_model.hfov(zoom)))
        print(
            f"the head sweeping {args.pan_deg_s:g}°/s, ±{view_deg / 2:.2f}° about the chart's centre (one view width)"
        )
        return panning(args, cam, sizes, pan, tilt, zoom, view_deg, pictures, rng)
    views = {}
    for w, h in sizes:
        views[(w, h)] = (
            model.soften(renderer.render(pan, tilt, zoom, w, h), zoom),
            model.noise_field(w, h) if model.noisy else None,
            acuity.pose_homography(renderer, target, pan, tilt, zoom, w, h),
        )
        raw = acuity.score(noisy(views[(w, h)][0], views[(w, h)][1], rng), views[(w, h)][2])
        print(f"  {w}x{h} uncoded: {raw.rows_read} rows")
    best: dict[int, tuple[int, int, int]] = {}  # bitrate -> (median rows, worst rows, pixels) of the best size
    sizes_at: dict[int, str] = {}
    for kbps in (int(k) for k in args.kbps.split(",")):
        for w, h in sizes:
            soft, noise, H = views[(w, h)]
            t0 = time.perf_counter()
            enc = camera_encoder(fps, kbps, gop, args.preset, w, h)
            dec = H264Decoder()
            rows: list[int] = []
            bits = 0
            for k in range(pictures):
                out = enc.encode_bgr(np.ascontiguousarray(noisy(soft, noise, rng), dtype=np.uint8), 1)
                pic = dec.decode(out.data)
                if k < fps:
                    continue
                bits += len(out.data) * 8
                if pic is not None and k % 5 == 0:
                    rows.append(acuity.score(pic.image, H).rows_read)
            rate = bits * fps / max(1, pictures - fps) / 1e3
            bpp = bits_per_pixel(kbps, Resolution(w, h), fps)
            med, worst = int(np.median(rows)), min(rows)
            print(
                f"{kbps:5d} kbit/s {w:4d}x{h:<4d}: {rate:5.0f} kbit/s reached, {bpp:.3f} bit/px, rows read "
                f"median {med:2d} worst {worst:2d} ({time.perf_counter() - t0:.1f} s)"
            )
            if kbps not in best or (med, worst, w * h) > best[kbps]:
                best[kbps] = (med, worst, w * h)
                sizes_at[kbps] = f"{w}x{h}"
        m, worst, _ = best[kbps]
        print(f"  best at {kbps} kbit/s: {sizes_at[kbps]} ({m} rows median, {worst} worst)")
        what = f"best {sizes_at[kbps]}: {m} rows (worst {worst})"
        row(f"resolution by acuity, q6075 persona, {CHART}, {kbps} kbit/s", what)
    return 0


def camera_encoder(fps: int, kbps: int, gop: int, preset: str, w: int, h: int) -> H264Encoder:
    """x264 as a camera's own H.264 stands in: Constrained Baseline, an IDR every ``gop`` pictures."""
    settings = H264Settings(
        fps=fps, bitrate_kbps=kbps, keyframe_interval=gop, preset=preset, profile="baseline", refresh="idr"
    )
    return H264Encoder(settings, w, h)


def sweep_pan(pan0: float, view_deg: float, deg_s: float, t: float) -> float:
    """The pan (°) at ``t`` s of a sweep at ``deg_s`` starting at ``pan0`` (the chart's centre) towards +pan,
    reversing ``view_deg`` / 2 either side of it: a triangle wave."""
    phase = (t * deg_s + view_deg / 2) % (2 * view_deg)  # 0 at -view/2 going up
    return pan0 - view_deg / 2 + (phase if phase <= view_deg else 2 * view_deg - phase)


def panning(  # noqa: PLR0913 - the set-up main() made
    args: argparse.Namespace,
    cam: SimulatedCamera,
    sizes: tuple[tuple[int, ...], ...],
    pan0: float,
    tilt: float,
    zoom: float,
    view_deg: float,
    pictures: int,
    rng: np.random.Generator,
) -> int:
    """``--pan-deg-s``: each size coded at each bitrate while the head sweeps; rows read against the uncoded
    picture of each pose (see the module docstring)."""
    renderer, model = cam.renderer, cam.persona.picture
    target = renderer.scene.target(CHART)
    fps, gop = args.fps, args.gop or args.fps
    for kbps in (int(k) for k in args.kbps.split(",")):
        for w, h in sizes:
            t0 = time.perf_counter()
            enc, dec = camera_encoder(fps, kbps, gop, args.preset, w, h), H264Decoder()
            noise = model.noise_field(w, h) if model.noisy else None
            rows: list[int] = []  # coded, of the pictures whose uncoded picture reads >= 1 row
            ref: list[int] = []  # uncoded, the same pictures
            bits = 0
            for k in range(pictures):
                p = sweep_pan(pan0, view_deg, args.pan_deg_s, k / fps)
                frame = np.ascontiguousarray(
                    noisy(model.soften(renderer.render(p, tilt, zoom, w, h), zoom), noise, rng)
                )
                out = enc.encode_bgr(frame, 1)
                pic = dec.decode(out.data)
                if k < fps:
                    continue
                bits += len(out.data) * 8
                if pic is None or k % 5:
                    continue
                H = acuity.pose_homography(renderer, target, p, tilt, zoom, w, h)
                own = acuity.score(frame, H).rows_read
                if own >= 1:
                    ref.append(own)
                    rows.append(acuity.score(pic.image, H).rows_read)
            rate = bits * fps / max(1, pictures - fps) / 1e3
            bpp = bits_per_pixel(kbps, Resolution(w, h), fps)
            if not rows:
                print(f"{kbps:5d} kbit/s {w:4d}x{h:<4d}: the chart was in view in no picture read")
                continue
            lost = [a - b for a, b in zip(ref, rows, strict=True)]
            print(
                f"{kbps:5d} kbit/s {w:4d}x{h:<4d}: {rate:5.0f} kbit/s reached, {bpp:.3f} bit/px, rows read median "
                f"{np.median(rows):4.1f} worst {min(rows):2d} (uncoded {np.median(ref):4.1f}; lost median "
                f"{np.median(lost):4.1f} worst {max(lost):2d}; {len(rows)} pictures) ({time.perf_counter() - t0:.1f} s)"
            )
            row(
                f"resolution by acuity, q6075 persona, {CHART}, panning {args.pan_deg_s:g}°/s, {kbps} kbit/s, {w}x{h}",
                f"rows read median {np.median(rows):g}, worst {min(rows)} (uncoded {np.median(ref):g})",
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
