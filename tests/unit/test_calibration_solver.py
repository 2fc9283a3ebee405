"""Joint multi-view extrinsic calibration on seeded synthetic scenes with ground truth."""

import math
from dataclasses import replace

import numpy as np
import pytest

from axis_ptz_ros2.calibration import synthetic as syn
from axis_ptz_ros2.calibration.cli import main as cli_main
from axis_ptz_ros2.calibration.correspondences import CorrespondenceSet, View, save_correspondences
from axis_ptz_ros2.calibration.problem import exp_so3, log_so3
from axis_ptz_ros2.calibration.result import CalibrationRefused
from axis_ptz_ros2.calibration.solver import calibrate, rotation_error_deg
from axis_ptz_ros2.config import load_mount, save_mount

pytestmark = pytest.mark.unit


def _errors(scene, result):
    return syn.translation_error_m(scene, result.transform), rotation_error_deg(
        result.transform, scene.equivalent_truth
    )


def test_so3_exp_log_round_trip():
    rng = np.random.default_rng(1)
    for w in [*rng.normal(0, 1, (20, 3)), np.zeros(3), np.array([0, 0, math.pi - 1e-6])]:
        R = exp_so3(w)
        assert pytest.approx(np.eye(3), abs=1e-12) == R.T @ R
        assert exp_so3(log_so3(R)) == pytest.approx(R, abs=1e-9)


def test_noiseless_exact_recovery():
    scene = syn.make_scene(0, pixel_noise_px=0.0, point_noise_m=0.0)
    r = calibrate(scene.views, scene.camera_model, sigma_3d_m=0.0)
    t_err, r_err = _errors(scene, r)
    assert t_err < 1e-6
    assert r_err < 1e-5
    assert r.rms_px < 1e-4
    assert r.holdout_rms_px < 1e-3
    assert r.n_inliers == r.n_points == 40
    assert r.refused_reason is None


def test_noisy_recovery_within_bounds_and_mount_file(tmp_path):
    scene = syn.make_scene(11, pixel_noise_px=1.0, point_noise_m=0.02)
    r = calibrate(scene.views, scene.camera_model, sigma_px=1.0, sigma_3d_m=0.02)
    t_err, r_err = _errors(scene, r)
    assert t_err < 0.03
    assert r_err < 0.3
    # the reported uncertainty is in the right ballpark of the actual error
    assert t_err < 4.0 * float(np.linalg.norm(r.sigma_translation_m))
    assert 0.5 < r.normalised_rms < 1.5
    assert r.holdout_mode == "views"
    assert math.isfinite(r.holdout_rms_px)
    assert r.holdout_p95_px >= r.holdout_rms_px * 0.5
    assert len(r.residuals) == 40
    assert not r.focal_check.flagged
    mount = r.to_mount_config()
    path = tmp_path / "mount.yaml"
    save_mount(mount, path)
    loaded = load_mount(path)
    assert loaded.transform.t == pytest.approx(r.transform.t, abs=1e-6)
    assert pytest.approx(r.transform.R, abs=1e-6) == loaded.transform.R
    cov = np.array(loaded.covariance).reshape(6, 6)
    assert cov == pytest.approx(r.covariance)
    assert np.all(np.linalg.eigvalsh(cov) > 0)


