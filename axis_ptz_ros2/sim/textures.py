"""Procedural high-resolution textures of the simulator's planar targets (ROS-free, numpy + OpenCV).

Every texture is BGRA uint8 with **premultiplied** colour (colour already multiplied by alpha), so a
bilinear warp with a transparent border gives correctly anti-aliased edges. Each texture builder returns the
texture and a dictionary of named feature points in *fractions* of the texture size ((0, 0) = top-left outer
corner, (1, 1) = bottom-right outer corner); :mod:`axis_ptz_ros2.sim.scene` turns them into 3-D points.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import cv2
import numpy as np
import numpy.typing as npt

U8Array = npt.NDArray[np.uint8]
Features = dict[str, tuple[float, float]]
BGR = tuple[int, int, int]

_FONT = cv2.FONT_HERSHEY_SIMPLEX
_FONT_BOLD = cv2.FONT_HERSHEY_DUPLEX

# Calibration-board dot colours (BGR): saturated and far apart in hue so tests can find them by colour.
CALIB_DOTS: dict[str, BGR] = {
    "red": (0, 0, 255),
    "green": (0, 200, 0),
    "blue": (255, 0, 0),
    "yellow": (0, 230, 255),
}


def _canvas(width: int, height: int, color: BGR) -> U8Array:
    img = np.empty((height, width, 4), np.uint8)
    img[:, :, :3] = color
    img[:, :, 3] = 255
    return img


def _text(
    img: U8Array, text: str, center: tuple[float, float], height_px: float, color: BGR, bold: bool = False
) -> None:
    """Draw ``text`` centred on ``center`` with a cap height of about ``height_px`` pixels."""
    font = _FONT_BOLD if bold else _FONT
    (w0, h0), _ = cv2.getTextSize(text, font, 1.0, 1)
    scale = height_px / max(h0, 1)
    thick = max(1, int(round(scale * (2.6 if bold else 1.6))))
    (w, h), _ = cv2.getTextSize(text, font, scale, thick)
    org = (int(round(center[0] - w / 2)), int(round(center[1] + h / 2)))
    cv2.putText(img, text, org, font, scale, (*color, 255), thick, cv2.LINE_AA)


def _premultiply(img: U8Array) -> U8Array:
    a = img[:, :, 3:4].astype(np.uint16)
    img[:, :, :3] = (img[:, :, :3].astype(np.uint16) * a // 255).astype(np.uint8)
    return img


def plate_texture(width_m: float, height_m: float, text: str) -> tuple[U8Array, Features]:
    """A European-style car number plate: white, black border, blue country strip, large characters."""
    W = 2000
    H = int(round(W * height_m / width_m))
    img = _canvas(W, H, (245, 245, 245))
    b = max(4, H // 30)
    cv2.rectangle(img, (b, b), (W - 1 - b, H - 1 - b), (20, 20, 20, 255), b, cv2.LINE_AA)
    strip = int(H * 0.42)
    cv2.rectangle(img, (2 * b, 2 * b), (2 * b + strip, H - 1 - 2 * b), (150, 50, 0, 255), -1)
    for k in range(12):  # the ring of EU stars
        a = 2 * math.pi * k / 12
        c = (int(2 * b + strip / 2 + math.cos(a) * strip * 0.25), int(H * 0.36 + math.sin(a) * strip * 0.25))
        cv2.circle(img, c, max(2, strip // 24), (0, 220, 255, 255), -1, cv2.LINE_AA)
    _text(img, "CZ", (2 * b + strip / 2, H * 0.76), H * 0.16, (255, 255, 255), bold=True)
    _text(img, text, (W / 2 + strip / 2, H / 2), H * 0.62, (15, 15, 15), bold=True)
    return img, {"center": (0.5, 0.5)}


def hazard_texture(width_m: float, height_m: float, text: str) -> tuple[U8Array, Features]:
    """A hazard diamond (placard) with a large UN number and lines of small print (1.5 cm letters)."""
    W = 2000
    H = int(round(W * height_m / width_m))
    img = _canvas(W, H, (255, 255, 255))
    img[:, :, 3] = 0
    diamond = np.array([[W // 2, 0], [W - 1, H // 2], [W // 2, H - 1], [0, H // 2]], np.int32)
    cv2.fillConvexPoly(img, diamond, (255, 255, 255, 255), cv2.LINE_AA)
    inner = np.array([[W // 2, 60], [W - 61, H // 2], [W // 2, H - 61], [60, H // 2]], np.int32)
    cv2.polylines(img, [inner], True, (0, 0, 200, 255), 28, cv2.LINE_AA)
    top = np.array([[W // 2, 120], [W - 600, H // 2 - 480], [600, H // 2 - 480]], np.int32)
    cv2.fillConvexPoly(img, top, (0, 0, 210, 255), cv2.LINE_AA)
    _text(img, "FLAMMABLE", (W / 2, H * 0.40), H * 0.055, (0, 0, 0), bold=True)
    _text(img, text, (W / 2, H * 0.51), H * 0.09, (0, 0, 0), bold=True)
    px_per_m = W / width_m
    small = 0.015 * px_per_m  # 1.5 cm letters: about 1 px at zoom 1 from 12 m, about 19 px at zoom 9999
    for i, line in enumerate(("KEEP AWAY FROM HEAT", "UN 1203 PETROL", "CALL 112 IN CASE", "OF FIRE OR LEAK")):
        _text(img, line, (W / 2, H * 0.60 + i * small * 1.8), small, (0, 0, 0))
    _text(img, "3", (W / 2, H * 0.86), H * 0.06, (0, 0, 0), bold=True)
    return _premultiply(img), {"center": (0.5, 0.5), "top": (0.5, 0.0), "bottom": (0.5, 1.0)}


def person_texture(width_m: float, height_m: float) -> tuple[U8Array, Features]:
    """A person-sized cut-out silhouette (transparent around it)."""
    H = 2400
    W = int(round(H * width_m / height_m))
    img = _canvas(W, H, (0, 0, 0))
    img[:, :, 3] = 0
    s = H / height_m  # px per metre
    cx = W // 2
    skin, shirt, trousers = (140, 170, 225, 255), (60, 110, 30, 255), (80, 50, 40, 255)
    cv2.ellipse(img, (cx, int(0.12 * s)), (int(0.085 * s), int(0.11 * s)), 0, 0, 360, skin, -1, cv2.LINE_AA)
    cv2.rectangle(img, (cx - int(0.05 * s), int(0.2 * s)), (cx + int(0.05 * s), int(0.28 * s)), skin, -1)
    cv2.rectangle(img, (cx - int(0.2 * s), int(0.27 * s)), (cx + int(0.2 * s), int(0.9 * s)), shirt, -1)
    cv2.rectangle(img, (cx - int(0.29 * s), int(0.3 * s)), (cx - int(0.2 * s), int(0.85 * s)), shirt, -1)
    cv2.rectangle(img, (cx + int(0.2 * s), int(0.3 * s)), (cx + int(0.29 * s), int(0.85 * s)), shirt, -1)
    cv2.rectangle(img, (cx - int(0.19 * s), int(0.9 * s)), (cx - int(0.02 * s), H - 1), trousers, -1)
    cv2.rectangle(img, (cx + int(0.02 * s), int(0.9 * s)), (cx + int(0.19 * s), H - 1), trousers, -1)
    for ex in (-0.035, 0.035):
        cv2.circle(img, (cx + int(ex * s), int(0.1 * s)), int(0.01 * s), (40, 40, 40, 255), -1, cv2.LINE_AA)
    _text(img, "SIM", (cx, 0.5 * s), 0.06 * s, (255, 255, 255), bold=True)
    _text(img, "VISITOR 07", (cx, 0.62 * s), 0.025 * s, (255, 255, 255))
    return _premultiply(img), {"head": (0.5, 0.12 / height_m), "center": (0.5, 0.5)}


def marker_texture(width_m: float, height_m: float, color: BGR) -> tuple[U8Array, Features]:
    """A solid colour square with a white ring and a black centre cross (for pointing tests)."""
    W = 1600
    H = int(round(W * height_m / width_m))
    img = _canvas(W, H, color)
    cv2.circle(img, (W // 2, H // 2), int(min(W, H) * 0.3), (255, 255, 255, 255), int(W * 0.04), cv2.LINE_AA)
    t = max(3, W // 200)
    cv2.line(img, (W // 2, H // 2 - H // 8), (W // 2, H // 2 + H // 8), (0, 0, 0, 255), t, cv2.LINE_AA)
    cv2.line(img, (W // 2 - W // 8, H // 2), (W // 2 + W // 8, H // 2), (0, 0, 0, 255), t, cv2.LINE_AA)
    return img, {"center": (0.5, 0.5)}


def calib_texture(width_m: float, height_m: float, label: str) -> tuple[U8Array, Features]:
    """A white board with four distinct coloured corner dots (known 3-D positions) and a label."""
    W = 2000
    H = int(round(W * height_m / width_m))
    img = _canvas(W, H, (235, 235, 235))
    cv2.rectangle(img, (0, 0), (W - 1, H - 1), (40, 40, 40, 255), 16)
    inset = 0.15
    pos = {
        "red": (inset, inset),
        "green": (1 - inset, inset),
        "blue": (1 - inset, 1 - inset),
        "yellow": (inset, 1 - inset),
    }
    r = int(0.08 * W)
    feats: Features = {}
    for name, (fx, fy) in pos.items():
        c = (int(round(fx * W)), int(round(fy * H)))
        cv2.circle(img, c, r, (*CALIB_DOTS[name], 255), -1, cv2.LINE_AA)
        feats[f"dot_{name}"] = ((c[0] + 0.5) / W, (c[1] + 0.5) / H)
    _text(img, label.upper(), (W / 2, H / 2), H * 0.06, (30, 30, 30), bold=True)
    feats["center"] = (0.5, 0.5)
    return img, feats


def checker_texture(width_m: float, height_m: float, cols: int = 10, rows: int = 7) -> tuple[U8Array, Features]:
    """A checkerboard of ``cols``×``rows`` squares; features ``corner_<i>_<j>`` are its inner corners."""
    cell = 200
    W, H = cols * cell, rows * cell
    yy, xx = np.mgrid[0:H, 0:W]
    black = ((yy // cell + xx // cell) % 2) == 0
    img = _canvas(W, H, (250, 250, 250))
    img[black, :3] = 15
    feats: Features = {}
    for j in range(1, rows):
        for i in range(1, cols):
            feats[f"corner_{i}_{j}"] = (i / cols, j / rows)
    return img, feats


TextureBuilder = Callable[..., tuple[U8Array, Features]]
