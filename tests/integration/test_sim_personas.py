"""The simulator's modern-camera persona (``--model q6075``) against the 214 default, over real HTTP(S)."""

import json
import math
import ssl
import time

import httpx
import pytest

from axis_ptz_ros2.sim import SimulatedCamera
from axis_ptz_ros2.sim.cli import build_parser
from axis_ptz_ros2.sim.persona import AXIS_214, AXIS_Q6075, persona
from axis_ptz_ros2.sim.ptz import Speeds
from tests.support.sim import decode, frames, read_stream
from tests.support.waiting import wait_until

pytestmark = pytest.mark.integration
USER, PASSWORD = "root", "modern-pw"


@pytest.fixture(scope="module")
def modern():
    with SimulatedCamera(model="q6075", password=PASSWORD, speeds=Speeds(90.0, 90.0, 0.5, 0.5)) as c:
        yield c


@pytest.fixture
def mc(modern):
    """httpx client with Digest credentials, verifying the camera's certificate against its own CA file."""
    with httpx.Client(
        base_url=modern.base_url, auth=httpx.DigestAuth(USER, PASSWORD), verify=modern.ca_file, timeout=5.0
    ) as c:
        yield c


def _kv(text: str) -> dict[str, str]:
    return dict(line.split("=", 1) for line in text.splitlines() if "=" in line)


def test_persona_lookup_and_cli():
    assert persona(None) is AXIS_214
    assert persona("214") is AXIS_214
    assert persona("Q6075-E") is AXIS_Q6075
    assert persona("modern") is AXIS_Q6075
    with pytest.raises(ValueError, match="unknown camera model"):
        persona("p5512")
    args = build_parser().parse_args(["--model", "q6075", "--no-https"])
    assert args.model == "q6075"
    assert args.https is False


def test_https_by_default_with_certificate_checking(modern, mc):
    assert modern.base_url.startswith("https://")
    assert modern.ca_file
    with open(modern.ca_file, encoding="ascii") as f:
        assert f.read().startswith("-----BEGIN CERTIFICATE-----")
    r = mc.get("/axis-cgi/param.cgi", params={"action": "list", "group": "Properties.API.HTTP.Version"})
    assert r.status_code == 200
    assert r.text == "Properties.API.HTTP.Version=3\n"
    # The system trust store does not know the self-signed certificate: verification must fail.
    with httpx.Client(base_url=modern.base_url, timeout=5.0) as strict, pytest.raises(httpx.ConnectError) as exc:
        strict.get("/axis-cgi/param.cgi?action=list&group=Brand")
    assert isinstance(exc.value.__cause__, ssl.SSLError) or "CERTIFICATE" in str(exc.value).upper()
    # Plain HTTP to the HTTPS port gets nothing useful.
    with (
        httpx.Client(base_url=f"http://127.0.0.1:{modern.port}", timeout=3.0) as plain,
        pytest.raises(httpx.HTTPError),
    ):
        plain.get("/axis-cgi/param.cgi?action=list&group=Brand")


def test_digest_only(modern):
    with httpx.Client(base_url=modern.base_url, verify=modern.ca_file, timeout=5.0) as c:
        r = c.get("/axis-cgi/param.cgi?action=list&group=Brand")
        assert r.status_code == 401
        challenges = r.headers.get_list("www-authenticate")
        assert len(challenges) == 1
        assert challenges[0].startswith('Digest realm="AXIS_')
        r = c.get("/axis-cgi/param.cgi?action=list&group=Brand", auth=httpx.BasicAuth(USER, PASSWORD))
        assert r.status_code == 401  # Basic is refused even with the right password


