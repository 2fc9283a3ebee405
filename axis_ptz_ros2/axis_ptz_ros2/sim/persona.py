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

The parameter trees the personas answer ``param.cgi`` with are in :mod:`axis_ptz_ros2.sim.params`, the error
pages in :mod:`axis_ptz_ros2.sim.http.pages`; :func:`persona` looks a model up by name.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from axis_ptz_ros2.config import default_config_path, load_camera_model
from axis_ptz_ros2.geometry import PtzKinematics
from axis_ptz_ros2.optics import ZoomModel
from axis_ptz_ros2.sim.camera_model import CameraModel
from axis_ptz_ros2.sim.params import TREE_BUILDERS, TreeTag, parameter_tree
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


# --------------------------------------------------------------------------------------------------------
# Personas
# --------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Persona:
    """Everything that differs between simulated camera models (frozen data; see the module docstring).

    ``limits``/``zoom_model`` None: take them from the world (the 214: its limits from ``sim_world.yaml``, its zoom
    model from ``axis214.yaml``, the world file having none).
    ``resolutions`` maps the names listed in ``Properties.Image.Resolution`` (CIF names or ``WxH``) to sizes;
    ``square_pixel_factor`` is the width stretch of ``squarepixel=1`` (1.0 = pixels already square).
    ``frame_rate`` is the most pictures per second the camera makes (its video standard's or sensor's rate): a
    stream asked for more (``fps=`` up to :data:`~axis_ptz_ros2.sim.frames.MAX_FPS` is accepted) gets this many.
    """

    key: str
    product: str
    resolutions: Mapping[str, tuple[int, int]]
    default_resolution: str
    square_pixel_factor: float
    api_version: int
    default_auth: str
    https: bool
    tree: TreeTag  # which parameter tree it answers param.cgi with (sim/params.py builds it)
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
    frame_rate: int = 30  # pictures per second at most, whatever fps= asks (see the class docstring)

    def __post_init__(self) -> None:
        if self.tree not in TREE_BUILDERS:
            raise ValueError(
                f"persona {self.key}: unknown parameter tree {self.tree!r}; known: {', '.join(TREE_BUILDERS)}"
            )
        if not 1 <= self.frame_rate <= 120:
            raise ValueError(f"persona {self.key}: frame_rate={self.frame_rate} outside 1…120 pictures per second")

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
        return parameter_tree(self.tree, self, limits, zoom, mac, auth)


#: The 214's picture (``sim/camera_model.py``; README "What the simulated camera's pictures are made of").
#: Sources: PAL 4CIF sampled per ITU-R BT.601 (13.5 MHz, 704 active samples); PAL chroma bandwidth ~1.3 MHz
#: and the line-averaging delay line (PAL system standard); Kell factor ~0.7 for interlaced CCDs (textbook).
#: Guesses: luminance bandwidth 4 MHz (composite/Y-C decoder of the camera block), lens σ 0.5…1.0 px
#: (wide…tele). Fitted to the thesis's Tables 6.2-6.4 (read as kB/s, bench/bench_bitrate.py) on the demo
#: world's home view (config/sim_world.yaml: a brick facade across a paved square; README "What the simulated
#: camera's pictures are made of"): temporal noise 2.0 / 0.7 DN (luma / chroma at 704×576), scaler softness
#: 0.3 px per halving of the width, and the compression → IJG quality curve q(c) = 98 − (98 − q100)·(c/100)^1.85
#: with q100 = 17 at 704×576 and 6 quality points lower per halving of the width (q(0, 10, 30, 60, 100) = 98, 97,
#: 89, 67, 17 at 704×576; 98, 97, 89, 64, 11 at 352×288; 98, 97, 88, 62, 5 at 176×144), held to the tables
#: (every cell 0.5–2×, median 0.8–1.25, with 30 fps served at the PAL 25) and to the thesis's Figure 6.4
#: statement as measured by tests/support/picture.py at all three sizes: compression 30 like 0, 60 usable, 100
#: not usable. The exponent stays below 2 so that a first compression step of 10 is visible in the frame size
#: (the stream node's budget controller must not learn that compression does nothing). No source explains the
#: small per-resolution drop; the tables want it (the real 214's small pictures shrink a little more at
#: compression 100 than its 704×576 picture).
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
    quality_at_100=17.0,
    quality_gamma=1.85,
    quality_drop_per_halving=6.0,
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
    tree="axis214",
    camera_model_file="axis214.yaml",
    preset_params=True,  # every recorded listing keeps presets under PTZ.Preset.P0 (assumed for fw 4.49)
    server_header="",  # a real Axis MJPEG reply has no Server header; for other replies of fw 4.49: unknown
    aliases=("214",),
    picture=AXIS_214_PICTURE,
    # PAL: 25 pictures per second (50 fields). vapix.md lists the 214's video as "up to 30 fps (25 PAL)" (the
    # 25 an inference there); the thesis's Table 6.5 shows it: its raw 704x576 topic carried 1.217 MB pictures
    # at 1.0, 14.8 and 24.8 per second when 1, 15 and 30 fps were asked (camera_model.THESIS_UNIT_BYTES). What
    # the real 214 answers to fps=30 is not recorded: taken to be accepted (as the thesis's driver asked it
    # without an error) and served at 25.
    frame_rate=25,
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

#: AXIS Q6075-E class facts from its camera-model file config/q6075.yaml (the sources are listed there), read
#: through the camera-model loader when this module is imported: the camera's facts live in its YAML file only.
#: Raises :class:`~axis_ptz_ros2.config.CameraModelError` (a ``ValueError``) naming the file when it cannot be read.
Q6075_MODEL_FILE = "q6075.yaml"
_Q6075_MODEL = load_camera_model(default_config_path(Q6075_MODEL_FILE))
#: its optics: 40× optical reaching 9999, digital zoom to 19999
Q6075_ZOOM: ZoomModel = _Q6075_MODEL.zoom
#: its limits: the file's fallback limits (what a real one reports for itself)
Q6075_LIMITS = PtzLimits(
    _Q6075_MODEL.limits.min_pan_deg,
    _Q6075_MODEL.limits.max_pan_deg,
    _Q6075_MODEL.limits.min_tilt_deg,
    _Q6075_MODEL.limits.max_tilt_deg,
    _Q6075_MODEL.limits.min_zoom,
    _Q6075_MODEL.limits.max_zoom,
)

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
    tree="modern",
    camera_model_file=Q6075_MODEL_FILE,
    speeds=Speeds(
        pan_deg_s=_Q6075_MODEL.max_pan_speed_dps,
        tilt_deg_s=_Q6075_MODEL.max_tilt_speed_dps,
        zoom_full_travel_s=4.0,  # GUESS, not in the model file (the driver does not need it)
        focus_full_travel_s=1.0,
    ),
    limits=Q6075_LIMITS,
    zoom_model=Q6075_ZOOM,
    kinematics=_Q6075_MODEL.head,
    move_step_fov=0.25,
    attributes=True,
    preset_params=True,
    whoami="Axis_PTZ",
    server_header="Apache",
    aliases=("q6075-e", "modern"),
    picture=Q6075_PICTURE,
    frame_rate=30,  # a guess: the 50 Hz variant's 1080p25/50 is not modelled (fps= accepts up to 30)
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
