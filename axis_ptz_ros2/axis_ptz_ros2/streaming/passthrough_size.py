"""Which picture size to ask a camera's own H.264 for, given the bitrate it may use (issue 39 item 6). ROS-free.

A camera that streams H.264 itself is passed through (:mod:`.rtsp_source`): the stream node asks it for a size, a
frame rate and ``videomaxbitrate``. At a bitrate the weak link can carry, 1920x1080 is the wrong size to ask for: the
encoder spreads too few bits over too many pixels, every picture (and most of all the periodic IDR) is quantised
coarsely and fine detail (text, plates, an acuity chart's rows) is lost, while a smaller picture at the same bitrate
keeps it. So with ``resolution`` left empty (auto) the passthrough asks for the **largest size the camera lists, in
the requested shape, whose bits per pixel per picture** (``bitrate / (width × height × fps)``) **reach**
:data:`MIN_BITS_PER_PIXEL`; with none, the smallest. An explicit ``resolution`` is asked for as it is.

Why 0.03 bit per pixel per picture:

* The rule of thumb for H.264 (the "Kush gauge": bitrate ≈ width × height × fps × motion rank × 0.07, rank 1 for
  low motion) puts a good-looking low-motion picture at 0.07 bit/px. That is for appearance; reading a still
  subject needs less.
* ``bench/resolution_acuity.py`` (offline, the simulated current-Axis persona looking at the 35 m acuity chart at
  its zoom limit, x264 ``veryfast``, an IDR a second, 25 fps; at d82297c): at 400 kbit/s 1024x576 (0.027 bit/px)
  reads 12 rows median and 10 worst, 1920x1080 (0.008) 12 median but 1 worst (its IDR picture breaks down); at
  1000 kbit/s 1920x1080 (0.019) reads all 12 in every picture. At 30 fps (``--kbps 150,300,700 --seconds 2 --fps
  30``, at 7705f2d; rows median / worst; uncoded, the sizes from 1920x1080 down to 480x270 read 12, 11, 10, 10, 7
  and 9 rows): 150 kbit/s: 480x270 (0.039) 9 / 8, 640x360 (0.022) 9 / 4, 1920x1080 0 / 0; 300 kbit/s: 1280x720
  (0.011) 11 / 8, 800x450 (0.028) 10 / 9, 1920x1080 4 / 0; 700 kbit/s: 1920x1080 (0.011) 12 / 12, 1024x576 (0.040)
  10 / 10. So in this scene a size reads down to about 0.01-0.02 and breaks down under 0.01; 0.03 gives up one or
  two rows against the best size at 300-700 kbit/s here, and keeps the worst picture (8 rows, not 4, at 150).
* Panning moves the edge up (``--pan-deg-s 9``, at 67e8d0c): at 0.011 bit/px 1080p reads 12 / 12 still but 7 / 0
  while the head sweeps 9°/s across the chart; sizes hold from about 0.016 up; at 700 kbit/s this rule's 1024x576
  reads 10 / 10 (docs/weak-link.md).
* The simulator's scene is static, with the sensor noise of its camera model only: a real scene moves, a PTZ pans,
  a real sensor's noise and the camera's own encoder (unknown to us; Axis's Zipstream and its rate control differ
  from x264) all take bits a static scene does not. 0.03 leaves 1.5× over the measured edge and stays under half the
  appearance rule. How a real camera reads at 0.02-0.07 bit/px is not measured here (docs/weak-link.md).

At 30 fps that is 1920x1080 from 1.87 Mbit/s on, 1280x720 from 830 kbit/s, 1024x576 from 531, 640x360 from 207.

A size change restarts the camera's RTSP session (a gap, an IDR), so :class:`PassthroughSize` changes size only on
a lasting change of the bitrate: down once the bitrate has wanted a smaller size for :attr:`SizeConfig.down_hold_s`,
up once a larger size has had :attr:`SizeConfig.up_margin` × the threshold for :attr:`SizeConfig.up_hold_s`, and
never within :attr:`SizeConfig.min_interval_s` of the last change (or of the first choice).
"""

from __future__ import annotations

import threading
from collections.abc import Collection
from dataclasses import dataclass
from typing import Final

from axis_ptz_ros2.streaming.budget import same_aspect
from axis_ptz_ros2.vapix.models import Resolution

#: bits per pixel per picture the size chosen must have at the bitrate in force (see the module docstring)
MIN_BITS_PER_PIXEL: Final = 0.03


def pixels_of(size: Resolution) -> int:
    """Width × height."""
    return size.width * size.height


def bits_per_pixel(kbps: float, size: Resolution, fps: float) -> float:
    """``kbps`` kbit/s spread over ``fps`` pictures a second of ``size``: bits per pixel per picture."""
    if fps <= 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    return kbps * 1000.0 / (pixels_of(size) * fps)


