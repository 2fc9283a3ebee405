"""The panorama as the virtual camera receives it, decoded to BGR (or grey) pixels (ROS-free, numpy + OpenCV).

Two inputs, given as the plain fields of their messages: a ``sensor_msgs/CompressedImage`` (JPEG or PNG bytes:
:func:`decode_compressed`) and an 8-bit ``sensor_msgs/Image`` (``encoding``, ``width``, ``height``, ``step`` and
the row-padded bytes: :func:`decode_raw`). Anything else decodes to None: the caller drops the frame.
"""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

U8 = npt.NDArray[np.uint8]

#: The 8-bit ``sensor_msgs/Image`` encodings the virtual camera takes, and their channels.
RAW_CHANNELS = {"mono8": 1, "8UC1": 1, "bgr8": 3, "rgb8": 3, "8UC3": 3, "bgra8": 4, "rgba8": 4, "8UC4": 4}


def decode_compressed(data: bytes) -> U8 | None:
    """JPEG/PNG bytes as a BGR (or grey) uint8 array (alpha dropped); None if they cannot be decoded."""
    buf = np.frombuffer(data, dtype=np.uint8)
    if buf.size == 0:
        return None
    img = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    if img is None or img.dtype != np.uint8:
        return None
    if img.ndim == 3 and img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    return np.asarray(img, dtype=np.uint8)


def decode_raw(data: bytes, encoding: str, width: int, height: int, step: int) -> U8 | None:
    """An 8-bit image (mono8, bgr8, rgb8, bgra8, rgba8, 8UC1/3/4) of ``height`` rows of ``step`` bytes as BGR or
    grey; None for another encoding, an empty image or too few bytes."""
    ch = RAW_CHANNELS.get(encoding)
    h, w, step = int(height), int(width), int(step)
    if ch is None or h == 0 or w == 0 or step < w * ch or len(data) < step * h:
        return None
    rows = np.frombuffer(data, dtype=np.uint8, count=step * h).reshape(h, step)
    img = rows[:, : w * ch].reshape(h, w, ch) if ch > 1 else rows[:, :w]
    if encoding == "rgb8":
        return np.asarray(cv2.cvtColor(img, cv2.COLOR_RGB2BGR), dtype=np.uint8)
    if ch == 4:
        code = cv2.COLOR_RGBA2BGR if encoding == "rgba8" else cv2.COLOR_BGRA2BGR
        return np.asarray(cv2.cvtColor(img, code), dtype=np.uint8)
    return np.ascontiguousarray(img)
