"""What the camera is (ROS-free): ``param.cgi`` listings (v3 and v2 paths), its resolutions as sizes (CIF names through
``imagesize.cgi``, the video standard, the parameter's definition) and its device info (reference ``vapix.md`` §5.3,
§6, §8).

:class:`VapixDevice` sits between :class:`~axis_ptz_ros2.vapix.transport.VapixTransport` (the requests) and
:class:`~axis_ptz_ros2.vapix.client.VapixClient` (PTZ and video).
"""

from __future__ import annotations

import re

import httpx

from axis_ptz_ros2.vapix.auth import AuthCounters
from axis_ptz_ros2.vapix.camera_config import CameraConfig
from axis_ptz_ros2.vapix.errors import (
    AuthError,
    CommandRejected,
    HttpStatusError,
    InvalidArgument,
    ResponseParseError,
)
from axis_ptz_ros2.vapix.models import (
    CIF_NTSC,
    CIF_PAL,
    DeviceInfo,
    Resolution,
    parse_bool,
    parse_int,
    parse_key_values,
)
from axis_ptz_ros2.vapix.replies import build_path
from axis_ptz_ros2.vapix.transport import VapixTransport

__all__ = ["IMAGESIZE_CGI_PATHS", "PARAM_CGI_PATHS", "VapixDevice"]

PARAM_CGI_PATHS = ("/axis-cgi/param.cgi", "/axis-cgi/view/param.cgi")
IMAGESIZE_CGI_PATHS = ("/axis-cgi/imagesize.cgi", "/axis-cgi/view/imagesize.cgi")
_NTSC_HEIGHTS = frozenset({480, 240, 120})
_PAL_HEIGHTS = frozenset({576, 288, 144})
_XML_ENTRY = re.compile(r"<entry\b([^>]*)>")
_XML_ATTR = re.compile(r'(\w+)="([^"]*)"')
_NICE_SIZE = re.compile(r"\((\d+)\s*[xX]\s*(\d+)\)")


