"""``axis_calibrate``: extrinsic calibration of the PTZ base from a correspondence file (ROS-free).

Sub-commands::

    axis_calibrate solve CORRESPONDENCES.yaml [--camera-model config/axis214.yaml] [--out mount.yaml]
                   [--encoder-offsets] [--sigma-px 1.0] [--sigma-3d 0.02] [--no-robust] [--holdout auto]
    axis_calibrate synth OUT.yaml [--seed 0] [--views 5] [--points 8] [--pixel-noise 1] [--point-noise 0.02]

Exit codes: 0 success, 1 bad input (file or arguments), 2 calibration refused (the reason is printed).
The ``capture`` sub-command (recording views from the running ROS system) builds on
:func:`axis_ptz_ros2.calibration.correspondences.append_view`.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from axis_ptz_ros2.calibration.correspondences import (
    CorrespondenceError,
    CorrespondenceSet,
    load_correspondences,
    save_correspondences,
)
from axis_ptz_ros2.calibration.solver import CalibrationRefused, CalibrationResult, calibrate
from axis_ptz_ros2.calibration.synthetic import make_scene
from axis_ptz_ros2.config import load_camera_model, save_mount


def format_result(result: CalibrationResult, *, max_rows: int = 200) -> str:
    """Human-readable report: transform, σ per axis, focal check, residual table, held-out error."""
    x, y, z, r, p, yw = result.xyz_rpy()
    st = result.sigma_translation_m * 100.0
    sr = np.degrees(result.sigma_rotation_rad)
    lines = [
        f"T_base_ptz  xyz [m]   : {x:+.4f} {y:+.4f} {z:+.4f}",
        f"            rpy [deg] : {math.degrees(r):+.3f} {math.degrees(p):+.3f} {math.degrees(yw):+.3f}",
        f"σ translation [cm]    : x {st[0]:.2f}  y {st[1]:.2f}  z {st[2]:.2f}",
        f"σ rotation [deg]      : rotX {sr[0]:.3f}  rotY {sr[1]:.3f}  rotZ {sr[2]:.3f}  (about base axes)",
    ]
    if result.tilt_offset_sigma > 0:
        lines.append(
            f"tilt encoder offset   : {math.degrees(result.tilt_offset):+.3f}° ± "
            f"{math.degrees(result.tilt_offset_sigma):.3f}° (pan offset is part of the yaw)"
        )
    lines += [
        f"points                : {result.n_inliers}/{result.n_points} inliers in {result.n_views} views "
        f"(start: {result.start})",
        f"RMS reprojection      : {result.rms_px:.2f} px (normalised {result.normalised_rms:.2f})",
        f"held-out ({result.holdout_mode:6s})     : RMS {result.holdout_rms_px:.2f} px, "
        f"p95 {result.holdout_p95_px:.2f} px",
        f"focal check           : {result.focal_check.message}",
    ]
    lines += [f"note                  : {n}" for n in result.notes]
    lines.append("")
    lines.append(f"{'view':<12} {'#':>3} {'label':<16} {'u':>8} {'v':>8} {'du':>7} {'dv':>7} {'|e| px':>7} {'e/σ':>5}")
    for row in result.residuals[:max_rows]:
        du = row.predicted[0] - row.pixel[0]
        dv = row.predicted[1] - row.pixel[1]
        flag = "" if row.inlier else "  OUTLIER"
        lines.append(
            f"{row.view[:12]:<12} {row.index:>3} {row.label[:16]:<16} "
            f"{row.pixel[0]:8.1f} {row.pixel[1]:8.1f} "
            f"{du:+7.2f} {dv:+7.2f} {row.error_px:7.2f} {row.normalised:5.2f}{flag}"
        )
    if len(result.residuals) > max_rows:
        lines.append(f"... {len(result.residuals) - max_rows} more rows")
    return "\n".join(lines)


def _cmd_solve(args: argparse.Namespace) -> int:
    try:
        cs = load_correspondences(args.correspondences)
    except CorrespondenceError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    model_path = args.camera_model or cs.resolve_camera_model()
    try:
        cm = load_camera_model(model_path)
    except (OSError, ValueError) as err:
        print(f"error: camera model {model_path}: {err}", file=sys.stderr)
        return 1
    try:
        result = calibrate(
            cs.views,
            cm,
            estimate_encoder_offsets=args.encoder_offsets,
            sigma_px=args.sigma_px,
            sigma_3d_m=args.sigma_3d,
            robust=not args.no_robust,
            holdout_mode=args.holdout,
        )
    except CalibrationRefused as err:
        if err.result is not None:
            print(format_result(err.result))
            print()
        print(f"REFUSED: {err.reason}", file=sys.stderr)
        return 2
    print(format_result(result))
    if args.out:
        mount = result.to_mount_config(args.parent_frame, args.child_frame)
        save_mount(mount, args.out)
        print(f"\nwrote {args.out}")
    return 0


def _cmd_synth(args: argparse.Namespace) -> int:
    scene = make_scene(
        args.seed,
        n_views=args.views,
        points_per_view=args.points,
        pixel_noise_px=args.pixel_noise,
        point_noise_m=args.point_noise,
    )
    x, y, z, r, p, yw = scene.truth.xyz_rpy()
    comment = (
        f"synthetic scene seed {args.seed}: true T_base_ptz xyz [{x:.4f}, {y:.4f}, {z:.4f}] m, "
        f"rpy [{math.degrees(r):.3f}, {math.degrees(p):.3f}, {math.degrees(yw):.3f}] deg; "
        f"noise {args.pixel_noise} px, {args.point_noise} m"
    )
    save_correspondences(CorrespondenceSet(scene.views, args.camera_model_ref, comment), args.out)
    print(f"wrote {args.out}: {comment}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (exposed for documentation and tests)."""
    ap = argparse.ArgumentParser(prog="axis_calibrate", description=__doc__.split("\n")[0] if __doc__ else None)
    sub = ap.add_subparsers(dest="command", required=True)
    s = sub.add_parser("solve", help="calibrate base_link -> ptz_base from a correspondence file")
    s.add_argument("correspondences", type=Path, help="correspondence YAML (axis_ptz_ros2/correspondences/v1)")
    s.add_argument("--camera-model", type=Path, default=None, help="camera model YAML (default: file's or built-in)")
    s.add_argument("--out", type=Path, default=None, help="write the mount file (axis_ptz_ros2/mount/v1) here")
    s.add_argument("--encoder-offsets", action="store_true", help="also estimate the tilt encoder offset")
    s.add_argument("--sigma-px", type=float, default=1.0, help="pixel picking noise σ per axis [px] (1.0)")
    s.add_argument("--sigma-3d", type=float, default=0.02, help="3-D point picking noise σ per axis [m] (0.02)")
    s.add_argument("--no-robust", action="store_true", help="plain least squares, no outlier rejection")
    s.add_argument("--holdout", choices=["auto", "views", "points", "none"], default="auto")
    s.add_argument("--parent-frame", default="base_link")
    s.add_argument("--child-frame", default="axis_ptz_base")
    s.set_defaults(func=_cmd_solve)
    g = sub.add_parser("synth", help="write a synthetic correspondence file with known truth (for testing)")
    g.add_argument("out", type=Path)
    g.add_argument("--seed", type=int, default=0)
    g.add_argument("--views", type=int, default=5)
    g.add_argument("--points", type=int, default=8)
    g.add_argument("--pixel-noise", type=float, default=1.0, help="px, σ per axis")
    g.add_argument("--point-noise", type=float, default=0.02, help="m, σ per axis")
    g.add_argument("--camera-model-ref", default=None, help="camera_model path to record in the file")
    g.set_defaults(func=_cmd_synth)
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``axis_calibrate`` console script."""
    args = build_parser().parse_args(argv)
    rc: int = args.func(args)
    return rc


if __name__ == "__main__":
    sys.exit(main())
