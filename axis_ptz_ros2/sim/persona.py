"""The Axis 214 PTZ persona: parameter tree, resolutions and fixed reply texts (vapix.md §2, §5, §6, §7)."""

from __future__ import annotations

import fnmatch
import math

from axis_ptz_ros2.geometry import ZoomModel
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
ERROR_HTML = (
    "<HTML><HEAD><TITLE>{code} {reason}</TITLE></HEAD>\n<BODY><H1>{code} {reason}</H1>\n</BODY></HTML>\n"
)

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
