"""Capture mode of ``axis_calibrate``: record calibration views from the running ROS system.

For every view the tool records

* the PTZ state (``ptz/state``: pan/tilt rad REP-103, zoom units) while the head stands still — minus the
  encoder offsets of the mount file the PTZ node runs with, so the file holds the *reported* head position;
* one frame of ``image_raw/compressed`` received after the head stopped (and the settle time), saved as
  ``<OUT stem>_views/<view>.jpg`` next to the correspondence file (path stored in the view's ``image``);
* one laser snapshot (``laser/points``, ``sensor_msgs/PointCloud2`` with float x, y, z[, intensity])
  received after the head stopped, transformed into ``base_link`` with the laser pose of
  ``config/robot.yaml`` (or ``--laser-pose``) and saved as ``<OUT stem>_views/<view>.npy`` — an (N, 4)
  float32 array x, y, z (m, base_link), intensity (NaN when the cloud has none);

optionally after commanding the head to a list of poses (``ptz/move_absolute`` with ``wait=true``). The view
is then appended to the correspondence file with :func:`~axis_ptz_ros2.calibration.correspondences.append_view`
— with its picked points when a :class:`BoardPicker` plug-in picks them (``--picker MODULE:CLASS``; the tests
pass in the simulated boards' picker, ``tests/support/sim_picker.py``), otherwise with none for a person to
add (see the ``axis_calibrate`` docs).

Picking by hand (a real robot; no automatic picker)::

    axis_calibrate capture calib.yaml --views 6 --camera-model config/axis214.yaml --ply
    # per view: aim the camera (web console / keyboard teleop) at corners the laser sees well (board
    # corners, box edges) at several depths, keep the robot still, press Enter

1. Open ``calib_views/viewNN.jpg`` in an image viewer that shows pixel indices (GIMP's pointer dialog,
   ``cv2.imshow`` with a mouse callback): integer pixel indices are pixel *centres* in the file's
   convention, so read [u, v] directly (sub-pixel where the viewer allows).
2. Open ``calib_views/viewNN.ply`` (written with ``--ply``; same points as the ``.npy``, base_link, intensity
   as a scalar field) in CloudCompare / MeshLab and use its point-picking tool to read [x, y, z] of the same
   corner; or, live, RViz with fixed frame ``base_link``, ``laser/points`` and the *Publish Point* tool.
3. Add the pairs under the view's ``points:`` (``{pixel: [u, v], point: [x, y, z], label: ...}``): ≥ 8 per
   view spread over the image, ≥ 5 views, some at a higher zoom; then ``axis_calibrate solve calib.yaml
   --sigma-3d 0.01 --out mount.yaml`` and check the residual table for mis-picks.

This module is ROS-free: the views, their files, the picker plug-ins, what makes a still view and the capture
run. The ROS side that receives the data and commands the head (``CaptureSession``, ``RosCapture``) is
:mod:`axis_ptz_ros2.nodes.calibration_capture`, which is also the ``axis_calibrate`` executable.
"""

from __future__ import annotations

import importlib
import importlib.util
import math
import re
import sys
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol, cast

import cv2
import numpy as np
import numpy.typing as npt

from axis_ptz_ros2.calibration.correspondences import (
    Correspondence,
    CorrespondenceError,
    View,
    append_view,
    load_correspondences,
)
from axis_ptz_ros2.calibration.picking import (
    NoiseStats,
    PickedPoint,
    PickMode,
    picking_noise,
)
from axis_ptz_ros2.config import CameraModel
from axis_ptz_ros2.transforms import Transform

FloatArray = npt.NDArray[np.float64]


class CaptureError(RuntimeError):
    """A view could not be captured (no data, head moving, service refused); the message says why."""


# --------------------------------------------------------------------------------------------------------
# Poses
# --------------------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class PoseCommand:
    """An absolute PTZ set-point: pan/tilt in rad (REP-103), zoom in VAPIX units (NaN = keep)."""

    pan: float
    tilt: float
    zoom: float = math.nan


