"""Panorama decoding of the virtual camera (axis_ptz_ros2.virtual.decode): 8-bit raw encodings with row padding,
JPEG/PNG bytes, and what is refused."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from axis_ptz_ros2.virtual.decode import decode_compressed, decode_raw

pytestmark = pytest.mark.unit

RNG = np.random.default_rng(7)
BGR = RNG.integers(0, 256, (6, 10, 3), dtype=np.uint8)


def raw(img: np.ndarray, encoding: str, pad: int = 0) -> tuple[bytes, str, int, int, int]:
    """The fields of a ``sensor_msgs/Image`` holding ``img``, rows padded by ``pad`` bytes."""
    h, w = img.shape[:2]
    ch = 1 if img.ndim == 2 else img.shape[2]
    rows = np.zeros((h, w * ch + pad), np.uint8)
    rows[:, : w * ch] = img.reshape(h, w * ch)
    return rows.tobytes(), encoding, w, h, w * ch + pad


@pytest.mark.parametrize("pad", [0, 6])
def test_raw_encodings_to_bgr(pad):
    assert np.array_equal(decode_raw(*raw(BGR, "bgr8", pad)), BGR)
    assert np.array_equal(decode_raw(*raw(BGR, "8UC3", pad)), BGR)
    assert np.array_equal(decode_raw(*raw(BGR[:, :, ::-1].copy(), "rgb8", pad)), BGR)
    bgra = np.dstack([BGR, np.full(BGR.shape[:2], 9, np.uint8)])
    assert np.array_equal(decode_raw(*raw(bgra, "bgra8", pad)), BGR)
    assert np.array_equal(decode_raw(*raw(bgra, "8UC4", pad)), BGR)
    rgba = np.dstack([BGR[:, :, ::-1], np.full(BGR.shape[:2], 9, np.uint8)])
    assert np.array_equal(decode_raw(*raw(rgba, "rgba8", pad)), BGR)
    grey = BGR[:, :, 0].copy()
    assert np.array_equal(decode_raw(*raw(grey, "mono8", pad)), grey)
    out = decode_raw(*raw(grey, "8UC1", pad))
    assert np.array_equal(out, grey)
    assert out.flags["C_CONTIGUOUS"]


def test_unsupported_empty_or_truncated_raw_is_refused():
    assert decode_raw(*raw(BGR.astype(np.uint16)[:, :, 0], "mono16")) is None
    data, enc, w, h, step = raw(BGR, "bgr8")
    assert decode_raw(data[:-1], enc, w, h, step) is None
    assert decode_raw(data, enc, w, h, 10) is None  # a step shorter than a row
    assert decode_raw(b"", enc, 0, 0, 0) is None
    assert np.array_equal(decode_raw(data + b"extra", enc, w, h, step), BGR)  # bytes past the image are ignored


def test_compressed_jpeg_png_and_garbage():
    png = cv2.imencode(".png", BGR)[1].tobytes()
    assert np.array_equal(decode_compressed(png), BGR)
    bgra = np.dstack([BGR, np.full(BGR.shape[:2], 200, np.uint8)])
    assert np.array_equal(decode_compressed(cv2.imencode(".png", bgra)[1].tobytes()), BGR)  # alpha dropped
    grey = BGR[:, :, 1].copy()
    assert np.array_equal(decode_compressed(cv2.imencode(".png", grey)[1].tobytes()), grey)
    yy, xx = np.mgrid[0:48, 0:64]
    smooth = np.dstack([xx * 3, yy * 4, (xx + yy) * 2]).astype(np.uint8)  # JPEG keeps smooth images
    jpg = cv2.imencode(".jpg", smooth, [cv2.IMWRITE_JPEG_QUALITY, 100])[1].tobytes()
    out = decode_compressed(jpg)
    assert out.shape == smooth.shape
    assert np.abs(out.astype(int) - smooth.astype(int)).mean() < 2
    assert decode_compressed(cv2.imencode(".png", BGR.astype(np.uint16) * 100)[1].tobytes()) is None  # 16-bit
    assert decode_compressed(b"not a jpeg") is None
    assert decode_compressed(b"") is None
