"""Per-model camera models and what the driver learns from the camera at start-up (ROS-free).

The driver assumes nothing about the camera: at start-up :func:`discover` asks it for its product
(``Brand.ProdNbr`` / ``Brand.ProdShortName``), firmware and HTTP API version (``Properties``), resolution list
(CIF names → analogue PAL/NTSC with non-square pixels; ``WxH`` → a digital sensor with square pixels),
PTZ limits (``query=limits``, wrap-around pan when they span the full circle), ``PTZ.Support`` (digital zoom),
``query=attributes`` (zoom magnifications, newer firmware) and presets, and sums it up in one log line.

Camera models ship per model in ``config/<model>.yaml`` (format ``axis_ptz_ros2/camera_model/v1``) with a
``products:`` list of the ``Brand.ProdNbr``/``ProdShortName`` values they describe. :func:`select_camera_model`
picks the file whose list names the camera; an unknown camera gets :func:`generic_model`: the convention and
head of ``config/generic.yaml`` with optics built from what the camera reports (its wide/tele field angles,
``MaxZoom``, digital-zoom attributes, pixel aspect from its resolutions).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from axis_ptz_ros2.config import CONFIG_DIR, CameraModel, CameraModelError, _share_config_dir, load_camera_model
from axis_ptz_ros2.optics import ZoomModel
from axis_ptz_ros2.vapix import AxisPtzError, CameraConfig, PtzLimits, VapixClient
from axis_ptz_ros2.vapix.models import CIF_NTSC, CIF_PAL, Resolution

GENERIC_MODEL_FILE = "generic.yaml"
OPTICAL_ZOOM_END = 9999  #: VAPIX: optical zoom is 1…9999; up to 19999 only with DigitalZoom (vapix.md §4.1)


def _norm(name: str) -> str:
    n = name.strip().upper()
    for prefix in ("AXIS ",):
        if n.startswith(prefix):
            n = n[len(prefix) :]
    for suffix in (" PTZ NETWORK CAMERA", " PTZ DOME NETWORK CAMERA", " NETWORK CAMERA", " PTZ"):
        if n.endswith(suffix):
            n = n[: -len(suffix)]
    return n.strip()


def model_dirs() -> list[Path]:
    """Where camera-model files are looked up: the repository's ``config/``, then the installed share."""
    dirs = [CONFIG_DIR]
    share = _share_config_dir()
    if share is not None and share != CONFIG_DIR:
        dirs.append(share)
    return [d for d in dirs if d.is_dir()]


def _read(path: Path) -> dict[str, Any]:
    with open(path, encoding="utf-8") as f:
        data = yaml.safe_load(f) or {}
    return data if isinstance(data, dict) else {}


def find_model_file(*names: str) -> Path | None:
    """The camera-model file whose ``products:`` list names one of ``names`` (ProdNbr, ProdShortName…)."""
    wanted = {_norm(n) for n in names if n and n.strip()}
    if not wanted:
        return None
    for d in model_dirs():
        for path in sorted(d.glob("*.yaml")):
            try:
                data = _read(path)
            except (OSError, yaml.YAMLError):
                continue
            if not str(data.get("format", "")).startswith("axis_ptz_ros2/camera_model/"):
                continue
            products = {_norm(str(p)) for p in data.get("products", []) or []}
            if products & wanted:
                return path
    return None


@dataclass(frozen=True, slots=True)
class Optics:
    """What the camera says about its optics and image."""

    resolutions: tuple[Resolution, ...] = ()
    video_standard: str = "unknown"  # PAL | NTSC (analogue block, CIF names) | digital (WxH list) | unknown
    limits: PtzLimits | None = None
    digital_zoom: bool = False
    max_optical_mag: float | None = None  # query=attributes
    max_digital_mag: float | None = None  # query=attributes

    @property
    def square_pixels(self) -> bool:
        """Digital sensors have square pixels; analogue PAL/NTSC blocks do not (12:11 / 10:11)."""
        return self.video_standard == "digital"