def parse_poses(text: str) -> list[PoseCommand]:
    """Parse ``"pan_deg,tilt_deg[,zoom];..."`` (REP-103 degrees: pan left positive, tilt up positive; zoom
    in VAPIX units, omitted = keep the current zoom). Raises ``ValueError`` naming the bad entry."""
    out: list[PoseCommand] = []
    for i, entry in enumerate(e.strip() for e in text.split(";")):
        if not entry:
            continue
        parts = [p.strip() for p in entry.split(",")]
        if len(parts) not in (2, 3):
            raise ValueError(f"pose {i + 1} {entry!r}: expected 'pan_deg,tilt_deg[,zoom]'")
        try:
            vals = [float(p) for p in parts]
        except ValueError as err:
            raise ValueError(f"pose {i + 1} {entry!r}: not a number") from err
        if not all(math.isfinite(v) for v in vals):
            raise ValueError(f"pose {i + 1} {entry!r}: values must be finite")
        if abs(vals[0]) > 360.0 or abs(vals[1]) > 90.0:
            raise ValueError(f"pose {i + 1} {entry!r}: pan must be within ±360°, tilt within ±90° (degrees)")
        if len(vals) == 3 and vals[2] < 0:
            raise ValueError(f"pose {i + 1} {entry!r}: zoom must be >= 0 (VAPIX units)")
        out.append(PoseCommand(math.radians(vals[0]), math.radians(vals[1]), vals[2] if len(vals) == 3 else math.nan))
    if not out:
        raise ValueError("no poses given")
    return out


def parse_pose6(text: str) -> Transform:
    """Parse ``"x,y,z,roll_deg,pitch_deg,yaw_deg"`` (metres, degrees) into a transform."""
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 6:
        raise ValueError(f"{text!r}: expected 'x,y,z,roll_deg,pitch_deg,yaw_deg'")
    v = [float(p) for p in parts]
    return Transform.from_xyz_rpy(v[0], v[1], v[2], *(math.radians(a) for a in v[3:]))


def transform_cloud(cloud: FloatArray, T: Transform) -> FloatArray:
    """Apply ``T`` to the x, y, z columns of an (N, 3|4) cloud (other columns unchanged)."""
    out = np.array(cloud, dtype=np.float64, copy=True)
    if len(out):
        out[:, :3] = T.apply(out[:, :3])
    return out


# --------------------------------------------------------------------------------------------------------
# Captured views and their files
# --------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CapturedView:
    """Raw data of one view, before picking."""

    name: str
    pan: float  # rad, REP-103, reported by the head (encoder offsets removed)
    tilt: float  # rad
    zoom: float  # VAPIX units
    jpeg: bytes
    image_width: int
    image_height: int
    cloud: FloatArray  # (N, 4) x, y, z (m, base_link), intensity
    state_spread: float = 0.0  # rad, max pan/tilt change over the states received while capturing
    timings: dict[str, float] = field(default_factory=dict)  # s, for the record

    def image(self) -> npt.NDArray[np.uint8]:
        """The decoded BGR frame."""
        img = cv2.imdecode(np.frombuffer(self.jpeg, np.uint8), cv2.IMREAD_COLOR)
        if img is None:
            raise CaptureError(f"view {self.name!r}: the frame is not a decodable JPEG")
        return np.asarray(img, dtype=np.uint8)


def views_dir(out: str | Path) -> Path:
    """Folder of the images and clouds of a correspondence file: ``<dir>/<stem>_views``."""
    p = Path(out)
    return p.parent / f"{p.stem}_views"


def cloud_path(correspondence_file: str | Path, view: View) -> Path:
    """The laser snapshot of a captured view: its image path with the suffix ``.npy``."""
    if not view.image:
        raise CorrespondenceError(f"view {view.name!r} has no image path (not captured by axis_calibrate?)")
    img = Path(view.image)
    if not img.is_absolute():
        img = Path(correspondence_file).parent / img
    return img.with_suffix(".npy")


