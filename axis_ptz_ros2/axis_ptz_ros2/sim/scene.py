"""The procedural 3-D scene the simulated cameras and the laser see (ROS-free).

Frames: everything is expressed in ``base_link`` (REP-103, x forward, y left, z up, metres); the ground is the
plane z = 0. The scene is built from a :class:`~axis_ptz_ros2.sim.world.SimWorld`: a procedural background (sky
gradient, a distant skyline on a cylinder of radius :data:`SKYLINE_RADIUS`, a textured ground plane with a
distance grid and coloured marks) plus planar rectangular :class:`Target` s with high-resolution textures at known
poses. :meth:`Scene.raycast` is the one vectorised ray tracer used for the background panorama of the PTZ
renderer, the omnidirectional camera and the laser scanner.
"""

from __future__ import annotations

import hashlib
import math
import os
from functools import cached_property
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from axis_ptz_ros2.geometry import equirect_to_direction
from axis_ptz_ros2.sim import textures
from axis_ptz_ros2.sim.world import PtzLimits as PtzLimits  # re-exported: persona.py imports it from here
from axis_ptz_ros2.sim.world import SimWorld as SimWorld  # re-exported: camera.py, frames.py
from axis_ptz_ros2.sim.world import TargetSpec, target_frame
from axis_ptz_ros2.sim.world import load_world as load_world  # re-exported: camera.py
from axis_ptz_ros2.transforms import FloatArray, Transform

U8Array = npt.NDArray[np.uint8]
IntArray = npt.NDArray[np.int64]

HIT_SKY = -1  #: ``hit_index`` of a ray that escapes to the sky (depth = inf)
HIT_GROUND = -2  #: ``hit_index`` of a ray that hits the ground plane
HIT_SKYLINE = -3  #: ``hit_index`` of a ray that hits the distant skyline
SKYLINE_RADIUS = 400.0  #: metres from the base_link origin
BACKGROUND_VERSION = 3  #: bump when the procedural background changes (invalidates the disk cache)


# --------------------------------------------------------------------------------------------------------
# Targets
# --------------------------------------------------------------------------------------------------------
def _unit(v: npt.ArrayLike) -> FloatArray:
    a = np.asarray(v, dtype=np.float64)
    return np.asarray(a / np.linalg.norm(a), dtype=np.float64)


