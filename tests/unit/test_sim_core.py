"""Simulator core without sockets: sign mapping, world, raycast, PTZ language and dynamics, optics."""

import dataclasses
import math

import numpy as np
import pytest

from axis_ptz_ros2 import geometry as g
from axis_ptz_ros2.sim import ptz as sp
from axis_ptz_ros2.sim.persona import AXIS_214
from axis_ptz_ros2.sim.ptz_args import PtzCommandError
from axis_ptz_ros2.sim.renderer import PtzRenderer, encode_jpeg, insert_comment
from axis_ptz_ros2.sim.scene import HIT_GROUND, HIT_SKY, Scene, shared_scene
from axis_ptz_ros2.sim.world import PtzLimits, load_world
from tests.support.models import AXIS_214_ZOOM

pytestmark = pytest.mark.unit


@pytest.fixture(scope="module")
def world():
    return load_world()


@pytest.fixture(scope="module")
def scene(world):
    return shared_scene(world)


@pytest.fixture(scope="module")
def renderer(world, scene):
    return PtzRenderer(world, scene)


def test_sim_sign_mapping_is_axis_documented():
    # +pan = right = clockwise from above = towards -y of base_link; +tilt = up.
    pan, tilt = sp.vapix_to_ros(30.0, 20.0)
    assert pan == pytest.approx(-math.radians(30.0))
    assert tilt == pytest.approx(math.radians(20.0))
    d = g.pan_tilt_to_direction(pan, 0.0)
    assert d[1] < 0  # a camera panned right looks towards -y
    assert sp.ros_to_vapix(*sp.vapix_to_ros(-123.4, 56.7)) == pytest.approx((-123.4, 56.7))


def test_world_defaults_differ_from_nominal_mount(world):
    x, y, z, r, p, yaw = world.T_base_ptz.xyz_rpy()
    assert (x, y, z) == pytest.approx((-0.209, -0.047, 0.462))
    assert math.degrees(yaw) == pytest.approx(1.1)
    assert world.kinematics.h_tilt == pytest.approx(0.0687)
    assert world.T_base_pano.t[0] - world.T_base_ptz.t[0] == pytest.approx(0.425, abs=0.01)
    assert len(world.targets) >= 10


def test_target_geometry_and_features(scene):
    plate = scene.target("number_plate")
    c = plate.corners()
    assert np.linalg.norm(c[1] - c[0]) == pytest.approx(0.52)
    assert np.linalg.norm(c[3] - c[0]) == pytest.approx(0.11)
    assert plate.normal[0] < -0.99  # faces the robot
    assert c[1][1] < c[0][1]  # texture right = viewer's right = -y
    calib = scene.target("calib_left")
    f = calib.features()
    assert {"dot_red", "dot_green", "dot_blue", "dot_yellow", "corner_tl"} <= set(f)
    for p in f.values():  # all features lie in the target plane
        assert float((p - calib.center) @ calib.normal) == pytest.approx(0.0, abs=1e-9)


def test_raycast_hits_targets_ground_and_sky(scene, world):
    o = world.pan_tilt_centre
    tgt = scene.target("calib_front")
    dot = tgt.features()["dot_red"]
    dirs = np.array([dot - o, [1.0, 0.0, -0.5], [0.0, 0.0, 1.0]])
    bgr, depth, idx = scene.raycast(o, dirs)
    assert idx[0] == scene.targets.index(tgt)
    assert depth[0] == pytest.approx(float(np.linalg.norm(dot - o)), rel=1e-6)
    assert tuple(bgr[0]) == pytest.approx((0, 0, 255), abs=3)  # the red dot
    assert idx[1] == HIT_GROUND
    assert depth[1] == pytest.approx(o[2] * math.sqrt(1.25) / 0.5, rel=1e-6)
    assert idx[2] == HIT_SKY
    assert math.isinf(depth[2])


def test_the_facade_fills_the_home_views_upper_half_beyond_the_lasers_reach(scene, world, renderer):
    """Issue 22's scene detail: the building across the square is what the home view sees above the horizon
    (rays at 2-15 degrees up, +-20 degrees across), farther than the laser's default 30 m, opaque, detailed
    down to single bricks, and the same texture every time it is built."""
    facade = scene.target("facade")
    o = world.pan_tilt_centre
    az, el = np.meshgrid(np.radians(np.linspace(-20, 20, 9)), np.radians(np.linspace(2, 15, 5)))
    dirs = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], -1).reshape(-1, 3)
    _, _, idx = scene.raycast(o, dirs)
    assert set(idx.tolist()) <= {
        scene.targets.index(facade),
        scene.targets.index(scene.target("checker_board")),
        scene.targets.index(scene.target("calib_front")),
    }
    assert (idx == scene.targets.index(facade)).mean() > 0.8
    laser_o = world.T_base_laser.t
    assert float(np.min(np.abs((facade.corners() - laser_o) @ facade.normal))) > 30.0
    tex = facade.texture
    assert (tex[:, :, 3] == 255).all()
    y = tex[:, :, :3].astype(np.float64).mean(axis=2)
    brick = y[400:460, 200:260]  # 0.9 x 0.9 m of wall between two windows: one shade per brick
    assert brick.std() > 8.0
    assert np.array_equal(Scene(world).target("facade").texture, tex)
    home = renderer.render(0.0, 0.0, 1.0, 704, 576)
    top = home[:250].astype(np.float64)
    assert np.abs(np.diff(top, axis=1)).mean() > 6.0  # fine detail across the upper half (the sky had none)