def write_ply(path: str | Path, cloud: FloatArray) -> None:
    """ASCII PLY of an (N, 3|4) cloud (x, y, z in metres; intensity as a scalar property) for point viewers."""
    C = np.asarray(cloud, dtype=np.float64)
    has_i = C.shape[1] >= 4
    header = ["ply", "format ascii 1.0", f"element vertex {len(C)}", "property float x", "property float y"]
    header += ["property float z"] + (["property float intensity"] if has_i else []) + ["end_header"]
    cols = C[:, :4] if has_i else C[:, :3]
    with open(path, "w", encoding="ascii") as f:
        f.write("\n".join(header) + "\n")
        np.savetxt(f, np.nan_to_num(cols, nan=0.0), fmt="%.5f")


def store_view(
    out: str | Path,
    cap: CapturedView,
    points: Sequence[Correspondence] = (),
    *,
    camera_model: str | None = None,
    comment: str = "",
    ply: bool = False,
) -> View:
    """Write the view's JPEG and cloud (and a PLY copy with ``ply``) next to ``out`` and append the view
    (with ``points``) to ``out``."""
    d = views_dir(out)
    d.mkdir(parents=True, exist_ok=True)
    if not re.fullmatch(r"[A-Za-z0-9_.-]+", cap.name):
        raise CorrespondenceError(f"view name {cap.name!r}: use letters, digits, '_', '-', '.' only")
    img_path = d / f"{cap.name}.jpg"
    img_path.write_bytes(cap.jpeg)
    np.save(d / f"{cap.name}.npy", cap.cloud.astype(np.float32))
    if ply:
        write_ply(d / f"{cap.name}.ply", cap.cloud)
    rel = img_path.relative_to(Path(out).parent).as_posix()
    view = View(
        cap.name,
        cap.pan,
        cap.tilt,
        cap.zoom,
        cap.image_width,
        cap.image_height,
        tuple(points),
        rel,
        comment or f"laser snapshot {Path(rel).with_suffix('.npy').as_posix()} (base_link x y z intensity)",
    )
    append_view(out, view, camera_model=camera_model)
    return view


# --------------------------------------------------------------------------------------------------------
# One still view from what the running system sent (the session that receives it: nodes/calibration_capture.py)
# --------------------------------------------------------------------------------------------------------
class HeadState(Protocol):
    """The fields of a ``ptz/state`` message the capture reads (rad REP-103, zoom units; encoder offsets added)."""

    @property
    def pan(self) -> float: ...  # noqa: D102
    @property
    def tilt(self) -> float: ...  # noqa: D102
    @property
    def zoom(self) -> float: ...  # noqa: D102
    @property
    def moving(self) -> bool: ...  # noqa: D102


def still_view(
    name: str,
    states: Sequence[HeadState],
    jpeg: bytes,
    cloud: FloatArray,
    *,
    pan_offset: float = 0.0,
    tilt_offset: float = 0.0,
    still_tolerance: float = 2e-4,
    timings: dict[str, float] | None = None,
) -> CapturedView:
    """The view ``name`` from the states received while the head stood still (its pose: their median, minus the
    encoder offsets), one camera frame and one laser cloud in ``base_link``. Refused (:class:`CaptureError`) when a
    state says the head moved, pan/tilt changed by more than ``still_tolerance`` rad, or the frame does not
    decode."""
    if not states:
        raise CaptureError(f"view {name!r}: no ptz/state received while capturing")
    if any(s.moving for s in states):
        raise CaptureError(f"view {name!r}: the head moved while capturing; hold it still and retry")
    pans = np.array([s.pan for s in states])
    tilts = np.array([s.tilt for s in states])
    zooms = np.array([s.zoom for s in states])
    spread = float(max(np.ptp(pans), np.ptp(tilts)))
    if spread > still_tolerance:
        raise CaptureError(f"view {name!r}: pan/tilt changed by {math.degrees(spread):.4f}° while capturing; retry")
    arr = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
    if arr is None:
        raise CaptureError(f"view {name!r}: the camera frame is not a decodable JPEG")
    return CapturedView(
        name=name,
        pan=float(np.median(pans)) - pan_offset,
        tilt=float(np.median(tilts)) - tilt_offset,
        zoom=float(np.median(zooms)),
        jpeg=jpeg,
        image_width=int(arr.shape[1]),
        image_height=int(arr.shape[0]),
        cloud=cloud,
        state_spread=spread,
        timings=dict(timings or {}),
    )


