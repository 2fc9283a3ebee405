"""The virtual camera's decisions without ROS (axis_ptz_ros2.virtual.camera): its square-pixel camera model and
when a view is rendered."""

from __future__ import annotations

import pytest
import yaml

from axis_ptz_ros2.config import camera_model_from_dict, default_config_path
from axis_ptz_ros2.virtual.camera import RenderGate, view_model_dict
from axis_ptz_ros2.virtual.render import ViewSpec

pytestmark = pytest.mark.unit


def _shipped() -> dict:
    return yaml.safe_load(default_config_path("virtual_camera.yaml").read_text(encoding="utf-8"))


@pytest.mark.parametrize(("width", "height"), [(640, 480), (800, 450), (333, 500)])
def test_the_model_has_square_pixels_and_the_render_intrinsics(width, height):
    model = camera_model_from_dict(view_model_dict(_shipped(), width, height))
    assert model.head.h_tilt == 0.0
    assert tuple(model.head.d_opt) == (0.0, 0.0, 0.0)  # the optical centre is the panorama origin
    for zoom in (model.zoom.min_zoom, 2500.0, model.zoom.max_zoom):
        k = model.zoom.intrinsics(zoom, width, height)
        view = ViewSpec(width, height, 0.0, 0.0, model.zoom.hfov(zoom)).intrinsics
        assert k.fy == pytest.approx(k.fx, rel=1e-9)
        assert (k.fx, k.fy, k.cx, k.cy) == pytest.approx((view.fx, view.fy, view.cx, view.cy), rel=1e-9)


def test_the_model_dict_is_a_copy_and_keeps_the_rest():
    raw = {"zoom": {"hfov_wide_deg": 70.0}, "head": {"h_tilt": 0.1, "d_opt": [0.05, 0.0, 0.0]}, "dynamics": {"x": 1}}
    d = view_model_dict(raw, 640, 480)
    assert d["zoom"] == {"hfov_wide_deg": 70.0, "image_aspect": 640 / 480}
    assert d["head"] == {"h_tilt": 0.0, "d_opt": [0.0, 0.0, 0.0]}
    assert d["dynamics"] == {"x": 1}
    assert raw == {"zoom": {"hfov_wide_deg": 70.0}, "head": {"h_tilt": 0.1, "d_opt": [0.05, 0.0, 0.0]},
                   "dynamics": {"x": 1}}  # fmt: skip
    assert view_model_dict({}, 4, 2)["zoom"] == {"image_aspect": 2.0}


def test_nothing_is_due_while_nobody_watches():
    gate = RenderGate()
    assert not gate.watch(0)
    assert gate.watch(1)


def test_a_view_is_rendered_again_only_on_change_new_subscriber_or_min_rate():
    gate = RenderGate()
    view = ViewSpec(64, 48, 0.1, 0.0, 1.0)
    moved = ViewSpec(64, 48, 0.2, 0.0, 1.0)
    assert gate.watch(1)
    assert gate.due((1, view), 10.0, 0.0)  # the first view
    gate.rendered((1, view), 10.0)
    assert gate.watch(1)
    assert not gate.due((1, view), 10.1, 0.0)  # nothing changed, min_rate off
    assert gate.due((1, moved), 10.1, 0.0)  # the pose changed
    assert gate.due((2, view), 10.1, 0.0)  # a new panorama
    assert gate.watch(2)
    assert gate.due((1, view), 10.2, 0.0)  # a new subscriber gets a frame of the same view
    gate.rendered((1, view), 10.2)
    assert gate.watch(2)
    assert not gate.due((1, view), 10.3, 0.0)  # ... once
    assert gate.watch(1)
    assert not gate.due((1, view), 10.3, 0.0)  # one leaving is no reason
    # min_rate 2 Hz: a still view is re-rendered 0.5 s after the last published frame
    assert not gate.due((1, view), 10.69, 2.0)
    assert gate.due((1, view), 10.7, 2.0)


def test_a_frame_that_could_not_be_published_does_not_restart_the_min_rate_clock():
    gate = RenderGate()
    gate.watch(1)
    gate.rendered("a", 5.0)
    gate.watch(1)
    gate.rendered("a", None)  # rendered at 5.6 but not published
    assert not gate.due("a", 5.5, 1.0)
    assert gate.due("a", 6.0, 1.0)  # 1 s after the last published frame, not after the failed one
    assert not gate.due("a", 6.0, 0.0)