def generic_model(optics: Optics, base: CameraModel | None = None) -> CameraModel:
    """A camera model for an unknown camera: ``base`` (default :func:`load_generic_base`, ``config/generic.yaml``)
    with the camera's optics.

    HFOV wide/tele from ``MaxFieldAngle``/``MinFieldAngle`` (1/10°, vapix.md §8.3 strategy 2), magnification
    linear in zoom units (every published table is), digital zoom above 9999 when ``DigitalZoom=true`` with the
    magnification ``query=attributes`` reports (else none assumed). Square pixels for a digital sensor with the
    aspect of its largest resolution; a 4:3 analogue frame otherwise.
    """
    base = base or load_generic_base()
    z = base.zoom
    lim = optics.limits
    hfov_wide, max_mag = z.hfov_wide_deg, z.max_magnification
    min_zoom, max_zoom = z.min_zoom, z.max_zoom
    optical_end, digital = 0, 1.0
    if lim is not None:
        min_zoom, max_zoom = lim.min_zoom, lim.max_zoom
        if lim.max_field_angle_deg:
            hfov_wide = lim.max_field_angle_deg
            if lim.min_field_angle_deg and 0 < lim.min_field_angle_deg < lim.max_field_angle_deg:
                max_mag = math.tan(math.radians(hfov_wide) / 2) / math.tan(math.radians(lim.min_field_angle_deg) / 2)
        if optics.digital_zoom and max_zoom > OPTICAL_ZOOM_END > min_zoom:
            optical_end = OPTICAL_ZOOM_END
            digital = optics.max_digital_mag or 1.0
    if optics.max_optical_mag:
        max_mag = optics.max_optical_mag
    aspect = 4.0 / 3.0
    if optics.square_pixels and optics.resolutions:
        biggest = max(optics.resolutions, key=lambda r: (r.width * r.height, r.width))
        aspect = biggest.width / biggest.height
    zoom = ZoomModel(
        hfov_wide_deg=hfov_wide,
        max_magnification=max(1.0, max_mag),
        min_zoom=min_zoom,
        max_zoom=max_zoom if max_zoom > min_zoom else min_zoom + 1,
        curve=z.curve,
        image_aspect=aspect,
        square_pixels=optics.square_pixels,
        optical_max_zoom=optical_end,
        digital_max_magnification=max(1.0, digital),
    )
    return dataclasses.replace(base, zoom=zoom)


def load_generic_base() -> CameraModel:
    """``config/generic.yaml`` (convention, head geometry, fallback limits and speeds of an unknown camera);
    :class:`CameraModelError` if no model folder has it (the code holds no camera's figures to fall back on)."""
    dirs = model_dirs()
    for d in dirs:
        path = d / GENERIC_MODEL_FILE
        if path.exists():
            return load_camera_model(path)
    where = ", ".join(str(d) for d in dirs) or f"{CONFIG_DIR} (missing)"
    raise CameraModelError(f"no {GENERIC_MODEL_FILE} in the camera-model folders ({where})")


def select_camera_model(prod_nbr: str, short_name: str, optics: Optics) -> tuple[CameraModel, str]:
    """The shipped model of this product, else the generic one built from ``optics``; (model, source)."""
    path = find_model_file(prod_nbr, short_name)
    if path is not None:
        return load_camera_model(path), str(path.name)
    return generic_model(optics, load_generic_base()), "generic (optics from the camera)"


@dataclass(frozen=True, slots=True)
class CameraProfile:
    """What the driver learned from the camera at start-up, and the camera model chosen for it."""

    product: str
    prod_nbr: str
    firmware: str
    api_version: int | None
    optics: Optics
    presets: tuple[str, ...]
    https: bool
    auth: str
    model: CameraModel
    model_source: str
    ptz_enabled: bool | None = None  # PTZ.ImageSource.I<camera-1>.PTZEnabled (newer firmware), None = not listed

    @property
    def pan_wraps(self) -> bool:
        """Endless pan (limits spanning the whole circle)."""
        lim = self.optics.limits
        return lim is not None and lim.max_pan_deg - lim.min_pan_deg >= 360.0 - 1e-6

    def summary(self) -> str:
        """One log line: the camera, its protocol, video and PTZ as learned."""
        o = self.optics
        res = sorted(o.resolutions, key=lambda r: (r.width * r.height, r.width))
        top = res[-1] if res else None
        if top is not None:
            g = math.gcd(top.width, top.height)
            video = f"{len(res)} resolutions up to {top} ({top.width // g}:{top.height // g})"
        else:
            video = "resolutions unknown"
        pixels = {"PAL": "PAL 12:11 pixels", "NTSC": "NTSC 10:11 pixels", "digital": "square pixels"}.get(
            o.video_standard, "pixel aspect unknown"
        )
        lim = o.limits
        if lim is None:
            ptz = "PTZ limits unknown"
        else:
            pan = "endless pan" if self.pan_wraps else f"pan {lim.min_pan_deg:g}..{lim.max_pan_deg:g} deg"
            ptz = f"{pan}, tilt {lim.min_tilt_deg:g}..{lim.max_tilt_deg:g} deg, zoom {lim.min_zoom}..{lim.max_zoom}"
            if o.digital_zoom:
                ptz += " (digital above 9999)"
        if self.ptz_enabled is False:
            ptz += "; PTZ DISABLED for this image source (PTZEnabled=false)"
        api = f"VAPIX HTTP API v{self.api_version}" if self.api_version is not None else "VAPIX version unknown"
        return (
            f"camera: {self.product} (ProdNbr {self.prod_nbr or '?'}, firmware {self.firmware}), {api}, "
            f"{'HTTPS' if self.https else 'HTTP'} with {self.auth} auth; video {video}, {pixels}; {ptz}; "
            f"{len(self.presets)} presets; camera model {self.model.name!r} from {self.model_source}"
        )


