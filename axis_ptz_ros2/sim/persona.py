"""Simulated camera personas: what a model answers (vapix.md §2, §5, §6, §7, §11.6).

A :class:`Persona` is frozen data: product names, VAPIX version, resolution list, pixel aspect, PTZ limits and
optics, default authentication and HTTPS, and which newer VAPIX features the model has. Two ship:

* :data:`AXIS_214` (default, ``--model axis214``): the Axis 214 PTZ of the thesis — firmware 4.49, VAPIX 2,
  PAL CIF names, 12:11 pixels, pan ±170° with end stops, tilt −30…+90°, zoom 1…9999, anonymous, HTTP;
* :data:`AXIS_Q6075` (``--model q6075``): a current 1080p PTZ dome in the style of the AXIS Q6075-E — AXIS OS,
  VAPIX 3, ``WxH`` resolutions up to 1920×1080 (16:9, square pixels), endless pan (−180…180, wrapping), dome
  tilt −90…+20°, ``MaxZoom=19999`` (optical to 9999 + digital), Digest only, HTTPS with a self-signed
  certificate, ``query=attributes``, presets also under ``PTZ.Preset.P0.*``, ``PTZ.ImageSource.I0.PTZEnabled``.
  Where each figure comes from is in ``config/q6075.yaml`` and the README.

The 214's parameter tree and reply texts below are unchanged module-level helpers; :func:`persona` looks a
model up by name.
"""

from __future__ import annotations

import fnmatch
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from axis_ptz_ros2.geometry import PtzKinematics, ZoomCurve, ZoomModel
from axis_ptz_ros2.sim.camera_model import CameraModel
from axis_ptz_ros2.sim.ptz import Speeds
from axis_ptz_ros2.sim.scene import PtzLimits

#: PAL CIF names of the 214 (vapix.md §5.5).
RESOLUTIONS: dict[str, tuple[int, int]] = {
    "4CIF": (704, 576),
    "2CIFEXP": (704, 576),
    "2CIF": (704, 288),
    "CIF": (352, 288),
    "QCIF": (176, 144),
}
SQUARE_PIXEL_FACTOR = 12.0 / 11.0  # PAL


def square_width(width: int) -> int:
    """Width of the square-pixel (``squarepixel=1``) stream."""
    return int(round(width * SQUARE_PIXEL_FACTOR))


#: Every WxH the simulated 214 accepts in ``resolution=`` (native and square-pixel sizes).
ACCEPTED_SIZES: frozenset[tuple[int, int]] = frozenset(
    list(RESOLUTIONS.values()) + [(square_width(w), h) for w, h in RESOLUTIONS.values()]
)


def parse_resolution(value: str, squarepixel: bool) -> tuple[int, int]:
    """``resolution`` (CIF name or WxH) → output (width, height); raises ValueError if unsupported."""
    name = value.strip().upper()
    if name in RESOLUTIONS:
        w, h = RESOLUTIONS[name]
    else:
        parts = name.split("X")
        if len(parts) != 2 or not all(p.isdigit() for p in parts):
            raise ValueError(f"Invalid resolution: {value}")
        w, h = int(parts[0]), int(parts[1])
        if (w, h) not in ACCEPTED_SIZES:
            raise ValueError(f"Unsupported resolution: {value}")
    if squarepixel and (w, h) in RESOLUTIONS.values():
        w = square_width(w)
    return w, h


NOT_FOUND_HTML = (
    "<HTML><HEAD><TITLE>404 Not Found</TITLE></HEAD>\n<BODY><H1>404 Not Found</H1>\n"
    "The requested URL {path} was not found on this server.\n</BODY></HTML>\n"
)
UNAUTHORIZED_HTML = (
    "<HTML><HEAD><TITLE>401 Unauthorized</TITLE></HEAD>\n<BODY><H1>401 Unauthorized</H1>\n"
    "Your client does not have permission to get URL {path} from this server.\n</BODY></HTML>\n"
)
ERROR_HTML = "<HTML><HEAD><TITLE>{code} {reason}</TITLE></HEAD>\n<BODY><H1>{code} {reason}</H1>\n</BODY></HTML>\n"