def test_encoder_tilt_offset_estimated_and_pan_offset_folded_into_yaw():
    scene = syn.make_scene(
        5, pixel_noise_px=0.5, point_noise_m=0.0, pan_offset=math.radians(2.0), tilt_offset=math.radians(-1.5)
    )
    r = calibrate(scene.views, scene.camera_model, sigma_px=0.5, sigma_3d_m=0.0, estimate_encoder_offsets=True)
    assert math.degrees(r.tilt_offset) == pytest.approx(-1.5, abs=0.05)
    assert r.pan_offset == 0.0
    t_err, r_err = _errors(scene, r)
    assert t_err < 0.005
    assert r_err < 0.05
    # ignoring a 1.5° tilt offset is not silently accepted: most points disagree with any mount at 0.5 px
    with pytest.raises(CalibrationRefused, match="too few inliers.*encoder offsets"):
        calibrate(scene.views, scene.camera_model, sigma_px=0.5, sigma_3d_m=0.0)
    # without outlier rejection it is solved, with a warning naming the cause
    r2 = calibrate(scene.views, scene.camera_model, sigma_px=0.5, sigma_3d_m=0.0, robust=False)
    assert any("encoder offsets" in w for w in r2.warnings)
    assert r2.normalised_rms > 2.0
    with pytest.raises(CalibrationRefused, match="inconsistent data.*encoder offsets"):
        calibrate(scene.views, scene.camera_model, sigma_px=0.5, sigma_3d_m=0.0, robust=False, max_normalised_rms=2.0)


def test_thesis_like_set_is_refused_with_a_reason():
    scene = syn.thesis_like_scene(3)
    with pytest.raises(CalibrationRefused, match="single camera pose of nearly coplanar points") as exc:
        calibrate(scene.views, scene.camera_model)
    assert exc.value.reason
    assert exc.value.result is None  # refused before any solution
    # raise_on_refusal=False is honoured before a solution exists too
    r0 = calibrate(scene.views, scene.camera_model, raise_on_refusal=False)
    assert r0.refused_reason == exc.value.reason
    assert not r0.solved
    assert not np.all(np.isfinite(r0.sigma_translation_m))
    # without the coplanarity gate the solution is written with its (large) uncertainty ...
    r = calibrate(scene.views, scene.camera_model, min_planarity_ratio=0.0)
    assert r.refused_reason is None
    assert float(r.sigma_translation_m.max()) > 0.05
    # ... and the user's --max-sigma-cm limit refuses it
    with pytest.raises(CalibrationRefused, match="predicted σ translation") as exc2:
        calibrate(scene.views, scene.camera_model, min_planarity_ratio=0.0, max_sigma_translation_m=0.03)
    assert exc2.value.result is not None
    r = calibrate(
        scene.views, scene.camera_model, min_planarity_ratio=0.0, max_sigma_translation_m=0.03, raise_on_refusal=False
    )
    assert r.refused_reason is not None
    assert "requested limit" in r.refused_reason


def test_too_few_points_refused():
    scene = syn.make_scene(2, n_views=1, points_per_view=5)
    with pytest.raises(CalibrationRefused, match="too few points: 5"):
        calibrate(scene.views, scene.camera_model)
    scene = syn.make_scene(2, n_views=3, points_per_view=3)
    with pytest.raises(CalibrationRefused, match="no view has the 4 correspondences"):
        calibrate(scene.views, scene.camera_model)


def test_narrow_angular_spread_refused():
    cm = syn.default_camera_model()
    scene = syn.make_scene(
        4,
        n_views=3,
        pan_span_deg=1.0,
        tilt_range_deg=(0.0, 0.5),
        zoom_range=(9999.0, 9999.0),
        camera_model=cm,
    )
    with pytest.raises(CalibrationRefused, match="angular spread"):
        calibrate(scene.views, cm)


def test_outliers_rejected():
    scene = syn.make_scene(8, pixel_noise_px=1.0, point_noise_m=0.0, outlier_fraction=0.125, points_per_view=8)
    truth = scene.outlier_mask
    assert truth.sum() == 5
    r = calibrate(scene.views, scene.camera_model, sigma_3d_m=0.0)
    assert np.array_equal(~r.inliers, truth)
    t_err, r_err = _errors(scene, r)
    assert t_err < 0.01
    assert r_err < 0.1
    # a plain least-squares fit on the same data is much worse: the rejection matters
    plain = calibrate(scene.views, scene.camera_model, sigma_3d_m=0.0, robust=False, raise_on_refusal=False)
    assert syn.translation_error_m(scene, plain.transform) > 3 * t_err


