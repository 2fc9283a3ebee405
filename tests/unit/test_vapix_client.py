"""VapixClient over httpx.MockTransport with real device replies (vapix.md §2, §4, §5, §6, §12)."""

import threading

import httpx
import pytest

from axis_ptz_ros2 import __version__
from axis_ptz_ros2.vapix import (
    AbsoluteMove,
    AuthError,
    CameraConfig,
    CameraTimeout,
    CameraUnreachable,
    CommandRejected,
    ContinuousMove,
    GotoPreset,
    HttpStatusError,
    InvalidArgument,
    Preset,
    Resolution,
    ResponseParseError,
    SetPreset,
    VapixClient,
    VideoParams,
)
from axis_ptz_ros2.vapix.replies import build_path, parse_error_body
from tests.unit import fixtures_vapix as fx

pytestmark = pytest.mark.unit

PTZ = "/axis-cgi/com/ptz.cgi"
PARAM = "/axis-cgi/param.cgi"
V2PARAM = "/axis-cgi/view/param.cgi"
VIDEO = VideoParams(Resolution(704, 576), fps=25, compression=30)


def make(routes, **config) -> tuple[VapixClient, fx.Recorder]:
    rec = fx.Recorder(routes)
    return VapixClient(CameraConfig(**config), transport=rec.transport()), rec


def test_query_position_request_and_user_agent():
    vapix, rec = make({PTZ: fx.text(fx.POSITION_RESPONSE)})
    with vapix:
        pos = vapix.query_position()
    assert pos.pan_deg == pytest.approx(51.2891)
    assert pos.tilt_deg == pytest.approx(46.1914)
    assert rec.paths == ["/axis-cgi/com/ptz.cgi?query=position"]
    assert rec.requests[0].headers["user-agent"] == f"axis_ptz_ros2/{__version__}"
    assert rec.requests[0].url.host == "127.0.0.1"


def test_camera_argument_only_when_not_one():
    vapix, rec = make({PTZ: fx.text(fx.POSITION_RESPONSE)}, camera=2)
    vapix.query_position()
    assert rec.paths == ["/axis-cgi/com/ptz.cgi?camera=2&query=position"]


def test_query_limits_cached_and_used_to_refuse_commands_before_sending():
    vapix, rec = make({PTZ: fx.text(fx.LIMITS_RESPONSE)})
    limits = vapix.query_limits()
    assert limits.max_field_angle_deg == pytest.approx(62.3)
    assert vapix.limits == limits
    with pytest.raises(InvalidArgument, match="tilt -25 outside the camera limits -20..90"):
        vapix.ptz(AbsoluteMove(tilt_deg=-25.0))
    with pytest.raises(InvalidArgument, match="pan 500 outside the protocol range"):
        vapix.ptz(AbsoluteMove(pan_deg=500.0))
    assert rec.paths == ["/axis-cgi/com/ptz.cgi?query=limits"]  # the refused commands never left


def test_query_limits_falls_back_to_params_when_query_rejected():
    def ptz(request: httpx.Request) -> httpx.Response:
        return httpx.Response(200, text=fx.ERROR_UNKNOWN_QUERY_NEXT_LINE.replace("foo", "limits"))

    vapix, rec = make({PTZ: ptz, PARAM: fx.text(fx.P5512_PTZ_LIMIT_PARAMS)})
    limits = vapix.query_limits()
    assert (limits.min_tilt_deg, limits.max_tilt_deg, limits.max_zoom) == (-180, 0, 19999)
    assert rec.paths[-1] == "/axis-cgi/param.cgi?action=list&group=PTZ.Limit"


def test_ptz_command_204_and_wire_format():
    vapix, rec = make({PTZ: fx.no_content()})
    vapix.ptz(AbsoluteMove(pan_deg=10.0, tilt_deg=-15.0, zoom=3000))
    vapix.ptz(ContinuousMove(0, 0, 0))
    vapix.ptz(GotoPreset(name="My preset"))
    assert rec.paths == [
        "/axis-cgi/com/ptz.cgi?pan=10.0000&tilt=-15.0000&zoom=3000",
        "/axis-cgi/com/ptz.cgi?continuouspantiltmove=0,0&continuouszoommove=0",
        "/axis-cgi/com/ptz.cgi?gotoserverpresetname=My%20preset",
    ]


def test_preset_config_path():
    vapix, rec = make({"/axis-cgi/com/ptzconfig.cgi": fx.no_content()})
    vapix.ptz(SetPreset("Door"))
    assert rec.paths == ["/axis-cgi/com/ptzconfig.cgi?setserverpresetname=Door"]