_SUPPORT = [
    "AbsolutePan",
    "AbsoluteTilt",
    "AbsoluteZoom",
    "AbsoluteFocus",
    "AbsoluteIris",
    "AreaZoom",
    "AutoFocus",
    "AutoIris",
    "ContinuousPan",
    "ContinuousTilt",
    "ContinuousZoom",
    "ContinuousFocus",
    "RelativePan",
    "RelativeTilt",
    "RelativeZoom",
    "RelativeFocus",
    "RelativeIris",
    "ServerPreset",
    "SpeedCtl",
    "IrCutFilter",
    "AutoIrCutFilter",
    "BackLight",
]
_NO_SUPPORT = [
    "AbsoluteBrightness",
    "RelativeBrightness",
    "ContinuousBrightness",
    "ContinuousIris",
    "DigitalZoom",
    "Auxiliary",
    "DevicePreset",
    "OSDMenu",
    "ActionNotification",
    "ProportionalSpeed",
    "LensOffset",
    "JoyStickEmulation",
    "GenericHTTP",
]

READ_ONLY_PREFIXES = ("Properties.", "Brand.")


def parameter_tree(limits: PtzLimits, zoom: ZoomModel, mac: str, auth: str) -> dict[str, str]:
    """The 214's parameters (names without the ``root.`` prefix) in listing order."""
    p: dict[str, str] = {
        "Brand.Brand": "AXIS",
        "Brand.ProdFullName": "AXIS 214 PTZ Network Camera",
        "Brand.ProdNbr": "214",
        "Brand.ProdShortName": "AXIS 214 PTZ",
        "Brand.ProdType": "PTZ Network Camera",
        "Brand.WebURL": "http://www.axis.com/",
        "Image.I0.Appearance.Compression": "30",
        "Image.I0.Appearance.Resolution": "4CIF",
        "Image.I0.Appearance.Rotation": "0",
        "Image.I0.Appearance.SquarePixelEnabled": "no",
        "Image.I0.Stream.FPS": "0",
        # the analogue input's standard, as an AXIS P5512 (fw 5.51) reports it [V-obs S8]; on the 214 [I]
        "ImageSource.I0.Video.DetectedType": "PAL",
        "ImageSource.I0.Video.CaptureMode": "PAL",
        "Network.HTTP.AuthenticationPolicy": "basic_digest" if auth == "none" else auth,
        "Properties.API.HTTP.Version": "2",
        "Properties.API.HTTP.AdminPath": "/operator/basic.shtml",
        "Properties.Firmware.BuildDate": "Mar 05 2009 14:23",
        "Properties.Firmware.Version": "4.49",
        "Properties.Image.Format": "jpeg,mjpeg,mpeg4",
        "Properties.Image.NbrOfViews": "1",
        "Properties.Image.Resolution": ",".join(RESOLUTIONS),
        "Properties.Image.Rotation": "0,180",
        "Properties.PTZ.PTZ": "yes",
        "Properties.PTZ.DigitalPTZ": "no",
        "Properties.System.Architecture": "crisv32",
        "Properties.System.SerialNumber": mac,
        "PTZ.BoaProtPTZOperator": "anonymous" if auth == "none" else "password",
        "PTZ.CameraDefault": "1",
        "PTZ.NbrOfCameras": "1",
        "PTZ.NbrOfSerPorts": "1",
        "PTZ.Limit.L1.MinPan": f"{limits.min_pan:g}",
        "PTZ.Limit.L1.MaxPan": f"{limits.max_pan:g}",
        "PTZ.Limit.L1.MinTilt": f"{limits.min_tilt:g}",
        "PTZ.Limit.L1.MaxTilt": f"{limits.max_tilt:g}",
        "PTZ.Limit.L1.MinZoom": str(limits.min_zoom),
        "PTZ.Limit.L1.MaxZoom": str(limits.max_zoom),
        "PTZ.Limit.L1.MinFocus": "1",
        "PTZ.Limit.L1.MaxFocus": "9999",
        "PTZ.Limit.L1.MinIris": "1",
        "PTZ.Limit.L1.MaxIris": "9999",
        "PTZ.Limit.L1.MinFieldAngle": str(int(round(math.degrees(zoom.hfov(limits.max_zoom)) * 10))),
        "PTZ.Limit.L1.MaxFieldAngle": str(int(round(math.degrees(zoom.hfov(limits.min_zoom)) * 10))),
    }
    p.update(real_listing_ptz_keys())
    for cap in _SUPPORT:
        p[f"PTZ.Support.S1.{cap}"] = "true"
    for cap in _NO_SUPPORT:
        p[f"PTZ.Support.S1.{cap}"] = "false"
    p.update(
        {
            "PTZ.UserAdv.U1.MoveSpeed": "100",
            "PTZ.Various.V1.PanEnabled": "true",
            "PTZ.Various.V1.TiltEnabled": "true",
            "PTZ.Various.V1.ZoomEnabled": "true",
            "PTZ.Various.V1.FocusEnabled": "true",
            "PTZ.Various.V1.IrisEnabled": "true",
            "PTZ.Various.V1.HomePresetSet": "true",
            "PTZ.Various.V1.Locked": "false",
            "System.BoaProtViewer": "anonymous" if auth == "none" else "password",
        }
    )
    return p


