"""Zoom optics of square-pixel / digital-zoom cameras, per-model camera-model files and the generic model."""

import math

import pytest

from axis_ptz_ros2.camera_models import Optics, find_model_file, generic_model, select_camera_model
from axis_ptz_ros2.config import default_config_path, load_camera_model
from axis_ptz_ros2.optics import ZoomModel
from axis_ptz_ros2.vapix import PtzLimits, Resolution
from tests.support.models import AXIS_214_ZOOM

Q = load_camera_model(default_config_path("q6075.yaml")).zoom


def test_214_intrinsics_unchanged_pal_12_11():
    k = AXIS_214_ZOOM.intrinsics(1, 704, 576)
    assert k.fx == pytest.approx(352 / math.tan(math.radians(47.98) / 2))
    assert k.fy / k.fx == pytest.approx(12 / 11)


def test_square_pixels_16_9_and_cropped_4_3():
    k = Q.intrinsics(1, 1920, 1080)
    assert k.fx == pytest.approx(k.fy)
    assert math.degrees(k.hfov) == pytest.approx(63.7)
    k720 = Q.intrinsics(1, 1280, 720)
    assert math.degrees(k720.hfov) == pytest.approx(63.7)
    assert k720.fx == pytest.approx(k720.fy)
    k43 = Q.intrinsics(1, 1280, 960)  # 4:3 from a 16:9 sensor: full height, sides cropped
    assert k43.fx == pytest.approx(k43.fy)
    assert math.degrees(k43.vfov) == pytest.approx(math.degrees(k.vfov))
    assert k43.hfov < k.hfov


def test_digital_zoom_above_the_optical_end():
    assert Q.magnification(1) == pytest.approx(1.0)
    assert Q.magnification(257) == pytest.approx(2.0, abs=0.01)  # vapix.md S11 (Q6075-E table)
    assert Q.magnification(9999) == pytest.approx(40.0)
    assert Q.magnification(19999) == pytest.approx(640.0)
    assert Q.magnification(14999) == pytest.approx(40.0 * 8.5)
    for z in (1, 500, 9999, 12000, 19999):
        assert Q.zoom_for_magnification(Q.magnification(z)) == pytest.approx(z, abs=1e-6)
    with pytest.raises(ValueError, match="optical_max_zoom"):
        ZoomModel(hfov_wide_deg=63.7, max_magnification=40.0, max_zoom=9999, optical_max_zoom=20000)


def test_model_files_selected_by_reported_product():
    assert find_model_file("214", "AXIS 214 PTZ").name == "axis214.yaml"
    assert find_model_file("Q6075-E", "").name == "q6075.yaml"
    assert find_model_file("", "AXIS Q6075-E").name == "q6075.yaml"
    assert find_model_file("P5512", "AXIS P5512") is None
    model, source = select_camera_model("214", "AXIS 214 PTZ", Optics())
    assert model.name == "AXIS 214 PTZ"
    assert source == "axis214.yaml"


def test_generic_model_learns_the_optics_from_the_camera():
    # The real P5512 of vapix.md S8: NTSC CIF names, MinFieldAngle 44, MaxFieldAngle 516, MaxZoom 19999.
    lim = PtzLimits(-180, 180, -180, 0, 1, 19999, min_field_angle_deg=4.4, max_field_angle_deg=51.6)
    analogue = Optics((Resolution(704, 480), Resolution(352, 240)), "NTSC", lim, digital_zoom=True)
    model, source = select_camera_model("P5512", "AXIS P5512", analogue)
    assert source.startswith("generic")
    z = model.zoom
    assert math.degrees(z.hfov(1)) == pytest.approx(51.6)
    assert math.degrees(z.hfov(9999)) == pytest.approx(4.4)
    assert z.max_zoom == 19999
    assert z.optical_max_zoom == 9999
    assert z.magnification(19999) == pytest.approx(z.magnification(9999))  # digital factor unknown: none assumed
    k = z.intrinsics(1, 704, 480)
    assert k.fy != pytest.approx(k.fx)  # analogue: non-square pixels
    digital = Optics((Resolution(1280, 720), Resolution(640, 360)), "digital", lim, True, 30.0, 12.0)
    z2 = generic_model(digital).zoom
    assert z2.square_pixels
    assert z2.image_aspect == pytest.approx(16 / 9)
    assert z2.magnification(9999) == pytest.approx(30.0)
    assert z2.magnification(19999) == pytest.approx(360.0)
    k2 = z2.intrinsics(1, 1280, 720)
    assert k2.fx == pytest.approx(k2.fy)


def test_endless_pan_backend_wraps_a_joint_target_pushed_past_the_seam():
    """An encoder offset can push a wrapped joint target past +-180 deg: the head must still get a valid pan."""
    import httpx

    from axis_ptz_ros2.ptz.axis_backend import AxisBackend
    from axis_ptz_ros2.vapix import CameraConfig, VapixClient

    sent: list[str] = []

    def handler(request: httpx.Request) -> httpx.Response:
        q = request.url.query.decode()
        if "query=limits" in q:
            return httpx.Response(
                200, text="MinPan=-180\nMaxPan=180\nMinTilt=-90\nMaxTilt=20\nMinZoom=1\nMaxZoom=19999\n"
            )
        sent.append(q)
        return httpx.Response(204)

    cfg = CameraConfig(port=80)
    clients = [VapixClient(cfg, transport=httpx.MockTransport(handler)) for _ in range(2)]
    backend = AxisBackend(
        cfg, load_camera_model(default_config_path("q6075.yaml")), command_client=clients[0], state_client=clients[1]
    )
    assert backend.limits().full_turn
    backend.move_to(math.radians(181.0), None, None)  # REP-103 +181 deg = VAPIX +179 after wrapping
    assert len(sent) == 1
    assert float(sent[0].removeprefix("pan=")) == pytest.approx(179.0)