def candidate_sizes(listed: Collection[Resolution], shape: Resolution) -> tuple[Resolution, ...]:
    """The sizes of ``listed`` in the shape (width:height) of ``shape``, no larger than it, largest first."""
    sizes = {r for r in listed if same_aspect(r, shape) and pixels_of(r) <= pixels_of(shape)}
    return tuple(sorted(sizes, key=lambda r: (pixels_of(r), r.width), reverse=True))


def size_for(
    listed: Collection[Resolution], shape: Resolution, fps: float, kbps: float, threshold: float = MIN_BITS_PER_PIXEL
) -> Resolution:
    """The largest of :func:`candidate_sizes` with at least ``threshold`` bits per pixel per picture at ``kbps``
    and ``fps``; the smallest of them when none has; ``shape`` itself when the camera lists none of that shape."""
    if threshold <= 0:
        raise ValueError(f"threshold must be > 0, got {threshold}")
    sizes = candidate_sizes(listed, shape)
    if not sizes:
        return shape
    for size in sizes:
        if bits_per_pixel(kbps, size, fps) >= threshold:
            return size
    return sizes[-1]


@dataclass(frozen=True, slots=True)
class SizeConfig:
    """How :class:`PassthroughSize` changes size (seconds; ``up_margin`` × ``threshold`` to go up)."""

    threshold: float = MIN_BITS_PER_PIXEL
    up_margin: float = 1.25  # a larger size only with this × the threshold: no flapping at the boundary
    down_hold_s: float = 2.0  # the bitrate wants a smaller size this long (a link budget's step lasts) ...
    up_hold_s: float = 10.0  # ... a larger one this long (a restart to go up is a cost, not an emergency)
    min_interval_s: float = 10.0  # at most one restart of the camera's session per this

    def __post_init__(self) -> None:
        """Refuse settings that would flap or never decide."""
        if self.threshold <= 0 or self.up_margin < 1.0:
            raise ValueError("need threshold > 0 and up_margin >= 1")
        if min(self.down_hold_s, self.up_hold_s, self.min_interval_s) < 0:
            raise ValueError("need down_hold_s, up_hold_s, min_interval_s >= 0")


class PassthroughSize:
    """The size to ask the camera for, with hysteresis (see the module docstring); thread-safe.

    :meth:`update` is called with what the request is made of (often: on every access unit); it returns the size to
    ask for now. The first call, and the first after the camera's list, the shape or the frame rate changed, decides
    at once (no session of that request is playing yet)."""

    def __init__(self, config: SizeConfig | None = None) -> None:
        """No size chosen yet."""
        self.config = config or SizeConfig()
        self._lock = threading.Lock()
        self._size: Resolution | None = None
        self._key: tuple[tuple[Resolution, ...], Resolution, float] | None = None
        self._changed = -1e18  # when the size was last chosen
        self._want: Resolution | None = None  # another size the bitrate asks for ...
        self._since = 0.0  # ... in that direction since then
        self.changes = 0  #: size changes after the first choice (each one restarts the camera's session)

    @property
    def size(self) -> Resolution | None:
        """The size last chosen (None before the first :meth:`update`)."""
        return self._size

    def update(
        self, now: float, listed: Collection[Resolution], shape: Resolution, fps: float, kbps: float
    ) -> Resolution:
        """The size to ask for at ``now`` (monotonic s): ``listed`` = the camera's sizes, ``shape`` = the size
        asked for (auto: the largest listed; its shape and the most pixels), ``fps`` and ``kbps`` = the frame rate
        and bitrate the camera is to be asked for."""
        cfg = self.config
        key = (tuple(sorted(set(listed), key=lambda r: (r.width, r.height))), shape, float(fps))
        with self._lock:
            if self._size is None or key != self._key:
                self._key = key
                self._size = size_for(listed, shape, fps, kbps, cfg.threshold)
                self._want, self._changed = None, now
                return self._size
            current = self._size
            want = size_for(listed, shape, fps, kbps, cfg.threshold)
            if pixels_of(want) > pixels_of(current):
                # up only to a size with the threshold and a margin: a step down to the boundary does not come
                # straight back up
                want = size_for(listed, shape, fps, kbps / cfg.up_margin, cfg.threshold)
                if pixels_of(want) <= pixels_of(current):
                    want = current
            if want == current:
                self._want = None
                return current
            down = pixels_of(want) < pixels_of(current)
            if self._want is None or down != (pixels_of(self._want) < pixels_of(current)):
                self._since = now  # a new direction: its hold starts now (within one, the latest size counts)
            self._want = want
            hold = cfg.down_hold_s if down else cfg.up_hold_s
            if now - self._since >= hold and now - self._changed >= cfg.min_interval_s:
                self._size, self._changed, self._want = want, now, None
                self.changes += 1
            return self._size
