"""The thesis's Figure 6.4 statement as a measure on the simulated 214's pictures (test and bench support).

Figure 6.4 (the thesis, §6.2): "The values up to level 30 are almost indistinguishable. The values between 30
and 60 are still applicable but the reduction in quality is visible. The values greater than 60 should not be
used." Measured on one frame per compression of the demo scene's home view (pan 0, tilt 0, zoom 1), each with the
same sensor noise (a new :class:`PicturePool` per compression: its first frame draws the same noise):

* **almost indistinguishable from 0** (compression 30): luma SSIM against the compression-0 frame ≥ 0.95;
* **usable** (compression 60): luma SSIM ≥ 0.90 and PSNR ≥ 30 dB against the noise-free (softened) view;
* **not usable** (compression 100): SSIM < 0.90 or PSNR < 30 dB against that view.

SSIM is Wang et al. 2004 (11×11 Gaussian window, σ 1.5); 30 dB and 0.90 are the usual "fair" boundaries of
8-bit picture quality (ITU-R BT.500's five grades are not defined in dB; these thresholds are our choice).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from axis_ptz_ros2.sim.camera_model import CameraModel, PicturePool
from axis_ptz_ros2.sim.renderer import PtzRenderer
from axis_ptz_ros2.sim.world import load_world

COMPRESSIONS = (0, 10, 30, 60, 80, 100)
SAME_AS_0 = 0.95  #: SSIM against the compression-0 frame: "almost indistinguishable"
USABLE_SSIM = 0.90  #: SSIM against the noise-free view: at least this to be "usable"
USABLE_PSNR_DB = 30.0  #: PSNR against the noise-free view: at least this to be "usable"


def psnr_db(a: np.ndarray, b: np.ndarray) -> float:
    """PSNR of two 8-bit-range pictures of one shape (any dtype), in dB; inf when identical."""
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return math.inf if mse == 0 else 10.0 * math.log10(255.0**2 / mse)


def luma(img: np.ndarray) -> np.ndarray:
    """The Y plane of a BGR picture (JPEG's YCbCr)."""
    return np.asarray(cv2.cvtColor(img, cv2.COLOR_BGR2YCrCb)[:, :, 0])


def ssim(a: np.ndarray, b: np.ndarray) -> float:
    """Mean SSIM of two 8-bit planes (Wang et al. 2004, 11×11 Gaussian window σ 1.5)."""
    x, y = a.astype(np.float64), b.astype(np.float64)
    c1, c2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2

    def g(v: np.ndarray) -> np.ndarray:
        return np.asarray(cv2.GaussianBlur(v, (11, 11), 1.5), dtype=np.float64)

    mx, my = g(x), g(y)
    sxx, syy, sxy = g(x * x) - mx * mx, g(y * y) - my * my, g(x * y) - mx * my
    m = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2))
    return float(m.mean())


@dataclass(frozen=True)
class Grade:
    """One compression's frame: SSIM against the compression-0 frame; PSNR and SSIM against the noise-free view;
    its JPEG size and IJG quality."""

    ssim_vs_0: float
    psnr_db: float
    ssim: float
    nbytes: int
    quality: int

    @property
    def usable(self) -> bool:
        return self.ssim >= USABLE_SSIM and self.psnr_db >= USABLE_PSNR_DB


@dataclass(frozen=True)
class Figure64:
    """The measure at one size: a :class:`Grade` per compression and the verdict per band of the statement."""

    grades: dict[int, Grade]

    @property
    def up_to_30_like_0(self) -> bool:
        return self.grades[30].ssim_vs_0 >= SAME_AS_0

    @property
    def at_60_usable(self) -> bool:
        return self.grades[60].usable

    @property
    def at_100_not_usable(self) -> bool:
        return not self.grades[100].usable

    @property
    def holds(self) -> bool:
        return self.up_to_30_like_0 and self.at_60_usable and self.at_100_not_usable


def figure_6_4(model: CameraModel, width: int, height: int, renderer: PtzRenderer | None = None) -> Figure64:
    """The measure of the module docstring for ``model`` at ``width``×``height``."""
    renderer = renderer if renderer is not None else PtzRenderer(load_world())
    view = renderer.render(0.0, 0.0, 1.0, width, height)
    ref = luma(model.soften(view, 1.0))
    frames = {}
    for comp in COMPRESSIONS:
        pool = PicturePool(model)  # a new pool: its first frame has the same noise as the others' first
        jpeg = pool.jpeg("home", lambda: view, 1.0, comp)
        frames[comp] = (luma(cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)), len(jpeg))
    y0 = frames[0][0]
    return Figure64(
        {
            comp: Grade(ssim(y0, y), float(cv2.PSNR(ref, y)), ssim(ref, y), n, model.quality(comp, width))
            for comp, (y, n) in frames.items()
        }
    )


@dataclass(frozen=True)
class Headroom:
    """How far the measure's "not usable" reaches at one size: the best IJG quality whose frame of the home view
    (with the same sensor noise as :func:`figure_6_4`'s) the measure calls not usable, and that frame's size."""

    quality: int  #: 0 if every quality 1…100 is usable
    nbytes: int
    psnr_db: float
    ssim: float


def unusable_headroom(model: CameraModel, width: int, height: int, renderer: PtzRenderer | None = None) -> Headroom:
    """The largest frame the measure calls "not usable" (:class:`Headroom`), by a sweep of IJG quality 100…1 on
    ``model`` with its quality curve replaced by a constant (everything else of the chain unchanged).

    Figure 6.4 and the thesis's tables can hold together at this size only if this frame is at least the smallest
    compression-100 frame the tables allow (0.5× theirs)."""
    renderer = renderer if renderer is not None else PtzRenderer(load_world())
    view = renderer.render(0.0, 0.0, 1.0, width, height)
    ref = luma(model.soften(view, 1.0))
    for q in range(100, 0, -1):
        flat = replace(model, quality_at_0=float(q), quality_at_100=float(q), quality_drop_per_halving=0.0)
        jpeg = PicturePool(flat).jpeg("home", lambda: view, 1.0, 0)
        y = luma(cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR))
        grade = Grade(1.0, float(cv2.PSNR(ref, y)), ssim(ref, y), len(jpeg), q)
        if not grade.usable:
            return Headroom(q, len(jpeg), grade.psnr_db, grade.ssim)
    return Headroom(0, 0, float("nan"), float("nan"))