@pytest.mark.parametrize(
    "body",
    [
        fx.ERROR_UNKNOWN_QUERY_NEXT_LINE,
        fx.ERROR_UNKNOWN_QUERY_SAME_LINE,
        "Error:query: unknown value: foo\r\n",
    ],
)
def test_error_body_raises_command_rejected(body):
    vapix, _ = make({PTZ: fx.text(body)})
    with pytest.raises(CommandRejected) as excinfo:
        vapix.query_position()
    assert excinfo.value.camera_message == "query: unknown value: foo"
    assert "query: unknown value: foo" in str(excinfo.value)


def test_parse_error_body_forms():
    assert parse_error_body(fx.ERROR_HTML) == "Unknown command"
    assert parse_error_body(fx.POSITION_RESPONSE) is None
    assert parse_error_body("") is None
    assert parse_error_body("Error:\n\n") == "(no message)"


def test_presets_and_speed():
    def ptz(request: httpx.Request) -> httpx.Response:
        query = request.url.params["query"]
        return httpx.Response(
            200, text={"presetposcam": fx.PRESETPOSCAM_RESPONSE_TWO, "speed": fx.SPEED_RESPONSE}[query]
        )

    vapix, _ = make({PTZ: ptz})
    assert vapix.query_presets() == (Preset(1, "Home"), Preset(2, "Door"))
    assert vapix.query_speed() == 100


def test_list_params_v3_strips_root():
    vapix, rec = make({PARAM: fx.text(fx.PARAM_BRAND_214)})
    assert vapix.list_params("Brand") == {
        "Brand.ProdShortName": "AXIS 214 PTZ",
        "Brand.ProdFullName": "AXIS 214 PTZ Network Camera",
    }
    assert rec.paths == ["/axis-cgi/param.cgi?action=list&group=Brand"]


def test_list_params_falls_back_to_v2_path_and_remembers_it():
    vapix, rec = make({V2PARAM: fx.text(fx.PARAM_RESOLUTION_P5512_NO_ROOT)})
    assert vapix.list_params("Properties.Image.Resolution") == {"Properties.Image.Resolution": "4CIF,2CIF,CIF,QCIF"}
    vapix.list_params("Properties.Image.Resolution")
    assert rec.paths == [
        "/axis-cgi/param.cgi?action=list&group=Properties.Image.Resolution",
        "/axis-cgi/view/param.cgi?action=list&group=Properties.Image.Resolution",
        "/axis-cgi/view/param.cgi?action=list&group=Properties.Image.Resolution",
    ]


def test_list_params_error_line_raises():
    vapix, _ = make({PARAM: fx.text(fx.PARAM_ERROR)})
    with pytest.raises(CommandRejected) as excinfo:
        vapix.list_params("Foo.Bar")
    assert excinfo.value.camera_message == "Error -1 getting param in group 'Foo.Bar'"


def test_list_params_404_everywhere_is_http_status_error():
    vapix, _ = make({})
    with pytest.raises(HttpStatusError) as excinfo:
        vapix.list_params("Brand")
    assert excinfo.value.status_code == 404
    assert "/axis-cgi/param.cgi" in str(excinfo.value)


def test_supported_resolutions_pal_cif_names_detected_with_imagesize():
    vapix, _ = make(
        {
            V2PARAM: fx.text("root.Properties.Image.Resolution=4CIF,2CIFEXP,2CIF,CIF,QCIF\n"),
            "/axis-cgi/view/imagesize.cgi": fx.text(fx.IMAGESIZE_4CIF_PAL),
        }
    )
    assert vapix.supported_resolutions() == (
        Resolution(704, 576),
        Resolution(704, 288),
        Resolution(352, 288),
        Resolution(176, 144),
    )


def test_supported_resolutions_ntsc_detected():
    vapix, rec = make(
        {
            PARAM: fx.text(fx.PARAM_RESOLUTION_P5512_NO_ROOT),
            "/axis-cgi/imagesize.cgi": fx.text(fx.IMAGESIZE_4CIF_NTSC),
        }
    )
    assert vapix.supported_resolutions() == (
        Resolution(704, 480),
        Resolution(704, 240),
        Resolution(352, 240),
        Resolution(176, 120),
    )
    assert "/axis-cgi/imagesize.cgi?resolution=4CIF&squarepixel=0" in rec.paths


