"""Frames of the simulated camera: the rendered view as the camera sends it (camera_model.py), and the per-frame
stamp (ROS-free).

Every JPEG the camera sends carries a COM segment right after SOI: ``axsim seq=<n> t=<time.time_ns() at send>``
(:func:`stamp`); tests and benchmarks measure latency and loss with it.
"""

from __future__ import annotations

import time

import cv2
import numpy as np

from axis_ptz_ros2.sim.camera_model import CameraModel, PicturePool
from axis_ptz_ros2.sim.persona import AXIS_214_PICTURE
from axis_ptz_ros2.sim.ptz import PtzState
from axis_ptz_ros2.sim.renderer import PtzRenderer, insert_comment
from axis_ptz_ros2.sim.scene import SimWorld

MAX_FPS = 30  #: the highest ``fps=`` the cameras accept (what they deliver: ``Persona.frame_rate``)
MAX_COMPRESSION = 100  #: the highest ``compression=`` the cameras accept (0 = best quality … this = smallest)


def stamp(jpeg: bytes, seq: int) -> bytes:
    """``jpeg`` with the ``axsim seq=<seq> t=<now ns>`` COM segment right after SOI."""
    return insert_comment(jpeg, f"axsim seq={seq} t={time.time_ns()}".encode())


class FrameSource:
    """The view of a PTZ head in a world, rendered on demand, as the camera sends it (thread-safe): softened, with
    a new frame of sensor noise per call, from a pool per view, quality and overlay text (the last 16 views are
    kept; :mod:`axis_ptz_ros2.sim.camera_model`)."""

    def __init__(self, world: SimWorld, state: PtzState, picture: CameraModel | None = None) -> None:
        """Render ``world`` as seen from where ``state`` points (the renderer is built on first use) through the
        camera model ``picture`` (None: the Axis 214's)."""
        self.world = world
        self.state = state
        self._renderer: PtzRenderer | None = None
        self._pictures = PicturePool(picture if picture is not None else AXIS_214_PICTURE, views=16)

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
        """The current view as the camera sends it (a new noisy frame per call; see the class docstring)."""
        pan, tilt, zoom = self.position()
        key = (round(pan, 5), round(tilt, 5), round(zoom, 3), width, height)

        def draw(img: np.ndarray, text: str) -> None:
            scale = max(0.35, width / 1400.0)
            (tw, th), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
            cv2.rectangle(img, (2, 2), (8 + tw, 8 + th + 2), (0, 0, 0), -1)
            cv2.putText(img, text, (5, 5 + th), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), 1, cv2.LINE_AA)

        return self._pictures.jpeg(
            key, lambda: self.renderer.render(pan, tilt, zoom, width, height), zoom, compression, overlay, draw
        )