class VapixDevice(VapixTransport):
    """Parameters, resolutions and device info of one camera (the requests: :class:`VapixTransport`)."""

    def __init__(
        self,
        config: CameraConfig,
        *,
        transport: httpx.BaseTransport | None = None,
        auth_counters: AuthCounters | None = None,
    ) -> None:
        """As :class:`VapixTransport`; nothing is asked of the camera yet."""
        super().__init__(config, transport=transport, auth_counters=auth_counters)
        self._param_path: str | None = None
        self._imagesize_path: str | None = None
        self._resolutions: tuple[Resolution, ...] | None = None
        self._ntsc: bool | None = None
        self._asked_standard = False
        self.resolution_problem = ""  #: why some listed resolution names have no size (empty: none)

    # -- parameters -----------------------------------------------------------------------------

    def _list_at(self, path: str, group: str) -> dict[str, str]:
        _, text = self._get_text(build_path(path, {"action": "list", "group": group}))
        errors = [line.strip().lstrip("#").strip() for line in text.splitlines() if line.lstrip().startswith("#")]
        errors = [e for e in errors if e.startswith("Error")]
        if errors:
            message = errors[0].partition(":")[2].strip() or errors[0]
            raise CommandRejected(f"{path}?action=list&group={group}: camera says {message!r}", camera_message=message)
        return parse_key_values(text)

    def list_params(self, group: str) -> dict[str, str]:
        """``param.cgi?action=list&group=<group>`` → ``{name: value}`` with ``root.`` stripped.

        Tries the v3 path ``/axis-cgi/param.cgi`` then the v2 path ``/axis-cgi/view/param.cgi``
        (the 214) and remembers which one answered. ``# Error:`` lines raise :class:`CommandRejected`.
        """
        if not group or any(c in group for c in "&=?#"):
            raise InvalidArgument(f"bad parameter group {group!r}")
        if self._param_path is not None:
            return self._list_at(self._param_path, group)
        first_error: HttpStatusError | AuthError | None = None
        for path in PARAM_CGI_PATHS:
            try:
                values = self._list_at(path, group)
            except HttpStatusError as err:
                if err.status_code != 404:
                    raise
                first_error = first_error or err
                continue
            except AuthError as err:
                # Firmware 5.0-5.6 answers the v3 path with 401 even to allowed users (vapix.md §2.2): the
                # legacy path may still answer. A 401 there too is the real answer (reported first).
                first_error = err if not isinstance(first_error, AuthError) else first_error
                continue
            self._param_path = path
            return values
        assert first_error is not None  # noqa: S101 - loop ran at least once
        raise first_error

    def _imagesize(self, name: str | None) -> Resolution | None:
        """Ask ``imagesize.cgi`` (§5.3) the size of ``name`` (None: the camera's default); None if it cannot."""
        if self._imagesize_path == "":
            return None  # neither path answered before
        args = {"squarepixel": "0", **self._camera_args()}
        if name is not None:
            args = {"resolution": name, **args}
        paths = (self._imagesize_path,) if self._imagesize_path else IMAGESIZE_CGI_PATHS
        answered = False
        for path in paths:
            assert path is not None  # noqa: S101
            try:
                _, text = self._get_text(build_path(path, args))
            except HttpStatusError:
                continue
            except CommandRejected:
                answered = True
                continue
            answered = True
            values = {k.strip().lower(): v for k, v in parse_key_values(text).items()}
            try:
                width = parse_int(values["image width"], key="image width")
                height = parse_int(values["image height"], key="image height")
            except (KeyError, ResponseParseError):
                continue
            self._imagesize_path = path
            return Resolution(width, height)
        if not answered and self._imagesize_path is None:
            self._imagesize_path = ""  # no imagesize.cgi on this camera: do not ask again for every name
        return None

    def _video_standard(self) -> bool | None:
        """NTSC (True) or PAL (False) from the camera's own default image size (``imagesize.cgi``), else from the
        video input it reports (:meth:`_reported_standard`); None if it cannot say."""
        if self._ntsc is None:
            size = self._imagesize(None)
            if size is not None and size.height in _NTSC_HEIGHTS:
                self._ntsc = True
            elif size is not None and size.height in _PAL_HEIGHTS:
                self._ntsc = False
            elif not self._asked_standard:
                self._asked_standard = True  # once: a camera without the group is not asked per name
                self._ntsc = self._reported_standard()
        return self._ntsc

    def _reported_standard(self) -> bool | None:
        """NTSC (True) / PAL (False) as the camera reports its analogue video input:
        ``ImageSource.I<n>.Video.DetectedType`` (the signal found), else ``CaptureMode`` (both recorded on an
        AXIS P5512, firmware 5.51, vapix.md S8); None if it reports neither (a camera without such a group)."""
        group = f"ImageSource.I{self._config.camera - 1}.Video"
        try:
            values = self.list_params(group)
        except (CommandRejected, HttpStatusError, AuthError, ResponseParseError):
            return None
        for key in ("DetectedType", "CaptureMode"):
            value = values.get(f"{group}.{key}", "").strip().upper()
            if value in ("PAL", "NTSC"):
                return value == "NTSC"
        return None

    def _defined_sizes(self) -> dict[str, Resolution]:
        """Sizes the resolution parameter's definition gives its names (``param.cgi?action=listdefinitions``,
        entries like ``<entry value="4CIF" niceValue="4CIF (704x480)" />`` as recorded on an AXIS P5512,
        firmware 5.51); empty if the camera gives none."""
        group = f"Image.I{self._config.camera - 1}.Appearance.Resolution"
        args = {"action": "listdefinitions", "listformat": "xmlschema", "group": group}
        try:
            _, text = self._get_text(build_path(self._param_path or PARAM_CGI_PATHS[0], args))
        except (CommandRejected, HttpStatusError, AuthError, ResponseParseError):
            return {}
        sizes: dict[str, Resolution] = {}
        for tag in _XML_ENTRY.findall(text):
            attrs = dict(_XML_ATTR.findall(tag))
            match = _NICE_SIZE.search(attrs.get("niceValue", ""))
            if "value" in attrs and match and int(match.group(1)) > 0 and int(match.group(2)) > 0:
                sizes[attrs["value"].strip().upper()] = Resolution(int(match.group(1)), int(match.group(2)))
        return sizes

    def _resolutions_from(self, listing: str) -> tuple[Resolution, ...]:
        """Sizes of the camera's resolution names. CIF/D1 names are sized by the camera itself: the first one
        through ``imagesize.cgi`` (which tells PAL from NTSC), else the video standard of the camera's default
        size or of the video input it reports; without ``imagesize.cgi`` (some firmware answers 404) and
        without a reported standard, from the parameter's definition, else the sizes of both standards
        (:meth:`_size_unsized`) — never an empty list for a non-empty listing, never silently PAL."""
        names = [n.strip() for n in listing.split(",") if n.strip()]
        result: list[Resolution] = []
        unsized: list[str] = []
        for name in names:
            upper = name.upper()
            resolution: Resolution | None
            try:
                resolution = Resolution.parse(name) if upper not in CIF_PAL else None
            except InvalidArgument:
                resolution = None
            if resolution is None and upper in CIF_PAL and self._ntsc is not None:
                resolution = Resolution(*(CIF_NTSC if self._ntsc else CIF_PAL)[upper])  # standard known
            if resolution is None:
                resolution = self._imagesize(upper if upper in CIF_PAL else name)
                if resolution is not None and upper in CIF_PAL and self._ntsc is None:
                    if resolution == Resolution(*CIF_NTSC[upper]):
                        self._ntsc = True
                    elif resolution == Resolution(*CIF_PAL[upper]):
                        self._ntsc = False
            if resolution is None and upper in CIF_PAL:
                ntsc = self._video_standard()
                if ntsc is not None:
                    resolution = Resolution(*(CIF_NTSC if ntsc else CIF_PAL)[upper])
            if resolution is None:
                unsized.append(name)
            elif resolution not in result:
                result.append(resolution)
        self.resolution_problem = ""
        if unsized:
            result += self._size_unsized(unsized, result)
        return tuple(result)

    def _size_unsized(self, unsized: list[str], known: list[Resolution]) -> list[Resolution]:
        """Sizes for names neither ``imagesize.cgi`` nor a reported video standard could size: from the
        resolution parameter's definition, else (CIF names) the sizes of both video standards, so the list is
        never empty; what was not known for sure is said in :attr:`resolution_problem`."""
        defined = self._defined_sizes()
        out: list[Resolution] = []
        guessed: list[str] = []
        for name in unsized:
            upper = name.upper()
            candidates = [defined[upper]] if upper in defined else []
            if not candidates and upper in CIF_PAL:
                candidates = [Resolution(*CIF_PAL[upper]), Resolution(*CIF_NTSC[upper])]
                guessed.append(name)
            out += [r for r in candidates if r not in known and r not in out]
        lost = [n for n in unsized if n.upper() not in defined and n.upper() not in CIF_PAL]
        problems = []
        if guessed:
            problems.append(
                f"camera lists {', '.join(guessed)} but tells neither their size (no imagesize.cgi, no parameter "
                "definition) nor PAL/NTSC: offering the sizes of both standards; configure resolution as "
                "WIDTHxHEIGHT of your camera's standard"
            )
        if lost:
            problems.append(f"camera lists {', '.join(lost)} but could not tell their size; left out")
        self.resolution_problem = "; ".join(problems)
        return out

    def supported_resolutions(self) -> tuple[Resolution, ...]:
        """``Properties.Image.Resolution`` as sizes (CIF names mapped, PAL/NTSC via ``imagesize.cgi``)."""
        params = self.list_params("Properties.Image.Resolution")
        listing = params.get("Properties.Image.Resolution")
        if listing is None:
            raise ResponseParseError(f"no Properties.Image.Resolution in reply (keys: {sorted(params)})")
        self._resolutions = self._resolutions_from(listing)
        return self._resolutions

    def device_info(self) -> DeviceInfo:
        """Product, firmware, API version, resolutions, PTZ presence and ``PTZ.Support`` capabilities."""
        brand = self.list_params("Brand")
        props = self.list_params("Properties")
        product = brand.get("Brand.ProdFullName") or brand.get("Brand.ProdShortName") or "unknown"
        version = props.get("Properties.API.HTTP.Version")
        listing = props.get("Properties.Image.Resolution", "")
        self._resolutions = self._resolutions_from(listing) if listing else ()
        ptz_flag = props.get("Properties.PTZ.PTZ")
        supports: frozenset[str] = frozenset()
        if ptz_flag is None or parse_bool(ptz_flag, key="Properties.PTZ.PTZ"):
            prefix = f"PTZ.Support.S{self._config.camera}."
            try:
                support = self.list_params("PTZ.Support")
            except CommandRejected:
                support = {}
            supports = frozenset(
                key[len(prefix) :]
                for key, value in support.items()
                if key.startswith(prefix) and value.strip().lower() in ("true", "yes", "on", "1")
            )
        ptz = parse_bool(ptz_flag, key="Properties.PTZ.PTZ") if ptz_flag is not None else bool(supports)
        if ptz and self.mechanical_ptz() is False:
            ptz = False  # a fixed camera with digital PTZ only
        return DeviceInfo(
            product=product,
            firmware=props.get("Properties.Firmware.Version", "unknown"),
            api_version=parse_int(version, key="Properties.API.HTTP.Version") if version else None,
            resolutions=self._resolutions,
            ptz=ptz,
            supports=supports,
        )

    def mechanical_ptz(self) -> bool | None:
        """``PTZ.ImageSource.I<n>.PTZEnabled``: False on fixed cameras (digital PTZ only), True on PTZ heads,
        None when the camera has no such parameter (e.g. the 214's firmware)."""
        key = f"PTZ.ImageSource.I{self._config.camera - 1}.PTZEnabled"
        try:
            values = self.list_params("PTZ.ImageSource")
        except (CommandRejected, HttpStatusError):
            return None
        value = values.get(key)
        return None if value is None else parse_bool(value, key=key)
