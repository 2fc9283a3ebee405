"""Picked 2-D/3-D correspondences for the extrinsic calibration (ROS-free).

File format ``axis_ptz_ros2/correspondences/v1`` (YAML)::

    format: axis_ptz_ros2/correspondences/v1
    camera_model: ../config/axis214.yaml   # optional; relative paths are relative to this file
    comment: "furniture scene, 2025-01-01"  # optional
    views:
      - name: left                           # unique per file
        pan: 0.7854                          # rad, REP-103 (counter-clockwise positive, looking left)
        tilt: -0.1745                        # rad, REP-103 (up positive)
        zoom: 1                              # VAPIX zoom units (1...9999)
        image_width: 704                     # px, the stream the pixels were picked in
        image_height: 576
        image: images/left.jpg               # optional, for the record
        points:
          - pixel: [412.5, 300.0]            # [u, v] px, u right, v down, origin at the centre of the
            point: [3.12, 1.05, 0.42]        #   top-left pixel; [x, y, z] m in base_link (the laser's frame)
            label: table corner              # optional

A fixed camera's views (``axis_calibrate solve --fixed``) omit ``pan``, ``tilt`` and ``zoom`` (all three;
stored as NaN, :attr:`View.has_ptz` is False). Duplicate keys are refused.

Pan and tilt are the camera's *reported* position converted to REP-103 radians (``VapixConvention.to_ros``);
the solver may estimate an encoder offset on top of them. Unknown keys are rejected (typos would otherwise be
ignored silently); every error names the file, the line and the field.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from axis_ptz_ros2.strict_yaml import YamlError, loads_strict, read_text

CORRESPONDENCES_FORMAT = "axis_ptz_ros2/correspondences/v1"

_TOP_KEYS = {"format", "camera_model", "comment", "views"}
_VIEW_KEYS = {"name", "pan", "tilt", "zoom", "image_width", "image_height", "image", "points", "comment"}
_POINT_KEYS = {"pixel", "point", "label"}


class CorrespondenceError(ValueError):
    """A correspondence file or object is malformed; the message names the file, line and field."""


@dataclass(frozen=True, slots=True)
class Correspondence:
    """One picked pair: a pixel in a view and the 3-D point (metres, ``base_link``) it shows."""

    pixel: tuple[float, float]
    point: tuple[float, float, float]
    label: str = ""
    line: int = field(default=0, compare=False)  # line in the file it was read from (0: not from a file)


@dataclass(frozen=True, slots=True)
class View:
    """One camera view at a known (reported) pan/tilt/zoom with its picked correspondences."""

    name: str
    pan: float  # rad, REP-103
    tilt: float  # rad, REP-103
    zoom: float  # VAPIX zoom units
    image_width: int
    image_height: int
    points: tuple[Correspondence, ...] = ()
    image: str | None = None
    comment: str = ""
    line: int = field(default=0, compare=False)  # line in the file it was read from (0: not from a file)

    @property
    def has_ptz(self) -> bool:
        """False for a fixed-camera view (pan, tilt and zoom all omitted, stored as NaN)."""
        return math.isfinite(self.pan) and math.isfinite(self.tilt) and math.isfinite(self.zoom)

    def __post_init__(self) -> None:
        """Validate (raises :class:`CorrespondenceError`)."""
        _validate_view(self, f"view {self.name!r}")


@dataclass(frozen=True, slots=True)
class CorrespondenceSet:
    """The content of a correspondence file."""

    views: tuple[View, ...] = ()
    camera_model: str | None = None  # path as written in the file (see :func:`resolve_camera_model`)
    comment: str = ""
    source: Path | None = field(default=None, compare=False)  # the file it was loaded from, if any

    @property
    def n_points(self) -> int:
        """Total number of correspondences over all views."""
        return sum(len(v.points) for v in self.views)

    def resolve_camera_model(self) -> Path | None:
        """The camera-model path, resolved relative to the correspondence file."""
        if not self.camera_model:
            return None
        p = Path(self.camera_model).expanduser()
        if not p.is_absolute() and self.source is not None:
            p = self.source.parent / p
        return p.resolve()


# --------------------------------------------------------------------------------------------------------
# Validation helpers
# --------------------------------------------------------------------------------------------------------
def _finite(x: float) -> bool:
    return math.isfinite(x)


def _view_problem(name: str, pan: float, tilt: float, zoom: float, width: int, height: int) -> tuple[str, str] | None:
    """The first problem of a view's scalar fields as (field, message), or None."""
    if not name:
        return "name", "must be a non-empty string"
    absent = [not _finite(v) for v in (pan, tilt, zoom)]
    if all(absent):  # a fixed camera's view: no pan/tilt/zoom at all
        return None if width > 0 and height > 0 else ("image_width", "must be positive integers")
    for key, val in (("pan", pan), ("tilt", tilt), ("zoom", zoom)):
        if not _finite(val):
            return key, f"must be finite, got {val}"
    if abs(pan) > 2.0 * math.pi + 1e-9:
        return "pan", f"{pan} is outside ±2π rad — degrees given instead of radians?"
    if abs(tilt) > math.pi / 2.0 + 0.2:
        return "tilt", f"{tilt} is outside ±(π/2 + 0.2) rad — degrees given instead of radians?"
    if zoom < 0.0:
        return "zoom", f"must be >= 0 (VAPIX units), got {zoom}"
    if width <= 0 or height <= 0:
        return "image_width", "image_width and image_height must be positive integers"
    return None