class Target:
    """A planar rectangular target with a texture. Texture column direction = ``right``, rows = −``up``."""

    def __init__(self, spec: TargetSpec, facing_point: FloatArray) -> None:
        self.spec = spec
        self.name = spec.name
        self.center = np.asarray(spec.center, dtype=np.float64)
        self.width, self.height = spec.size
        normal = None if spec.normal is None else np.asarray(spec.normal, dtype=np.float64)
        n, right, _ = target_frame(self.center, normal, np.asarray(spec.up, dtype=np.float64), facing_point)
        self.normal = n
        self.right = right
        self.up = _unit(np.cross(n, self.right))
        tex, feats = self._build_texture()
        self.texture: U8Array = tex
        self._features_uv = feats
        self._mips: list[U8Array] = [tex]

    def _build_texture(self) -> tuple[U8Array, textures.Features]:
        s, (w, h) = self.spec, self.spec.size
        if s.kind == "plate":
            return textures.plate_texture(w, h, s.text or "ABC 1234")
        if s.kind == "hazard":
            return textures.hazard_texture(w, h, s.text or "1203")
        if s.kind == "person":
            return textures.person_texture(w, h)
        if s.kind == "marker":
            return textures.marker_texture(w, h, s.color)
        if s.kind == "calib":
            return textures.calib_texture(w, h, s.name)
        if s.kind == "checker":
            return textures.checker_texture(w, h)
        if s.kind == "facade":
            return textures.facade_texture(w, h, s.text)
        if s.kind == "image":  # a PNG/JPEG file (checked when the world was loaded)
            return textures.image_texture(s.file)
        raise ValueError(f"unknown target kind {s.kind!r} for target {s.name!r}")

    @property
    def top_left(self) -> FloatArray:
        """Outer top-left corner (base_link)."""
        return np.asarray(self.center - self.right * self.width / 2 + self.up * self.height / 2, np.float64)

    def uv_to_point(self, fu: npt.ArrayLike, fv: npt.ArrayLike) -> FloatArray:
        """Texture fractions (0…1 across, 0…1 down) → 3-D points in base_link."""
        a = np.asarray(fu, dtype=np.float64)[..., None]
        b = np.asarray(fv, dtype=np.float64)[..., None]
        return np.asarray(self.top_left + a * self.width * self.right - b * self.height * self.up, np.float64)

    def corners(self) -> FloatArray:
        """4×3 outer corners in base_link: top-left, top-right, bottom-right, bottom-left."""
        return self.uv_to_point([0.0, 1.0, 1.0, 0.0], [0.0, 0.0, 1.0, 1.0])

    def features(self) -> dict[str, FloatArray]:
        """Named 3-D points (base_link): texture features plus the corners ``corner_tl`` … ``corner_bl``."""
        out = {k: self.uv_to_point(u, v) for k, (u, v) in self._features_uv.items()}
        for k, c in zip(("corner_tl", "corner_tr", "corner_br", "corner_bl"), self.corners(), strict=True):
            out[k] = c
        return out

    def mip(self, level: int) -> U8Array:
        """Texture at mip ``level`` (0 = full resolution), built lazily with ``cv2.pyrDown``."""
        while len(self._mips) <= level:
            prev = self._mips[-1]
            if min(prev.shape[:2]) < 4:
                return prev
            self._mips.append(np.asarray(cv2.pyrDown(prev), dtype=np.uint8))
        return self._mips[level]

    def texel_step(self, level: int) -> tuple[FloatArray, FloatArray]:
        """3-D step per texel along columns and rows at mip ``level``."""
        tex = self.mip(level)
        h, w = tex.shape[:2]
        return self.right * (self.width / w), -self.up * (self.height / h)

    def intersect(self, origins: FloatArray, dirs: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Ray/rectangle intersection: (distance along dir (inf if none), u fraction, v fraction)."""
        denom = dirs @ self.normal
        with np.errstate(divide="ignore", invalid="ignore"):
            s = ((self.center - origins) @ self.normal) / denom
        s = np.where((np.abs(denom) > 1e-12) & (s > 1e-9), s, np.inf)
        finite = np.isfinite(s)
        P = origins + dirs * np.where(finite, s, 0.0)[:, None]
        rel = P - self.top_left
        fu = (rel @ self.right) / self.width
        fv = -(rel @ self.up) / self.height
        inside = finite & (fu >= 0) & (fu < 1) & (fv >= 0) & (fv < 1)
        s = np.where(inside, s, np.inf)
        if inside.any():  # transparent texels (cut-out silhouettes) do not stop the ray
            h, w = self.texture.shape[:2]
            cols = np.clip((fu[inside] * w).astype(np.int64), 0, w - 1)
            rows = np.clip((fv[inside] * h).astype(np.int64), 0, h - 1)
            alpha = self.texture[rows, cols, 3]
            idx = np.flatnonzero(inside)
            s[idx[alpha < 128]] = np.inf
        return s, fu, fv


# --------------------------------------------------------------------------------------------------------
# Procedural background
# --------------------------------------------------------------------------------------------------------
def _hash01(ix: npt.NDArray[np.int64], iy: npt.NDArray[np.int64], seed: int) -> FloatArray:
    """A cheap deterministic per-cell pseudo-random number in [0, 1)."""
    h = (ix * 73856093) ^ (iy * 19349663) ^ (seed * 83492791)
    h = (h ^ (h >> 13)) * 1274126177
    h = h ^ (h >> 16)
    return np.asarray((h & 0xFFFF).astype(np.float64) / 65536.0, dtype=np.float64)


def _line_coverage(coord: FloatArray, spacing: float, width: float, footprint: FloatArray) -> FloatArray:
    """Box-filtered coverage of periodic lines (``width`` wide every ``spacing``) by a pixel footprint."""
    d = np.abs(coord - spacing * np.round(coord / spacing))
    f = np.maximum(footprint, 1e-6)
    lo = np.maximum(d - f / 2, -width / 2)
    hi = np.minimum(d + f / 2, width / 2)
    return np.asarray(np.clip((hi - lo) / f, 0.0, 1.0), dtype=np.float64)


class Scene:
    """The procedural world: background plus textured planar targets, all in ``base_link``."""

    def __init__(self, world: SimWorld | None = None) -> None:
        self.world = world if world is not None else load_world()
        centre = self.world.pan_tilt_centre
        self.targets: list[Target] = [Target(spec, centre) for spec in self.world.targets]
        rng = np.random.default_rng(214)
        # Skyline: buildings on a cylinder, as (start azimuth, height m, shade) sorted by azimuth.
        n = 140
        widths = rng.uniform(0.5, 4.0, n)
        starts = np.cumsum(widths)
        starts = starts / starts[-1] * 2 * math.pi - math.pi
        self._sky_starts = np.concatenate([[-math.pi], starts[:-1]])
        self._sky_heights = rng.uniform(8.0, 60.0, n) * (rng.uniform(0, 1, n) > 0.12)
        self._sky_shade = rng.uniform(0.55, 1.0, n)
        self._max_skyline_el = math.atan2(float(self._sky_heights.max()) + 1.0, SKYLINE_RADIUS - 5.0)

    # ---- background colours -------------------------------------------------------------------------
    @staticmethod
    def sky_color(dirs: FloatArray) -> FloatArray:
        """Sky gradient (BGR float 0…255) for unit directions."""
        el = np.arcsin(np.clip(dirs[:, 2], -1.0, 1.0))
        t = np.clip(el / (math.pi / 2), 0.0, 1.0)[:, None] ** 0.6
        horizon = np.array([235.0, 215.0, 190.0])
        zenith = np.array([170.0, 95.0, 35.0])
        return np.asarray(horizon * (1 - t) + zenith * t, dtype=np.float64)

    def _skyline(self, origins: FloatArray, dirs: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Distance to the skyline cylinder and building colour (inf where the ray passes above)."""
        ox, oy, dx, dy = origins[:, 0], origins[:, 1], dirs[:, 0], dirs[:, 1]
        a = dx * dx + dy * dy
        b = 2 * (ox * dx + oy * dy)
        c = ox * ox + oy * oy - SKYLINE_RADIUS**2
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (-b + np.sqrt(np.maximum(b * b - 4 * a * c, 0.0))) / (2 * a)
        s = np.where(a > 1e-12, s, np.inf)
        P = origins + dirs * np.where(np.isfinite(s), s, 0.0)[:, None]
        az = np.arctan2(P[:, 1], P[:, 0])
        idx = np.clip(np.searchsorted(self._sky_starts, az, side="right") - 1, 0, len(self._sky_starts) - 1)
        height = self._sky_heights[idx]
        hit = np.isfinite(s) & (P[:, 2] < height) & (P[:, 2] >= -1.0)
        shade = self._sky_shade[idx]
        base = np.stack([95 * shade, 90 * shade, 85 * shade], -1)
        # Windows: a grid in (arc length, height); lit or dark per window.
        arc = az * SKYLINE_RADIUS
        win = (np.mod(arc, 3.0) > 1.2) & (np.mod(P[:, 2], 3.5) > 1.4) & (P[:, 2] < height - 1.5)
        lit = _hash01(np.floor(arc / 3.0).astype(np.int64), np.floor(P[:, 2] / 3.5).astype(np.int64), 7) > 0.6
        col = np.where((win & lit)[:, None], np.array([120.0, 210.0, 235.0]), np.where(win[:, None], base * 0.6, base))
        return np.where(hit, s, np.inf), col

    def ground_color(self, P: FloatArray, footprint: FloatArray) -> FloatArray:
        """Ground texture at points ``P`` (z = 0) for a pixel footprint (m), anti-aliased (BGR float)."""
        x, y = P[:, 0], P[:, 1]
        ix, iy = np.floor(x / 0.5).astype(np.int64), np.floor(y / 0.5).astype(np.int64)
        tile = ((ix + iy) % 2).astype(np.float64)
        # Paving: 0.25 m setts, each its own shade, 1.5 cm joints; a grain of 5 cm cells inside each sett.
        sx, sy = np.floor(x / 0.25).astype(np.int64), np.floor(y / 0.25).astype(np.int64)
        sett = _hash01(sx, sy, 4)
        joint = np.maximum(_line_coverage(x, 0.25, 0.015, footprint), _line_coverage(y, 0.25, 0.015, footprint))
        noise = _hash01(np.floor(x / 0.05).astype(np.int64), np.floor(y / 0.05).astype(np.int64), 3)
        fine = np.clip(0.05 / footprint, 0.0, 1.0)  # fade sub-pixel noise instead of aliasing it
        setts = np.clip(0.25 / footprint, 0.0, 1.0)
        lum = 1.0 + (0.06 * tile + 0.36 * (sett - 0.5) * setts + 0.36 * (noise - 0.5) * fine) - 0.4 * joint
        col = np.array([105.0, 118.0, 110.0])[None, :] * lum[:, None]
        grid1 = np.maximum(
            _line_coverage(x - 0.5, 1.0, 0.015, footprint), _line_coverage(y - 0.5, 1.0, 0.015, footprint)
        )
        grid5 = np.maximum(_line_coverage(x - 2.5, 5.0, 0.05, footprint), _line_coverage(y - 2.5, 5.0, 0.05, footprint))
        col = col * (1 - 0.5 * grid1[:, None]) + np.array([200.0, 200.0, 200.0]) * 0.5 * grid1[:, None]
        col = col * (1 - grid5[:, None]) + np.array([235.0, 235.0, 235.0]) * grid5[:, None]
        r = np.hypot(x, y)
        for radius, ring_col in (
            (5.0, (0.0, 0.0, 220.0)),
            (10.0, (0.0, 200.0, 230.0)),
            (20.0, (220.0, 80.0, 0.0)),
        ):
            cov = _line_coverage(r - radius, 1000.0, 0.12, footprint)
            col = col * (1 - cov[:, None]) + np.array(ring_col) * cov[:, None]
        # Coloured marks painted on the ground: at most one square per 4 m cell, hashed from the cell.
        cx, cy = np.floor(x / 4.0).astype(np.int64), np.floor(y / 4.0).astype(np.int64)
        has = _hash01(cx, cy, 11) > 0.8
        if has.any():
            half = 0.15 + 0.45 * _hash01(cx, cy, 12)
            mx = (cx + 0.2 + 0.6 * _hash01(cx, cy, 13)) * 4.0
            my = (cy + 0.2 + 0.6 * _hash01(cx, cy, 14)) * 4.0
            inside = has & (np.abs(x - mx) < half) & (np.abs(y - my) < half) & (r < 60.0)
            if inside.any():
                mark = np.stack([_hash01(cx, cy, 15 + k)[inside] for k in range(3)], -1) * 215 + 40
                col[inside] = mark
        # Far away the ground fades to its mean colour (the grid is no longer resolvable).
        far = np.clip((r - 60.0) / 200.0, 0.0, 1.0)[:, None]
        return np.asarray(col * (1 - far) + np.array([110.0, 122.0, 114.0]) * far, dtype=np.float64)

    # ---- ray tracing --------------------------------------------------------------------------------
    def raycast(
        self,
        origins: npt.ArrayLike,
        dirs: npt.ArrayLike,
        include_targets: bool = True,
        pixel_angle: float = 1e-3,
    ) -> tuple[U8Array, FloatArray, IntArray]:
        """Trace rays: returns (BGR uint8 N×3, depth N (distance along the unit direction, inf for sky),
        hit index N: target index ≥ 0, or :data:`HIT_GROUND`, :data:`HIT_SKYLINE`, :data:`HIT_SKY`).

        ``origins`` (3,) or (N, 3), ``dirs`` (N, 3) in base_link; ``pixel_angle`` (rad) sets the
        anti-aliasing footprint of the ground texture.
        """
        D = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
        D = D / np.linalg.norm(D, axis=1, keepdims=True)
        O = np.broadcast_to(np.asarray(origins, dtype=np.float64), D.shape)
        n = D.shape[0]
        depth = np.full(n, np.inf)
        index = np.full(n, HIT_SKY, dtype=np.int64)
        color = self.sky_color(D)
        # Skyline (a cylinder far away): only rays below its highest roof can hit it.
        low = np.flatnonzero(D[:, 2] < math.sin(self._max_skyline_el))
        if low.size:
            sk, sky_col = self._skyline(O[low], D[low])
            k = np.isfinite(sk)
            color[low[k]], depth[low[k]], index[low[k]] = sky_col[k], sk[k], HIT_SKYLINE
        # Ground plane z = 0 (in front of the skyline where nearer).
        down = np.flatnonzero((D[:, 2] < -1e-9) & (O[:, 2] > 0))
        if down.size:
            sg = -O[down, 2] / D[down, 2]
            g = sg < depth[down]
            idx, sg = down[g], sg[g]
            P = O[idx] + D[idx] * sg[:, None]
            foot = sg * pixel_angle / np.sqrt(np.maximum(-D[idx, 2], 0.02))
            color[idx] = self.ground_color(P, foot)
            depth[idx], index[idx] = sg, HIT_GROUND
        if include_targets:
            for ti, tgt in enumerate(self.targets):
                # Cull with the target's bounding cone seen from the (first) origin.
                rel = tgt.center - O[0]
                dist = float(np.linalg.norm(rel))
                radius = math.hypot(tgt.width, tgt.height) / 2 + float(np.ptp(O, axis=0).max() if n > 1 else 0.0)
                cand = (
                    np.arange(n)
                    if dist <= radius
                    else np.flatnonzero(D @ (rel / dist) > math.cos(math.asin(radius / dist)))
                )
                if cand.size == 0:
                    continue
                s, fu, fv = tgt.intersect(O[cand], D[cand])
                closer = s < depth[cand]
                if not closer.any():
                    continue
                idx = cand[closer]
                h, w = tgt.texture.shape[:2]
                cols = np.clip((fu[closer] * w).astype(np.int64), 0, w - 1)
                rows = np.clip((fv[closer] * h).astype(np.int64), 0, h - 1)
                texel = tgt.texture[rows, cols].astype(np.float64)
                a = texel[:, 3:4] / 255.0
                color[idx] = color[idx] * (1 - a) + texel[:, :3]
                depth[idx], index[idx] = s[closer], ti
        return np.clip(color + 0.5, 0, 255).astype(np.uint8), depth, index

    def render_equirect(
        self,
        T_base_pano: Transform,
        width: int,
        height: int | None = None,
        include_targets: bool = True,
        chunk_rows: int = 256,
    ) -> U8Array:
        """Equirectangular BGR image (column 0 at azimuth +π, row 0 at elevation +π/2) seen from the
        panorama frame ``T_base_pano`` (its own orientation; geometry-and-calibration.md §3)."""
        H = height if height is not None else width // 2
        out = np.empty((H, width, 3), np.uint8)
        xs = np.arange(width, dtype=np.float64)
        pix = 2 * math.pi / width
        identity = bool(np.allclose(T_base_pano.R, np.eye(3)))
        r_start = 0
        if identity and not include_targets:
            # Rows entirely above the skyline (and every target) are pure sky: one colour per row.
            els = math.pi / 2 - math.pi * (np.arange(H) + 0.5) / H
            r_start = int(np.searchsorted(-els, -(self._max_skyline_el + 2 * math.pi / width)))
            d0 = equirect_to_direction(np.zeros(r_start), np.arange(r_start, dtype=np.float64), width, H)
            out[:r_start] = np.clip(self.sky_color(d0.reshape(-1, 3)) + 0.5, 0, 255).astype(np.uint8)[:, None, :]
        for r0 in range(r_start, H, chunk_rows):
            r1 = min(H, r0 + chunk_rows)
            xx, yy = np.meshgrid(xs, np.arange(r0, r1, dtype=np.float64))
            d = equirect_to_direction(xx, yy, width, H).reshape(-1, 3)
            if not identity:
                d = np.einsum("ij,nj->ni", T_base_pano.R, d)
            bgr, _, _ = self.raycast(T_base_pano.t, d, include_targets=include_targets, pixel_angle=pix)
            out[r0:r1] = bgr.reshape(r1 - r0, width, 3)
        return out

    @cached_property
    def background_equirect(self) -> U8Array:
        """Target-free background panorama from the pan/tilt centre (base_link orientation).

        Costs a few seconds to trace, so it is cached on disk (``$AXIS_SIM_CACHE_DIR``, default
        ``~/.cache/axis_ptz_ros2``) keyed by the world geometry and :data:`BACKGROUND_VERSION`.
        """
        T = Transform(np.eye(3), self.world.pan_tilt_centre)
        key = hashlib.sha1(repr((BACKGROUND_VERSION, np.round(T.t, 6).tolist(), self.world.equirect_width)).encode())
        cache_dir = Path(os.environ.get("AXIS_SIM_CACHE_DIR", Path.home() / ".cache" / "axis_ptz_ros2"))
        path = cache_dir / f"sim_background_{key.hexdigest()[:16]}.npy"
        try:
            img = np.load(path)
            if img.shape == (self.world.equirect_width // 2, self.world.equirect_width, 3) and img.dtype == np.uint8:
                return np.asarray(img, dtype=np.uint8)
        except (OSError, ValueError):
            pass
        img = self.render_equirect(T, self.world.equirect_width, include_targets=False)
        try:
            cache_dir.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(f".{os.getpid()}.tmp.npy")
            np.save(tmp, img)
            os.replace(tmp, path)
        except OSError:
            pass
        return img

    def target(self, name: str) -> Target:
        """The target called ``name``."""
        for t in self.targets:
            if t.name == name:
                return t
        raise KeyError(name)


_SCENES: dict[tuple[Any, ...], Scene] = {}


def shared_scene(world: SimWorld) -> Scene:
    """A process-wide cached :class:`Scene` for ``world`` (building textures and the background is costly)."""
    key = world.cache_key()
    scene = _SCENES.get(key)
    if scene is None:
        scene = Scene(world)
        _SCENES[key] = scene
    return scene
