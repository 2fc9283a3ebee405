"""Panorama decoding of axis_virtual_camera (sensor_msgs Image encodings with row padding, CompressedImage)."""

from __future__ import annotations

import pytest

pytest.importorskip("rclpy")

import cv2  # noqa: E402
import numpy as np  # noqa: E402
from sensor_msgs.msg import CompressedImage, Image  # noqa: E402

from axis_ptz_ros2.nodes.virtual_camera import decode_compressed, decode_raw  # noqa: E402

pytestmark = pytest.mark.ros

RNG = np.random.default_rng(7)
BGR = RNG.integers(0, 256, (6, 10, 3), dtype=np.uint8)


def raw(img: np.ndarray, encoding: str, pad: int = 0) -> Image:
    h, w = img.shape[:2]
    ch = 1 if img.ndim == 2 else img.shape[2]
    rows = np.zeros((h, w * ch + pad), np.uint8)
    rows[:, : w * ch] = img.reshape(h, w * ch)
    return Image(height=h, width=w, encoding=encoding, step=w * ch + pad, data=rows.tobytes())


@pytest.mark.parametrize("pad", [0, 6])
def test_raw_encodings_to_bgr(pad):
    assert np.array_equal(decode_raw(raw(BGR, "bgr8", pad)), BGR)
    assert np.array_equal(decode_raw(raw(BGR[:, :, ::-1].copy(), "rgb8", pad)), BGR)
    bgra = np.dstack([BGR, np.full(BGR.shape[:2], 9, np.uint8)])
    assert np.array_equal(decode_raw(raw(bgra, "bgra8", pad)), BGR)
    rgba = np.dstack([BGR[:, :, ::-1], np.full(BGR.shape[:2], 9, np.uint8)])
    assert np.array_equal(decode_raw(raw(rgba, "rgba8", pad)), BGR)
    grey = BGR[:, :, 0].copy()
    assert np.array_equal(decode_raw(raw(grey, "mono8", pad)), grey)


def test_unsupported_or_truncated_raw_is_refused():
    assert decode_raw(raw(BGR.astype(np.uint16)[:, :, 0], "mono16")) is None
    m = raw(BGR, "bgr8")
    m.data = bytes(m.data)[:-1]
    assert decode_raw(m) is None
    m = raw(BGR, "bgr8")
    m.step = 10  # shorter than a row
    assert decode_raw(m) is None


def test_compressed_jpeg_png_and_garbage():
    png = cv2.imencode(".png", BGR)[1].tobytes()
    assert np.array_equal(decode_compressed(CompressedImage(format="png", data=png)), BGR)
    yy, xx = np.mgrid[0:48, 0:64]
    smooth = np.dstack([xx * 3, yy * 4, (xx + yy) * 2]).astype(np.uint8)  # JPEG keeps smooth images
    jpg = cv2.imencode(".jpg", smooth, [cv2.IMWRITE_JPEG_QUALITY, 100])[1].tobytes()
    out = decode_compressed(CompressedImage(format="jpeg", data=jpg))
    assert out.shape == smooth.shape
    assert np.abs(out.astype(int) - smooth.astype(int)).mean() < 2
    assert decode_compressed(CompressedImage(format="jpeg", data=b"not a jpeg")) is None
    assert decode_compressed(CompressedImage(format="jpeg", data=b"")) is None