def test_minus_ten_percent_focal_error_detected():
    scene = syn.make_scene(21, pixel_noise_px=1.0, point_noise_m=0.02)
    cm = syn.default_camera_model()
    hfov = math.radians(cm.zoom.hfov_wide_deg)
    wrong_hfov = 2.0 * math.degrees(math.atan(math.tan(hfov / 2.0) / 0.9))  # fx 10 % too small
    wrong = replace(cm, zoom=replace(cm.zoom, hfov_wide_deg=wrong_hfov))
    # the wrong focal makes the fixed-focal fit disagree with most points: refused, and the reason says why
    with pytest.raises(CalibrationRefused, match="too few inliers.*focal length looks .* too short") as exc:
        calibrate(scene.views, wrong)
    res = exc.value.result
    assert res is not None
    assert res.focal_check.flagged
    assert res.focal_check.p_value < 1e-3
    assert res.focal_check.cv_rms_fitted < res.focal_check.cv_rms_model
    assert res.focal_check.scale == pytest.approx(1 / 0.9, abs=0.04)
    with pytest.raises(CalibrationRefused, match="inconsistent intrinsics"):
        calibrate(scene.views, wrong, min_inlier_fraction=0.0, refuse_on_focal_mismatch=True)
    # with the right model the check passes and reports a scale near 1
    ok = calibrate(scene.views, scene.camera_model)
    assert not ok.focal_check.flagged
    assert ok.focal_check.scale == pytest.approx(1.0, abs=0.02)


def test_covariance_consistency_over_seeded_trials():
    z_t, within = [], []
    for seed in range(30):
        scene = syn.make_scene(500 + seed, pixel_noise_px=1.0, point_noise_m=0.02)
        r = calibrate(scene.views, scene.camera_model, holdout_mode="none", covariance_inflation=1.0, check_focal=False)
        e = r.transform.t - scene.truth.t
        z_t.append(e / r.sigma_translation_m)
        within.append(np.abs(e) <= 2.0 * r.sigma_translation_m)
    z_t = np.array(z_t)
    rms = float(np.sqrt(np.mean(z_t**2)))
    frac = float(np.mean(within))
    # uninflated Σ = (JᵀWJ)⁻¹ is consistent on this generator: RMS normalised error ≈ 1, ≈ 95 % within 2σ
    assert 0.7 < rms < 1.4
    assert frac > 0.85


def test_cli_solve_and_refuse(tmp_path, capsys):
    scene = syn.make_scene(9, pixel_noise_px=1.0, point_noise_m=0.02)
    corr = tmp_path / "c.yaml"
    save_correspondences(CorrespondenceSet(scene.views), corr)
    out = tmp_path / "mount.yaml"
    assert cli_main(["solve", str(corr), "--out", str(out), "--holdout", "points"]) == 0
    text = capsys.readouterr().out
    assert "T_base_ptz" in text
    assert "σ translation" in text
    assert "held-out" in text
    assert load_mount(out).transform.t == pytest.approx(scene.truth.t, abs=0.03)
    thesis = syn.thesis_like_scene(1)
    corr2 = tmp_path / "t.yaml"
    save_correspondences(CorrespondenceSet(thesis.views), corr2)
    assert cli_main(["solve", str(corr2), "--out", str(tmp_path / "m2.yaml")]) == 2
    assert "REFUSED" in capsys.readouterr().err
    assert not (tmp_path / "m2.yaml").exists()
    bad = tmp_path / "bad.yaml"
    bad.write_text("format: nope\n")
    assert cli_main(["solve", str(bad)]) == 1


def test_views_without_points_are_ignored():
    scene = syn.make_scene(12, pixel_noise_px=0.5, point_noise_m=0.0)
    empty = View("empty", 0.1, 0.0, 1.0, 704, 576)
    r = calibrate((*scene.views, empty), scene.camera_model, sigma_px=0.5, sigma_3d_m=0.0)
    assert r.n_views == 5
    assert syn.translation_error_m(scene, r.transform) < 0.01