def test_supported_resolutions_wxh_list_and_used_for_validation():
    vapix, rec = make({PARAM: fx.text(fx.PARAM_RESOLUTION_BULLET)})
    resolutions = vapix.supported_resolutions()
    assert resolutions[0] == Resolution(1920, 1080)
    assert len(resolutions) == 5
    n = len(rec.requests)
    with pytest.raises(InvalidArgument, match="resolution 704x576 not supported"):
        vapix.open_mjpeg(VIDEO, read_timeout_s=1.0)
    with pytest.raises(InvalidArgument, match="fps 0 outside"):
        vapix.snapshot(VideoParams(Resolution(1920, 1080), fps=0, compression=30))
    assert len(rec.requests) == n  # nothing was sent


def test_device_info_214_persona():
    vapix, _ = make(
        {
            V2PARAM: lambda req: httpx.Response(
                200,
                text={
                    "Brand": fx.PARAM_BRAND_214,
                    "Properties": fx.PARAM_PROPERTIES_214,
                    "PTZ.Support": fx.PARAM_PTZ_SUPPORT,
                }.get(
                    req.url.params["group"],
                    f"# Error: Error -1 getting param in group '{req.url.params['group']}'\n",
                ),
            ),
            "/axis-cgi/view/imagesize.cgi": fx.text(fx.IMAGESIZE_4CIF_PAL),
        }
    )
    info = vapix.device_info()
    assert info.product == "AXIS 214 PTZ Network Camera"
    assert info.firmware == "4.49"
    assert info.api_version == 2
    assert info.ptz is True
    assert Resolution(704, 576) in info.resolutions
    assert info.supports == frozenset(
        {"AbsolutePan", "AbsoluteTilt", "AbsoluteZoom", "AreaZoom", "ContinuousPan"}
    )  # DigitalZoom=false is not a capability


def test_snapshot_and_error_reply():
    image = fx.jpeg(b"snap")
    vapix, rec = make({"/axis-cgi/jpg/image.cgi": lambda _r: httpx.Response(200, content=image)})
    assert vapix.snapshot(VIDEO) == image
    assert rec.paths == ["/axis-cgi/jpg/image.cgi?resolution=704x576&compression=30"]
    vapix, _ = make({"/axis-cgi/jpg/image.cgi": fx.text("<html>no</html>")})
    with pytest.raises(ResponseParseError, match="expected a JPEG"):
        vapix.snapshot(VIDEO)


def test_video_path_has_no_host_or_credentials():
    vapix, _ = make({}, username="root", password="hunter2", port=8080)
    assert vapix.video_path(VIDEO) == "/axis-cgi/mjpg/video.cgi?resolution=704x576&fps=25&compression=30"
    assert vapix.config.base_url == "http://127.0.0.1:8080"
    assert "hunter2" not in repr(vapix)


def stream_reply(chunks, *, status=200, content_type=fx.MULTIPART):
    def handler(_req: httpx.Request) -> httpx.Response:
        return httpx.Response(status, headers={"Content-Type": content_type}, content=iter(chunks))

    return handler


def test_open_mjpeg_yields_frames_and_stats():
    frames = [fx.jpeg(b"a" * 50), fx.jpeg(b"b" * 70), fx.jpeg(b"c" * 10)]
    data = b"".join(fx.part(f) for f in frames)
    chunks = [data[i : i + 33] for i in range(0, len(data), 33)]
    vapix, rec = make({"/axis-cgi/mjpg/video.cgi": stream_reply(chunks)})
    with vapix.open_mjpeg(VIDEO, read_timeout_s=2.0) as stream:
        got = list(stream)
        assert stream.stats.frames == 3
    assert got == frames
    assert rec.paths == ["/axis-cgi/mjpg/video.cgi?resolution=704x576&fps=25&compression=30"]


def test_open_mjpeg_boundary_with_quotes_and_space():
    frame = fx.jpeg(b"q")
    vapix, _ = make(
        {
            "/axis-cgi/mjpg/video.cgi": stream_reply(
                [fx.part(frame, boundary=b"abc")], content_type='multipart/x-mixed-replace; boundary="--abc"'
            )
        }
    )
    with vapix.open_mjpeg(VIDEO, 1.0) as stream:
        assert list(stream) == [frame]


@pytest.mark.parametrize(
    ("status", "error"), [(401, AuthError), (403, AuthError), (404, HttpStatusError), (503, HttpStatusError)]
)
def test_open_mjpeg_non_2xx_mapped(status, error):
    vapix, _ = make({"/axis-cgi/mjpg/video.cgi": stream_reply([b"nope"], status=status, content_type="text/plain")})
    with pytest.raises(error):
        vapix.open_mjpeg(VIDEO, 1.0)


