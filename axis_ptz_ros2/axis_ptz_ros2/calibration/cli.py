"""``axis_calibrate``: extrinsic calibration of the PTZ base from a correspondence file (ROS-free).

Sub-commands::

    axis_calibrate solve CORRESPONDENCES.yaml [--camera-model config/axis214.yaml] [--camera-info ost.yaml]
                   [--fixed] [--out mount.yaml] [--report report.json] [--encoder-offsets] [--sigma-px 1.0]
                   [--sigma-3d 0.02] [--max-sigma-cm X] [--max-sigma-deg Y] [--no-robust] [--holdout auto]
    axis_calibrate synth OUT.yaml [--seed 0] [--views 5] [--points 8] [--pixel-noise 1] [--point-noise 0.02]
                   [--outliers 0.1] [--distortion plumb_bob --camera-info-out ost.yaml] [--fixed]

    axis_calibrate capture OUT.yaml [--poses "pan_deg,tilt_deg[,zoom];..."] [--views N]
                   [--picker MODULE:NAME [--picker-arg KEY=VALUE ...] [--pick-mode blob]]
                   [--camera-model ...] [--mount config/mount.yaml] [--robot config/robot.yaml]
                   [--laser-pose x,y,z,roll_deg,pitch_deg,yaw_deg]

Exit codes: 0 success, 1 bad input (file or arguments), 2 calibration refused (the reason is printed),
3 capture failed (ROS data missing, head did not arrive; the reason is printed).

``solve`` takes the raw pixels the user clicked; with ``--camera-info`` (the ROS camera calibration YAML the
``camera_calibration`` tool writes) they are modelled with the measured K and distortion. ``--fixed`` solves a
fixed camera (no PTZ head): the result is the optical frame's pose in the reference (laser) frame. The solve
refuses only when the data cannot determine the pose; ``--max-sigma-cm`` / ``--max-sigma-deg`` make it strict.
``--report`` writes a JSON report (:mod:`~axis_ptz_ros2.calibration.report`), also for a refusal.

``capture`` records views from the running ROS system (``ptz/state``, ``image_raw/compressed``,
``laser/points``; see :mod:`axis_ptz_ros2.calibration.capture`; the ROS side, plugged in by the executable, is
:mod:`axis_ptz_ros2.nodes.calibration_capture`) and appends them to OUT.yaml with
:func:`~axis_ptz_ros2.calibration.correspondences.append_view`. With ``--picker`` a plug-in
(:class:`~axis_ptz_ros2.calibration.capture.BoardPicker`; the tests pass the simulated boards' picker) picks
the pairs automatically; otherwise a person adds them to each view's ``points``.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import sys
from collections.abc import Sequence
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from axis_ptz_ros2.calibration.correspondences import (
    CorrespondenceError,
    CorrespondenceSet,
    load_correspondences,
    save_correspondences,
)
from axis_ptz_ros2.calibration.report import report_dict, write_report
from axis_ptz_ros2.calibration.result import CalibrationInputError, CalibrationResult
from axis_ptz_ros2.calibration.solver import calibrate
from axis_ptz_ros2.calibration.synthetic import make_fixed_scene, make_scene, real_like_camera_info
from axis_ptz_ros2.camera_info import CameraInfoError, load_camera_info, save_camera_info
from axis_ptz_ros2.config import load_camera_model, load_mount, load_robot, save_mount

if TYPE_CHECKING:
    from axis_ptz_ros2.calibration.capture import CaptureOpener


def format_result(result: CalibrationResult, *, max_rows: int = 200) -> str:
    """Human-readable report: transform, σ per axis, focal check, residual table, held-out error."""
    x, y, z, r, p, yw = result.xyz_rpy()
    st = result.sigma_translation_m * 100.0
    sr = np.degrees(result.sigma_rotation_rad)
    name = "T_ref_opt" if result.fixed else "T_base_ptz"
    lines = [
        f"{name:<11} xyz [m]   : {x:+.4f} {y:+.4f} {z:+.4f}",
        f"            rpy [deg] : {math.degrees(r):+.3f} {math.degrees(p):+.3f} {math.degrees(yw):+.3f}",
        f"σ translation [cm]    : x {st[0]:.2f}  y {st[1]:.2f}  z {st[2]:.2f}",
        f"σ rotation [deg]      : rotX {sr[0]:.3f}  rotY {sr[1]:.3f}  rotZ {sr[2]:.3f}  (about parent axes)",
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
    lines += [f"WARNING               : {w}" for w in result.warnings]
    if not result.fixed and result.views:
        lines.append("")
        lines.append(
            f"{'view':<12} {'camera xyz in reference frame [m]':<34} {'σ xyz [cm]':<20} {'RMS px':>7} {'held-out':>8}"
        )
        for v in result.views:
            t = v.T_reference_optical.t
            s3 = np.asarray(v.sigma_translation_m) * 100.0
            lines.append(
                f"{v.name[:12]:<12} {t[0]:+9.4f} {t[1]:+9.4f} {t[2]:+9.4f}       "
                f"{s3[0]:5.2f} {s3[1]:5.2f} {s3[2]:5.2f}    {v.rms_px:7.2f} {v.holdout_rms_px:8.2f}"
            )
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


def _writable_target(path: Path, what: str) -> str | None:
    """Why ``path`` cannot be written (checked before the solve, so no work is lost), or None."""
    parent = path.expanduser().resolve().parent
    if path.exists() and path.is_dir():
        return f"{what} {path} is a directory"
    if not parent.is_dir():
        return f"{what} {path}: folder {parent} does not exist"
    if not os.access(parent, os.W_OK):
        return f"{what} {path}: folder {parent} is not writable"
    return None


def _refuse_unwritable(*targets: tuple[Path | None, str]) -> bool:
    """Print the error for the first ``(path or None, what)`` that cannot be written; True if one cannot."""
    for target, what in targets:
        problem = None if target is None else _writable_target(target, what)
        if problem:
            print(f"error: {problem}", file=sys.stderr)
            return True
    return False


def _cmd_solve(args: argparse.Namespace) -> int:
    if _refuse_unwritable((args.out, "--out"), (args.report, "--report")):
        return 1
    if args.max_sigma_cm is not None and not args.max_sigma_cm > 0:
        print("error: --max-sigma-cm must be positive", file=sys.stderr)
        return 1
    if args.max_sigma_deg is not None and not args.max_sigma_deg > 0:
        print("error: --max-sigma-deg must be positive", file=sys.stderr)
        return 1
    if not (args.sigma_px > 0 and args.sigma_3d >= 0):
        print("error: --sigma-px must be positive and --sigma-3d non-negative", file=sys.stderr)
        return 1
    try:
        cs = load_correspondences(args.correspondences)
    except CorrespondenceError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    model_path = args.camera_model or cs.resolve_camera_model()
    try:
        cm = load_camera_model(model_path)
    except ValueError as err:  # CameraModelError: broken YAML, duplicate or unknown keys, bad values
        print(f"error: camera model: {err}", file=sys.stderr)
        return 1
    if args.camera_info is not None:
        try:
            cm = cm.with_camera_info(load_camera_info(args.camera_info), args.camera_info_zoom)
        except CameraInfoError as err:
            print(f"error: camera info: {err}", file=sys.stderr)
            return 1
    if args.fixed and cm.camera_info is None:
        print(
            "warning: --fixed without --camera-info: using the camera model's nominal wide-end intrinsics "
            "(no distortion); measure the camera with the ROS camera_calibration tool for real data",
            file=sys.stderr,
        )
    child = args.child_frame or ("camera_optical_frame" if args.fixed else "axis_ptz_base")
    source = str(args.correspondences)
    refused: str | None = None
    try:
        result = calibrate(
            cs.views,
            cm,
            fixed=args.fixed,
            estimate_encoder_offsets=args.encoder_offsets,
            sigma_px=args.sigma_px,
            sigma_3d_m=args.sigma_3d,
            robust=not args.no_robust,
            holdout_mode=args.holdout,
            max_sigma_translation_m=args.max_sigma_cm / 100.0 if args.max_sigma_cm else math.inf,
            max_sigma_rotation_deg=args.max_sigma_deg if args.max_sigma_deg else math.inf,
            raise_on_refusal=False,
            source=source,
        )
    except CalibrationInputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    refused = result.refused_reason
    if args.report is not None:
        inputs = {
            "correspondences": source,
            "camera_model": str(model_path) if model_path else "built-in",
            "camera_info": str(args.camera_info) if args.camera_info else None,
            "fixed": bool(args.fixed),
        }
        write_report(report_dict(result, parent_frame=args.parent_frame, child_frame=child, inputs=inputs), args.report)
    if result.solved:
        print(format_result(result))
    if refused is not None:
        print(f"\nREFUSED: {refused}", file=sys.stderr)
        if args.report is not None:
            print(f"wrote {args.report}")
        return 2
    if args.out:
        mount = result.to_mount_config(args.parent_frame, child)
        save_mount(mount, args.out)
        print(f"\nwrote {args.out}")
    if args.report is not None:
        print(f"wrote {args.report}")
    return 0


def _cmd_synth(args: argparse.Namespace) -> int:
    if args.camera_info_out is not None and args.distortion == "none":
        print("error: --camera-info-out needs --distortion (the nominal model has no camera_info)", file=sys.stderr)
        return 1
    if _refuse_unwritable((args.out, "output"), (args.camera_info_out, "--camera-info-out")):
        return 1
    ref = None
    if args.camera_model_ref is not None:
        ref = Path(args.camera_model_ref).expanduser()
        ref = ref if ref.is_absolute() else args.out.parent / ref
    try:
        cm = load_camera_model(ref)  # the model `solve` will load for this file
    except ValueError as err:
        print(f"error: camera model: {err}", file=sys.stderr)
        return 1
    if args.distortion != "none":
        cm = cm.with_camera_info(real_like_camera_info(args.distortion))
    make = partial(make_fixed_scene, args.seed, cm) if args.fixed else partial(make_scene, args.seed, camera_model=cm)
    scene = make(
        n_views=args.views,
        points_per_view=args.points,
        pixel_noise_px=args.pixel_noise,
        point_noise_m=args.point_noise,
        outlier_fraction=args.outliers,
    )
    x, y, z, r, p, yw = scene.truth.xyz_rpy()
    what = "T_reference_optical" if args.fixed else "T_base_ptz"
    comment = (
        f"synthetic scene seed {args.seed}: true {what} xyz [{x:.4f}, {y:.4f}, {z:.4f}] m, "
        f"rpy [{math.degrees(r):.3f}, {math.degrees(p):.3f}, {math.degrees(yw):.3f}] deg; "
        f"noise {args.pixel_noise} px, {args.point_noise} m"
        + (f", {args.outliers:.0%} outliers" if args.outliers else "")
        + (f"; raw pixels of a {args.distortion} lens" if args.distortion != "none" else "")
    )
    save_correspondences(CorrespondenceSet(scene.views, args.camera_model_ref, comment), args.out)
    print(f"wrote {args.out}: {comment}")
    if args.camera_info_out is not None and cm.camera_info is not None:
        save_camera_info(cm.camera_info, args.camera_info_out)
        print(f"wrote {args.camera_info_out} (solve with --camera-info {args.camera_info_out})")
    return 0


def _relpath(target: Path, start: Path) -> str:
    try:
        return os.path.relpath(target.resolve(), start.resolve())
    except ValueError:  # other drive (Windows)
        return str(target.resolve())


def _interrupt_once(signum: int, frame: object) -> None:
    """SIGINT or SIGTERM (launch's second step, a service manager's stop): stop the capture once; a second signal
    (under launch, terminal and launch both send one) must not cut the clean-up short, and SIG_IGN also outlives
    the interpreter's finalisation (no exit by signal)."""
    for sig in _STOP_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)
    raise KeyboardInterrupt


_STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def _cmd_capture(args: argparse.Namespace) -> int:
    # Imported here: keep the solve path light.
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
        if args.picker:
            factory = cap.load_picker_factory(args.picker)
            options = cap.parse_picker_options(args.picker_arg)
            try:
                picker = factory(model, mount.transform, mode=args.pick_mode, **options)
            except TypeError as err:  # an option the picker does not take
                raise ValueError(f"picker {args.picker}: {err}") from err
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

    open_capture: CaptureOpener | None = args.open_capture
    if open_capture is None:
        print(
            "error: capture needs the ROS side: run the axis_calibrate executable "
            "(axis_ptz_ros2.nodes.calibration_capture:main)",
            file=sys.stderr,
        )
        return 1
    for sig in _STOP_SIGNALS:
        signal.signal(sig, _interrupt_once)
    try:
        with open_capture(
            args.namespace,
            T_base_laser=T_laser,
            laser_frame=laser_frame,
            base_frame=robot.base_frame,
            pan_offset=mount.pan_offset,
            tilt_offset=mount.tilt_offset,
            laser_qos=args.laser_qos,
            settle_s=args.settle,
            timeout_s=args.timeout,
        ) as session:
            session.wait_ready()
            report = cap.capture_views(
                session,
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
    except KeyboardInterrupt:  # Ctrl-C is how a user ends a capture: every view taken is already in the file
        print(f"\ncapture stopped (Ctrl-C); the views captured so far are in {args.out}", file=sys.stderr)
        return 0
    print(f"\nwrote {len(report.views)} views to {args.out} (images and laser snapshots in {cap.views_dir(args.out)})")
    if picker is not None:
        noise = report.picking_noise()
        print(
            f"automatic picking: {noise.n} pairs; 3-D picking error against the picker's feature positions "
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
    s.add_argument("--camera-info", type=Path, default=None, help="measured intrinsics: ROS camera calibration YAML")
    s.add_argument(
        "--camera-info-zoom",
        type=float,
        default=None,
        help="VAPIX zoom units the camera info was measured at (default: the wide end)",
    )
    s.add_argument("--fixed", action="store_true", help="fixed camera: solve the optical frame in the laser frame")
    s.add_argument("--out", type=Path, default=None, help="write the mount file (axis_ptz_ros2/mount/v1) here")
    s.add_argument("--report", type=Path, default=None, help="write a JSON report here (also when refused)")
    s.add_argument("--max-sigma-cm", type=float, default=None, help="refuse if a translation σ exceeds this [cm]")
    s.add_argument("--max-sigma-deg", type=float, default=None, help="refuse if a rotation σ exceeds this [deg]")
    s.add_argument("--encoder-offsets", action="store_true", help="also estimate the tilt encoder offset")
    s.add_argument("--sigma-px", type=float, default=1.0, help="pixel picking noise σ per axis [px] (1.0)")
    s.add_argument("--sigma-3d", type=float, default=0.02, help="3-D point picking noise σ per axis [m] (0.02)")
    s.add_argument("--no-robust", action="store_true", help="plain least squares, no outlier rejection")
    s.add_argument("--holdout", choices=["auto", "views", "points", "none"], default="auto")
    s.add_argument("--parent-frame", default="base_link")
    s.add_argument("--child-frame", default=None, help="default axis_ptz_base (PTZ) or camera_optical_frame (--fixed)")
    s.set_defaults(func=_cmd_solve)
    g = sub.add_parser("synth", help="write a synthetic correspondence file with known truth (for testing)")
    g.add_argument("out", type=Path)
    g.add_argument("--seed", type=int, default=0)
    g.add_argument("--views", type=int, default=5)
    g.add_argument("--points", type=int, default=8)
    g.add_argument("--pixel-noise", type=float, default=1.0, help="px, σ per axis")
    g.add_argument("--point-noise", type=float, default=0.02, help="m, σ per axis")
    g.add_argument("--camera-model-ref", default=None, help="camera_model path to record in the file")
    g.add_argument("--outliers", type=float, default=0.0, help="fraction of gross outliers (30–150 px)")
    g.add_argument(
        "--distortion",
        choices=["none", "plumb_bob", "rational_polynomial", "equidistant"],
        default="none",
        help="raw pixels of a real-like measured lens (off-centre principal point, distortion)",
    )
    g.add_argument("--camera-info-out", type=Path, default=None, help="write that lens' camera_info YAML here")
    g.add_argument("--fixed", action="store_true", help="a fixed camera (views without pan/tilt/zoom)")
    g.set_defaults(func=_cmd_synth)
    c = sub.add_parser("capture", help="record views (PTZ state, image, laser snapshot) from the running ROS system")
    c.add_argument("out", type=Path, help="correspondence YAML to append the views to (created if missing)")
    c.add_argument("--poses", default=None, help='"pan_deg,tilt_deg[,zoom];..." REP-103 degrees, VAPIX zoom units')
    c.add_argument("--views", type=int, default=None, help="number of views (default: one per pose)")
    c.add_argument(
        "--picker",
        default=None,
        metavar="MODULE:NAME",
        help="automatic picking plug-in (MODULE:NAME or PATH.py:NAME, e.g. the tests' simulated-board picker "
        "tests/support/sim_picker.py:SimBoardPicker); default: none, a person picks",
    )
    c.add_argument(
        "--picker-arg",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="option for the picker (repeatable), e.g. world_file=config/sim_world.yaml",
    )
    c.add_argument("--pick-mode", choices=["nearest", "plane", "blob"], default="blob", help="laser pick refinement")
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


def main(argv: Sequence[str] | None = None, *, open_capture: CaptureOpener | None = None) -> int:
    """The ``axis_calibrate`` command line; ``open_capture``: the ROS side ``capture`` records views with (the
    executable, :func:`axis_ptz_ros2.nodes.calibration_capture.main`, plugs it in; without it ``capture``
    refuses once its arguments are checked)."""
    args = build_parser().parse_args(argv)
    args.open_capture = open_capture
    try:
        rc: int = args.func(args)
    except BrokenPipeError:  # output piped into `head` & co.: stop quietly, like other command-line tools
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    return rc


if __name__ == "__main__":
    sys.exit(main())