def cloud_in_base(
    points: FloatArray, frame: str, *, base_frame: str, laser_frame: str, T_base_laser: Transform
) -> FloatArray:
    """A decoded laser cloud in ``base_frame``: as is when it is already there, moved by ``T_base_laser`` when it
    is in ``laser_frame``; any other frame is refused (the laser pose given is not for it)."""
    frame = frame.lstrip("/")
    if frame == base_frame:
        return points
    if frame != laser_frame:
        raise CaptureError(
            f"laser/points is in frame {frame!r}, but the laser pose given is for {laser_frame!r} "
            f"(set the laser frame/pose, e.g. config/robot.yaml)"
        )
    return transform_cloud(points, T_base_laser)


class ViewSource(Protocol):
    """Where :func:`capture_views` gets its views: the running system
    (:class:`axis_ptz_ros2.nodes.calibration_capture.CaptureSession`)."""

    def wait_ready(self, timeout: float | None = None) -> None:
        """Wait until PTZ state, a camera frame and a laser scan have been received."""

    def move(self, pose: PoseCommand) -> None:
        """Command an absolute pose and wait until the head arrived (CaptureError when it does not)."""

    def capture(self, name: str) -> CapturedView:
        """Record one view at the current (still) head position."""


#: Opens a :class:`ViewSource` on the running system for ``axis_calibrate capture``: called with the ROS
#: namespace and the session's keywords, a context manager that closes it again.
CaptureOpener = Callable[..., AbstractContextManager[ViewSource]]


# --------------------------------------------------------------------------------------------------------
# Running a capture (used by ``axis_calibrate capture``)
# --------------------------------------------------------------------------------------------------------
class BoardPicker(Protocol):
    """Automatic picking of one captured view's 2-D/3-D pairs: a plug-in of ``axis_calibrate capture``.

    The product ships none (a person picks by hand, see the module docs); the simulated scene's board picker
    (``tests/support/sim_picker.py``) is one the tests and benches pass in. A picker returns
    :class:`~axis_ptz_ros2.calibration.picking.PickedPoint` s whose ``feature.point`` is where the picker
    believes the feature is (for the simulated boards: the scene's truth), which
    :meth:`CaptureReport.picking_noise` compares the picked laser points with.
    """

    def __call__(self, cap: CapturedView) -> list[PickedPoint]:
        """Pick the pairs of one captured view."""
        ...


class PickerFactory(Protocol):
    """How ``axis_calibrate capture --picker MODULE:CLASS`` builds a :class:`BoardPicker`: called with the
    camera model, the *guessed* (nominal) mount, the laser refinement ``mode`` (``--pick-mode``) and the
    ``--picker-arg KEY=VALUE`` options as strings."""

    def __call__(
        self, camera_model: CameraModel, T_base_ptz_guess: Transform, *, mode: PickMode, **options: str
    ) -> BoardPicker:
        """A picker for these inputs (``ValueError`` / ``OSError`` with the reason when it cannot be made)."""
        ...