def real_listing_ptz_keys() -> dict[str, str]:
    """``PTZ`` keys every recorded real listing has (Kane610 fixtures of a Sony-block dome and of 5.51
    cameras, vapix.md §4.7) that are the same on both personas. Values as recorded; the brightness limits
    agree with ``query=limits``."""
    p = {
        "PTZ.CamPorts.Cam1Port": "1",
        "PTZ.ImageSource.I0.PTZEnabled": "true",
        "PTZ.Limit.L1.MinBrightness": "1",
        "PTZ.Limit.L1.MaxBrightness": "9999",
        "PTZ.PTZDriverStatuses.Driver1Status": "3",  # 3 = driver installed
        "PTZ.Various.V1.AutoFocus": "true",
        "PTZ.Various.V1.AutoIris": "true",
        "PTZ.Various.V1.CtlQueueing": "false",
        "PTZ.Various.V1.CtlQueueLimit": "20",
        "PTZ.Various.V1.CtlQueuePollTime": "20",
        "PTZ.Various.V1.SpeedCtlEnabled": "true",
        "PTZ.Various.V1.ReturnToOverview": "0",
    }
    for n, (group, priority, timeout_type, timeout, cookie) in enumerate(
        (
            ("Administrator", 10, "activity", 60, "yes"),
            ("Operator", 30, "activity", 60, "yes"),
            ("Viewer", 50, "timespan", 60, "yes"),
            ("Event", 20, "activity", 20, "no"),
        )
    ):
        p[f"PTZ.UserCtlQueue.U{n}.Priority"] = str(priority)
        p[f"PTZ.UserCtlQueue.U{n}.TimeoutTime"] = str(timeout)
        p[f"PTZ.UserCtlQueue.U{n}.TimeoutType"] = timeout_type
        p[f"PTZ.UserCtlQueue.U{n}.UseCookie"] = cookie
        p[f"PTZ.UserCtlQueue.U{n}.UserGroup"] = group
    return p


def list_params(tree: dict[str, str], groups: list[str]) -> str:
    """``param.cgi?action=list`` body; echoes the requester's ``root.`` style (vapix.md §6)."""
    lines: list[str] = []
    if not groups:
        return "".join(f"root.{k}={v}\n" for k, v in tree.items())
    for g in groups:
        rooted = g.startswith("root.") or g == "root"
        bare = g[5:] if g.startswith("root.") else ("" if g == "root" else g)
        hits = [
            k
            for k in tree
            if not bare
            or k == bare
            or k.startswith(bare + ".")
            or ("*" in bare and (fnmatch.fnmatchcase(k, bare) or fnmatch.fnmatchcase(k, bare + ".*")))
        ]
        if not hits:
            lines.append(f"# Error: Error -1 getting param in group '{g}'")
        lines += [f"{'root.' if rooted else ''}{k}={tree[k]}" for k in hits]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------------------
# Personas
# --------------------------------------------------------------------------------------------------------
TreeBuilder = Callable[["Persona", PtzLimits, ZoomModel, str, str], dict[str, str]]


