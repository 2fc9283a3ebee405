"""Our typed VAPIX client against the simulated Axis 214 over real loopback HTTP (port 0, no ROS)."""

from __future__ import annotations

import time

import cv2
import numpy as np
import pytest

from axis_ptz_ros2.sim.camera import SimulatedCamera
from axis_ptz_ros2.sim.faults import FaultConfig
from axis_ptz_ros2.sim.ptz import Speeds
from axis_ptz_ros2.vapix import (
    AbsoluteMove,
    AuthError,
    CameraConfig,
    CameraUnreachable,
    CommandRejected,
    ContinuousMove,
    GotoPreset,
    HttpStatusError,
    InvalidArgument,
    RelativeMove,
    Resolution,
    SetPreset,
    VapixClient,
    VideoParams,
)
from tests.support.waiting import succeeds, wait_until

pytestmark = pytest.mark.integration

FAST = Speeds(pan_deg_s=2000.0, tilt_deg_s=2000.0, zoom_full_travel_s=0.2)


@pytest.fixture
def sim():
    cam = SimulatedCamera(speeds=FAST).start()
    try:
        yield cam
    finally:
        cam.stop()


def client_for(cam: SimulatedCamera, **kw) -> VapixClient:
    return VapixClient(CameraConfig(host="127.0.0.1", port=cam.port, timeout_s=3.0, **kw))


def wait_pose(cam, pan, tilt, zoom, timeout=5.0, tol=1e-3):
    def at() -> tuple[float, float, float] | None:
        p = cam.position()
        return p if abs(p[0] - pan) < tol and abs(p[1] - tilt) < tol and abs(p[2] - zoom) < 0.5 else None

    if (p := wait_until(at, timeout, scaled=False, raises=False)) is None:
        raise AssertionError(f"camera at {cam.position()}, expected {(pan, tilt, zoom)}")
    return p


def jpeg_comment(jpeg: bytes) -> str:
    assert jpeg[:2] == b"\xff\xd8"
    i = jpeg.find(b"\xff\xfe")
    assert i >= 0, "no COM segment"
    n = int.from_bytes(jpeg[i + 2 : i + 4], "big")
    return jpeg[i + 4 : i + 2 + n].decode()


def test_device_discovery_matches_the_214_persona(sim):
    with client_for(sim) as c:
        info = c.device_info()
        assert "214" in info.product
        assert info.api_version == 2
        res = c.supported_resolutions()
        assert Resolution(704, 576) in res
        assert Resolution(352, 288) in res
        assert Resolution(176, 144) in res
        lim = c.query_limits()
        assert (lim.min_pan_deg, lim.max_pan_deg, lim.min_tilt_deg, lim.max_tilt_deg) == (-170, 170, -30, 90)
        assert (lim.min_zoom, lim.max_zoom) == (1, 9999)
        assert lim.min_field_angle_deg == pytest.approx(2.7)
        assert lim.max_field_angle_deg == pytest.approx(48.0)


def test_absolute_and_relative_moves_land_with_sub_degree_precision(sim):
    with client_for(sim) as c:
        c.query_limits()
        c.ptz(AbsoluteMove(pan_deg=12.3456, tilt_deg=-7.8912, zoom=2500))
        wait_pose(sim, 12.3456, -7.8912, 2500)
        pos = c.query_position()
        assert pos.pan_deg == pytest.approx(12.3456, abs=1e-4)
        assert pos.tilt_deg == pytest.approx(-7.8912, abs=1e-4)
        assert pos.zoom == 2500
        c.ptz(RelativeMove(rpan_deg=0.25, rtilt_deg=-0.125, rzoom=100))
        wait_pose(sim, 12.5956, -8.0162, 2600)


def test_out_of_limit_command_is_refused_before_sending(sim):
    with client_for(sim) as c:
        c.query_limits()
        before = sim.request_counts.as_dict()
        with pytest.raises(InvalidArgument, match="pan"):
            c.ptz(AbsoluteMove(pan_deg=175.0))
        with pytest.raises(InvalidArgument):
            c.ptz(AbsoluteMove(zoom=0))
        assert sim.request_counts.as_dict() == before, "the camera must never see a refused command"
        assert sim.position() == pytest.approx((0.0, 0.0, 1.0))


def test_camera_error_body_maps_to_command_rejected(sim):
    with client_for(sim) as c:
        with pytest.raises(CommandRejected) as err:
            c._get_text("/axis-cgi/com/ptz.cgi?query=foo")  # noqa: SLF001 - a raw query the client never builds
        assert "foo" in str(err.value)


