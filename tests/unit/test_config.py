"""Configuration files load on a machine without a sourced ROS environment, and round-trip."""

import pytest

from axis_ptz_ros2.config import load_camera_model, load_mount, load_robot, mount_from_dict, save_mount

pytestmark = pytest.mark.unit


def test_defaults_load_without_a_ros_environment(monkeypatch):
    monkeypatch.delenv("AMENT_PREFIX_PATH", raising=False)
    assert load_camera_model().zoom.max_zoom == 9999
    assert load_mount().parent_frame == "base_link"
    assert load_robot().panorama.frame == "panorama_link"


def test_mount_round_trip_and_validation(tmp_path):
    m = load_mount()
    p = tmp_path / "m.yaml"
    save_mount(m, p)
    assert load_mount(p).transform.xyz_rpy() == pytest.approx(m.transform.xyz_rpy())
    with pytest.raises(ValueError, match="36 values"):
        mount_from_dict({"covariance": [0.0] * 5})
    with pytest.raises(ValueError, match="unsupported mount format"):
        mount_from_dict({"format": "other/v9"})
