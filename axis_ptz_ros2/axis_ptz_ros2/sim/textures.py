"""Procedural high-resolution textures of the simulator's planar targets (ROS-free, numpy + OpenCV).

Every texture is BGRA uint8 with **premultiplied** colour (colour already multiplied by alpha), so a
bilinear warp with a transparent border gives correctly anti-aliased edges. Each texture builder returns the
texture and a dictionary of named feature points in *fractions* of the texture size ((0, 0) = top-left outer
corner, (1, 1) = bottom-right outer corner); :mod:`axis_ptz_ros2.sim.scene` turns them into 3-D points.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from pathlib import Path

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


def _cell_hash(ix: npt.NDArray[np.int64], iy: npt.NDArray[np.int64], seed: int) -> npt.NDArray[np.float64]:
    """A deterministic per-cell pseudo-random number in [0, 1) (the scene's hash, kept local: no import cycle)."""
    h = (ix * 73856093) ^ (iy * 19349663) ^ (seed * 83492791)
    h = (h ^ (h >> 13)) * 1274126177
    h = h ^ (h >> 16)
    return np.asarray((h & 0xFFFF).astype(np.float64) / 65536.0)


def _smooth_noise(shape: tuple[int, int], cell_px: float, seed: int) -> npt.NDArray[np.float64]:
    """Value noise in [0, 1) with features about ``cell_px`` texels across (hashed lattice, bicubic upsampling)."""
    h, w = shape
    gh, gw = int(math.ceil(h / cell_px)) + 2, int(math.ceil(w / cell_px)) + 2
    iy, ix = np.mgrid[0:gh, 0:gw]
    grid = _cell_hash(ix.astype(np.int64), iy.astype(np.int64), seed).astype(np.float32)
    up = cv2.resize(grid, (int(gw * cell_px), int(gh * cell_px)), interpolation=cv2.INTER_CUBIC)
    return np.asarray(up[:h, :w], dtype=np.float64)


#: Texels per metre of the facade texture (1.5 cm texels: a brick is 14 × 4 texels; at zoom 1 from 34 m a
#: 704×576 pixel spans about 4 cm, so the texture is sharper than the picture up to zoom ≈ 2.7).
FACADE_PX_PER_M = 1.0 / 0.015


def facade_texture(width_m: float, height_m: float, text: str) -> tuple[U8Array, Features]:
    """The front of a four-storey brick building across the square: bricks in running bond (each brick its own
    shade), weathering, stone cornices between storeys, windows with frames, glazing bars, reflections and some
    curtains, a shop front with a sign (``text``) and posters in small print, drainpipes.

    Fine detail of the kind a real camera's scene has (issue 22: the demo scene's flat surfaces made the
    simulated 214's pictures far cheaper to compress than the thesis's camera's). Deterministic."""
    s = FACADE_PX_PER_M
    W, H = int(round(width_m * s)), int(round(height_m * s))
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    # Bricks: 7.5 cm courses, 22.5 cm pitch, 1 cm mortar, half-brick offset every other course.
    course = np.floor(yy / (0.075 * s)).astype(np.int64)
    xo = xx + (course % 2) * (0.1125 * s)
    brick = np.floor(xo / (0.225 * s)).astype(np.int64)
    mortar = (np.mod(yy, 0.075 * s) < 0.01 * s) | (np.mod(xo, 0.225 * s) < 0.01 * s)
    shade = 0.78 + 0.36 * _cell_hash(brick, course, 41)
    burnt = _cell_hash(brick, course, 42) > 0.9  # the odd dark brick
    shade = np.where(burnt, shade * 0.6, shade)
    grain = 1.0 + 0.10 * (_cell_hash(xx.astype(np.int64), yy.astype(np.int64), 43) - 0.5)
    weather = 0.82 + 0.3 * _smooth_noise((H, W), 1.5 * s, 44) + 0.12 * _smooth_noise((H, W), 0.3 * s, 45)
    brick_bgr = np.array([60.0, 85.0, 150.0])
    mortar_bgr = np.array([165.0, 170.0, 175.0])
    col = np.where(mortar[..., None], mortar_bgr, brick_bgr * shade[..., None]) * (grain * weather)[..., None]
    img = np.empty((H, W, 4), np.uint8)
    img[:, :, :3] = np.clip(col + 0.5, 0, 255).astype(np.uint8)
    img[:, :, 3] = 255
    stone, frame_c, sill = (170, 185, 195, 255), (225, 228, 230, 255), (150, 160, 168, 255)

    def m(v: float) -> int:
        return int(round(v * s))

    storey = 3.2
    n_storeys = max(1, int(height_m // storey))
    ground_h = storey
    # Stone cornice bands between storeys and at the top.
    for k in range(1, n_storeys + 1):
        y = H - m(k * storey)
        if 0 <= y < H:
            cv2.rectangle(img, (0, y - m(0.12)), (W - 1, y + m(0.12)), stone, -1)
            cv2.line(img, (0, y + m(0.12)), (W - 1, y + m(0.12)), (90, 100, 108, 255), max(1, m(0.03)))
    cv2.rectangle(img, (0, 0), (W - 1, m(0.35)), stone, -1)
    # Upper-floor windows: 1.2 m × 1.6 m every 2.6 m; frames, two glazing bars, sky reflection, curtains.
    pitch, ww, wh = 2.6, 1.2, 1.6
    n_win = int(width_m // pitch)
    x0 = (width_m - n_win * pitch) / 2 + (pitch - ww) / 2
    for k in range(1, n_storeys):
        top = H - m((k + 1) * storey) + m(0.8)  # texels from the texture's top
        for i in range(n_win):
            r = float(_cell_hash(np.array([i]), np.array([k]), 46)[0])
            xl = m(x0 + i * pitch)
            x1, y1 = xl + m(ww), top + m(wh)
            if top < 0:
                continue
            gy = np.linspace(0.0, 1.0, y1 - top)[:, None]
            pane = np.array([110.0, 90.0, 70.0]) * (0.55 + 0.5 * gy) + 40.0 * r
            img[top:y1, xl:x1, :3] = np.clip(pane, 0, 255).astype(np.uint8)[:, None, :]
            if r > 0.45:  # curtains: vertical folds
                cols = np.arange(x1 - xl)
                fold = 0.75 + 0.25 * np.cos(cols / max(m(0.06), 1) * 2 * math.pi)
                ccol = np.array([[200, 210, 225], [120, 140, 200], [190, 190, 190]][int(r * 10) % 3], np.float64)
                drawn = int((0.35 + 0.5 * r) * (y1 - top))
                img[top : top + drawn, xl:x1, :3] = np.clip(ccol * fold[:, None], 0, 255).astype(np.uint8)[None]
            cv2.rectangle(img, (xl, top), (x1, y1), frame_c, max(2, m(0.07)))
            cv2.line(img, ((xl + x1) // 2, top), ((xl + x1) // 2, y1), frame_c, max(2, m(0.05)))
            cv2.line(img, (xl, top + (y1 - top) // 3), (x1, top + (y1 - top) // 3), frame_c, max(2, m(0.04)))
            cv2.rectangle(img, (xl - m(0.08), y1), (x1 + m(0.08), y1 + m(0.08)), sill, -1)
            streak = np.s_[y1 + m(0.08) : min(H, y1 + m(0.9)), xl:x1]  # rain streaks under the sill
            img[streak][:, :, :3] = (img[streak][:, :, :3] * 0.88).astype(np.uint8)
    # Ground floor: a shop front with a sign, shop windows, posters in small print.
    gf_top = H - m(ground_h)
    cv2.rectangle(img, (m(0.4), gf_top + m(0.2)), (W - m(0.4), gf_top + m(0.85)), (40, 40, 40, 255), -1)
    _text(img, text or "PHARMACY", (W * 0.5, gf_top + m(0.53)), m(0.4), (255, 255, 255), bold=True)
    for i, x in enumerate(np.arange(1.0, width_m - 2.5, 4.0)):
        xl, x1 = m(float(x)), m(float(x) + 3.0)
        y0, y1 = gf_top + m(1.05), H - m(0.5)
        gy = np.linspace(0.0, 1.0, y1 - y0)[:, None]
        img[y0:y1, xl:x1, :3] = np.clip(np.array([95.0, 80.0, 65.0]) * (0.6 + 0.6 * gy), 0, 255).astype(np.uint8)[
            :, None, :
        ]
        cv2.rectangle(img, (xl, y0), (x1, y1), (60, 60, 60, 255), max(2, m(0.06)))
        if i % 2 == 0:  # a poster: a headline and six lines of 5 cm print
            px0, py0 = xl + m(0.3), y0 + m(0.2)
            cv2.rectangle(img, (px0, py0), (px0 + m(0.7), py0 + m(1.0)), (235, 240, 240, 255), -1)
            _text(img, f"NO {12 + i}", (px0 + m(0.35), py0 + m(0.14)), m(0.1), (0, 0, 180), bold=True)
            for j, line in enumerate(("OPEN", "MON-FRI", "8-20", "SAT 9-14", "TEL 555", f"01{i:02d}")):
                _text(img, line, (px0 + m(0.35), py0 + m(0.33 + 0.11 * j)), m(0.05), (20, 20, 20))
    # Ivy climbing the wall in a few patches, and a hedge along its foot.
    leaf = _smooth_noise((H, W), 0.09 * s, 47) * 0.6 + _smooth_noise((H, W), 0.035 * s, 48) * 0.4
    shade_l = _smooth_noise((H, W), 0.05 * s, 49)
    reach = np.zeros((H, W))
    for k, (fx, top_m, half_m) in enumerate(((0.12, 6.5, 2.2), (0.42, 9.5, 1.6), (0.71, 4.0, 3.0), (0.93, 11.0, 1.8))):
        dx = np.abs(xx[0] / s - fx * width_m) / half_m
        height_here = top_m * (1.0 - 0.5 * dx**2) + 1.5 * (_smooth_noise((1, W), 0.7 * s, 50 + k)[0] - 0.5)
        reach = np.maximum(reach, np.where(dx < 1.0, height_here, 0.0)[None, :] - (H - yy) / s)
    reach = np.maximum(reach, 0.9 + 0.3 * _smooth_noise((1, W), 0.5 * s, 55) - (H - yy) / s)  # the hedge
    ivy = (reach > 0) & (leaf > 0.42 + 0.25 * np.clip(1.0 - reach, 0.0, 1.0))
    green = np.stack([20 + 40 * shade_l, 70 + 90 * shade_l * leaf, 35 + 45 * shade_l], -1)
    img[ivy, :3] = np.clip(green[ivy], 0, 255).astype(np.uint8)
    # Drainpipes.
    for x in (0.25, width_m * 0.3, width_m - 0.35):
        cv2.rectangle(img, (m(x), m(0.35)), (m(x + 0.1), H - 1), (110, 115, 118, 255), -1)
        cv2.line(img, (m(x + 0.03), m(0.35)), (m(x + 0.03), H - 1), (160, 165, 168, 255), max(1, m(0.02)))
    img[:, :, 3] = 255  # a wall: OpenCV's anti-aliased small print also blends the alpha channel
    return img, {"center": (0.5, 0.5)}


# --------------------------------------------------------------------------------------------------------
# Image targets (kind ``image``): a PNG or JPEG file drawn on the target's rectangle
# --------------------------------------------------------------------------------------------------------
MAX_IMAGE_SIDE = 4096  #: pixels: the widest or tallest image a target may use
#: pixels of one image (a texture costs 4 bytes a texel, plus a third for its mip levels: at most 85 MiB)
MAX_IMAGE_PIXELS = MAX_IMAGE_SIDE * MAX_IMAGE_SIDE
MAX_IMAGE_FILE_BYTES = 64 * 2**20  #: bytes of one image file
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_JPEG_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}


class ImageError(ValueError):
    """An image file cannot be a target's texture; the message says why (and the bound it broke)."""


def image_header(data: bytes) -> tuple[int, int, str]:
    """(width, height, "png" | "jpeg") from a PNG's IHDR or a JPEG's frame header, without decoding the pixels
    (so an image too large to decode is refused before it costs any memory)."""
    if data.startswith(_PNG_SIGNATURE):
        if len(data) < 33 or data[12:16] != b"IHDR":
            raise ImageError("not a valid PNG file (no IHDR header)")
        w, h = struct.unpack(">II", data[16:24])
        return int(w), int(h), "png"
    if data.startswith(b"\xff\xd8"):
        w, h, _ = _jpeg_walk(data)
        return w, h, "jpeg"
    raise ImageError("not a PNG or JPEG file")


def _jpeg_walk(data: bytes) -> tuple[int, int, int]:
    """(width, height, offset of the first start-of-scan) of a JPEG file, from its marker segments."""
    i, size = 2, None
    while i + 4 <= len(data):
        if data[i] != 0xFF:
            raise ImageError(f"not a valid JPEG file (no marker at byte {i})")
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        if marker == 0x01 or 0xD0 <= marker <= 0xD7:  # stand-alone markers
            i += 2
            continue
        if marker == 0xD9:
            break
        (length,) = struct.unpack(">H", data[i + 2 : i + 4])
        if length < 2:
            raise ImageError(f"not a valid JPEG file (segment length {length} at byte {i})")
        if marker in _JPEG_SOF and i + 9 <= len(data):
            h, w = struct.unpack(">HH", data[i + 5 : i + 9])
            size = (int(w), int(h))
        if marker == 0xDA:
            if size is None:
                break
            return size[0], size[1], i
        i += 2 + length
    raise ImageError("not a valid JPEG file (no frame header or no scan: truncated or corrupt)")


def decode_image(data: bytes) -> U8Array:
    """A PNG or JPEG file's bytes → BGRA uint8 texture with premultiplied alpha (grey, 16-bit and palette images
    converted; no alpha: opaque). Raises :class:`ImageError` for anything else, a truncated or corrupt file, or an
    image beyond :data:`MAX_IMAGE_SIDE` / :data:`MAX_IMAGE_PIXELS` (checked from the header, before decoding)."""
    if len(data) > MAX_IMAGE_FILE_BYTES:
        raise ImageError(f"file of {len(data)} bytes; at most {MAX_IMAGE_FILE_BYTES} bytes allowed")
    w, h, fmt = image_header(data)
    if w < 1 or h < 1:
        raise ImageError(f"image of {w}x{h} pixels: empty")
    if w > MAX_IMAGE_SIDE or h > MAX_IMAGE_SIDE or w * h > MAX_IMAGE_PIXELS:
        raise ImageError(
            f"image of {w}x{h} pixels: too large; at most {MAX_IMAGE_SIDE}x{MAX_IMAGE_SIDE} "
            f"({MAX_IMAGE_PIXELS} pixels) per image"
        )
    if fmt == "jpeg" and data.rfind(b"\xff\xd9") < _jpeg_walk(data)[2]:
        raise ImageError("truncated JPEG file (no end-of-image marker after its scan)")
    if fmt == "png" and data.rfind(b"IEND") < 0:
        raise ImageError("truncated PNG file (no IEND chunk)")
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ImageError(f"cannot decode this {fmt.upper()} file (corrupt or truncated)")
    if img.shape[:2] != (h, w):
        raise ImageError(f"decoded {img.shape[1]}x{img.shape[0]} pixels, the header says {w}x{h} (corrupt file)")
    if img.dtype == np.uint16:
        img = (np.asarray(img, dtype=np.uint16) >> 8).astype(np.uint8)
    if img.dtype != np.uint8:
        raise ImageError(f"unsupported pixel type {img.dtype}")
    if img.ndim == 2:
        return np.asarray(cv2.cvtColor(img, cv2.COLOR_GRAY2BGRA), dtype=np.uint8)
    if img.shape[2] == 3:
        return np.asarray(cv2.cvtColor(img, cv2.COLOR_BGR2BGRA), dtype=np.uint8)
    if img.shape[2] == 4:
        return _premultiply(np.ascontiguousarray(img))
    raise ImageError(f"unsupported image with {img.shape[2]} channels")


_IMAGE_TEXTURES: dict[tuple[str, int, int], U8Array] = {}


def image_texture(path: str | Path) -> tuple[U8Array, Features]:
    """The texture of an ``image`` target: the file's pixels, one texel each, stretched over the target's
    rectangle (top row of the image at the target's top). Raises :class:`ImageError` (or ``OSError``).

    Targets showing the same file share one read-only texture (the demo world's three acuity charts)."""
    p = Path(path)
    st = p.stat()
    key = (str(p.resolve()), st.st_mtime_ns, st.st_size)
    tex = _IMAGE_TEXTURES.get(key)
    if tex is None:
        tex = decode_image(p.read_bytes())
        tex.setflags(write=False)
        if len(_IMAGE_TEXTURES) >= 16:
            _IMAGE_TEXTURES.pop(next(iter(_IMAGE_TEXTURES)))
        _IMAGE_TEXTURES[key] = tex
    return tex, {"center": (0.5, 0.5)}


def texture_shape(kind: str, width_m: float, height_m: float) -> tuple[int, int]:
    """(columns, rows) of the texture the builder of ``kind`` makes for a ``width_m``×``height_m`` target (not for
    ``image`` targets: their file says). Lets a world file's textures be bounded before any is built."""
    if kind in ("plate", "hazard", "calib"):
        return 2000, int(round(2000 * height_m / width_m))
    if kind == "marker":
        return 1600, int(round(1600 * height_m / width_m))
    if kind == "person":
        return int(round(2400 * width_m / height_m)), 2400
    if kind == "checker":
        return 2000, 1400
    if kind == "facade":
        return int(round(width_m * FACADE_PX_PER_M)), int(round(height_m * FACADE_PX_PER_M))
    raise ValueError(f"no procedural texture for kind {kind!r}")


TextureBuilder = Callable[..., tuple[U8Array, Features]]