def test_modern_parameters(mc):
    p = _kv(mc.get("/axis-cgi/param.cgi?action=list").text)
    assert p["root.Brand.ProdNbr"] == "Q6075-E"
    assert p["root.Properties.API.HTTP.Version"] == "3"
    assert p["root.Network.HTTP.AuthenticationPolicy"] == "digest"
    assert p["root.HTTPS.Enabled"] == "yes"
    assert p["root.PTZ.ImageSource.I0.PTZEnabled"] == "true"
    assert p["root.PTZ.Support.S1.DigitalZoom"] == "true"
    res = p["root.Properties.Image.Resolution"].split(",")
    assert res[0] == "1920x1080"
    assert all("x" in r for r in res)
    assert p["root.PTZ.Limit.L1.MinPan"] == "-180"
    assert p["root.PTZ.Limit.L1.MaxPan"] == "180"
    assert (p["root.PTZ.Limit.L1.MinTilt"], p["root.PTZ.Limit.L1.MaxTilt"]) == ("-90", "20")
    assert p["root.PTZ.Limit.L1.MaxZoom"] == "19999"
    lim = _kv(mc.get("/axis-cgi/com/ptz.cgi?query=limits").text)
    assert lim["MaxZoom"] == "19999"
    assert lim["MinPan"] == "-180"
    assert int(lim["MaxFieldAngle"]) == round(10 * AXIS_Q6075.zoom_model.hfov_wide_deg)


def test_1080p_square_pixel_stream_and_wxh_only(mc):
    status, headers, body, _ = read_stream(mc, "/axis-cgi/mjpg/video.cgi?resolution=1920x1080&fps=30&nbrofframes=2")
    assert status == 200
    img = decode(frames(body)[0])
    assert img.shape[:2] == (1080, 1920)
    r = mc.get("/axis-cgi/imagesize.cgi?resolution=1280x720&squarepixel=1")
    assert r.text == "image width = 1280\nimage height = 720\n"  # square already: squarepixel changes nothing
    for bad in ("4CIF", "704x576"):
        r = mc.get(f"/axis-cgi/jpg/image.cgi?resolution={bad}")
        assert r.status_code == 400, bad


def test_query_attributes_text_and_json(mc):
    text = mc.get("/axis-cgi/com/ptz.cgi?query=attributes").text
    assert text.startswith("Attributes for camera 1\n")
    kv = _kv(text.split("\n", 1)[1])
    assert kv["maxOpticalZoomMag"] == "40"
    assert kv["maxDigitalZoomMag"] == "16"
    steps = json.loads(mc.get("/axis-cgi/com/ptz.cgi?query=attributes&format=json").text)["Camera 1"]["zoomSteps"]
    table = {int(s["value"]): float(s["zoom"]) for s in steps}
    assert table[1] == 1.0
    assert table[9999] == 40.0
    assert table[19999] == 640.0
    assert table[257] == pytest.approx(2.0, abs=0.01)  # vapix.md S11: 2x at 257 on a Q6075-E
    assert "attributes" in mc.get("/axis-cgi/com/ptz.cgi?info=1").text


def test_214_has_no_attributes_and_stays_default():
    with SimulatedCamera() as cam, httpx.Client(base_url=cam.base_url, timeout=5.0) as c:
        assert cam.persona is AXIS_214
        assert cam.base_url.startswith("http://")
        assert cam.ca_file is None
        assert c.get("/axis-cgi/com/ptz.cgi?query=attributes").text == "Error:\nquery: unknown value: attributes\n"
        assert c.get("/axis-cgi/view/param.cgi?action=list&group=Brand.ProdNbr").text == "Brand.ProdNbr=214\n"
        # Presets under PTZ.Preset.P0 as in every recorded listing (the older, parameter-based storage).
        assert "PTZ.Preset.P0.Position.P1.Name=Home" in c.get("/axis-cgi/param.cgi?action=list&group=PTZ").text