@dataclass(frozen=True)
class Persona:
    """Everything that differs between simulated camera models (frozen data; see the module docstring).

    ``limits``/``zoom_model`` None: take them from the world file (the 214's come from ``sim_world.yaml``).
    ``resolutions`` maps the names listed in ``Properties.Image.Resolution`` (CIF names or ``WxH``) to sizes;
    ``square_pixel_factor`` is the width stretch of ``squarepixel=1`` (1.0 = pixels already square).
    """

    key: str
    product: str
    resolutions: Mapping[str, tuple[int, int]]
    default_resolution: str
    square_pixel_factor: float
    api_version: int
    default_auth: str
    https: bool
    tree: TreeBuilder
    camera_model_file: str
    speeds: Speeds = field(default_factory=Speeds)
    limits: PtzLimits | None = None
    zoom_model: ZoomModel | None = None
    kinematics: PtzKinematics | None = None  # head geometry (None: the world file's, the 214's URDF)
    move_step_fov: float = 0.0  # move=left|…: 0 = 5° steps (VAPIX v2), else this fraction of the HFOV (v3)
    attributes: bool = False  # answers ptz.cgi?query=attributes
    preset_params: bool = False  # mirrors the server presets under PTZ.Preset.P0.*
    whoami: str = "Sony_camblock"
    server_header: str = ""  # "" = no Server header
    aliases: tuple[str, ...] = ()
    picture: CameraModel = field(default_factory=CameraModel)  # softness, noise, JPEG quality (camera_model.py)

    @property
    def accepted_sizes(self) -> frozenset[tuple[int, int]]:
        """Every WxH accepted in ``resolution=`` (native and, for non-square pixels, square-pixel sizes)."""
        native = list(self.resolutions.values())
        if self.square_pixel_factor == 1.0:
            return frozenset(native)
        return frozenset(native + [(self._square_width(w), h) for w, h in native])

    def _square_width(self, width: int) -> int:
        return int(round(width * self.square_pixel_factor))

    def parse_resolution(self, value: str, squarepixel: bool) -> tuple[int, int]:
        """``resolution`` (a listed name or WxH) → output (width, height); ValueError if unsupported."""
        name = value.strip().upper()
        names = {k.upper(): v for k, v in self.resolutions.items()}
        if name in names:
            w, h = names[name]
        else:
            parts = name.split("X")
            if len(parts) != 2 or not all(p.isdigit() for p in parts):
                raise ValueError(f"Invalid resolution: {value}")
            w, h = int(parts[0]), int(parts[1])
            if (w, h) not in self.accepted_sizes:
                raise ValueError(f"Unsupported resolution: {value}")
        if squarepixel and (w, h) in self.resolutions.values():
            w = self._square_width(w)
        return w, h

    def parameter_tree(self, limits: PtzLimits, zoom: ZoomModel, mac: str, auth: str) -> dict[str, str]:
        """The camera's parameters (names without ``root.``) in listing order."""
        return self.tree(self, limits, zoom, mac, auth)


def _axis214_tree(persona: Persona, limits: PtzLimits, zoom: ZoomModel, mac: str, auth: str) -> dict[str, str]:
    return parameter_tree(limits, zoom, mac, auth)


