"""What could let the thesis's Figure 6.4 statement and its Tables 6.2–6.4 hold together at 704×576 (issue 22).

Run: ``.venv/bin/python bench/fig64_candidates.py [--quick]`` (several minutes: it traces background panoramas).
Not part of ``./scripts/bench``: an exploration whose figures the README's "What the simulated camera's pictures
are made of" quotes. Nothing here is in the simulator's model.

For each candidate it prints the largest frame of the home view (pan 0, tilt 0, zoom 1, 704×576) that the
measure of ``tests/support/picture.py`` calls "not usable" (SSIM < 0.90 or PSNR < 30 dB against the view
without sensor noise), by a sweep of IJG quality 100…1. The thesis's compression-100 frames are 36–43 kB; every
cell within 0.5× needs at least 21.5 kB (the 1-fps cell; 18–19 kB at 15 and 30 fps). Candidates: the camera
chain (sharper, noisier, aperture correction, an interlace field offset, 4:2:2 chroma) on the demo scene, and a
busier scene (:class:`DetailedScene`: fBm texture on the ground, textured facades and a tree belt on the
skyline, a forested hill behind it) traced at a finer panorama. Sensor noise: the model's noise field at offset
(0, 0), added after the chain (and after the candidate's processing), as the simulator adds it.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests.support

from axis_ptz_ros2.geometry import Transform  # noqa: E402
from axis_ptz_ros2.sim.camera_model import CameraModel
from axis_ptz_ros2.sim.persona import AXIS_214_PICTURE
from axis_ptz_ros2.sim.renderer import PtzRenderer
from axis_ptz_ros2.sim.scene import SKYLINE_RADIUS, Scene, _hash01
from axis_ptz_ros2.sim.world import SimWorld, load_world
from tests.support.picture import USABLE_PSNR_DB, USABLE_SSIM, luma, ssim

W, H = 704, 576


def _vnoise(u: np.ndarray, v: np.ndarray, seed: int) -> np.ndarray:
    """Bilinear value noise on the integer lattice (cell values from the scene's hash)."""
    iu, iv = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
    fu, fv = u - iu, v - iv
    n00, n10 = _hash01(iu, iv, seed), _hash01(iu + 1, iv, seed)
    n01, n11 = _hash01(iu, iv + 1, seed), _hash01(iu + 1, iv + 1, seed)
    return np.asarray((n00 * (1 - fu) + n10 * fu) * (1 - fv) + (n01 * (1 - fu) + n11 * fu) * fv)


class DetailedScene(Scene):
    """The demo scene with more fine detail (each addition optional; traced without the disk cache)."""

    HILL_DEG = 16.0  # the forested hill's highest elevation

    def __init__(self, world: SimWorld, ground: bool, skyline: bool, hill: bool) -> None:
        super().__init__(world)
        self.ground, self.skyline, self.hill = ground, skyline, hill
        if hill:  # rows up to the hill are traced per pixel, not one sky colour per row
            self._max_skyline_el = max(self._max_skyline_el, math.radians(self.HILL_DEG) + 0.01)

    @property
    def background_equirect(self) -> np.ndarray:  # type: ignore[override]
        if not hasattr(self, "_bg_detail"):
            centre = Transform(np.eye(3), self.world.pan_tilt_centre)  # as Scene.background_equirect
            self._bg_detail = self.render_equirect(centre, self.world.equirect_width, None, False)
        return self._bg_detail

    def sky_color(self, dirs: np.ndarray) -> np.ndarray:  # type: ignore[override]
        col = Scene.sky_color(dirs)
        if not self.hill:
            return col
        el = np.arcsin(np.clip(dirs[:, 2], -1.0, 1.0))
        a = np.arctan2(dirs[:, 1], dirs[:, 0]) * 1000.0  # mrad
        z0 = np.zeros_like(a)
        prof = math.radians(self.HILL_DEG) * (0.55 + 0.3 * _vnoise(a / 90.0, z0, 70) + 0.15 * _vnoise(a / 20.0, z0, 71))
        prof += 0.006 * (_vnoise(a / 3.0, z0, 72) - 0.5) + 0.003 * (_vnoise(a / 1.2, z0, 73) - 0.5)
        e = el * 1000.0
        leaf = (
            0.45 * _vnoise(a / 1.0, e / 1.0, 60)
            + 0.3 * _vnoise(a / 2.3, e / 2.3, 61)
            + 0.25 * _vnoise(a / 6.0, e / 6.0, 62)
        )
        g = np.clip(0.25 + (leaf - 0.35) * 2.2, 0.12, 1.6)
        foliage = np.stack([45 * g, 95 * g, 70 * g], -1)
        on_hill = (el < prof) & (el > -0.05)
        return np.asarray(np.where(on_hill[:, None], foliage, col))

    def _skyline(self, origins: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s, col = super()._skyline(origins, dirs)
        if not self.skyline:
            return s, col
        P = origins + dirs * np.where(np.isfinite(s), s, 0.0)[:, None]
        arc = np.arctan2(P[:, 1], P[:, 0]) * SKYLINE_RADIUS
        z = P[:, 2]
        fac = sum(
            a * (_vnoise(arc / c, z / c, 40 + k) - 0.5) * 2
            for k, (c, a) in enumerate(((0.6, 0.25), (1.2, 0.175), (2.5, 0.125)))
        )
        col = col * (1 + fac)[:, None]
        z0 = np.zeros_like(arc)
        crown = 18.0 * (
            0.45 + 0.55 * (0.5 * (_vnoise(arc / 6.0, z0, 50) - 0.5) + 0.5 * (_vnoise(arc / 15.0, z0, 51) - 0.5)) + 0.3
        )
        leaf = (
            0.5 * _vnoise(arc / 0.7, z / 0.7, 60)
            + 0.3 * _vnoise(arc / 0.35, z / 0.35, 61)
            + 0.2 * _vnoise(arc / 1.6, z / 1.6, 62)
        )
        g = 0.35 + 1.1 * leaf
        tree = (z < crown) & (z >= -1.0)
        return s, np.asarray(np.where(tree[:, None], np.stack([50 * g, 95 * g, 70 * g], -1), col))

    def ground_color(self, P: np.ndarray, footprint: np.ndarray) -> np.ndarray:
        col = super().ground_color(P, footprint)
        if not self.ground:
            return col
        x, y = P[:, 0], P[:, 1]
        g = np.zeros_like(x)
        for k, (c, a) in enumerate(((0.015, 0.15), (0.03, 0.15), (0.06, 0.12), (0.12, 0.09), (0.25, 0.075))):
            fade = np.clip(c / np.maximum(footprint, 1e-6) - 1.0, 0.0, 1.0)  # no texture finer than the pixel
            g += a * (_vnoise(x / c, y / c, 101 + k) - 0.5) * 2 * fade
        far = np.clip((np.hypot(x, y) - 60.0) / 200.0, 0.0, 1.0)
        return np.asarray(col * (1 + g * (1 - far))[:, None])


def _aperture(img: np.ndarray, gain: float) -> np.ndarray:
    """Aperture correction: luma + (gain − 1)·(luma − Gaussian σ 1 px of it)."""
    ycc = cv2.cvtColor(img, cv2.COLOR_BGR2YCrCb).astype(np.float32)
    y = ycc[:, :, 0]
    ycc[:, :, 0] = y + (gain - 1.0) * (y - cv2.GaussianBlur(y, (0, 0), 1.0))
    return np.asarray(cv2.cvtColor(np.clip(ycc + 0.5, 0, 255).astype(np.uint8), cv2.COLOR_YCrCb2BGR))


def _field_offset(img: np.ndarray, dn: int) -> np.ndarray:
    out = img.astype(np.int16)
    out[1::2] += dn
    return np.clip(out, 0, 255).astype(np.uint8)


def headroom(view: np.ndarray, model: CameraModel, extra=None, sampling: int | None = None) -> str:  # type: ignore[no-untyped-def]
    """The largest not-usable frame of ``view`` through ``model`` (and ``extra`` after the chain)."""
    soft = model.soften(view, 1.0)
    if extra is not None:
        soft = extra(soft)
    ref = luma(soft)
    pos, neg = model.noise_field(W, H)
    noisy = cv2.subtract(cv2.add(soft, pos[:H, :W]), neg[:H, :W])
    for q in range(100, 0, -1):
        params = [cv2.IMWRITE_JPEG_QUALITY, q]
        if sampling is not None:
            params += [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, sampling]
        _ok, buf = cv2.imencode(".jpg", noisy, params)
        y = luma(cv2.imdecode(buf, cv2.IMREAD_COLOR))
        p, s = float(cv2.PSNR(ref, y)), ssim(ref, y)
        if p < USABLE_PSNR_DB or s < USABLE_SSIM:
            return f"quality {q:3d}: {len(buf) / 1000:5.1f} kB ({p:4.1f} dB, SSIM {s:.3f})"
    return "every quality usable"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the camera-chain candidates only (no panorama traces)")
    ap.add_argument("--scene-only", action="store_true", help="the scene candidates only")
    a = ap.parse_args()
    m = AXIS_214_PICTURE
    world = load_world()
    view = PtzRenderer(world).render(0.0, 0.0, 1.0, W, H)
    rows: list[tuple[str, str]] = (
        []
        if a.scene_only
        else [
            ("the model as it is", headroom(view, m)),
            ("noise 1 DN luma", headroom(view, dataclasses.replace(m, noise_luma=1.0))),
            ("noise 4 DN luma", headroom(view, dataclasses.replace(m, noise_luma=4.0))),
            (
                "sharpest chain (no band limit, no lens, Kell 1)",
                headroom(view, dataclasses.replace(m, luma_bandwidth_mhz=0.0, lens_sigma_wide=0.0, kell_factor=1.0)),
            ),
            ("aperture correction gain 2", headroom(view, m, lambda i: _aperture(i, 2.0))),
            ("aperture correction gain 3", headroom(view, m, lambda i: _aperture(i, 3.0))),
            ("field offset 2 DN", headroom(view, m, lambda i: _field_offset(i, 2))),
            ("field offset 4 DN", headroom(view, m, lambda i: _field_offset(i, 4))),
            ("4:2:2 chroma", headroom(view, m, sampling=cv2.IMWRITE_JPEG_SAMPLING_FACTOR_422)),
        ]
    )
    for name, text in rows:
        print(f"{name:<60} {text}", flush=True)
    if a.quick:
        return 0
    for label, eq, flags in (
        ("scene: ground fBm + facades + tree belt, 4096 panorama", 4096, (True, True, False)),
        ("scene: forested hill, 6144 panorama", 6144, (False, False, True)),
        ("scene: all three, 6144 panorama", 6144, (True, True, True)),
    ):
        w = dataclasses.replace(world, equirect_width=eq)
        t0 = time.monotonic()
        scene = DetailedScene(w, *flags)
        _ = scene.background_equirect
        trace = time.monotonic() - t0
        v = PtzRenderer(w, scene).render(0.0, 0.0, 1.0, W, H)
        print(f"{label:<60} {headroom(v, m)}  (trace {trace:.0f} s)", flush=True)
        if all(flags):
            print(f"{label + ' + aperture gain 2':<60} {headroom(v, m, lambda i: _aperture(i, 2.0))}", flush=True)
            cv2.imwrite("/tmp/fig64_detailed_scene.png", v)
    return 0


if __name__ == "__main__":
    sys.exit(main())