def test_render_equirect_sees_the_high_target(scene, world):
    img = scene.render_equirect(world.T_base_pano, 256)
    assert img.shape == (128, 256, 3)
    hi = scene.target("high_marker").center - world.T_base_pano.t
    x, y = g.direction_to_equirect(hi, 256, 128)
    b, gg, r = (int(v) for v in img[int(round(y)), int(round(x))])
    assert b > 150
    assert r > 150
    assert gg < 100


def _blob(img, lo, hi):
    import cv2

    mask = cv2.inRange(img, np.array(lo), np.array(hi))
    n, _, stats, cent = cv2.connectedComponentsWithStats(mask)
    assert n > 1, "blob not found"
    k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return cent[k]


def _aim(world, point):
    P = world.T_base_ptz.inverse().apply(point)
    return sp.ros_to_vapix(*world.kinematics.look_at(P))


def test_optics_zoom_1_to_9999_magnifies_18_9x(world, scene, renderer):
    tgt = scene.target("zoom_ref")
    pan, tilt = _aim(world, tgt.center)
    sep = []
    for zoom in (1, 9999):
        img = renderer.render(pan, tilt, zoom, 704, 576)
        if zoom == 1:  # only look near the image centre, where the aimed-at board is
            img = np.ascontiguousarray(img[288 - 40 : 288 + 40, 352 - 40 : 352 + 40])
        red = _blob(img, (0, 0, 150), (90, 90, 255))
        green = _blob(img, (0, 120, 0), (90, 255, 90))
        sep.append(float(np.linalg.norm(red - green)))
    assert sep[1] / sep[0] == pytest.approx(18.88, rel=0.03)
    # and the absolute scale matches the 214 lens calculator (fx = 791 px at zoom 1)
    d = float(np.linalg.norm(tgt.center - world.pan_tilt_centre))
    assert sep[0] == pytest.approx(0.7 * 0.8 * 791 / d, rel=0.05)


def test_pal_pixels_are_12_11(renderer):
    k = renderer.intrinsics(1, 704, 576)
    assert k.fy / k.fx == pytest.approx(12 / 11)
    assert renderer.intrinsics(1, 768, 576).fy == pytest.approx(renderer.intrinsics(1, 768, 576).fx)


def test_render_cache_and_jpeg_comment(renderer):
    n0 = renderer.renders
    a = renderer.render(3.0, 1.0, 1, 352, 288)
    b = renderer.render(3.0, 1.0, 1, 352, 288)
    assert a is b
    assert renderer.renders == n0 + 1
    jpeg = insert_comment(encode_jpeg(a, 30), b"axsim seq=1 t=2")
    assert jpeg[:4] == b"\xff\xd8\xff\xfe"
    assert jpeg[-2:] == b"\xff\xd9"
    assert len(encode_jpeg(a, 90)) < len(encode_jpeg(a, 10))


class FakeClock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


@pytest.fixture
def head(world):
    clock = FakeClock()
    return sp.PtzState(zoom_model=world.zoom_model, clock=clock), clock


def test_position_format_and_errors_change_nothing(head):
    st, clock = head
    assert st.handle([("pan", "12.34567"), ("tilt", "-5.5")]) is None
    clock.t = 10.0
    body = st.handle([("query", "position")])
    assert body.startswith("pan=12.3457\ntilt=-5.5\nzoom=1\n")
    for bad in (
        [("pan", "500")],
        [("zoom", "0")],
        [("pan", "abc")],
        [("foo", "1")],
        [("query", "foo")],
        [("pan", "10"), ("tilt", "999")],
        [("continuouspantiltmove", "50")],
        [("center", "10,10"), ("areazoom", "10,10,200")],  # IndexError inside the simulator before (simsplit)
    ):
        with pytest.raises(PtzCommandError):
            st.handle(bad)
    clock.t = 20.0
    assert st.position()[:2] == pytest.approx((12.34567, -5.5))
    with pytest.raises(PtzCommandError, match="query: unknown value: foo"):
        st.handle([("query", "foo")])