#: The 214's picture (``sim/camera_model.py``; README "What the simulated camera's pictures are made of").
#: Sources: PAL 4CIF sampled per ITU-R BT.601 (13.5 MHz, 704 active samples); PAL chroma bandwidth ~1.3 MHz
#: and the line-averaging delay line (PAL system standard); Kell factor ~0.7 for interlaced CCDs (textbook).
#: Guesses: luminance bandwidth 4 MHz (composite/Y-C decoder of the camera block), lens σ 0.5…1.0 px
#: (wide…tele). Fitted to the thesis's Tables 6.2-6.4 (read as kB/s, bench/bench_bitrate.py): temporal noise
#: 2.0 / 0.7 DN (luma / chroma at 704×576), scaler softness 0.3 px per halving of the width, and the
#: compression → IJG quality curve q(c) = 98 − (98 − 60)·(c/100)^1.7, 27 quality points lower at compression 100
#: per halving of the width (q(0, 10, 30, 60, 100) = 98, 97, 93, 82, 60 at 704×576; 98, 97, 90, 71, 33 at
#: 352×288; 98, 96, 86, 59, 6 at 176×144). The exponent 1.7 rather than 2 keeps a first compression step of 10
#: visible in the frame size (with 2 it rounds to the same quality: the stream node's budget controller then
#: learns that compression does nothing). No source explains the per-resolution drop; the tables need it (the real 214's
#: small pictures shrink far more at compression 100 than its 704×576 picture).
AXIS_214_PICTURE = CameraModel(
    native_width=704,
    sample_rate_mhz=13.5,
    luma_bandwidth_mhz=4.0,
    chroma_bandwidth_mhz=1.3,
    chroma_vertical_sigma=0.7,
    kell_factor=0.7,
    lens_sigma_wide=0.5,
    lens_sigma_tele=1.0,
    scaler_sigma=0.3,
    tele_zoom=9999.0,
    noise_luma=2.0,
    noise_chroma=0.7,
    quality_at_0=98.0,
    quality_at_100=60.0,
    quality_gamma=1.7,
    quality_drop_per_halving=27.0,
    pool_frames=8,
)

AXIS_214 = Persona(
    key="axis214",
    product="AXIS 214 PTZ",
    resolutions=RESOLUTIONS,
    default_resolution="4CIF",
    square_pixel_factor=SQUARE_PIXEL_FACTOR,
    api_version=2,
    default_auth="none",
    https=False,
    tree=_axis214_tree,
    camera_model_file="axis214.yaml",
    preset_params=True,  # every recorded listing keeps presets under PTZ.Preset.P0 (assumed for fw 4.49)
    server_header="",  # a real Axis MJPEG reply has no Server header; for other replies of fw 4.49: unknown
    aliases=("214",),
    picture=AXIS_214_PICTURE,
)

#: The modern persona's resolution list: 16:9 sizes and a few 4:3 ones (square pixels, 4:3 = sides cropped).
#: Modelled on the WxH lists of current AXIS OS cameras (vapix.md §5.5, the Companion Bullet recording); the
#: exact list of a Q6075-E is not known here.
MODERN_RESOLUTIONS: dict[str, tuple[int, int]] = {
    f"{w}x{h}": (w, h)
    for w, h in (
        (1920, 1080),
        (1280, 960),
        (1280, 720),
        (1024, 768),
        (1024, 576),
        (800, 600),
        (800, 450),
        (640, 480),
        (640, 360),
        (480, 270),
        (320, 240),
        (320, 180),
        (160, 120),
        (160, 90),
    )
}

#: AXIS Q6075-E class optics (see config/q6075.yaml for sources): 40× optical reaching 9999 (vapix.md S11
#: table), digital zoom to 19999 (MaxZoom 19999 observed with DigitalZoom=true, vapix.md §4.7, S8).
Q6075_ZOOM = ZoomModel(
    hfov_wide_deg=63.7,
    max_magnification=40.0,
    min_zoom=1,
    max_zoom=19999,
    curve=ZoomCurve.LINEAR,
    image_aspect=16.0 / 9.0,
    square_pixels=True,
    optical_max_zoom=9999,
    digital_max_magnification=16.0,
)
Q6075_LIMITS = PtzLimits(-180.0, 180.0, -90.0, 20.0, 1, 19999)

_Q6075_SUPPORT = {
    "AbsolutePan": True,
    "AbsoluteTilt": True,
    "AbsoluteZoom": True,
    "AbsoluteFocus": True,
    "AbsoluteIris": False,
    "AbsoluteBrightness": False,
    "AreaZoom": True,
    "AutoFocus": True,
    "AutoIris": True,
    "ContinuousPan": True,
    "ContinuousTilt": True,
    "ContinuousZoom": True,
    "ContinuousFocus": True,
    "ContinuousIris": False,
    "ContinuousBrightness": False,
    "RelativePan": True,
    "RelativeTilt": True,
    "RelativeZoom": True,
    "RelativeFocus": True,
    "RelativeIris": False,
    "RelativeBrightness": False,
    "DigitalZoom": True,
    "ServerPreset": True,
    "DevicePreset": False,
    "SpeedCtl": True,
    "IrCutFilter": True,
    "AutoIrCutFilter": True,
    "BackLight": False,
    "Auxiliary": False,  # the simulator implements no auxiliary= functions (info=1 does not offer them)
    "OSDMenu": False,
    "ActionNotification": True,
    "ProportionalSpeed": True,
    "LensOffset": False,
    "JoyStickEmulation": True,
    "GenericHTTP": False,
}