def _video_standard(client: VapixClient, resolutions: tuple[Resolution, ...]) -> str:
    """PAL/NTSC when the camera lists CIF names (an analogue camera block), digital for a WxH list."""
    try:
        listing = client.list_params("Properties.Image.Resolution").get("Properties.Image.Resolution", "")
    except AxisPtzError:
        listing = ""
    names = [n.strip().upper() for n in listing.split(",") if n.strip()]
    if not names:
        return "unknown"
    if any(n in CIF_PAL for n in names):
        if any(r == Resolution(*CIF_NTSC["4CIF"]) for r in resolutions):
            return "NTSC"
        return "PAL"
    return "digital"


def _auth_in_use(client: VapixClient) -> str:
    """The scheme the camera made us use (Digest/Basic), or anonymous if it asked for none."""
    scheme = getattr(getattr(client, "_auth", None), "scheme", None)  # negotiated on the first 401
    return str(scheme.value) if scheme is not None else "anonymous"


def discover(client: VapixClient, model_file: str = "", auth_label: str = "") -> CameraProfile:
    """Ask the camera what it is (see the module docstring). Raises :class:`AxisPtzError` if it cannot even
    say who it is (unreachable, refused); every later question is optional."""
    brand = client.list_params("Brand")
    info = client.device_info()
    prod_nbr = brand.get("Brand.ProdNbr", "")
    short = brand.get("Brand.ProdShortName", "")
    try:
        limits: PtzLimits | None = client.query_limits()
    except AxisPtzError:
        limits = None
    max_opt = max_dig = None
    try:
        attrs = client.query_attributes()
        max_opt = float(attrs["maxOpticalZoomMag"]) if "maxOpticalZoomMag" in attrs else None
        max_dig = float(attrs["maxDigitalZoomMag"]) if "maxDigitalZoomMag" in attrs else None
    except (AxisPtzError, ValueError):
        pass  # not on older firmware (the 214)
    try:
        presets = tuple(p.name for p in client.query_presets())
    except AxisPtzError:
        presets = ()
    digital_zoom = "DigitalZoom" in info.supports
    ptz_enabled: bool | None = None
    try:  # newer firmware: PTZ can be switched off per image source (vapix.md S5 fixtures)
        flag = client.list_params("PTZ.ImageSource").get(f"PTZ.ImageSource.I{client.config.camera - 1}.PTZEnabled")
        if flag is not None:
            ptz_enabled = flag.strip().lower() in ("true", "yes", "on", "1")
    except AxisPtzError:
        pass  # not listed (the 214)
    optics = Optics(
        resolutions=info.resolutions,
        video_standard=_video_standard(client, info.resolutions),
        limits=limits,
        digital_zoom=digital_zoom,
        max_optical_mag=max_opt,
        max_digital_mag=max_dig,
    )
    if model_file:
        model, source = load_camera_model(model_file), Path(model_file).name
    else:
        model, source = select_camera_model(prod_nbr, short, optics)
    return CameraProfile(
        product=info.product,
        prod_nbr=prod_nbr,
        firmware=info.firmware,
        api_version=info.api_version,
        optics=optics,
        presets=presets,
        https=client.config.use_https,
        auth=auth_label or _auth_in_use(client),
        model=model,
        model_source=source,
        ptz_enabled=ptz_enabled,
    )


def learn_camera_model(
    config: CameraConfig, model_file: str = ""
) -> tuple[CameraModel, CameraProfile | None, str | None]:
    """For a node starting up: (model, profile, error). Asks the camera (one short-lived connection); if it
    cannot be asked, the named file or the generic model, and the reason."""
    try:
        with VapixClient(config) as client:
            profile = discover(client, model_file)
    except AxisPtzError as err:
        model = load_camera_model(model_file) if model_file else load_generic_base()
        return model, None, str(err)
    return profile.model, profile, None
