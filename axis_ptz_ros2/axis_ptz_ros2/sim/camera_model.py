"""What a camera makes of the rendered view: optics and video chain softness, sensor noise, JPEG quantisation.

ROS-free (numpy + OpenCV). The renderer draws an ideal, noise-free picture; a real camera's JPEGs are softer
and carry temporal noise, and their size follows from both. :class:`CameraModel` holds one camera's figures
(each persona has one, ``sim/persona.py``); :class:`PicturePool` turns a rendered view into the stream of
JPEGs the camera sends while it looks at it.

The chain, for a ``w``×``h`` stream (figures are given for the sensor's native width ``native_width`` and
scaled by ``w / native_width``, as the camera's scaler does):

1. **Softness** (deterministic, once per view): a Gaussian per axis and per component in YCrCb. Luma
   horizontally: the video chain's luminance bandwidth (``luma_bandwidth_mhz`` at ``sample_rate_mhz``, the
   ITU-R BT.601 13.5 MHz sampling of a PAL line) combined with the lens; vertically: the interlaced sensor's
   vertical resolution (``kell_factor``) combined with the lens. Chroma: ``chroma_bandwidth_mhz`` horizontally,
   ``chroma_vertical_sigma`` vertically (PAL's line-averaging delay line). Lens: a Gaussian MTF whose σ goes
   from ``lens_sigma_wide`` at zoom 1 to ``lens_sigma_tele`` at ``tele_zoom`` (VAPIX units).
   A Gaussian with σ (pixels) has MTF ``exp(-2π²σ²f²)``; it is down 3 dB at ``f = 0.1325/σ`` cycles/pixel,
   so a bandwidth B at sample rate S gives ``σ = 0.1325·S/B``.
2. **Temporal noise** (per frame): zero-mean, Gaussian, σ ``noise_luma`` (8-bit DN) in luma and
   ``noise_chroma`` in each colour difference at native size, shaped by the same chain (it is added at the
   sensor) and averaged down by the scaler (σ × ``w / native_width``). Frames draw from a precomputed noise
   field at random offsets, so noise costs one saturating add per frame.
3. **JPEG**: VAPIX ``compression`` c → IJG quality ``q(c) = q0 − (q0 − q100)·(c/100)^gamma`` (rounded, 1…100).

Costs: a still camera is served from a pool of ``pool_frames`` noisy JPEGs per view (made on the first
requests, then cycled: consecutive frames differ, the pool repeats after ``pool_frames``); a moving camera pays
the softening, one noise add and one encode per frame.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable
from dataclasses import dataclass, fields

import cv2
import numpy as np
import numpy.typing as npt

U8Array = npt.NDArray[np.uint8]

_SIGMA_AT_3DB = math.sqrt(math.log(math.sqrt(2.0)) / (2.0 * math.pi**2))  # 0.1325: σ·f at MTF = 1/√2
_NOISE_MARGIN = 64  # px: the noise field is this much larger than a frame, frames take random offsets
_POOLS_PER_VIEW = 4  # (compression, overlay text) pools kept per view


def sigma_from_bandwidth(bandwidth_mhz: float, sample_rate_mhz: float) -> float:
    """Gaussian σ (samples) whose MTF is down 3 dB at ``bandwidth_mhz`` when sampled at ``sample_rate_mhz``."""
    return _SIGMA_AT_3DB * sample_rate_mhz / bandwidth_mhz


@dataclass(frozen=True)
class CameraModel:
    """One camera's picture: softness, noise and compression (see the module docstring for the chain).

    Out-of-range values raise :class:`ValueError` naming the field, the value and the accepted range.
    ``luma_bandwidth_mhz``/``chroma_bandwidth_mhz`` of 0 mean "no band limit" (a digital sensor).
    """

    native_width: int = 704
    sample_rate_mhz: float = 13.5
    luma_bandwidth_mhz: float = 0.0
    chroma_bandwidth_mhz: float = 0.0
    chroma_vertical_sigma: float = 0.0
    kell_factor: float = 1.0
    lens_sigma_wide: float = 0.0
    lens_sigma_tele: float = 0.0
    scaler_sigma: float = 0.0
    tele_zoom: float = 9999.0
    noise_luma: float = 0.0
    noise_chroma: float = 0.0
    quality_at_0: float = 100.0
    quality_at_100: float = 5.0
    quality_gamma: float = 1.0
    quality_drop_per_halving: float = 0.0
    pool_frames: int = 8
    seed: int = 214

    #: field → (low, high, why): the accepted closed range of every figure
    LIMITS = {
        "native_width": (16, 8192, "sensor width in pixels"),
        "sample_rate_mhz": (1.0, 1000.0, "pixel sampling rate"),
        "luma_bandwidth_mhz": (0.0, 500.0, "0 = no band limit; else above 0.5 MHz"),
        "chroma_bandwidth_mhz": (0.0, 500.0, "0 = no band limit; else above 0.2 MHz"),
        "chroma_vertical_sigma": (0.0, 4.0, "pixels"),
        "kell_factor": (0.3, 1.0, "vertical resolution / line count"),
        "lens_sigma_wide": (0.0, 4.0, "pixels"),
        "lens_sigma_tele": (0.0, 4.0, "pixels"),
        "scaler_sigma": (0.0, 4.0, "output pixels per halving of the width"),
        "tele_zoom": (1.0, 1e6, "VAPIX zoom units"),
        "noise_luma": (0.0, 20.0, "8-bit DN; a camera noisier than 20 DN is broken"),
        "noise_chroma": (0.0, 20.0, "8-bit DN"),
        "quality_at_0": (1.0, 100.0, "IJG quality"),
        "quality_at_100": (1.0, 100.0, "IJG quality"),
        "quality_gamma": (0.1, 10.0, "curve exponent"),
        "quality_drop_per_halving": (0.0, 50.0, "IJG quality points at compression 100 per halving of the width"),
        "pool_frames": (1, 64, "noisy frames kept per view"),
        "seed": (0, 2**31 - 1, "noise seed"),
    }

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            lo, hi, why = self.LIMITS[f.name]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"camera model: {f.name}={value!r} is not a finite number ({why})")
            if f.type in ("int", int) and not isinstance(value, int):
                raise ValueError(f"camera model: {f.name}={value!r} must be an integer ({why})")
            if not lo <= value <= hi:
                raise ValueError(f"camera model: {f.name}={value!r} outside {lo:g}…{hi:g} ({why})")
        if 0 < self.luma_bandwidth_mhz < 0.5:
            raise ValueError(f"camera model: luma_bandwidth_mhz={self.luma_bandwidth_mhz} below 0.5 MHz")
        if 0 < self.chroma_bandwidth_mhz < 0.2:
            raise ValueError(f"camera model: chroma_bandwidth_mhz={self.chroma_bandwidth_mhz} below 0.2 MHz")
        if self.quality_at_100 > self.quality_at_0:
            raise ValueError(
                f"camera model: quality_at_100={self.quality_at_100} above quality_at_0={self.quality_at_0} "
                "(compression 100 must not be better than 0)"
            )

    # ---- the chain ------------------------------------------------------------------------------------
    def quality(self, compression: int, width: int | None = None) -> int:
        """IJG quality for VAPIX ``compression`` 0…100 (clamped) of a ``width``-wide stream (None: native)."""
        c = min(100.0, max(0.0, float(compression))) / 100.0
        q100 = self.quality_at_100
        if width is not None and width < self.native_width:
            q100 -= self.quality_drop_per_halving * math.log2(self.native_width / width)
        q100 = max(1.0, min(q100, self.quality_at_0))
        q = self.quality_at_0 - (self.quality_at_0 - q100) * c**self.quality_gamma
        return int(min(100, max(1, round(q))))

    def chain_sigmas(self, width: int) -> tuple[float, float, float, float]:
        """(luma σx, luma σy, chroma σx, chroma σy) of the video chain alone, pixels of a ``width``-wide stream."""
        bw_y = sigma_from_bandwidth(self.luma_bandwidth_mhz, self.sample_rate_mhz) if self.luma_bandwidth_mhz else 0.0
        bw_c = (
            sigma_from_bandwidth(self.chroma_bandwidth_mhz, self.sample_rate_mhz) if self.chroma_bandwidth_mhz else 0.0
        )
        # Kell factor k: the vertical response of an interlaced sensor is that of k·lines; modelled as the
        # Gaussian down 3 dB at k × Nyquist (0.5 cycles/line).
        kell = _SIGMA_AT_3DB / (0.5 * self.kell_factor) if self.kell_factor < 1.0 else 0.0
        s = width / self.native_width
        # the scaler's extra softness in output pixels, per halving of the width
        sc = self.scaler_sigma * math.log2(self.native_width / width) if width < self.native_width else 0.0
        return (
            math.hypot(bw_y * s, sc),
            math.hypot(kell * s, sc),
            math.hypot(bw_c * s, sc),
            math.hypot(self.chroma_vertical_sigma * s, kell * s, sc),
        )

    def sigmas(self, width: int, zoom: float) -> tuple[float, float, float, float]:
        """(luma σx, luma σy, chroma σx, chroma σy) in pixels of a ``width``-wide stream at ``zoom``: the chain
        and the lens (σ from ``lens_sigma_wide`` at zoom 1 to ``lens_sigma_tele`` at ``tele_zoom``)."""
        frac = min(1.0, max(0.0, (zoom - 1.0) / max(self.tele_zoom - 1.0, 1e-9)))
        lens = (self.lens_sigma_wide + (self.lens_sigma_tele - self.lens_sigma_wide) * frac) * width / self.native_width
        ysx, ysy, csx, csy = self.chain_sigmas(width)
        return math.hypot(ysx, lens), math.hypot(ysy, lens), math.hypot(csx, lens), math.hypot(csy, lens)

    def soften(self, img: U8Array, zoom: float) -> U8Array:
        """The view through the optics and video chain (BGR in, BGR out; ``img`` is not modified)."""
        ysx, ysy, csx, csy = self.sigmas(img.shape[1], zoom)
        if max(ysx, ysy, csx, csy) < 0.2:
            return img
        ycc = cv2.cvtColor(img, cv2.COLOR_BGR2YCrCb)
        y, cr, cb = (np.asarray(c, dtype=np.uint8) for c in cv2.split(ycc))
        y = _blur(y, ysx, ysy)
        cr = _blur(cr, csx, csy)
        cb = _blur(cb, csx, csy)
        out = cv2.cvtColor(cv2.merge([y, cr, cb]), cv2.COLOR_YCrCb2BGR)
        return np.asarray(out, dtype=np.uint8)

    def noise_sigmas(self, width: int) -> tuple[float, float]:
        """(luma, chroma) temporal-noise σ (DN) of a ``width``-wide stream, after the scaler."""
        s = min(1.0, width / self.native_width)
        return self.noise_luma * s, self.noise_chroma * s

    @property
    def noisy(self) -> bool:
        return self.noise_luma > 0 or self.noise_chroma > 0

    def noise_field(self, width: int, height: int) -> tuple[U8Array, U8Array]:
        """A BGR noise field ``_NOISE_MARGIN`` px larger than the frame, as (positive, negative) parts, shaped
        by the video chain (not by the lens: the noise arises behind it)."""
        rng = np.random.default_rng(self.seed + 7919 * width + height)
        H, W = height + _NOISE_MARGIN, width + _NOISE_MARGIN
        sy, sc = self.noise_sigmas(width)
        ysx, ysy, csx, csy = self.chain_sigmas(width)
        planes = []
        for sigma, sx, sy_ in ((sy, ysx, ysy), (sc, csx, csy), (sc, csx, csy)):
            n = rng.standard_normal((H, W), dtype=np.float32)
            if max(sx, sy_) >= 0.2:
                n = np.asarray(cv2.GaussianBlur(n, (0, 0), sigmaX=max(sx, 0.01), sigmaY=max(sy_, 0.01)), np.float32)
                n /= max(float(n.std()), 1e-6)  # σ is the figure after the chain: keep it
            planes.append(n * sigma)
        y, cr, cb = planes
        # YCrCb (JPEG / BT.601 full range) difference → BGR difference
        r = y + 1.402 * cr
        g = y - 0.714136 * cr - 0.344136 * cb
        b = y + 1.772 * cb
        bgr = np.stack([b, g, r], axis=2)
        pos = np.clip(np.rint(bgr), 0, 255).astype(np.uint8)
        neg = np.clip(np.rint(-bgr), 0, 255).astype(np.uint8)
        return pos, neg


def _blur(plane: U8Array, sx: float, sy: float) -> U8Array:
    """Gaussian blur of one 8-bit plane, kernels cut at ±2σ (a single plane with short kernels is ~5× faster
    than OpenCV's default ±3σ on a multi-channel image; the cut-off tails weigh < 5 %)."""
    if max(sx, sy) < 0.2:
        return plane
    kx, ky = 2 * math.ceil(2.0 * sx) + 1, 2 * math.ceil(2.0 * sy) + 1
    out = cv2.GaussianBlur(plane, (kx, ky), sigmaX=max(sx, 0.01), sigmaY=max(sy, 0.01))
    return np.asarray(out, dtype=np.uint8)


def encode(img: U8Array, quality: int) -> bytes:
    """Baseline JPEG at IJG ``quality`` (OpenCV / libjpeg, 4:2:0)."""
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    return bytes(buf)


class _View:
    """One view's soft picture, its noise field and its pool of encoded frames per (compression, overlay)."""

    def __init__(self, soft: U8Array) -> None:
        self.soft = soft
        self.pools: OrderedDict[tuple[int, str], list[bytes]] = OrderedDict()  # at most _POOLS_PER_VIEW
        self.turn: dict[tuple[int, str], int] = {}


class PicturePool:
    """The JPEGs a camera sends while it looks at a view (thread-safe).

    :meth:`jpeg` returns, for one view key and (compression, overlay), a new noisy frame on each of the first
    ``pool_frames`` calls and then cycles through them, so a still camera's consecutive frames differ (in
    content and in size) at the cost of a dictionary look-up. Without noise it returns one cached frame.
    """

    def __init__(self, model: CameraModel, views: int = 8) -> None:
        self.model = model
        self._views: OrderedDict[Hashable, _View] = OrderedDict()
        self._max_views = views
        self._lock = threading.Lock()
        self._rng = np.random.default_rng(model.seed)
        self._noise: dict[tuple[int, int], tuple[U8Array, U8Array]] = {}  # per frame size
        self.encodes = 0  # frames actually encoded

    def jpeg(
        self,
        key: Hashable,
        render: Callable[[], U8Array],
        zoom: float,
        compression: int,
        overlay: str = "",
        draw: Callable[[U8Array, str], None] | None = None,
    ) -> bytes:
        """The next JPEG of view ``key`` (``render()`` gives its ideal picture, called once per view);
        ``draw(img, overlay)`` burns the overlay text in (after the noise: the camera adds it digitally)."""
        m = self.model
        sub = (int(compression), overlay)
        with self._lock:
            view = self._views.get(key)
            if view is not None:
                self._views.move_to_end(key)
                pool = view.pools.get(sub)
                if pool is not None and (len(pool) >= m.pool_frames or not m.noisy):
                    i = view.turn[sub] % len(pool)
                    view.turn[sub] = i + 1
                    return pool[i]
        if view is None:
            view = _View(m.soften(render(), zoom))
        frame = view.soft
        if m.noisy:
            h, w = frame.shape[:2]
            with self._lock:
                noise = self._noise.get((w, h))
                dy, dx = (int(v) for v in self._rng.integers(0, _NOISE_MARGIN, 2))
            if noise is None:
                noise = m.noise_field(w, h)
                with self._lock:
                    self._noise[(w, h)] = noise
            pos, neg = noise
            noisy = cv2.subtract(cv2.add(frame, pos[dy : dy + h, dx : dx + w]), neg[dy : dy + h, dx : dx + w])
            frame = np.asarray(noisy, dtype=np.uint8)
        elif overlay:
            frame = np.array(frame)
        if overlay and draw is not None:
            draw(frame, overlay)
        jpeg = encode(np.asarray(frame, dtype=np.uint8), m.quality(compression, frame.shape[1]))
        with self._lock:
            self.encodes += 1
            current = self._views.setdefault(key, view)
            pool = current.pools.setdefault(sub, [])
            current.pools.move_to_end(sub)
            while len(current.pools) > _POOLS_PER_VIEW:  # e.g. a clock overlay: a new text every second
                old, _ = current.pools.popitem(last=False)
                current.turn.pop(old, None)
            if len(pool) < m.pool_frames:
                pool.append(jpeg)
            current.turn[sub] = current.turn.get(sub, 0) + 1
            self._views.move_to_end(key)
            while len(self._views) > self._max_views:
                self._views.popitem(last=False)
        return jpeg


#: The thesis's Tables 6.2–6.4 (real Axis 214 PTZ, ``axis214PTZ/compressed/compressed``), the values as
#: printed: resolution → compression → (1, 15, 30 fps). Printed as "kBit/s", they are kilobytes per second:
#: see :data:`THESIS_UNIT_BYTES` and the README.
THESIS_TABLES: dict[str, dict[int, tuple[float, float, float]]] = {
    "704x576": {0: (239, 2190, 3440), 30: (118, 1350, 2340), 100: (43, 540, 950)},
    "352x288": {0: (87, 1020, 2040), 30: (43, 530, 820), 100: (8, 104, 180)},
    "176x144": {0: (26, 250, 400), 30: (7, 65, 180), 100: (1.3, 19, 30)},
}
THESIS_FPS = (1, 15, 30)
#: bytes per printed unit: 1000 (kB/s, as ``rostopic bw`` prints). Evidence: Table 6.5's raw 704×576 topic
#: reads 1.22–1.36 at 1 fps, 18.0–18.3 at 15 and 30.2–30.6 at 30 fps "MBit/s", which is 704·576·3 bytes =
#: 1.217 MB per frame × 1.0, 14.9 and 24.9 frames/s in MB/s (in Mbit/s it would be 0.13 frames/s at 1 fps);
#: and 176×144 at compression 100 would be 125–162 bytes per frame in kbit/s, less than a JPEG's own
#: quantisation and Huffman tables (~600 bytes).
THESIS_UNIT_BYTES = 1000.0


def thesis_kbit_s(resolution: str, compression: int, fps: int) -> float:
    """A cell of the thesis's tables in kbit/s (the printed value read as kB/s, × 8)."""
    return THESIS_TABLES[resolution][compression][THESIS_FPS.index(fps)] * THESIS_UNIT_BYTES * 8.0 / 1000.0
