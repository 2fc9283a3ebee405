"""Acuity of the simulated Axis 214's pictures: rows of the acuity chart read at 10, 20 and 35 m (no link).

Run: ``.venv/bin/python bench/bench_acuity.py [--frames 4] [--compressions 0,30,60,100]``. For each chart of the
demo world (``config/sim_world.yaml``: ``acuity_10m``, ``acuity_20m``, ``acuity_35m``; the picture and its answer
key: ``bench/acuity_chart.py``) the head is aimed at the chart's centre, zoomed as far as the whole chart stays in
the 704×576 view (at most the tele limit), and the simulated 214's JPEGs (``sim/camera_model.py``: its softness,
sensor noise and quality curve; ``--frames`` frames each, each with its own noise) are read by ``bench/acuity.py``
(chart located by its markers). Reports rows read (line by line, a row read at 3 of 5), the smallest row's stroke
(mm, picture pixels, logMAR at the chart's distance) and the chance-corrected fraction of optotypes right; also the
ideal render (no camera model) for reference. In process: no HTTP, no link.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import acuity  # noqa: E402
import acuity_chart as chart  # noqa: E402
from report import SIM_CONFIG, inputs, row  # noqa: E402  (bench/report.py)

from axis_ptz_ros2.sim.camera_model import PicturePool  # noqa: E402
from axis_ptz_ros2.sim.persona import AXIS_214  # noqa: E402
from axis_ptz_ros2.sim.renderer import PtzRenderer  # noqa: E402
from axis_ptz_ros2.sim.world import load_world  # noqa: E402

CHARTS = ("acuity_10m", "acuity_20m", "acuity_35m")
W, H = 704, 576


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=4, help="JPEG frames read per setting (each its own noise)")
    ap.add_argument("--compressions", default="0,30,60,100", help="VAPIX compressions, comma-separated")
    args = ap.parse_args(argv)
    compressions = [int(c) for c in args.compressions.split(",")]
    inputs(
        "bench/bench_acuity.py",
        "bench/acuity.py",
        "bench/acuity_chart.py",
        "axis_ptz_ros2/axis_ptz_ros2/sim",
        *SIM_CONFIG,
        "axis_ptz_ros2/axis_ptz_ros2/geometry.py",
        "axis_ptz_ros2/axis_ptz_ros2/transforms.py",
        "axis_ptz_ros2/axis_ptz_ros2/optics.py",
        "config/sim_world.yaml",
    )
    world = load_world()
    renderer = PtzRenderer(world)
    model = AXIS_214.picture
    print(f"simulated 214 ({W}x{H}), chart {chart.WIDTH_MM:.0f}x{chart.HEIGHT_MM:.0f} mm, {chart.N_ROWS} rows of "
          f"{chart.PER_ROW} Es, strokes {chart.stroke_mm(0):.1f} ... {chart.stroke_mm(chart.N_ROWS - 1):.1f} mm; "
          f"{args.frames} frames a setting")  # fmt: skip
    failed = False
    for name in CHARTS:
        target = renderer.scene.target(name)
        pan, tilt = acuity.aim(world, target.center)
        zoom = acuity.fit_zoom(renderer, target, pan, tilt, W, H)
        distance = float(np.linalg.norm(target.center - renderer.camera_pose(pan, tilt).t))
        t0 = time.perf_counter()
        view = renderer.render(pan, tilt, zoom, W, H)
        ideal = acuity.score(view)
        top = acuity._apply(
            acuity.pose_homography(renderer, target, pan, tilt, zoom, W, H), np.array([[0.0, 0.0], [chart.WIDTH_MM, 0]])
        )
        mm_per_px = chart.WIDTH_MM / float(np.linalg.norm(top[1] - top[0]))
        print(f"\n{name}: {distance:.1f} m, pan {pan:.2f} tilt {tilt:.2f} zoom {zoom:.0f} ({mm_per_px:.2f} mm a pixel)")
        print(f"  ideal render        : {ideal.summary(distance)}")
        for comp in compressions:
            pool = PicturePool(model)
            scores = [acuity.score(pool.jpeg(name, lambda v=view: v, zoom, comp)) for _ in range(args.frames)]
            rows = [s.rows_read for s in scores]
            if not all(s.found for s in scores):
                print(f"  compression {comp:3d}     : chart not found in {sum(not s.found for s in scores)} frames")
                failed = True
                continue
            best = max(scores, key=lambda s: s.rows_read)
            med = sorted(scores, key=lambda s: s.rows_read)[len(scores) // 2]
            cf = float(np.mean([s.corrected_fraction for s in scores]))
            sm = med.smallest_row
            smallest = (
                f"row {sm.index}: {sm.stroke_mm:.2f} mm = {sm.stroke_px:.2f} px, logMAR {med.logmar(distance):+.2f}"
                if sm is not None
                else "none"
            )
            print(
                f"  compression {comp:3d} (q{model.quality(comp, W):3d}): rows read {rows} (median {med.rows_read}, "
                f"best {best.rows_read}); median frame's smallest {smallest}; chance-corrected {cf:.3f}"
            )
            if comp == compressions[0]:
                row(
                    f"acuity chart at {distance:.0f} m, simulated 214 704x576 compression {comp}, zoom {zoom:.0f}",
                    f"{med.rows_read}/{chart.N_ROWS} rows ({smallest}); chance-corrected {cf:.2f}",
                )
        print(f"  ({time.perf_counter() - t0:.1f} s)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