def test_open_mjpeg_error_body_instead_of_stream():
    vapix, _ = make({"/axis-cgi/mjpg/video.cgi": fx.text("Error:\nresolution not supported\n")})
    with pytest.raises(CommandRejected, match="resolution not supported"):
        vapix.open_mjpeg(VIDEO, 1.0)


def test_mjpeg_close_between_reads_stops_iteration():
    gate = threading.Event()
    first = fx.part(fx.jpeg(b"1"))

    def chunks():
        yield first
        gate.wait(5.0)
        yield fx.part(fx.jpeg(b"late"))

    vapix, _ = make({"/axis-cgi/mjpg/video.cgi": stream_reply(chunks())})
    stream = vapix.open_mjpeg(VIDEO, 1.0)
    it = iter(stream)
    assert next(it) == fx.jpeg(b"1")
    stream.close()  # no read in progress: released at once
    gate.set()
    assert list(it) == []
    assert stream.closed


def test_mjpeg_close_from_other_thread_while_reader_blocked_never_yields_late_frame():
    gate = threading.Event()
    reading = threading.Event()

    def chunks():
        yield fx.part(fx.jpeg(b"1"))
        reading.set()
        gate.wait(5.0)  # a stalled camera: the reader thread is blocked here
        yield fx.part(fx.jpeg(b"late"))

    vapix, _ = make({"/axis-cgi/mjpg/video.cgi": stream_reply(chunks())})
    stream = vapix.open_mjpeg(VIDEO, 1.0)
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.extend(stream))
    reader.start()
    assert reading.wait(5.0)
    stream.close()  # from this thread, while the reader is blocked inside a read
    gate.set()  # the "camera" delivers a late frame after close
    reader.join(5.0)
    assert not reader.is_alive()
    assert got == [fx.jpeg(b"1")]  # the late frame is never handed out


@pytest.mark.parametrize(
    ("exc", "error", "text"),
    [
        (httpx.ConnectError("[Errno 111] Connection refused"), CameraUnreachable, "unreachable"),
        (httpx.ReadError("Connection reset by peer"), CameraUnreachable, "unreachable"),
        (httpx.RemoteProtocolError("Server disconnected"), CameraUnreachable, "unreachable"),
        (httpx.ConnectTimeout("timed out"), CameraTimeout, "did not answer in time"),
        (httpx.ReadTimeout("timed out"), CameraTimeout, "did not answer in time"),
    ],
)
def test_transport_errors_mapped_without_credentials(exc, error, text):
    def handler(request: httpx.Request) -> httpx.Response:
        raise type(exc)(f"{exc} http://root:hunter2@127.0.0.1/", request=request)

    vapix, _ = make({PTZ: handler}, username="root", password="hunter2")
    with pytest.raises(error, match=text) as excinfo:
        vapix.query_position()
    message = str(excinfo.value)
    assert "hunter2" not in message
    assert "GET /axis-cgi/com/ptz.cgi?query=position" in message


def test_http_500_is_http_status_error_with_code():
    vapix, _ = make({PTZ: fx.text("boom", status=500)})
    with pytest.raises(HttpStatusError) as excinfo:
        vapix.ptz(ContinuousMove(0, 0))
    assert excinfo.value.status_code == 500


@pytest.mark.parametrize(
    ("kwargs", "reason"),
    [
        ({"host": "user:pw@cam"}, "bare host"),
        ({"port": 70000}, "port"),
        ({"auth": "ntlm"}, "auth must be one of"),
        ({"username": "root"}, "together"),
        ({"camera": 0}, "camera"),
    ],
)
def test_config_validation(kwargs, reason):
    with pytest.raises(InvalidArgument, match=reason):
        CameraConfig(**kwargs)


def test_build_path_encoding():
    assert build_path("/x", {"a": "b c", "d": "1,2", "e": "x&y"}) == "/x?a=b%20c&d=1,2&e=x%26y"
    assert CameraConfig(host="::1", port=80).base_url == "http://[::1]:80"
    assert CameraConfig(use_https=True).base_url == "https://127.0.0.1"


def test_https_verify_options(tmp_path):
    with VapixClient(CameraConfig(use_https=True, verify_tls=False), transport=fx.Recorder().transport()) as v:
        assert v.config.base_url.startswith("https://")
    with pytest.raises(InvalidArgument, match="cannot load CA bundle"):
        VapixClient(CameraConfig(use_https=True, verify_tls=str(tmp_path / "missing.pem")))