def test_clamped_to_limits_and_finite_speed(head):
    st, clock = head
    st.handle([("pan", "180"), ("tilt", "-60")])  # in protocol range, beyond PTZ.Limit
    clock.t = 0.5
    pan, tilt, _ = st.position()
    assert pan == pytest.approx(50.0)
    assert tilt == pytest.approx(-30.0)
    clock.t = 5.0
    assert st.position()[:2] == pytest.approx((170.0, -30.0))
    st.handle([("speed", "50"), ("pan", "120")])
    clock.t = 5.5
    assert st.position()[0] == pytest.approx(145.0)
    st.handle([("zoom", "9999")])
    clock.t = 5.5 + 3.5 / 2
    assert st.position()[2] == pytest.approx(5000.0, abs=1)


def test_continuous_move_until_stop_or_limit_and_cancelled_by_absolute(head):
    st, clock = head
    st.handle([("continuouspantiltmove", "50,-100")])
    clock.t = 1.0
    pan, tilt, _ = st.position()
    assert pan == pytest.approx(50.0)
    assert tilt == pytest.approx(-30.0)
    st.handle([("continuouspantiltmove", "0,0")])
    clock.t = 2.0
    assert st.position()[0] == pytest.approx(50.0)
    st.handle([("continuouszoommove", "100")])
    clock.t = 2.5
    st.handle([("rpan", "-10")])  # any relative command cancels continuous motion
    z = st.position()[2]
    clock.t = 4.0
    assert st.position()[2] == pytest.approx(z)
    assert st.position()[0] == pytest.approx(40.0)


def test_arrive_now_stops_everything_and_clamps(head):
    st, clock = head
    st.handle([("continuouspantiltmove", "50,50"), ("continuouszoommove", "100")])
    clock.t = 0.5
    st.arrive_now(-500.0, 20.0, 20000.0)  # beyond MinPan and MaxZoom
    assert st.position() == pytest.approx((-170.0, 20.0, 9999.0))
    assert not st.moving()
    clock.t = 5.0
    assert st.position() == pytest.approx((-170.0, 20.0, 9999.0))  # the continuous move did not resume
    with pytest.raises(ValueError, match="finite"):
        st.arrive_now(math.nan, 0.0, 1.0)
    endless = sp.PtzState(st.zoom_model, limits=PtzLimits(-180.0, 180.0, -90.0, 20.0, 1, 9999), clock=clock)
    endless.arrive_now(190.0, 0.0, 1.0)
    assert endless.position()[0] == pytest.approx(-170.0)  # wrapped, not clamped


def test_move_presets_and_home(head):
    st, clock = head
    st.handle([("move", "right")])
    st.handle([("move", "up")])  # v2: 5 degrees per step, from the current position
    clock.t = 1.0
    assert st.position()[:2] == pytest.approx((5.0, 5.0))
    st.handle([("setserverpresetname", "Door")])
    assert "presetposno2=Door" in st.handle([("query", "presetposcam")])
    st.handle([("pan", "-20")])
    clock.t = 2.0
    st.handle([("gotoserverpresetname", "Door")])
    clock.t = 3.0
    assert st.position()[:2] == pytest.approx((5.0, 5.0))
    st.handle([("move", "home")])
    clock.t = 4.0
    assert st.position() == pytest.approx((0.0, 0.0, 1.0))
    st.handle_config([("removeserverpresetname", "Door")])
    with pytest.raises(PtzCommandError):
        st.handle([("gotoserverpresetno", "2")])


def test_center_and_areazoom_are_exact_at_high_tilt(head):
    st, clock = head
    st.handle([("pan", "20"), ("tilt", "40"), ("zoom", "1")])
    clock.t = 2.0
    intr = AXIS_214_ZOOM.intrinsics(1, 704, 576)
    u, v = 600.0, 100.0
    d = g.pixel_direction_in_ptz_base(*sp.vapix_to_ros(20, 40), u, v, intr)
    st.handle([("center", f"{u:g},{v:g}")])
    clock.t = 4.0
    pan, tilt, _ = st.position()
    d2 = g.pan_tilt_to_direction(*sp.vapix_to_ros(pan, tilt))
    assert float(d @ d2) == pytest.approx(1.0, abs=1e-12)
    assert pan > 20
    assert tilt > 40
    st.handle([("areazoom", "352,288,300"), ("imagewidth", "704"), ("imageheight", "576")])
    clock.t = 10.0
    assert AXIS_214_ZOOM.magnification(st.position()[2]) == pytest.approx(3.0, rel=1e-3)


def test_scene_constructor_loads_default_world():
    assert Scene().target("hazard_label").width == pytest.approx(0.30)


@pytest.mark.parametrize("rate", [0, -25, 121])
def test_a_persona_frame_rate_out_of_range_is_refused(rate: int) -> None:
    with pytest.raises(ValueError, match="frame_rate"):
        dataclasses.replace(AXIS_214, frame_rate=rate)
    assert AXIS_214.frame_rate == 25  # PAL
