#!/usr/bin/env python3
"""Regenerate the guide's pictures from the simulated camera, over its HTTP interface (reproducible figures).

    .venv/bin/python scripts/make_figures.py            # docs/images/zoom_montage.png, bitrate.png, bitrate.csv
    .venv/bin/python scripts/make_figures.py --quick --out /tmp/figs

* ``zoom_montage.png`` — like the thesis's Figure 6.3: the simulated Axis 214 aimed at the number plate 20 m
  in front of the robot (``config/sim_world.yaml``) at several zooms, each frame fetched with
  ``jpg/image.cgi`` after a ``ptz.cgi`` move; the lower row enlarges the frame centre 2× (nearest neighbour),
  so the plate is a few unreadable pixels at zoom 1 and readable at 9999.
* ``bitrate.png`` / ``bitrate.csv`` — like the thesis's Tables 6.2–6.4: the MJPEG stream's bitrate over
  resolution × fps × compression, measured on ``mjpg/video.cgi`` at the home view, camera still: mean bytes
  per part (JPEG + multipart headers) × 8 × the pictures a second the camera serves (the requested fps, at most
  the PAL 214's 25, ``Persona.frame_rate``; the achieved fps is recorded beside it: on a loaded machine the
  simulator may fall short, which would understate a bytes-per-second figure). The
  thesis's values for the real 214 are drawn beside ours, read as kB/s (printed as "kBit/s"; see
  ``camera_model.THESIS_UNIT_BYTES``): ``thesis_kbit_s`` = printed value × 8, ``thesis_printed`` as printed.
  ``bench/bench_bitrate.py`` prints the same comparison with JPEG sizes only, still and panning.

Needs matplotlib (installed by scripts/bootstrap). The simulator runs in this process on a free loopback port.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import cv2
import httpx
import numpy as np

from axis_ptz_ros2.config import CONFIG_DIR, load_camera_model
from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.sim.camera_model import THESIS_TABLES, thesis_kbit_s
from axis_ptz_ros2.sim.persona import AXIS_214
from axis_ptz_ros2.sim.ptz import ros_to_vapix
from axis_ptz_ros2.sim.world import load_world

AXIS_214_ZOOM = load_camera_model(CONFIG_DIR / "axis214.yaml").zoom  # the 214's optics, from its model file

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # tests.support
from tests.support.sim import decode, parts, read_stream  # noqa: E402

ZOOMS = (1, 2500, 5000, 7500, 9999)
RESOLUTIONS = ("704x576", "352x288", "176x144")
FPS = (1, 15, 30)
COMPRESSIONS = (0, 30, 100)
#: the thesis's measurements on the real Axis 214 (Tables 6.2-6.4), as printed (kB/s): resolution -> compression -> fps
THESIS = THESIS_TABLES


def log(msg: str) -> None:
    print(f"[make_figures] {msg}", file=sys.stderr, flush=True)


def ptz(client: httpx.Client, **args: float) -> None:
    r = client.get("/axis-cgi/com/ptz.cgi", params={k: f"{v:.4f}" for k, v in args.items()})
    r.raise_for_status()


def position(client: httpx.Client) -> dict[str, float]:
    r = client.get("/axis-cgi/com/ptz.cgi", params={"query": "position"})
    r.raise_for_status()
    out = {}
    for line in r.text.splitlines():
        k, _, v = line.partition("=")
        try:
            out[k.strip()] = float(v)
        except ValueError:
            continue
    return out


def move_and_wait(client: httpx.Client, pan: float, tilt: float, zoom: int, timeout: float = 20.0) -> None:
    """Absolute move (VAPIX degrees / units) and wait until the camera reports that pose."""
    ptz(client, pan=pan, tilt=tilt, zoom=zoom)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        p = position(client)
        arrived = abs(p.get("pan", 1e9) - pan) < 0.05 and abs(p.get("tilt", 1e9) - tilt) < 0.05
        if arrived and abs(p.get("zoom", 1e9) - zoom) < 1.5:
            return
        time.sleep(0.05)
    raise RuntimeError(f"camera did not reach pan {pan} tilt {tilt} zoom {zoom}: {position(client)}")


def snapshot(client: httpx.Client, resolution: str = "704x576", compression: int = 10) -> np.ndarray:
    r = client.get("/axis-cgi/jpg/image.cgi", params={"resolution": resolution, "compression": compression})
    r.raise_for_status()
    return decode(r.content)


def plate_aim() -> tuple[float, float, float]:
    """VAPIX (pan, tilt) that centres the number plate, from the simulated world, and its distance (m)."""
    world = load_world()
    plate = next(t for t in world.targets if t.name == "number_plate")
    p_ptz = world.T_base_ptz.inverse().apply(np.asarray(plate.center, dtype=np.float64))
    pan, tilt = world.kinematics.look_at(p_ptz)
    vp, vt = ros_to_vapix(pan, tilt)
    return vp, vt, float(np.linalg.norm(p_ptz))


def zoom_montage(client: httpx.Client, out: Path, zooms: tuple[int, ...]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pan, tilt, dist = plate_aim()
    frames = []
    for z in zooms:
        move_and_wait(client, pan, tilt, z)
        frames.append(cv2.cvtColor(snapshot(client), cv2.COLOR_BGR2RGB))
        log(f"zoom {z}: frame {frames[-1].shape[1]}x{frames[-1].shape[0]}")
    fig, axes = plt.subplots(2, len(zooms), figsize=(2.3 * len(zooms), 3.7), dpi=100)
    for i, (z, img) in enumerate(zip(zooms, frames, strict=True)):
        h, w = img.shape[:2]
        fx = AXIS_214_ZOOM.intrinsics(z, w, h).fx
        plate_px = 0.52 / dist * fx  # the plate is 0.52 m wide
        axes[0, i].imshow(img)
        axes[0, i].set_title(f"zoom {z}\n(×{AXIS_214_ZOOM.magnification(z):.1f})", fontsize=9)
        # the plate's own pixels around the image centre, blown up to the same display size (no smoothing)
        half_w = max(24, int(0.8 * plate_px))
        half_h = max(10, int(0.32 * plate_px))
        cy, cx = h // 2, w // 2
        crop = img[max(0, cy - half_h) : cy + half_h, max(0, cx - half_w) : cx + half_w]
        axes[1, i].imshow(crop, interpolation="nearest")
        axes[1, i].set_title(f"plate: {plate_px:.0f} px wide", fontsize=8)
        for ax in axes[:, i]:
            ax.set_xticks([])
            ax.set_yticks([])
    fig.suptitle(
        f"Simulated Axis 214 PTZ, number plate at {dist:.1f} m (704×576 frames from jpg/image.cgi)", fontsize=10
    )
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)
    log(f"wrote {out}")


def stream_rate(client: httpx.Client, res: str, fps: int, comp: int, seconds: float) -> tuple[float, float, int]:
    """(kbit/s at the rate the camera serves, achieved fps, frames) of one MJPEG stream."""
    url = f"/axis-cgi/mjpg/video.cgi?resolution={res}&fps={fps}&compression={comp}"
    _status, _headers, body, marks = read_stream(client, url, max_seconds=seconds)
    found = parts(body)
    complete = [(n, off) for n, off in found if off + n <= len(body)]
    if len(complete) < 2:
        raise RuntimeError(f"{res} {fps} fps compression {comp}: only {len(complete)} frames in {seconds} s")
    # bytes per part: from one part header to the next (JPEG + boundary + headers), as on the wire
    starts = [off for _n, off in complete]
    per_part = float(np.mean(np.diff(starts)))
    elapsed = max(1e-6, marks[-1][0] - marks[0][0])
    achieved = (len(complete) - 1) / elapsed
    served = min(fps, AXIS_214.frame_rate)  # the PAL 214 makes 25 pictures a second
    return per_part * 8.0 * served / 1000.0, achieved, len(complete)


def bitrate(client: httpx.Client, out_png: Path, out_csv: Path, resolutions: tuple[str, ...], quick: bool) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    move_and_wait(client, 0.0, 0.0, 1)  # home: the robot's forward view
    rows = []
    for res in resolutions:
        for comp in COMPRESSIONS:
            for fps in FPS:
                seconds = (2.5 if quick else 4.5) if fps == 1 else (1.0 if quick else 2.0)
                kbps, achieved, n = stream_rate(client, res, fps, comp, seconds)
                printed = THESIS[res][comp][FPS.index(fps)]
                rows.append((res, fps, comp, kbps, achieved, n, thesis_kbit_s(res, comp, fps), printed))
                log(f"{res} {fps:>2} fps compression {comp:>3}: {kbps:8.0f} kbit/s (achieved {achieved:.1f} fps)")
    with open(out_csv, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(
            [
                "resolution",
                "fps",
                "compression",
                "sim_kbit_s",
                "sim_achieved_fps",
                "frames",
                "thesis_kbit_s",
                "thesis_printed",
                "ratio",
            ]
        )
        for r in rows:
            w.writerow([r[0], r[1], r[2], f"{r[3]:.1f}", f"{r[4]:.2f}", r[5], f"{r[6]:g}", r[7], f"{r[3] / r[6]:.2f}"])
    fig, axes = plt.subplots(1, len(resolutions), figsize=(4.0 * len(resolutions), 4.2), dpi=100, sharey=True)
    axes = np.atleast_1d(axes)
    colors = {0: "tab:red", 30: "tab:blue", 100: "tab:green"}
    for ax, res in zip(axes, resolutions, strict=True):
        for comp in COMPRESSIONS:
            sim = [r[3] for r in rows if r[0] == res and r[2] == comp]
            ax.plot(FPS, sim, "o-", color=colors[comp], label=f"simulator, compression {comp}")
            ax.plot(
                FPS,
                [thesis_kbit_s(res, comp, f) for f in FPS],
                "s--",
                color=colors[comp],
                alpha=0.6,
                label=f"thesis 214, compression {comp}",
            )
        ax.set_yscale("log")
        ax.set_xticks(FPS)
        ax.set_xlabel("fps asked (PAL 214: 30 asked, 25 served)")
        ax.set_title(res, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("kbit/s")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=8, loc="lower center", ncol=3)
    fig.suptitle(
        "MJPEG bitrate vs. settings: simulated camera (solid) and the thesis's Axis 214 (dashed, tables read as kB/s)",
        fontsize=10,
    )
    fig.tight_layout(rect=(0.0, 0.14, 1.0, 1.0))
    fig.savefig(out_png, dpi=100)
    plt.close(fig)
    log(f"wrote {out_png} and {out_csv}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "images"), help="output folder")
    ap.add_argument("--quick", action="store_true", help="shorter measurements, one resolution (for tests)")
    ap.add_argument("--only", choices=("zoom", "bitrate"), help="make only one of the figures")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    cam = SimulatedCamera(load_world(), port=0).start()
    try:
        with httpx.Client(base_url=cam.base_url, timeout=10.0) as client:
            if a.only in (None, "zoom"):
                zooms = (1, 9999) if a.quick else ZOOMS
                zoom_montage(client, out / "zoom_montage.png", zooms)
            if a.only in (None, "bitrate"):
                resolutions = ("176x144",) if a.quick else RESOLUTIONS
                bitrate(client, out / "bitrate.png", out / "bitrate.csv", resolutions, a.quick)
    finally:
        cam.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