def _validate_view(v: View, where: str) -> None:
    problem = _view_problem(v.name, v.pan, v.tilt, v.zoom, v.image_width, v.image_height)
    if problem is not None:
        raise CorrespondenceError(f"{where}: {problem[0]}: {problem[1]}")
    for i, c in enumerate(v.points):
        _validate_point(c, v.image_width, v.image_height, f"{where}: points[{i}]")


def _validate_point(c: Correspondence, width: int, height: int, where: str) -> None:
    if len(c.pixel) != 2 or not all(_finite(x) for x in c.pixel):
        raise CorrespondenceError(f"{where}.pixel: expected two finite numbers [u, v], got {list(c.pixel)}")
    if len(c.point) != 3 or not all(_finite(x) for x in c.point):
        raise CorrespondenceError(f"{where}.point: expected three finite numbers [x, y, z], got {list(c.point)}")
    u, v = c.pixel
    if not (-0.5 <= u <= width - 0.5 and -0.5 <= v <= height - 0.5):
        raise CorrespondenceError(f"{where}.pixel: [{u}, {v}] is outside the {width}x{height} image")


# --------------------------------------------------------------------------------------------------------
# Parsing with line numbers: walk the composed YAML node tree alongside the plain data
# --------------------------------------------------------------------------------------------------------
class _Ctx:
    """Maps a data path to the YAML line it came from, for error messages."""

    def __init__(self, source: str, root: yaml.Node | None) -> None:
        self.source = source
        self.root = root

    def _node(self, path: Sequence[str | int]) -> yaml.Node | None:
        node = self.root
        for key in path:
            if isinstance(node, yaml.MappingNode) and isinstance(key, str):
                nxt = None
                for k, val in node.value:
                    if isinstance(k, yaml.ScalarNode) and k.value == key:
                        nxt = val
                        break
                node = nxt
            elif isinstance(node, yaml.SequenceNode) and isinstance(key, int) and key < len(node.value):
                node = node.value[key]
            else:
                return node
            if node is None:
                return None
        return node

    def line(self, path: Sequence[str | int]) -> int:
        """1-based line of the node at ``path`` (0 if unknown)."""
        node = self._node(path)
        return node.start_mark.line + 1 if node is not None else 0

    def error(self, path: Sequence[str | int], msg: str) -> CorrespondenceError:
        node = self._node(path)
        line = f":{node.start_mark.line + 1}" if node is not None else ""
        dotted = ""
        for key in path:
            dotted += f"[{key}]" if isinstance(key, int) else (f".{key}" if dotted else key)
        return CorrespondenceError(f"{self.source}{line}: {dotted or '<document>'}: {msg}")


def _num(ctx: _Ctx, d: dict[str, Any], key: str, path: list[str | int], *, required: bool = True) -> float:
    if key not in d:
        if required:
            raise ctx.error(path, f"missing required field {key!r}")
        return math.nan
    val = d[key]
    if isinstance(val, bool) or not isinstance(val, int | float):
        raise ctx.error([*path, key], f"expected a number, got {val!r}")
    if not math.isfinite(float(val)):
        raise ctx.error([*path, key], f"expected a finite number, got {val!r}")
    return float(val)


def _int(ctx: _Ctx, d: dict[str, Any], key: str, path: list[str | int]) -> int:
    if key not in d:
        raise ctx.error(path, f"missing required field {key!r}")
    val = d[key]
    if isinstance(val, bool) or not isinstance(val, int) or val <= 0:
        raise ctx.error([*path, key], f"expected a positive integer, got {val!r}")
    return val