def test_continuous_move_and_stop(sim):
    with client_for(sim) as c:
        c.ptz(ContinuousMove(pan_speed=50, tilt_speed=0))
        wait_until(lambda: sim.position()[0] > 1.0, 5.0, what="the head moving right")  # + = right in VAPIX
        c.ptz(ContinuousMove(pan_speed=0, tilt_speed=0))
        wait_until(lambda: not sim.state.moving(), 5.0, what="the head to stop")
        stopped = sim.position()[0]
        time.sleep(0.2)  # a window for a (wrong) drift: the thing under test is that the head stays put
        assert sim.position()[0] == pytest.approx(stopped, abs=1e-6)


def test_presets_round_trip(sim):
    with client_for(sim) as c:
        c.ptz(AbsoluteMove(pan_deg=30.0, tilt_deg=10.0, zoom=4000))
        wait_pose(sim, 30.0, 10.0, 4000)
        c.ptz(SetPreset("door"))
        names = [p.name for p in c.query_presets()]
        assert "door" in names
        c.ptz(AbsoluteMove(pan_deg=-60.0, tilt_deg=0.0, zoom=1))
        wait_pose(sim, -60.0, 0.0, 1)
        c.ptz(GotoPreset(name="door"))
        wait_pose(sim, 30.0, 10.0, 4000)


def test_mjpeg_stream_honours_resolution_and_never_repeats_a_frame(sim):
    with client_for(sim) as c:
        params = VideoParams(Resolution(352, 288), fps=15, compression=30)
        seqs = []
        with c.open_mjpeg(params, read_timeout_s=3.0) as stream:
            for jpeg in stream:
                img = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
                assert img.shape[:2] == (288, 352)
                seqs.append(int(jpeg_comment(jpeg).split("seq=")[1].split()[0]))
                if len(seqs) == 8:
                    break
        assert seqs == sorted(set(seqs)), seqs


def test_parser_drops_garbage_and_truncated_frames_and_keeps_streaming(sim):
    sim.set_faults(garbage_between_parts=True, truncate_every=3)
    with client_for(sim) as c:
        params = VideoParams(Resolution(176, 144), fps=30, compression=50)
        good = 0
        with c.open_mjpeg(params, read_timeout_s=3.0) as stream:
            for jpeg in stream:
                assert cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR) is not None
                good += 1
                if good == 12:
                    break
            stats = stream.stats
        assert stats.dropped_truncated >= 3
        assert stats.garbage_bytes > 0


@pytest.mark.parametrize("mode", ["basic", "digest", "basic_digest"])
def test_auth_modes_negotiated_and_wrong_password_refused(mode):
    cam = SimulatedCamera(auth=mode, user="operator", password="s3cret-pw", speeds=FAST).start()
    # A Basic-only camera over plain HTTP needs auth: basic chosen explicitly (auto never sends Basic in clear).
    auth = "basic" if mode == "basic" else "auto"
    try:
        with VapixClient(CameraConfig(port=cam.port, username="operator", password="s3cret-pw", auth=auth)) as c:
            assert c.query_position().zoom == 1
        before = cam.request_counts.as_dict()
        bad = VapixClient(CameraConfig(port=cam.port, username="operator", password="wrong-pw", auth=auth))
        with bad as c, pytest.raises(AuthError) as err:
            c.query_position()
        assert "wrong-pw" not in str(err.value)
        assert "s3cret" not in repr(err.value)
        after = cam.request_counts.as_dict()
        total = sum(v for v in after.values() if isinstance(v, int)) - sum(
            v for v in before.values() if isinstance(v, int)
        )
        assert total <= 3, f"auth failure must not be hammered ({total} requests)"
    finally:
        cam.stop()


def test_digest_challenge_names_the_axis_realm():
    cam = SimulatedCamera(auth="digest", password="pw").start()
    try:
        import httpx

        r = httpx.get(f"{cam.base_url}/axis-cgi/com/ptz.cgi?query=position")
        assert r.status_code == 401
        ch = r.headers["www-authenticate"]
        assert 'realm="AXIS_' in ch
        assert 'qop="auth"' in ch
    finally:
        cam.stop()


def test_http_errors_and_reboot_map_to_the_error_tree(sim):
    with client_for(sim) as c:
        sim.set_faults(http_error=503)
        with pytest.raises(HttpStatusError) as err:
            c.query_position()
        assert err.value.status_code == 503
        sim.set_faults(http_error=0)
        assert c.query_position().zoom == 1
        sim.reboot(1.0)
        with pytest.raises(CameraUnreachable):
            c.query_position()
        wait_until(
            succeeds(c.query_position, CameraUnreachable),
            5.0,
            0.1,
            scaled=False,
            what="the camera to come back after the reboot",
        )


def test_fault_free_default_after_setting():
    assert FaultConfig().replace(truncate_every="2").truncate_every == 2
