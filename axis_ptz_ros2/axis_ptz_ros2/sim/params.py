"""The simulated cameras' parameter trees, what ``param.cgi?action=list`` prints of them, and which are
read-only (vapix.md §4.7, §6; ROS-free).

A persona (:mod:`axis_ptz_ros2.sim.persona`) names its tree by a :data:`TreeTag`; :func:`parameter_tree` builds
it with the builder of that tag: :func:`axis214_tree` (``axis214``: the 214 of the thesis, firmware 4.49, VAPIX 2)
or :func:`modern_tree` (``modern``: an AXIS OS PTZ dome). :func:`list_params` answers
``action=list`` the way the real cameras do; :func:`preset_params` mirrors server presets under
``PTZ.Preset.P0.*``.
"""

from __future__ import annotations

import fnmatch
import math
from collections.abc import Callable, Mapping
from typing import Literal, Protocol

from axis_ptz_ros2.optics import ZoomModel
from axis_ptz_ros2.sim.world import PtzLimits

#: The parameter trees there are, by tag: a persona names its own (``Persona.tree``).
TreeTag = Literal["axis214", "modern"]


class TreeFacts(Protocol):
    """What a parameter tree shows of the persona it is built for (a :class:`~.persona.Persona` has these)."""

    @property
    def resolutions(self) -> Mapping[str, tuple[int, int]]:
        """The resolution names listed in ``Properties.Image.Resolution``."""
        ...

    @property
    def default_resolution(self) -> str:
        """``Image.I0.Appearance.Resolution``."""
        ...

    @property
    def api_version(self) -> int:
        """``Properties.API.HTTP.Version``."""
        ...

    @property
    def https(self) -> bool:
        """``HTTPS.Enabled`` (before the camera's own setting overrides it)."""
        ...


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


def _ptz_various(auth: str, *, iris: bool) -> dict[str, str]:
    """The ``PTZ.Various`` switches both personas report (all on but iris and the lock), and who may view."""
    return {
        "PTZ.UserAdv.U1.MoveSpeed": "100",
        "PTZ.Various.V1.PanEnabled": "true",
        "PTZ.Various.V1.TiltEnabled": "true",
        "PTZ.Various.V1.ZoomEnabled": "true",
        "PTZ.Various.V1.FocusEnabled": "true",
        "PTZ.Various.V1.IrisEnabled": "true" if iris else "false",
        "PTZ.Various.V1.HomePresetSet": "true",
        "PTZ.Various.V1.Locked": "false",
        "System.BoaProtViewer": "anonymous" if auth == "none" else "password",
    }


def _limit_l1(limits: PtzLimits, zoom: ZoomModel, narrowest: float, floor: int) -> dict[str, str]:
    """The ``PTZ.Limit.L1`` group both personas list: ranges in VAPIX units, field angles in tenths of a degree
    (the narrowest at zoom ``narrowest``, at least ``floor``)."""
    return {
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
        "PTZ.Limit.L1.MinFieldAngle": str(max(floor, int(round(math.degrees(zoom.hfov(narrowest)) * 10)))),
        "PTZ.Limit.L1.MaxFieldAngle": str(int(round(math.degrees(zoom.hfov(limits.min_zoom)) * 10))),
    }


def axis214_tree(persona: TreeFacts, limits: PtzLimits, zoom: ZoomModel, mac: str, auth: str) -> dict[str, str]:
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
        "Properties.Image.Resolution": ",".join(persona.resolutions),
        "Properties.Image.Rotation": "0,180",
        "Properties.PTZ.PTZ": "yes",
        "Properties.PTZ.DigitalPTZ": "no",
        "Properties.System.Architecture": "crisv32",
        "Properties.System.SerialNumber": mac,
        "PTZ.BoaProtPTZOperator": "anonymous" if auth == "none" else "password",
        "PTZ.CameraDefault": "1",
        "PTZ.NbrOfCameras": "1",
        "PTZ.NbrOfSerPorts": "1",
        **_limit_l1(limits, zoom, limits.max_zoom, floor=0),
    }
    p.update(real_listing_ptz_keys())
    for cap in _SUPPORT:
        p[f"PTZ.Support.S1.{cap}"] = "true"
    for cap in _NO_SUPPORT:
        p[f"PTZ.Support.S1.{cap}"] = "false"
    p.update(
        {
            **_ptz_various(auth, iris=True),
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


def modern_tree(persona: TreeFacts, limits: PtzLimits, zoom: ZoomModel, mac: str, auth: str) -> dict[str, str]:
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
        **_limit_l1(limits, zoom, optical_end, floor=1),
    }
    p.update(real_listing_ptz_keys())
    for cap, on in _Q6075_SUPPORT.items():
        p[f"PTZ.Support.S1.{cap}"] = "true" if on else "false"
    p.update(
        {
            **_ptz_various(auth, iris=False),
            "PTZ.Various.V1.ProportionalSpeedEnabled": "true",
            "PTZ.Various.V1.MaxProportionalSpeed": "200",
        }
    )
    return p


TreeBuilder = Callable[[TreeFacts, PtzLimits, ZoomModel, str, str], dict[str, str]]

#: The builder of each tree tag.
TREE_BUILDERS: dict[str, TreeBuilder] = {"axis214": axis214_tree, "modern": modern_tree}


def parameter_tree(
    tag: str, persona: TreeFacts, limits: PtzLimits, zoom: ZoomModel, mac: str, auth: str
) -> dict[str, str]:
    """The parameters (names without ``root.``, in listing order) of the tree ``tag`` for ``persona``;
    :class:`ValueError` for an unknown tag."""
    builder = TREE_BUILDERS.get(tag)
    if builder is None:
        raise ValueError(f"unknown parameter tree {tag!r}; known: {', '.join(TREE_BUILDERS)}")
    return builder(persona, limits, zoom, mac, auth)


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