def load_picker_factory(spec: str) -> PickerFactory:
    """The :class:`PickerFactory` named by ``MODULE:NAME`` (an importable module) or ``PATH.py:NAME`` (a file).

    Raises ``ValueError`` naming what is wrong (bad spec, module or file not found, no such name)."""
    where, sep, name = spec.rpartition(":")
    if not sep or not where or not name.isidentifier():
        raise ValueError(f"picker {spec!r}: expected MODULE:NAME or PATH.py:NAME")
    try:
        if where.endswith(".py"):
            path = Path(where).expanduser()
            loader_spec = importlib.util.spec_from_file_location(f"_axis_calibrate_picker_{path.stem}", path)
            if loader_spec is None or loader_spec.loader is None or not path.is_file():
                raise ValueError(f"picker {spec!r}: no file {path}")
            module = importlib.util.module_from_spec(loader_spec)
            sys.modules[loader_spec.name] = module  # dataclasses and pickling look classes up there
            loader_spec.loader.exec_module(module)
        else:
            module = importlib.import_module(where)
    except ImportError as err:
        raise ValueError(f"picker {spec!r}: cannot import {where!r} ({err}; is it on PYTHONPATH?)") from err
    factory = getattr(module, name, None)
    if not callable(factory):
        raise ValueError(f"picker {spec!r}: {where} has no callable {name!r}")
    return cast(PickerFactory, factory)


def parse_picker_options(items: Sequence[str]) -> dict[str, str]:
    """``["key=value", ...]`` → ``{"key": "value"}`` (``ValueError`` naming a malformed item)."""
    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip().isidentifier():
            raise ValueError(f"picker option {item!r}: expected KEY=VALUE")
        out[key.strip()] = value
    return out


@dataclass
class CaptureReport:
    """What a capture run did."""

    views: list[View] = field(default_factory=list)
    picked: list[PickedPoint] = field(default_factory=list)  # auto picking only

    def picking_noise(self) -> NoiseStats:
        """3-D picking error of the automatically picked points against the picker's feature positions (for the
        simulated boards: the scene's truth)."""
        return picking_noise([p.laser.point for p in self.picked], [p.feature.point for p in self.picked])


def next_view_names(out: str | Path, count: int, prefix: str = "view") -> list[str]:
    """``count`` view names ``<prefix>NN`` not yet used in ``out`` (numbering continues an existing file)."""
    p = Path(out)
    used = {v.name for v in load_correspondences(p).views} if p.exists() else set()
    names: list[str] = []
    k = 0
    while len(names) < count:
        name = f"{prefix}{k:02d}"
        if name not in used:
            names.append(name)
        k += 1
    return names


def capture_views(
    session: ViewSource,
    out: str | Path,
    names: Sequence[str],
    *,
    poses: Sequence[PoseCommand] | None = None,
    picker: BoardPicker | None = None,
    camera_model_ref: str | None = None,
    prompt: Callable[[str], bool] | None = None,
    log: Callable[[str], None] = lambda s: None,
    ply: bool = False,
) -> CaptureReport:
    """Capture ``len(names)`` views into ``out``: at ``poses`` (one per name) if given, otherwise whenever
    ``prompt(message)`` returns True (False stops early). Each view is appended as soon as it is captured."""
    if poses is not None and len(poses) != len(names):
        raise ValueError(f"{len(poses)} poses for {len(names)} views")
    report = CaptureReport()
    for k, name in enumerate(names):
        if poses is not None:
            session.move(poses[k])
        elif prompt is not None and not prompt(f"view {k + 1}/{len(names)} ({name}): point the camera, then Enter"):
            break
        cap = session.capture(name)
        picked = picker(cap) if picker is not None else []
        view = store_view(out, cap, [p.correspondence() for p in picked], camera_model=camera_model_ref, ply=ply)
        report.views.append(view)
        report.picked.extend(picked)
        msg = (
            f"{name}: pan {math.degrees(cap.pan):+8.3f}°  tilt {math.degrees(cap.tilt):+7.3f}°  zoom {cap.zoom:6.0f}  "
            f"{cap.image_width}x{cap.image_height}  {len(cap.cloud)} laser points"
        )
        if picker is not None:
            msg += f"  {len(picked)} pairs picked"
        log(msg)
    return report
