"""Frames of the simulated camera: the rendered view as JPEG, cached per view, and the per-frame stamp (ROS-free).

Every JPEG the camera sends carries a COM segment right after SOI: ``axsim seq=<n> t=<time.time_ns() at send>``
(:func:`stamp`); tests and benchmarks measure latency and loss with it.
"""

from __future__ import annotations

import collections
import threading
import time
from typing import Any

import cv2
import numpy as np

from axis_ptz_ros2.sim.ptz import PtzState
from axis_ptz_ros2.sim.renderer import PtzRenderer, encode_jpeg, insert_comment
from axis_ptz_ros2.sim.scene import SimWorld

MAX_FPS = 30  #: the camera's top frame rate


def stamp(jpeg: bytes, seq: int) -> bytes:
    """``jpeg`` with the ``axsim seq=<seq> t=<now ns>`` COM segment right after SOI."""
    return insert_comment(jpeg, f"axsim seq={seq} t={time.time_ns()}".encode())


class FrameSource:
    """The view of a PTZ head in a world, rendered on demand; the last 16 encoded views are kept (thread-safe)."""

    def __init__(self, world: SimWorld, state: PtzState) -> None:
        """Render ``world`` as seen from where ``state`` points (the renderer is built on first use)."""
        self.world = world
        self.state = state
        self._renderer: PtzRenderer | None = None
        self._jpeg_cache: collections.OrderedDict[tuple[Any, ...], bytes] = collections.OrderedDict()
        self._jpeg_lock = threading.Lock()

    @property
    def renderer(self) -> PtzRenderer:
        """The view renderer (built on first use: the scene takes a moment)."""
        if self._renderer is None:
            self._renderer = PtzRenderer(self.world)
        return self._renderer

    def position(self) -> tuple[float, float, float]:
        """True current VAPIX (pan°, tilt°, zoom units), intermediate while moving."""
        return self.state.position()

    def frame_jpeg(self, width: int, height: int, compression: int, overlay: str = "") -> bytes:
        """The current view as JPEG (cached per view, quality and overlay text)."""
        pan, tilt, zoom = self.position()
        key = (round(pan, 5), round(tilt, 5), round(zoom, 3), width, height, compression, overlay)
        with self._jpeg_lock:
            jpeg = self._jpeg_cache.get(key)
        if jpeg is not None:
            return jpeg
        img = self.renderer.render(pan, tilt, zoom, width, height)
        if overlay:
            img = np.array(img)
            scale = max(0.35, width / 1400.0)
            (tw, th), _ = cv2.getTextSize(overlay, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
            cv2.rectangle(img, (2, 2), (8 + tw, 8 + th + 2), (0, 0, 0), -1)
            cv2.putText(
                img, overlay, (5, 5 + th), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), 1, cv2.LINE_AA
            )
        jpeg = encode_jpeg(img, compression)
        with self._jpeg_lock:
            self._jpeg_cache[key] = jpeg
            while len(self._jpeg_cache) > 16:
                self._jpeg_cache.popitem(last=False)
        return jpeg
