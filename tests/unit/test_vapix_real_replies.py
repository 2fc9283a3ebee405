"""Cameras that are not a PAL 214 (issue 10): replies shaped like recordings of real Axis firmware
(vapix.md §2.2, §4.7, §5.3, §5.5; P5512 NTSC dome fw 5.51, fixed cameras), over httpx.MockTransport."""

from __future__ import annotations

import itertools
import time

import httpx
import pytest

from axis_ptz_ros2.vapix import (
    AuthError,
    CameraConfig,
    CameraTimeout,
    HttpStatusError,
    Resolution,
    ResponseParseError,
    VapixClient,
)
from axis_ptz_ros2.vapix.models import CIF_NTSC, CIF_PAL
from tests.unit import fixtures_vapix as fx

pytestmark = pytest.mark.unit

PARAM = "/axis-cgi/param.cgi"
V2PARAM = "/axis-cgi/view/param.cgi"
IMAGESIZE = "/axis-cgi/imagesize.cgi"
PTZ = "/axis-cgi/com/ptz.cgi"
NTSC_LIST = fx.PARAM_RESOLUTION_P5512_NO_ROOT  # 4CIF,2CIF,CIF,QCIF [V-obs S8]
CIF_PAL_SIZES = [CIF_PAL[n] for n in ("4CIF", "2CIF", "CIF", "QCIF")]
CIF_NTSC_SIZES = [CIF_NTSC[n] for n in ("4CIF", "2CIF", "CIF", "QCIF")]
DIGEST_401 = fx.text("", 401)


def make(routes, **config) -> tuple[VapixClient, fx.Recorder]:
    rec = fx.Recorder(routes)
    return VapixClient(CameraConfig(**config), transport=rec.transport()), rec


def imagesize(default: str | None, per_name: dict[str, str] | None = None):
    """imagesize.cgi: ``default`` for a request without resolution=, per-name answers, else an HTML comment."""

    def reply(request: httpx.Request) -> httpx.Response:
        name = request.url.params.get("resolution")
        if name is None and default is not None:
            return httpx.Response(200, text=default)
        if name is not None and per_name and name in per_name:
            return httpx.Response(200, text=per_name[name])
        return httpx.Response(200, text=f"<!-- Invalid resolution {name} -->\n")

    return reply


# ---- resolutions -----------------------------------------------------------------------------------
def test_ntsc_camera_without_imagesize_or_standard_gets_both_standards_never_an_empty_list():
    """No imagesize.cgi (404), no ImageSource group, no parameter definitions: the CIF names get the sizes of
    both standards (issue 23: an empty list would refuse every request), said in resolution_problem — never
    silently PAL."""
    vapix, rec = make({PARAM: fx.text(NTSC_LIST)})
    sizes = vapix.supported_resolutions()
    assert Resolution(704, 480) in sizes
    assert Resolution(704, 576) in sizes
    assert set(sizes) == {Resolution(*s) for s in (*CIF_PAL_SIZES, *CIF_NTSC_SIZES)}
    assert "4CIF" in vapix.resolution_problem
    assert "both standards" in vapix.resolution_problem
    assert "WIDTHxHEIGHT" in vapix.resolution_problem
    # imagesize.cgi was found missing once (both paths), the standard and the definitions asked once each
    assert sum("imagesize" in p for p in rec.paths) == 2
    assert sum("group=ImageSource" in p for p in rec.paths) == 1
    assert sum("listdefinitions" in p for p in rec.paths) == 1


# Recorded on an AXIS P5512 PTZ Dome, firmware 5.51.7 (vapix.md S8): its analogue input and the resolution
# parameter's definition, verbatim lines of the recording.
P5512_IMAGESOURCE_VIDEO = (
    "root.ImageSource.I0.Video.Contrast=50\nroot.ImageSource.I0.Video.Saturation=50\n"
    "root.ImageSource.I0.Video.XOffset=0\nroot.ImageSource.I0.Video.YOffset=0\n"
    "root.ImageSource.I0.Video.Connector=yc\nroot.ImageSource.I0.Video.DetectedType=NTSC\n"
    "root.ImageSource.I0.Video.CaptureMode=NTSC\nroot.ImageSource.I0.Video.DeinterlaceMode=field_blend\n"
)
P5512_RESOLUTION_DEFINITION = """<?xml version="1.0"?>
<parameterDefinitions version="1.0">
  <group name="root">
    <group name="Image">
      <group name="I0">
        <group name="Appearance">
          <parameter name="Resolution" value="4CIF" securityLevel="7714" niceName="Resolution">
            <type>
              <enum>
                <entry value="4CIF" niceValue="4CIF (704x480)" />
                <entry value="2CIF" niceValue="2CIF (704x240)" />
                <entry value="CIF" niceValue="CIF (352x240)" />
                <entry value="QCIF" niceValue="QCIF (176x120)" />
              </enum>
            </type>
          </parameter>
        </group>
      </group>
    </group>
  </group>
</parameterDefinitions>
"""
NTSC_SIZES = (Resolution(704, 480), Resolution(704, 240), Resolution(352, 240), Resolution(176, 120))