def _modern_tree(persona: Persona, limits: PtzLimits, zoom: ZoomModel, mac: str, auth: str) -> dict[str, str]:
    """A current AXIS OS PTZ dome's parameters (names as in vapix.md §4.7, §6; values per the persona)."""
    resolutions = ",".join(persona.resolutions)
    optical_end = zoom.optical_max_zoom or limits.max_zoom
    p: dict[str, str] = {
        "Brand.Brand": "AXIS",
        "Brand.ProdFullName": "AXIS Q6075-E PTZ Network Camera",
        "Brand.ProdNbr": "Q6075-E",
        "Brand.ProdShortName": "AXIS Q6075-E",
        "Brand.ProdType": "PTZ Network Camera",
        "Brand.ProdVariant": "50 Hz",
        "Brand.WebURL": "http://www.axis.com",
        "HTTPS.Enabled": "yes" if persona.https else "no",
        "HTTPS.Port": "443",
        "Image.I0.Appearance.Compression": "30",
        "Image.I0.Appearance.Resolution": persona.default_resolution,
        "Image.I0.Appearance.Rotation": "0",
        "Image.I0.Stream.FPS": "0",
        "Network.HTTP.AuthenticationPolicy": "digest" if auth in ("none", "digest") else auth,
        "Properties.API.HTTP.Version": str(persona.api_version),
        "Properties.API.HTTP.AdminPath": "/index.html",
        "Properties.Firmware.BuildDate": "Jun 12 2024 09:41",
        "Properties.Firmware.Version": "11.11.73",
        "Properties.HTTPS.HTTPS": "yes",
        "Properties.Image.Format": "jpeg,mjpeg,h264,h265",
        "Properties.Image.NbrOfViews": "1",
        "Properties.Image.Resolution": resolutions,
        "Properties.Image.I0.Resolution": resolutions,
        "Properties.Image.Rotation": "0,180",
        "Properties.PTZ.PTZ": "yes",
        "Properties.PTZ.DigitalPTZ": "no",
        "Properties.System.Architecture": "armv7hf",
        "Properties.System.SerialNumber": mac,
        "PTZ.BoaProtPTZOperator": "anonymous" if auth == "none" else "password",
        "PTZ.CameraDefault": "1",
        "PTZ.ImageSource.I0.PTZEnabled": "true",
        "PTZ.NbrOfCameras": "1",
        "PTZ.NbrOfSerPorts": "0",
        "PTZ.Limit.L1.MinPan": f"{limits.min_pan:g}",
        "PTZ.Limit.L1.MaxPan": f"{limits.max_pan:g}",
        "PTZ.Limit.L1.MinTilt": f"{limits.min_tilt:g}",
        "PTZ.Limit.L1.MaxTilt": f"{limits.max_tilt:g}",
        "PTZ.Limit.L1.MinZoom": str(limits.min_zoom),
        "PTZ.Limit.L1.MaxZoom": str(limits.max_zoom),
        "PTZ.Limit.L1.MinFocus": "1",
        "PTZ.Limit.L1.MaxFocus": "9999",
        "PTZ.Limit.L1.MinIris": "1",
        "PTZ.Limit.L1.MaxIris": "9999",
        "PTZ.Limit.L1.MinFieldAngle": str(max(1, int(round(math.degrees(zoom.hfov(optical_end)) * 10)))),
        "PTZ.Limit.L1.MaxFieldAngle": str(int(round(math.degrees(zoom.hfov(limits.min_zoom)) * 10))),
    }
    p.update(real_listing_ptz_keys())
    for cap, on in _Q6075_SUPPORT.items():
        p[f"PTZ.Support.S1.{cap}"] = "true" if on else "false"
    p.update(
        {
            "PTZ.UserAdv.U1.MoveSpeed": "100",
            "PTZ.Various.V1.PanEnabled": "true",
            "PTZ.Various.V1.TiltEnabled": "true",
            "PTZ.Various.V1.ZoomEnabled": "true",
            "PTZ.Various.V1.FocusEnabled": "true",
            "PTZ.Various.V1.IrisEnabled": "false",
            "PTZ.Various.V1.HomePresetSet": "true",
            "PTZ.Various.V1.Locked": "false",
            "PTZ.Various.V1.ProportionalSpeedEnabled": "true",
            "PTZ.Various.V1.MaxProportionalSpeed": "200",
            "System.BoaProtViewer": "anonymous" if auth == "none" else "password",
        }
    )
    return p


