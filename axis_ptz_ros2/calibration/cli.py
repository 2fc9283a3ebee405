"""``axis_calibrate``: extrinsic calibration of the PTZ base from a correspondence file (ROS-free).

Sub-commands::

    axis_calibrate solve CORRESPONDENCES.yaml [--camera-model config/axis214.yaml] [--out mount.yaml]
                   [--encoder-offsets] [--sigma-px 1.0] [--sigma-3d 0.02] [--no-robust] [--holdout auto]
    axis_calibrate synth OUT.yaml [--seed 0] [--views 5] [--points 8] [--pixel-noise 1] [--point-noise 0.02]

    axis_calibrate capture OUT.yaml [--poses "pan_deg,tilt_deg[,zoom];..."] [--views N] [--pick none|auto]
                   [--camera-model ...] [--mount config/mount.yaml] [--robot config/robot.yaml]
                   [--laser-pose x,y,z,roll_deg,pitch_deg,yaw_deg] [--sim-world config/sim_world.yaml]

Exit codes: 0 success, 1 bad input (file or arguments), 2 calibration refused (the reason is printed),
3 capture failed (ROS data missing, head did not arrive; the reason is printed).

``capture`` records views from the running ROS system (``ptz/state``, ``image_raw/compressed``,
``laser/points``; see :mod:`axis_ptz_ros2.calibration.capture`) and appends them to OUT.yaml with
:func:`~axis_ptz_ros2.calibration.correspondences.append_view`. With ``--pick auto`` (simulated calibration
boards only) the pairs are picked automatically; otherwise a person adds them to each view's ``points``.
"""

from __future__ import annotations

import argparse
import math
import os
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
from axis_ptz_ros2.config import load_camera_model, load_mount, load_robot, save_mount


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


def _relpath(target: Path, start: Path) -> str:
    try:
        return os.path.relpath(target.resolve(), start.resolve())
    except ValueError:  # other drive (Windows)
        return str(target.resolve())


def _cmd_capture(args: argparse.Namespace) -> int:
    # Imported here: the capture module is ROS-free at import time, but keep the solve path light.
    from axis_ptz_ros2.calibration import capture as cap

    try:
        poses = cap.parse_poses(args.poses) if args.poses else None
        n_views = args.views if args.views is not None else (len(poses) if poses else 0)
        if n_views <= 0:
            raise ValueError("give --poses or --views N")
        if poses is not None and n_views != len(poses):
            raise ValueError(f"--views {n_views} but {len(poses)} poses given")
        model = load_camera_model(args.camera_model)
        mount = load_mount(args.mount)
        robot = load_robot(args.robot)
        T_laser = cap.parse_pose6(args.laser_pose) if args.laser_pose else robot.laser.pose
        laser_frame = args.laser_frame or robot.laser.frame
        names = cap.next_view_names(args.out, n_views, args.name_prefix)
        picker = None
        if args.pick == "auto":
            picker = cap.SimBoardPicker(args.sim_world, model, mount.transform, mode=args.pick_mode)
    except (OSError, ValueError, CorrespondenceError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    model_ref = None
    if args.camera_model is not None:
        model_ref = _relpath(args.camera_model, args.out.parent)
    prompt = None
    if poses is None:

        def prompt(message: str) -> bool:
            try:
                return input(message + " (q + Enter stops) ").strip().lower() != "q"
            except EOFError:
                return False

    try:
        with cap.RosCapture(
            args.namespace,
            T_base_laser=T_laser,
            laser_frame=laser_frame,
            base_frame=robot.base_frame,
            pan_offset=mount.pan_offset,
            tilt_offset=mount.tilt_offset,
            laser_qos=args.laser_qos,
            settle_s=args.settle,
            timeout_s=args.timeout,
        ) as ros:
            ros.session.wait_ready()
            report = cap.capture_views(
                ros.session,
                args.out,
                names,
                poses=poses,
                picker=picker,
                camera_model_ref=model_ref,
                prompt=prompt,
                log=print,
                ply=args.ply,
            )
    except (cap.CaptureError, CorrespondenceError) as err:
        print(f"capture failed: {err}", file=sys.stderr)
        return 3
    print(f"\nwrote {len(report.views)} views to {args.out} (images and laser snapshots in {cap.views_dir(args.out)})")
    if picker is not None:
        noise = report.picking_noise()
        print(
            f"automatic picking: {noise.n} pairs; 3-D picking error against the simulated scene "
            f"({args.pick_mode}): RMS {noise.rms * 100:.2f} cm ({noise.rms_per_axis * 100:.2f} cm per axis), "
            f"median {noise.median * 100:.2f} cm, max {noise.max * 100:.2f} cm"
        )
        print(f"next: axis_calibrate solve {args.out} --sigma-3d {max(noise.rms_per_axis, 0.002):.3f} --out mount.yaml")
    else:
        print("next: add the picked pairs to each view's points (see the docs), then axis_calibrate solve")
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
    c = sub.add_parser("capture", help="record views (PTZ state, image, laser snapshot) from the running ROS system")
    c.add_argument("out", type=Path, help="correspondence YAML to append the views to (created if missing)")
    c.add_argument("--poses", default=None, help='"pan_deg,tilt_deg[,zoom];..." REP-103 degrees, VAPIX zoom units')
    c.add_argument("--views", type=int, default=None, help="number of views (default: one per pose)")
    c.add_argument("--pick", choices=["none", "auto"], default="none", help="auto: simulated boards only")
    c.add_argument("--pick-mode", choices=["nearest", "plane", "blob"], default="blob", help="laser pick refinement")
    c.add_argument("--sim-world", type=Path, default=None, help="simulated world (auto picking; default built-in)")
    c.add_argument("--camera-model", type=Path, default=None, help="camera model YAML (recorded in the file)")
    c.add_argument(
        "--mount",
        type=Path,
        default=None,
        help="mount file the PTZ node runs with (encoder offsets, "
        "and the pose guess for auto picking); default config/mount.yaml",
    )
    c.add_argument("--robot", type=Path, default=None, help="robot YAML with the laser pose (config/robot.yaml)")
    c.add_argument("--laser-pose", default=None, help="base_link -> laser 'x,y,z,roll_deg,pitch_deg,yaw_deg'")
    c.add_argument("--laser-frame", default=None, help="frame_id of laser/points (default: the robot file's)")
    c.add_argument("--laser-qos", choices=["reliable", "best_effort"], default="reliable")
    c.add_argument("--settle", type=float, default=0.3, help="wait after the head stopped before the frame [s]")
    c.add_argument("--timeout", type=float, default=15.0, help="timeout for moves and data [s]")
    c.add_argument("--name-prefix", default="view", help="view names PREFIXNN")
    c.add_argument("--ply", action="store_true", help="also write each laser snapshot as PLY (for point viewers)")
    c.add_argument("--namespace", default="", help="ROS namespace of the camera topics")
    c.set_defaults(func=_cmd_capture)
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``axis_calibrate`` console script."""
    args = build_parser().parse_args(argv)
    rc: int = args.func(args)
    return rc


if __name__ == "__main__":
    sys.exit(main())