def _vec(ctx: _Ctx, val: Any, n: int, path: list[str | int], what: str) -> tuple[float, ...]:
    if not isinstance(val, list) or len(val) != n:
        raise ctx.error(path, f"expected a list of {n} numbers {what}, got {val!r}")
    out = []
    for i, x in enumerate(val):
        if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(float(x)):
            raise ctx.error([*path, i], f"expected a finite number, got {x!r}")
        out.append(float(x))
    return tuple(out)


def _check_keys(ctx: _Ctx, d: dict[str, Any], allowed: set[str], path: list[str | int]) -> None:
    unknown = sorted(str(k) for k in d if k not in allowed)
    if unknown:
        raise ctx.error([*path, unknown[0]], f"unknown field(s) {unknown}; allowed: {sorted(allowed)}")


def _parse_view(ctx: _Ctx, d: Any, path: list[str | int], names: set[str]) -> View:
    if not isinstance(d, dict):
        raise ctx.error(path, f"a view must be a mapping, got {type(d).__name__}")
    _check_keys(ctx, d, _VIEW_KEYS, path)
    name = d.get("name")
    if not isinstance(name, str) or not name:
        raise ctx.error([*path, "name"] if "name" in d else path, "a view needs a non-empty string 'name'")
    if name in names:
        raise ctx.error([*path, "name"], f"duplicate view name {name!r}")
    names.add(name)
    fixed = not any(k in d for k in ("pan", "tilt", "zoom"))  # a fixed camera's view omits all three
    pan = _num(ctx, d, "pan", path, required=not fixed)
    tilt = _num(ctx, d, "tilt", path, required=not fixed)
    zoom = _num(ctx, d, "zoom", path, required=not fixed)
    width = _int(ctx, d, "image_width", path)
    height = _int(ctx, d, "image_height", path)
    image = d.get("image")
    if image is not None and not isinstance(image, str):
        raise ctx.error([*path, "image"], f"expected a path string, got {image!r}")
    raw_points = d.get("points", [])
    if not isinstance(raw_points, list):
        raise ctx.error([*path, "points"], "expected a list of {pixel, point, label} mappings")
    points: list[Correspondence] = []
    for i, p in enumerate(raw_points):
        pp: list[str | int] = [*path, "points", i]
        if not isinstance(p, dict):
            raise ctx.error(pp, f"a point must be a mapping with pixel and point, got {p!r}")
        _check_keys(ctx, p, _POINT_KEYS, pp)
        for key in ("pixel", "point"):
            if key not in p:
                raise ctx.error(pp, f"missing required field {key!r}")
        pixel = _vec(ctx, p["pixel"], 2, [*pp, "pixel"], "[u, v] (px)")
        point = _vec(ctx, p["point"], 3, [*pp, "point"], "[x, y, z] (m, base_link)")
        label = p.get("label", "")
        if not isinstance(label, str | int | float):
            raise ctx.error([*pp, "label"], f"expected a string, got {label!r}")
        c = Correspondence((pixel[0], pixel[1]), (point[0], point[1], point[2]), str(label), ctx.line(pp))
        try:
            _validate_point(c, width, height, "point")
        except CorrespondenceError as err:
            raise ctx.error([*pp, "pixel"], str(err).split(": ", 1)[1]) from err
        points.append(c)
    problem = _view_problem(name, pan, tilt, zoom, width, height)  # checked here to name the line
    if problem is not None:
        raise ctx.error([*path, problem[0]], problem[1])
    return View(name, pan, tilt, zoom, width, height, tuple(points), image, str(d.get("comment", "")), ctx.line(path))


def parse_correspondences(text: str, source: str = "<string>") -> CorrespondenceSet:
    """Parse the YAML text of a correspondence file (see the module docstring for the format)."""
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
        data = loads_strict(text, source)  # refuses duplicate keys (naming both lines)
    except YamlError as err:
        raise CorrespondenceError(str(err)) from err
    except yaml.YAMLError as err:
        raise CorrespondenceError(f"{source}: not valid YAML: {err}") from err
    ctx = _Ctx(source, root)
    if not isinstance(data, dict):
        raise ctx.error([], "expected a mapping with 'format' and 'views'")
    _check_keys(ctx, data, _TOP_KEYS, [])
    fmt = data.get("format")
    if fmt != CORRESPONDENCES_FORMAT:
        raise ctx.error(
            ["format"] if "format" in data else [], f"expected format {CORRESPONDENCES_FORMAT!r}, got {fmt!r}"
        )
    cam = data.get("camera_model")
    if cam is not None and not isinstance(cam, str):
        raise ctx.error(["camera_model"], f"expected a path string, got {cam!r}")
    views_raw = data.get("views")
    if not isinstance(views_raw, list):
        raise ctx.error(["views"] if "views" in data else [], "expected a list of views")
    names: set[str] = set()
    views = tuple(_parse_view(ctx, v, ["views", i], names) for i, v in enumerate(views_raw))
    return CorrespondenceSet(views, cam or None, str(data.get("comment", "")))


