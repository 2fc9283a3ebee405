"""The virtual camera's own decisions (ROS-free): the camera model it serves and when it renders a view.

* :func:`view_model_dict`: the camera-model YAML (``config/virtual_camera.yaml`` format) as the virtual camera uses
  it. Square pixels: the zoom model's ``image_aspect`` is set to exactly ``width/height`` of the render, so the PTZ
  node's intrinsics (``fy = fx``) are those of :attr:`ViewSpec.intrinsics
  <axis_ptz_ros2.virtual.render.ViewSpec.intrinsics>`; no head offsets: the view's optical centre is the panorama
  origin.
* :class:`RenderGate`: a view is rendered only while someone watches, and then when the panorama or the view
  changed, when a new subscriber came, or when ``min_rate`` asks for a refresh of a still view.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Hashable, Mapping
from typing import Any


def view_model_dict(raw: Mapping[str, Any], width: int, height: int) -> dict[str, Any]:
    """A copy of the camera-model mapping ``raw`` with square pixels for a ``width``×``height`` view
    (``zoom.image_aspect = width/height``) and the optical centre at the pan/tilt centre (``head`` without
    offsets); the rest (convention, zoom curve, limits, speeds, ``dynamics``) as given."""
    d = copy.deepcopy(dict(raw))
    d.setdefault("zoom", {})["image_aspect"] = width / height
    d["head"] = {"h_tilt": 0.0, "d_opt": [0.0, 0.0, 0.0]}
    return d


class RenderGate:
    """When the virtual camera renders: called once per timer tick, first :meth:`watch`, then (with a panorama)
    :meth:`due` and after a render :meth:`rendered`. Not thread-safe (one timer)."""

    def __init__(self) -> None:
        """Nothing rendered, nobody watching."""
        self._subscribers = 0
        self._new_subscriber = False
        self._key: Hashable | None = None
        self._published_at = -math.inf

    def watch(self, subscribers: int) -> bool:
        """This tick's subscriber count (image and camera_info together); whether anyone watches. A count above
        the previous tick's is a new subscriber, who gets a frame even of an unchanged view."""
        self._new_subscriber = subscribers > self._subscribers
        self._subscribers = subscribers
        return subscribers > 0

    def due(self, key: Hashable, now: float, min_rate: float) -> bool:
        """Whether to render the view ``key`` (panorama and view) at monotonic ``now``: another key than the last
        render's, a new subscriber this tick, or the last publish at least ``1/min_rate`` s ago (``min_rate`` 0:
        only on change)."""
        stale = min_rate > 0.0 and now - self._published_at >= 1.0 / min_rate
        return key != self._key or self._new_subscriber or stale

    def rendered(self, key: Hashable, published_at: float | None) -> None:
        """``key`` was rendered; ``published_at``: monotonic time its frame went out (None: it could not be
        encoded, so ``min_rate`` still counts from the last frame that did)."""
        self._key = key
        if published_at is not None:
            self._published_at = published_at