def test_without_imagesize_the_reported_video_standard_sizes_the_cif_names():
    vapix, rec = make(
        {
            f"{PARAM}?action=list&group=Properties.Image.Resolution": fx.text(NTSC_LIST),
            f"{PARAM}?action=list&group=ImageSource.I0.Video": fx.text(P5512_IMAGESOURCE_VIDEO),
        }
    )
    assert vapix.supported_resolutions() == NTSC_SIZES
    assert vapix.resolution_problem == ""
    assert not any("listdefinitions" in p for p in rec.paths)


@pytest.mark.parametrize(("detected", "capture", "ntsc"), [("PAL", "NTSC", False), ("none", "NTSC", True)])
def test_the_detected_signal_wins_over_the_capture_mode(detected, capture, ntsc):
    body = f"root.ImageSource.I0.Video.DetectedType={detected}\nroot.ImageSource.I0.Video.CaptureMode={capture}\n"
    vapix, _ = make(
        {
            f"{PARAM}?action=list&group=Properties.Image.Resolution": fx.text(NTSC_LIST),
            f"{PARAM}?action=list&group=ImageSource.I0.Video": fx.text(body),
        }
    )
    assert vapix.supported_resolutions()[0] == (Resolution(704, 480) if ntsc else Resolution(704, 576))


def test_without_imagesize_or_standard_the_parameter_definition_sizes_the_names():
    group = "Image.I0.Appearance.Resolution"
    vapix, _ = make(
        {
            f"{PARAM}?action=list&group=Properties.Image.Resolution": fx.text(NTSC_LIST),
            f"{PARAM}?action=list&group=ImageSource.I0.Video": fx.text(fx.PARAM_ERROR),
            f"{PARAM}?action=listdefinitions&listformat=xmlschema&group={group}": fx.text(P5512_RESOLUTION_DEFINITION),
        }
    )
    assert vapix.supported_resolutions() == NTSC_SIZES
    assert vapix.resolution_problem == ""


def test_ntsc_from_the_default_image_size_when_names_are_not_answered():
    vapix, _ = make({PARAM: fx.text(NTSC_LIST + "\n"), IMAGESIZE: imagesize(fx.IMAGESIZE_4CIF_NTSC)})
    assert vapix.supported_resolutions() == (
        Resolution(704, 480),
        Resolution(704, 240),
        Resolution(352, 240),
        Resolution(176, 120),
    )
    assert vapix.resolution_problem == ""


def test_d1_is_a_real_resolution_name():
    listing = "Properties.Image.Resolution=D1,4CIF,CIF\n"
    vapix, _ = make(
        {PARAM: fx.text(listing), IMAGESIZE: imagesize(None, {"D1": "image width = 720\nimage height = 480\n"})}
    )
    assert vapix.supported_resolutions() == (Resolution(720, 480), Resolution(704, 480), Resolution(352, 240))
    pal, _ = make({PARAM: fx.text(listing), IMAGESIZE: imagesize("image width = 720\nimage height = 576\n")})
    assert pal.supported_resolutions() == (Resolution(720, 576), Resolution(704, 576), Resolution(352, 288))
    assert Resolution.parse("D1") == Resolution(720, 576)
    assert Resolution.parse("d1", ntsc=True) == Resolution(720, 480)


# ---- PTZ presence --------------------------------------------------------------------------------------
def _device(ptz_enabled: str | None):
    props = (
        "root.Properties.API.HTTP.Version=3\nroot.Properties.PTZ.PTZ=yes\nroot.Properties.Image.Resolution=1920x1080\n"
    )
    routes = {
        f"{PARAM}?action=list&group=Brand": fx.text("root.Brand.ProdShortName=AXIS M3045-V\n"),
        f"{PARAM}?action=list&group=Properties": fx.text(props),
        f"{PARAM}?action=list&group=PTZ.Support": fx.text("root.PTZ.Support.S1.AbsoluteZoom=true\n"),
    }
    if ptz_enabled is not None:
        routes[f"{PARAM}?action=list&group=PTZ.ImageSource"] = fx.text(
            f"root.PTZ.ImageSource.I0.PTZEnabled={ptz_enabled}\n"
        )
    else:
        routes[f"{PARAM}?action=list&group=PTZ.ImageSource"] = fx.text(fx.PARAM_ERROR)
    return make(routes)[0]


@pytest.mark.parametrize(("flag", "ptz"), [("false", False), ("true", True), (None, True)])
def test_fixed_camera_with_digital_ptz_is_not_a_ptz(flag, ptz):
    vapix = _device(flag)
    assert vapix.device_info().ptz is ptz
    assert vapix.mechanical_ptz() is (None if flag is None else ptz)


