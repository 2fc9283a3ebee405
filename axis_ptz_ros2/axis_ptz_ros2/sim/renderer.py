"""Renders what the simulated Axis 214 sees at a VAPIX pose and zoom (ROS-free, numpy + OpenCV).

Optics: the world's zoom model (``config/sim_world.yaml``, else the camera-model file's) gives the pinhole
intrinsics of the requested stream size (PAL 704×576: ``fy = fx·12/11``). Pose: the world's *true* mount
``T_base_ptz`` ∘ :meth:`PtzKinematics.optical_in_ptz_base`. Fast path (geometry-and-calibration.md §5):

* background: the precomputed target-free equirectangular panorama of :class:`Scene` (traced from the
  pan/tilt centre), sampled with ``cv2.remap``. Ground pixels are looked up through the ground point they see
  from the *true* optical centre, so the background has no parallax error; maps are computed on an 8-px grid
  and upsampled exactly (the mapping is smooth);
* targets: composited exactly with the plane-induced homography of each target (``cv2.warpPerspective`` of
  the mip level that matches the on-screen scale, premultiplied alpha), far to near.

Rendered views are cached per (pose, zoom, size). The picture is ideal (sharp, noise-free): what a camera makes
of it (softness, sensor noise, JPEG quality) is ``sim/camera_model.py``.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict

import cv2
import numpy as np
import numpy.typing as npt

from axis_ptz_ros2.optics import Intrinsics
from axis_ptz_ros2.sim.camera_model import CameraModel, encode
from axis_ptz_ros2.sim.ptz import vapix_to_ros
from axis_ptz_ros2.sim.scene import Scene, Target, shared_scene
from axis_ptz_ros2.sim.world import SimWorld
from axis_ptz_ros2.transforms import FloatArray, Transform

U8Array = npt.NDArray[np.uint8]
_GRID = 8  # map sub-sampling step (px)
_NEAR = 0.02  # near clipping distance (m)


class PtzRenderer:
    """Thread-safe renderer of the simulated PTZ view."""

    def __init__(self, world: SimWorld, scene: Scene | None = None, cache_size: int = 8) -> None:
        self.world = world
        self.scene = scene if scene is not None else shared_scene(world)
        self._bg = self.scene.background_equirect
        self._bg_centre = world.pan_tilt_centre
        self._cache: OrderedDict[tuple[float, float, float, int, int], U8Array] = OrderedDict()
        self._cache_size = cache_size
        self._lock = threading.Lock()
        self.renders = 0  # number of views actually rendered (cache misses)

    def intrinsics(self, zoom: float, width: int, height: int) -> Intrinsics:
        """Intrinsics of a ``width``×``height`` stream at ``zoom`` units."""
        return self.world.zoom_model.intrinsics(zoom, width, height)

    def camera_pose(self, pan_deg: float, tilt_deg: float) -> Transform:
        """``T_base_opt``: the true optical frame in base_link at a VAPIX pan/tilt."""
        pan, tilt = vapix_to_ros(pan_deg, tilt_deg)
        return self.world.T_base_ptz @ self.world.kinematics.optical_in_ptz_base(pan, tilt)

    def render(self, pan_deg: float, tilt_deg: float, zoom: float, width: int, height: int) -> U8Array:
        """BGR image (read-only, shared: copy before drawing on it) of the view at a VAPIX pose."""
        key = (round(pan_deg, 5), round(tilt_deg, 5), round(zoom, 3), width, height)
        with self._lock:
            img = self._cache.get(key)
            if img is not None:
                self._cache.move_to_end(key)
                return img
        img = self._render(pan_deg, tilt_deg, zoom, width, height)
        img.setflags(write=False)
        with self._lock:
            self.renders += 1
            self._cache[key] = img
            while len(self._cache) > self._cache_size:
                self._cache.popitem(last=False)
        return img

    # ---- implementation ------------------------------------------------------------------------------
    def _render(self, pan_deg: float, tilt_deg: float, zoom: float, width: int, height: int) -> U8Array:
        K = self.intrinsics(zoom, width, height)
        T = self.camera_pose(pan_deg, tilt_deg)
        img = self._background(T, K)
        T_opt_base = T.inverse()
        order = sorted(self.scene.targets, key=lambda t: -float(np.linalg.norm(t.center - T.t)))
        for tgt in order:
            self._composite(img, tgt, T_opt_base, K)
        return img

    def _background(self, T: Transform, K: Intrinsics) -> U8Array:
        W, H = K.width, K.height
        g = _GRID
        # Grid sample points u = (k + 0.5)·g − 0.5 for k = −1 … n (one extra each side): an INTER_LINEAR
        # resize by g then maps output pixel j to u = j − g exactly (see the module docstring).
        nu, nv = -(-W // g) + 2, -(-H // g) + 2
        u = (np.arange(nu) - 1 + 0.5) * g - 0.5
        v = (np.arange(nv) - 1 + 0.5) * g - 0.5
        uu, vv = np.meshgrid(u, v)
        rays = K.ray(uu, vv).reshape(-1, 3) @ T.R.T  # directions in base_link
        o = T.t
        c = self._bg_centre
        d = rays
        down = d[:, 2] < -1e-9
        if o[2] > 0 and down.any():
            s = -o[2] / d[down, 2]
            d = d.copy()
            d[down] = (o - c)[None, :] + d[down] * s[:, None]  # from the panorama centre to the ground point
        Weq = self._bg.shape[1]
        Heq = self._bg.shape[0]
        az = np.arctan2(d[:, 1], d[:, 0])
        az_c = math.atan2(float(T.R[1, 2]), float(T.R[0, 2]))  # azimuth of the optical axis
        az = az_c + np.remainder(az - az_c + math.pi, 2 * math.pi) - math.pi  # unwrapped around the view
        el = np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1]))
        mx = ((0.5 - az / (2 * math.pi)) * Weq - 0.5).astype(np.float32).reshape(nv, nu)
        my = ((0.5 - el / math.pi) * Heq - 0.5).astype(np.float32).reshape(nv, nu)
        size = (nu * g, nv * g)
        mx = cv2.resize(mx, size, interpolation=cv2.INTER_LINEAR)[g : g + H, g : g + W]
        my = cv2.resize(my, size, interpolation=cv2.INTER_LINEAR)[g : g + H, g : g + W]
        np.clip(my, 0.0, Heq - 1.0, out=my)
        out = cv2.remap(self._bg, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
        return np.asarray(out, dtype=np.uint8)

    @staticmethod
    def _clip_polygon(P: FloatArray) -> FloatArray:
        """Clip a polygon (N×3, optical frame) to z ≥ _NEAR (Sutherland–Hodgman against one plane)."""
        out: list[FloatArray] = []
        n = len(P)
        for i in range(n):
            a, b = P[i], P[(i + 1) % n]
            ina, inb = a[2] >= _NEAR, b[2] >= _NEAR
            if ina:
                out.append(a)
            if ina != inb:
                t = (_NEAR - a[2]) / (b[2] - a[2])
                out.append(a + t * (b - a))
        return np.array(out) if out else np.zeros((0, 3))

    def _composite(self, img: U8Array, tgt: Target, T_opt_base: Transform, K: Intrinsics) -> None:
        # The side of the plane the camera is on: only the front face is textured.
        cam_in_base = T_opt_base.inverse().t
        if float((cam_in_base - tgt.center) @ tgt.normal) <= 0:
            return
        corners = T_opt_base.apply(tgt.corners())
        poly = self._clip_polygon(corners)
        if len(poly) < 3:
            return
        uv = K.project(poly)
        H_img, W_img = img.shape[:2]
        x0 = max(0, int(math.floor(np.min(uv[:, 0]))) - 1)
        y0 = max(0, int(math.floor(np.min(uv[:, 1]))) - 1)
        x1 = min(W_img, int(math.ceil(np.max(uv[:, 0]))) + 2)
        y1 = min(H_img, int(math.ceil(np.max(uv[:, 1]))) + 2)
        if x1 <= x0 or y1 <= y0:
            return
        # Mip level: texels per screen pixel from the projected area (full-visibility estimate).
        tex0 = tgt.texture
        area_px = 0.5 * abs(float(np.dot(uv[:, 0], np.roll(uv[:, 1], 1)) - np.dot(uv[:, 1], np.roll(uv[:, 0], 1))))
        ratio = math.sqrt(tex0.shape[0] * tex0.shape[1] / max(area_px, 1.0))
        level = max(0, int(math.floor(math.log2(ratio)))) if ratio > 1 else 0
        tex = tgt.mip(level)
        ex, ey = tgt.texel_step(level)
        # Plane-induced homography: texture pixel (a, b) → image pixel.
        R, t = T_opt_base.R, T_opt_base.t
        X0 = tgt.top_left + 0.5 * ex + 0.5 * ey
        M = np.column_stack([R @ ex, R @ ey, R @ X0 + t])
        Hm = K.K @ M
        Hm = np.array([[1.0, 0.0, -x0], [0.0, 1.0, -y0], [0.0, 0.0, 1.0]]) @ Hm
        warped = cv2.warpPerspective(
            tex,
            Hm,
            (x1 - x0, y1 - y0),
            flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=(0, 0, 0, 0),
        )
        roi = img[y0:y1, x0:x1]
        if len(poly) == 4 and not np.any(corners[:, 2] < _NEAR):
            # roi·(1 − α) + colour (premultiplied), rounded: OpenCV's saturating uint8 arithmetic gives the same
            # bytes as the float blend below at a third of its cost (a facade fills half a 1080p picture).
            # (OpenCV's own channel split: numpy's strided views of the BGRA picture cost it a copy each.)
            colour = cv2.cvtColor(warped, cv2.COLOR_BGRA2BGR)
            inv = cv2.cvtColor(cv2.bitwise_not(cv2.extractChannel(warped, 3)), cv2.COLOR_GRAY2BGR)
            roi[:] = cv2.add(cv2.multiply(roi, inv, scale=1.0 / 255.0), colour)
            return
        # The polygon was clipped by the near plane: only what is in front of it is drawn.
        mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
        pts = np.round((uv - [x0, y0]) * 16).astype(np.int32)
        cv2.fillPoly(mask, [pts], 255, cv2.LINE_AA, shift=4)
        keep = mask[:, :, None].astype(np.float32) * (1.0 / 255.0)
        alpha = warped[:, :, 3:4].astype(np.float32) * (1.0 / 255.0) * keep
        warped = (warped[:, :, :3].astype(np.float32) * keep).astype(np.uint8)
        blended = roi.astype(np.float32) * (1.0 - alpha) + warped[:, :, :3].astype(np.float32)
        roi[:] = np.clip(blended + 0.5, 0, 255).astype(np.uint8)


def encode_jpeg(img: U8Array, compression: int, picture: CameraModel | None = None) -> bytes:
    """JPEG-encode ``img`` as it is at VAPIX ``compression`` 0…100.

    Without ``picture``: IJG quality ≈ 100 − compression (at least 5), the noise-free ideal. With a camera
    model: that camera's quality curve for this width (``CameraModel.quality``); the softening and sensor noise
    of a camera's frames are applied by :class:`axis_ptz_ros2.sim.camera_model.PicturePool`, which the
    simulated camera serves its frames from.
    """
    if picture is not None:
        quality = picture.quality(compression, img.shape[1])
    else:
        quality = max(5, min(100, 100 - int(compression)))
    return encode(img, quality)


def insert_comment(jpeg: bytes, text: bytes) -> bytes:
    """Insert a COM segment right after SOI (FFD8)."""
    return jpeg[:2] + b"\xff\xfe" + (len(text) + 2).to_bytes(2, "big") + text + jpeg[2:]
