"""End-to-end extrinsic calibration against the simulated camera and laser over real DDS (loopback).

The loop of ``tests/ros/test_calibration_e2e.py``: simulated Axis 214 (in-process HTTP on 127.0.0.1) + stream
node + PTZ node running the NOMINAL mount (config/mount.yaml) + laser sim node; ``axis_calibrate capture``
logic commands the poses, records state, frame and laser snapshot per view and picks the board dots
automatically; ``calibrate`` recovers ``base_link → ptz_base``. Prints the recovered mount against the
simulator's truth (cm, deg per axis), σ, residuals and held-out error, the measured picking noise (pixels
against the true projection; 3-D for each laser pick mode against the scene's dot positions) and times.

    .venv/bin/python bench/bench_calibration_e2e.py [--pick-mode blob|plane|nearest] [--range-noise 0.0]
                                                    [--extra-boards] [--sigma-px 0.5] [--sigma-3d auto]

``--extra-boards`` adds the calibration boards proposed for ``config/sim_world.yaml`` (EXTRA_BOARDS below) to a
temporary copy of the world, with poses that see two boards per 1× view (≥ 5 views × 8 points).
"""

from __future__ import annotations

import os

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import argparse  # noqa: E402
import math  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import yaml  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from axis_ptz_ros2.calibration.capture import (  # noqa: E402
    CaptureSession,
    SimBoardPicker,
    capture_views,
    cloud_path,
    next_view_names,
    parse_poses,
)
from axis_ptz_ros2.calibration.cli import format_result  # noqa: E402
from axis_ptz_ros2.calibration.correspondences import load_correspondences  # noqa: E402
from axis_ptz_ros2.calibration.picking import pick_view, picking_noise  # noqa: E402
from axis_ptz_ros2.calibration.solver import CalibrationRefused, calibrate, rotation_angle  # noqa: E402
from axis_ptz_ros2.config import default_config_path, load_camera_model, load_mount, load_robot  # noqa: E402
from axis_ptz_ros2.geometry import matrix_to_rpy  # noqa: E402
from axis_ptz_ros2.nodes.harness import RosHarness  # noqa: E402
from axis_ptz_ros2.nodes.laser_sim import LaserSim  # noqa: E402
from axis_ptz_ros2.nodes.ptz_node import PtzNode  # noqa: E402
from axis_ptz_ros2.nodes.stream_node import StreamNode  # noqa: E402
from axis_ptz_ros2.sim.ptz import Speeds  # noqa: E402
from axis_ptz_ros2.sim.scene import load_world  # noqa: E402
from axis_ptz_ros2.sim.server import SimulatedCamera  # noqa: E402

#: The boards in config/sim_world.yaml: 1× views see at most two boards (front + left), 12 dots in all.
POSES = "25,7,1;0,5,1;-38,1,1;25,20,1;25,-5,1;12.7,7.5,1200;38.4,9.3,1200;-38.5,0.8,1200"

#: Proposed additions to config/sim_world.yaml `targets:` (all inside the laser's ±30° and 30 m, facing the
#: PTZ head, not occluding each other or the existing targets from the head or the laser).
EXTRA_BOARDS_YAML = """
  - {name: calib_near_right, kind: calib, center: [2.6, -1.2, 0.8], size: [0.80, 0.60]}
  - {name: calib_far_front, kind: calib, center: [7.0, -0.8, 1.6], size: [1.20, 0.90]}
  - {name: calib_low_left, kind: calib, center: [1.8, 1.6, 0.35], size: [0.80, 0.60]}
  - {name: calib_back_left, kind: calib, center: [1.0, 3.2, 1.3], size: [0.80, 0.60]}
  - {name: calib_right2, kind: calib, center: [2.0, -3.6, 1.3], size: [0.80, 0.60]}
"""
#: Poses for the extended world: 1× views on two boards each, tilted variants, and zoomed views.
POSES_EXTRA = (
    "25,7,1;3,6,1;-30,4,1;54,8,1;-48,5,1;30,-4,1;25,18,1;-30,-8,1;"
    "12.7,7.5,1200;-22,5,1200;-6,8,2000;69.6,12.5,1200;-58,10.4,1200"
)