# ---- parameter paths -------------------------------------------------------------------------------------
def test_legacy_param_path_tried_after_401_on_the_v3_path():
    """Firmware 5.0-5.6 answers /axis-cgi/param.cgi with 401 even for allowed users (vapix.md §2.2)."""
    vapix, rec = make({PARAM: DIGEST_401, V2PARAM: fx.text("root.Brand.ProdShortName=AXIS 214 PTZ\n")})
    assert vapix.list_params("Brand") == {"Brand.ProdShortName": "AXIS 214 PTZ"}
    assert rec.paths[-1].startswith(V2PARAM)
    vapix.list_params("Brand")  # remembered
    assert rec.paths[-1].startswith(V2PARAM)


def test_401_on_both_param_paths_is_an_auth_error():
    vapix, _ = make({PARAM: DIGEST_401, V2PARAM: DIGEST_401})
    with pytest.raises(AuthError):
        vapix.list_params("Brand")


def test_404_on_v3_then_401_on_v2_reports_the_401():
    vapix, _ = make({V2PARAM: DIGEST_401})
    with pytest.raises(AuthError):
        vapix.list_params("Brand")


# ---- limits fallback ---------------------------------------------------------------------------------------
def test_limits_404_does_not_fall_back_to_the_listing():
    vapix, rec = make({PARAM: fx.text(fx.P5512_PTZ_LIMIT_PARAMS)})
    with pytest.raises(HttpStatusError):
        vapix.query_limits()
    assert not any("param.cgi" in p for p in rec.paths)


def test_limits_parse_error_falls_back_to_the_listing():
    vapix, rec = make({PTZ: fx.text("MinPan=-180\nnonsense\n"), PARAM: fx.text(fx.P5512_PTZ_LIMIT_PARAMS)})
    limits = vapix.query_limits()
    assert limits.max_zoom == 19999
    assert any("group=PTZ.Limit" in p for p in rec.paths)


# ---- body caps -----------------------------------------------------------------------------------------------
def _endless(chunk: bytes, ctype: str, delay: float = 0.0):
    pulled = {"n": 0}

    def body():
        for _ in itertools.count():
            pulled["n"] += 1
            if delay:
                time.sleep(delay)  # the simulated camera: a body that trickles in, ``delay`` per chunk
            yield chunk

    def reply(request: httpx.Request) -> httpx.Response:
        return httpx.Response(200, headers={"Content-Type": ctype}, content=body())

    return reply, pulled


def test_endless_page_is_refused_at_the_cap_not_read_for_ever():
    reply, pulled = _endless(b"x" * 65536, "text/plain")
    vapix, _ = make({PTZ: reply})
    with pytest.raises(ResponseParseError, match="larger than"):
        vapix.query_position()
    assert pulled["n"] <= (1 << 20) // 65536 + 1


def test_stream_on_the_wrong_port_is_refused_at_once():
    reply, pulled = _endless(b"--myboundary\r\n", "multipart/x-mixed-replace; boundary=myboundary")
    vapix, _ = make({PARAM: reply})
    with pytest.raises(ResponseParseError, match="stream"):
        vapix.list_params("Brand")
    assert pulled["n"] <= 1


def test_trickling_reply_ends_at_the_total_timeout():
    reply, _ = _endless(b"y" * 10, "text/plain", delay=0.05)
    vapix, _ = make({PTZ: reply}, timeout_s=0.5)
    t0 = time.monotonic()
    with pytest.raises(CameraTimeout, match="still arriving"):
        vapix.query_position()
    assert time.monotonic() - t0 < 5.0


def test_big_error_page_is_read_only_partly():
    reply, pulled = _endless(b"z" * 65536, "text/html")

    def status_500(request: httpx.Request) -> httpx.Response:
        response = reply(request)
        response.status_code = 500
        return response

    vapix, _ = make({PTZ: status_500})
    with pytest.raises(HttpStatusError):
        vapix.query_position()
    assert pulled["n"] <= 2


def test_endless_401_body_is_not_read_for_ever():
    """httpx reads a 401 body before the credentialed retry: ours caps it."""
    pulled = {"n": 0}

    def body():
        while True:
            pulled["n"] += 1
            yield b"<p>" * 4096

    def reply(request: httpx.Request) -> httpx.Response:
        challenge = 'Digest realm="AXIS_00408C1A2B3C", nonce="abc=", algorithm=MD5, qop="auth"'
        return httpx.Response(401, headers={"WWW-Authenticate": challenge, "Content-Type": "text/html"}, content=body())

    vapix, _ = make({PTZ: reply}, username="root", password="pw")
    with pytest.raises(ResponseParseError, match="401 reply larger"):
        vapix.query_position()
    assert pulled["n"] <= (64 << 10) // (3 * 4096) + 2