def test_pan_wraps_the_short_way_across_the_seam(modern, mc):
    # The head's dynamics run on a test clock that advances only when told to: every position below is exact,
    # however long the HTTP requests take on a loaded machine (real-time dynamics: test_sim_protocol).
    now = [0.0]
    modern.state.clock = lambda: now[0]

    def run(seconds: float, step: float = 0.01) -> list[float]:
        """Advance the head's clock in steps while it moves (at most ``seconds``); the pans seen on the way."""
        seen = []
        for _ in range(round(seconds / step)):
            if not modern.state.moving():
                break
            now[0] += step
            seen.append(modern.position()[0])
        return seen

    try:
        modern.teleport(170.0, 0.0, 1.0)
        assert mc.get("/axis-cgi/com/ptz.cgi?pan=-170").status_code == 204
        seen = run(3.0)  # 20 deg at 90 deg/s: 23 steps of 10 ms
        assert not modern.state.moving()
        assert modern.position()[0] == pytest.approx(-170.0, abs=1e-6)
        assert len(seen) == math.ceil(20.0 / 0.9)
        assert all(abs(p) >= 169.9 for p in seen), "went the long way through 0"
        assert any(p > 170.0 for p in seen)
        assert any(p < -170.0 for p in seen)
        assert all(-180.0 <= p < 180.0 for p in seen)
        # relative moves wrap too, and the reading stays in [-180, 180)
        assert mc.get("/axis-cgi/com/ptz.cgi?rpan=-30").status_code == 204
        run(3.0)
        assert not modern.state.moving()
        pos = _kv(mc.get("/axis-cgi/com/ptz.cgi?query=position").text)
        assert float(pos["pan"]) == pytest.approx(160.0, abs=1e-3)
        # continuous pan runs through the seam without stopping: 175 + 90 deg/s * 0.2 s = 193 = -167
        modern.teleport(175.0, 0.0, 1.0)
        assert mc.get("/axis-cgi/com/ptz.cgi?continuouspantiltmove=100,0").status_code == 204
        now[0] += 0.2
        assert mc.get("/axis-cgi/com/ptz.cgi?continuouspantiltmove=0,0").status_code == 204
        assert modern.position()[0] == pytest.approx(-167.0, abs=1e-6)
        now[0] += 1.0
        assert modern.position()[0] == pytest.approx(-167.0, abs=1e-6)  # and it stopped there
    finally:
        modern.state.clock = time.monotonic
        modern.state.reset()  # stopped at home, its time base back on the real clock


def test_tilt_range_and_v3_move_step(modern, mc):
    modern.teleport(0.0, 0.0, 1.0)
    mc.get("/axis-cgi/com/ptz.cgi?tilt=-60")
    wait_until(lambda: not modern.state.moving(), 3.0, scaled=False, raises=False)
    assert modern.position()[1] == pytest.approx(-60.0)
    modern.teleport(0.0, 0.0, 1.0)
    mc.get("/axis-cgi/com/ptz.cgi?move=right")
    wait_until(lambda: not modern.state.moving(), 3.0, scaled=False, raises=False)
    hfov = math.degrees(AXIS_Q6075.zoom_model.hfov(1.0))
    assert modern.position()[0] == pytest.approx(0.25 * hfov, abs=1e-3)  # VAPIX v3: 25 % of the field width


def test_presets_listed_under_ptz_preset_p0(mc):
    assert mc.get("/axis-cgi/com/ptzconfig.cgi?setserverpresetname=Door").status_code == 204
    p = _kv(mc.get("/axis-cgi/param.cgi?action=list&group=PTZ.Preset").text)
    names = {k: v for k, v in p.items() if k.endswith(".Name") and ".Position." in k}
    assert "Door" in names.values()
    assert "Home" in names.values()
    door = next(k for k, v in names.items() if v == "Door")
    assert p[door.replace(".Name", ".Data")].startswith("tilt=")
    assert "presetposno" in mc.get("/axis-cgi/com/ptz.cgi?query=presetposcam").text


def test_driver_discovery_reads_ptz_enabled_per_image_source():
    from axis_ptz_ros2.camera_models import discover
    from axis_ptz_ros2.vapix import CameraConfig, VapixClient

    with SimulatedCamera(model="q6075", https=False, auth="none") as cam:
        with VapixClient(CameraConfig(port=cam.port)) as client:
            assert discover(client).ptz_enabled is True
        cam.params["PTZ.ImageSource.I0.PTZEnabled"] = "false"
        with VapixClient(CameraConfig(port=cam.port)) as client:
            profile = discover(client)
        assert profile.ptz_enabled is False
        assert "PTZ DISABLED" in profile.summary()