#: The modern persona's picture: a digital 1080p sensor (no analogue band limit, progressive). All guesses:
#: temporal noise 1.0 / 0.5 DN (a current 1/2.8" CMOS in office light after the camera's noise filter), lens
#: σ 0 (no softening: it would cost a 1080p frame ~10 ms while panning), the compression curve linear from
#: quality 98 to 30 (close to the earlier noise-free mapping 100 − c) without the per-resolution drop.
#: bench/bench_bitrate.py prints the resulting 1080p bytes per frame (README: no Axis figure to compare with).
Q6075_PICTURE = CameraModel(
    native_width=1920,
    sample_rate_mhz=148.5,
    kell_factor=1.0,
    lens_sigma_wide=0.0,
    lens_sigma_tele=0.0,
    tele_zoom=9999.0,
    noise_luma=1.0,
    noise_chroma=0.5,
    quality_at_0=98.0,
    quality_at_100=30.0,
    quality_gamma=1.0,
    pool_frames=8,
)

AXIS_Q6075 = Persona(
    key="q6075",
    product="AXIS Q6075-E",
    resolutions=MODERN_RESOLUTIONS,
    default_resolution="1920x1080",
    square_pixel_factor=1.0,
    api_version=3,
    default_auth="digest",
    https=True,
    tree=_modern_tree,
    camera_model_file="q6075.yaml",
    speeds=Speeds(pan_deg_s=450.0, tilt_deg_s=300.0, zoom_full_travel_s=4.0, focus_full_travel_s=1.0),
    limits=Q6075_LIMITS,
    zoom_model=Q6075_ZOOM,
    kinematics=PtzKinematics(0.0, (0.05, 0.0, 0.0)),  # as config/q6075.yaml (a guess, see there)
    move_step_fov=0.25,
    attributes=True,
    preset_params=True,
    whoami="Axis_PTZ",
    server_header="Apache",
    aliases=("q6075-e", "modern"),
    picture=Q6075_PICTURE,
)

PERSONAS: dict[str, Persona] = {p.key: p for p in (AXIS_214, AXIS_Q6075)}


def persona(name: str | Persona | None) -> Persona:
    """A persona by key or alias (``axis214``/``214``, ``q6075``/``q6075-e``/``modern``); None → the 214."""
    if name is None:
        return AXIS_214
    if isinstance(name, Persona):
        return name
    key = name.strip().lower()
    for p in PERSONAS.values():
        if key == p.key or key in p.aliases:
            return p
    raise ValueError(f"unknown camera model {name!r}; known: {', '.join(PERSONAS)}")


def preset_params(presets: list[tuple[int, str, float, float, float]], home: int) -> dict[str, str]:
    """``PTZ.Preset.P0.*`` of a modern camera from (number, name, pan°, tilt°, zoom) server presets
    (layout of the deprecated parameter storage, vapix.md §4.6)."""
    out = {
        "PTZ.Preset.P0.HomePosition": str(home),
        "PTZ.Preset.P0.ImageSource": "0",
        "PTZ.Preset.P0.Name": "",
    }
    for number, name, pan, tilt, zoom in presets:
        out[f"PTZ.Preset.P0.Position.P{number}.Name"] = name
        out[f"PTZ.Preset.P0.Position.P{number}.Data"] = f"tilt={tilt:.6f}:pan={pan:.6f}:zoom={zoom:.6f}"
    return out