def load_correspondences(path: str | Path) -> CorrespondenceSet:
    """Load and validate a correspondence file (raises :class:`CorrespondenceError`)."""
    p = Path(path)
    cs = parse_correspondences(read_text(p, CorrespondenceError), str(p))
    return CorrespondenceSet(cs.views, cs.camera_model, cs.comment, p.resolve())


# --------------------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------------------
def view_to_dict(v: View) -> dict[str, Any]:
    """Serialisable mapping of one view (pixels rounded to 0.001 px, points to 10 µm, angles to 1e-9 rad)."""
    out: dict[str, Any] = {"name": v.name}
    if v.has_ptz:
        out.update(pan=round(float(v.pan), 9), tilt=round(float(v.tilt), 9), zoom=round(float(v.zoom), 3))
    out.update(image_width=int(v.image_width), image_height=int(v.image_height))
    if v.image:
        out["image"] = v.image
    if v.comment:
        out["comment"] = v.comment
    pts: list[dict[str, Any]] = []
    for c in v.points:
        d: dict[str, Any] = {
            "pixel": [round(float(c.pixel[0]), 3), round(float(c.pixel[1]), 3)],
            "point": [round(float(x), 5) for x in c.point],
        }
        if c.label:
            d["label"] = c.label
        pts.append(d)
    out["points"] = pts
    return out


def correspondences_to_dict(cs: CorrespondenceSet) -> dict[str, Any]:
    """Serialisable mapping of a whole file."""
    out: dict[str, Any] = {"format": CORRESPONDENCES_FORMAT}
    if cs.camera_model:
        out["camera_model"] = cs.camera_model
    if cs.comment:
        out["comment"] = cs.comment
    out["views"] = [view_to_dict(v) for v in cs.views]
    return out


class _FlowListDumper(yaml.SafeDumper):  # type: ignore[misc]  # PyYAML ships no stubs
    """Writes short numeric lists ([u, v], [x, y, z]) in flow style for readable files."""


def _represent_list(dumper: yaml.SafeDumper, data: list[Any]) -> yaml.Node:
    flow = len(data) <= 3 and all(isinstance(x, int | float) for x in data)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)


_FlowListDumper.add_representer(list, _represent_list)


def dump_correspondences(cs: CorrespondenceSet) -> str:
    """YAML text of a correspondence set."""
    header = f"# 2-D/3-D correspondences for axis_calibrate ({CORRESPONDENCES_FORMAT}): pan/tilt rad (REP-103),\n"
    header += "# zoom in VAPIX units, pixel [u, v] px, point [x, y, z] m in base_link.\n"
    body = str(
        yaml.dump(
            correspondences_to_dict(cs),
            Dumper=_FlowListDumper,
            sort_keys=False,
            allow_unicode=True,
            width=110,
        )
    )
    return header + body


def save_correspondences(cs: CorrespondenceSet, path: str | Path) -> None:
    """Write a correspondence file (validated by construction; atomically replaces ``path``)."""
    p = Path(path)
    tmp = p.with_name(p.name + ".tmp")
    tmp.write_text(dump_correspondences(cs), encoding="utf-8")
    tmp.replace(p)


def append_view(path: str | Path, view: View, *, camera_model: str | None = None) -> CorrespondenceSet:
    """Append one view to a correspondence file, creating the file if needed; returns the new content.

    This is the hook a capture tool uses: grab pan/tilt/zoom and the image size from the running camera,
    pick pixels and laser points, then call ``append_view``. A view with an existing name is rejected.
    """
    p = Path(path)
    cs = load_correspondences(p) if p.exists() else CorrespondenceSet((), camera_model)
    if any(v.name == view.name for v in cs.views):
        raise CorrespondenceError(f"{p}: a view named {view.name!r} already exists")
    new = CorrespondenceSet((*cs.views, view), cs.camera_model or camera_model, cs.comment, cs.source)
    save_correspondences(new, p)
    return new