SPEED = 300.0


def _world_file(tmp: Path, extra: bool) -> Path:
    base = default_config_path("sim_world.yaml")
    if not extra:
        return base
    text = base.read_text(encoding="utf-8").rstrip("\n") + "\n" + EXTRA_BOARDS_YAML.strip("\n") + "\n"
    p = tmp / "sim_world_extra.yaml"
    p.write_text(text, encoding="utf-8")
    return p


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0] if __doc__ else None)
    ap.add_argument("--pick-mode", choices=["nearest", "plane", "blob"], default="blob")
    ap.add_argument("--range-noise", type=float, default=0.0, help="laser range noise σ [m]")
    ap.add_argument("--extra-boards", action="store_true", help="add the proposed boards (EXTRA_BOARDS_YAML)")
    ap.add_argument("--poses", default=None, help="override the pose list 'pan_deg,tilt_deg,zoom;...'")
    ap.add_argument("--sigma-px", type=float, default=0.5)
    ap.add_argument("--sigma-3d", default="auto", help="m, or 'auto' = the measured per-axis picking noise")
    args = ap.parse_args()

    tmp = Path(tempfile.mkdtemp(prefix="bench_calib_e2e_"))
    world_file = _world_file(tmp, args.extra_boards)
    world = load_world(world_file)
    poses_text = args.poses or (POSES_EXTRA if args.extra_boards else POSES)
    poses = parse_poses(poses_text)

    model_dict = yaml.safe_load(default_config_path("axis214.yaml").read_text(encoding="utf-8"))
    model_dict["head"] = {"h_tilt": world.kinematics.h_tilt, "d_opt": list(world.kinematics.d_opt)}
    model_dict["max_speed"] = {"pan_dps": SPEED, "tilt_dps": SPEED}
    model_file = tmp / "model.yaml"
    model_file.write_text(yaml.safe_dump(model_dict), encoding="utf-8")
    model = load_camera_model(model_file)
    nominal_file = default_config_path("mount.yaml")
    nominal = load_mount(nominal_file)
    robot = load_robot()

    t0 = time.monotonic()
    cam = SimulatedCamera(world, port=0, speeds=Speeds(SPEED, SPEED, 0.5, 0.5)).start()
    h = RosHarness()
    try:
        ptz = h.add(
            PtzNode(
                context=h.context,
                parameter_overrides=[
                    Parameter("port", value=cam.port),
                    Parameter("camera_model", value=str(model_file)),
                    Parameter("mount_file", value=str(nominal_file)),
                    Parameter("arrival_tolerance", value=0.0005),
                ],
            )
        )
        h.add(
            StreamNode(
                context=h.context,
                parameter_overrides=[
                    Parameter("port", value=cam.port),
                    Parameter("camera_model", value=str(model_file)),
                    Parameter("compression", value=20),
                ],
            )
        )
        h.add(
            LaserSim(
                context=h.context,
                parameter_overrides=[
                    Parameter("rate", value=5.0),
                    Parameter("range_noise", value=args.range_noise),
                    Parameter("world_file", value=str(world_file)),
                ],
            )
        )
        probe = h.add(Node("bench_capture", context=h.context))
        deadline = time.monotonic() + 20
        while ptz.poller.latest is None and time.monotonic() < deadline:
            time.sleep(0.02)
        t_up = time.monotonic() - t0
        session = CaptureSession(probe, T_base_laser=robot.laser.pose, laser_frame=robot.laser.frame, timeout_s=20)
        session.wait_ready()
        picker = SimBoardPicker(world_file, model, nominal.transform, mode=args.pick_mode)
        out = tmp / "calib.yaml"
        t1 = time.monotonic()
        report = capture_views(session, out, next_view_names(out, len(poses)), poses=poses, picker=picker, log=print)
        t_capture = time.monotonic() - t1
        print(f"captured {len(report.views)} views, {len(report.picked)} pairs picked automatically")
        session.close()
    finally:
        h.close()
        cam.stop()

    cs = load_correspondences(out)
    # ---- picking noise ---------------------------------------------------------------------------------
    print(f"\n== picking noise ({len(cs.views)} views, {cs.n_points} pairs; poses {poses_text}) ==")
    px_err = []
    for v in cs.views:
        T = world.T_base_ptz @ world.kinematics.optical_in_ptz_base(v.pan, v.tilt)  # truth (the sim has no offsets)
        K = world.zoom_model.intrinsics(v.zoom, v.image_width, v.image_height)
        by_label = {f.label: f for f in picker.features}
        for c in v.points:
            uv = K.project(T.inverse().apply(np.array(by_label[c.label].point))[None])[0]
            px_err.append(np.hypot(c.pixel[0] - uv[0], c.pixel[1] - uv[1]))
    pe = np.array(px_err)
    print(
        f"pixels vs true projection      : RMS {np.sqrt(np.mean(pe**2)):.3f} px, median {np.median(pe):.3f}, "
        f"max {pe.max():.3f} px"
    )
    noise_by_mode = {}
    for mode in ("nearest", "plane", "blob"):
        picked = []
        for v in cs.views:
            img = cv2.imread(str(out.parent / str(v.image)), cv2.IMREAD_COLOR)
            cloud = np.load(cloud_path(out, v)).astype(np.float64)
            picked += pick_view(img, cloud, v.pan, v.tilt, v.zoom, picker.features, model, nominal.transform, mode=mode)
        n = picking_noise([p.laser.point for p in picked], [p.feature.point for p in picked])
        noise_by_mode[mode] = n
        print(
            f"3-D laser pick {mode:8s}        : RMS {n.rms * 100:.2f} cm ({n.rms_per_axis * 100:.2f} cm per axis), "
            f"median {n.median * 100:.2f} cm, max {n.max * 100:.2f} cm over {n.n} picks"
            + ("   <- used" if mode == args.pick_mode else "")
        )
    sigma_3d = (
        max(noise_by_mode[args.pick_mode].rms_per_axis, 0.002) if args.sigma_3d == "auto" else float(args.sigma_3d)
    )
    # ---- calibration -------------------------------------------------------------------------------------
    t2 = time.monotonic()
    try:
        res = calibrate(cs.views, model, sigma_px=args.sigma_px, sigma_3d_m=sigma_3d)
        refused = None
    except CalibrationRefused as err:
        refused, res = err.reason, err.result
    t_solve = time.monotonic() - t2
    print(f"\n== calibration (σ_px {args.sigma_px}, σ_3D {sigma_3d * 100:.2f} cm) ==")
    if res is None:
        print(f"REFUSED without a solution: {refused}")
        return 2
    print(format_result(res, max_rows=0).rsplit("\n\n", 1)[0])
    print(
        "residual RMS per view [px]    : "
        + ", ".join(
            f"{v.name} {_rms([r.error_px for r in res.residuals if r.view == v.name]):.2f} "
            f"(z {v.zoom:.0f}, {len(v.points)} pts)"
            for v in cs.views
        )
    )
    if refused:
        print(f"REFUSED: {refused}")
    truth = world.T_base_ptz
    for name, T in (("nominal mount", nominal.transform), ("recovered mount", res.transform)):
        dt = T.t - truth.t
        dR = truth.R.T @ T.R
        rpy = np.degrees(matrix_to_rpy(T.R)) - np.degrees(matrix_to_rpy(truth.R))
        print(
            f"{name:16s} vs truth: |Δt| {np.linalg.norm(dt) * 100:.2f} cm (x {dt[0] * 100:+.2f}, y {dt[1] * 100:+.2f}, "
            f"z {dt[2] * 100:+.2f}), rotation {math.degrees(rotation_angle(dR)):.3f}° "
            f"(Δroll {rpy[0]:+.3f}, Δpitch {rpy[1]:+.3f}, Δyaw {rpy[2]:+.3f})"
        )
    print(
        f"\ntimes: start-up {t_up:.1f} s, capture {t_capture:.1f} s ({t_capture / len(poses):.2f} s/view incl. "
        f"moves), calibrate {t_solve:.2f} s; total {time.monotonic() - t0:.1f} s"
    )
    print(f"files: {out}")
    return 0 if refused is None else 2


def _rms(x: list[float]) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if x else math.nan


if __name__ == "__main__":
    raise SystemExit(main())
