"""The MJPEG topic while the codec is H.264: a second camera stream on the MJPEG ladder, in a share of the budget.
ROS-free.

In ``h264`` mode the camera is asked for compression 0 (the encoder's best input, :mod:`.controller`). Before
issue 40 those JPEGs also went to every ``image_raw/compressed`` subscriber, at full rate: one ``rqt_image_view``
(or a link monitor left at ``codec: mjpeg``) on the operator's side swamped the link, the link adapter squeezed the
H.264 stream to almost nothing and the keep-last queue replaced its IDRs before they were repaired.

**A second stream, not skipped frames** (measured on the simulated 214, the view the benches use): a compression-0
704x576 JPEG is 245 kB, 1.96 Mbit -- a 2 Mbit/s link carries one a second and nothing else, so no rate of skipped
frames gives an MJPEG subscriber the 5 pictures/s it needs next to the H.264 stream on that link. The same view at
176x144 and compression 60 is about 4.5 kB: six a second are ~220 kbit/s. So while the codec is H.264 and someone
subscribes to ``image_raw/compressed``, the node opens a second MJPEG stream of the camera for that topic
(the pipeline's second reader, :mod:`.pipeline`; an Axis camera serves several at once), and its parameters come from
:class:`MjpegShare`:

* the share: :data:`MJPEG_SHARE` of what the budget lets the video have as a whole (the H.264 target,
  :func:`~.h264_policy.h264_target_kbps`, which follows the link adapter and ``max_bitrate_kbps``) goes to this
  stream, the rest to the encoder (:func:`split_kbps`) -- both cross the same link;
* the MJPEG ladder (:class:`~.budget.BandwidthController`) over the request (``resolution``, ``fps``,
  ``compression`` as asked) with finer rate steps (:data:`SHARE_FPS_STEPS`) and the size shrinking before the rate
  goes below :data:`SHARE_MIN_FPS`; it judges this stream's own measured rate against the share;
* its first level is predicted from the compression-0 stream's measured bytes per frame (the transcoder's input,
  already flowing on the robot's loopback), so not one full-size JPEG crosses the link first; without that
  measurement (a camera that streams H.264 itself) it starts at the bottom of the ladder and climbs.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from typing import Final

from axis_ptz_ros2.streaming.budget import AXIS214_PAL_RESOLUTIONS, BandwidthController, BudgetConfig
from axis_ptz_ros2.streaming.meter import BitrateMeter
from axis_ptz_ros2.vapix.models import Resolution, VideoParams

#: of the video's budget as a whole, the MJPEG stream's share while it has a subscriber (the encoder gets the rest)
MJPEG_SHARE: Final = 0.3
#: pictures/s: the share's ladder lowers the size before the rate below this (the crowded-link target is >= 5)
SHARE_MIN_FPS: Final = 6
#: the share's rate steps (finer than the main ladder's near the bottom: 6 pictures/s fit where 10 do not)
SHARE_FPS_STEPS: Final = (25, 20, 15, 12, 10, 8, 6, 5, 4, 3, 2, 1)
#: s: the share's ladder is judged at most this often
SHARE_PERIOD_S: Final = 0.25


def split_kbps(kbps: int, share_on: bool) -> tuple[int, int]:
    """``kbps`` for the video as a whole -> (the encoder's kbit/s, the MJPEG stream's kbit/s)."""
    if not share_on:
        return kbps, 0
    mjpeg = round(kbps * MJPEG_SHARE)
    return kbps - mjpeg, mjpeg


class MjpegShare:
    """The MJPEG stream's parameters while the codec is H.264 (see the module docstring); thread-safe."""

    def __init__(
        self,
        requested: VideoParams,
        total_kbps: Callable[[], float],
        *,
        max_compression: int = 60,
        window_s: float = 2.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """``total_kbps()``: what the budget lets the video have as a whole now (read at every judgement)."""
        self._lock = threading.Lock()
        self._total = total_kbps
        self._clock = clock
        self._max_compression = int(max_compression)
        self._requested = requested
        self._resolutions: tuple[Resolution, ...] = AXIS214_PAL_RESOLUTIONS
        self.meter = BitrateMeter(window_s)  # the second stream's reader feeds it
        self._ladder = self._new_ladder()
        self._checked = -1e18
        self.active = False  # someone subscribes to the MJPEG topic while the codec is H.264

    @property
    def current(self) -> VideoParams:
        """The parameters the second stream is to use now."""
        return self._ladder.current

    @property
    def budget_kbps(self) -> float:
        """The MJPEG stream's share now (0 while inactive)."""
        return self._share() if self.active else 0.0

    def configure(self, requested: VideoParams, resolutions: Sequence[Resolution] | None, max_compression: int) -> None:
        """A new request or the camera's own resolution list: the ladder is rebuilt. While the stream runs, its
        first level is predicted from this stream's own measured pictures (as :meth:`start` does from the
        compression-0 stream's), never the request as asked: the owner's reader then reconnects with it."""
        with self._lock:
            if resolutions:
                self._resolutions = tuple(resolutions)
            self._requested, self._max_compression = requested, int(max_compression)
            old = self._ladder.current
            self._ladder = self._new_ladder()
            if self.active:
                self._fit_locked(old, self.meter.rate(self._clock()).bytes_per_frame)

    def start(self, ref: VideoParams, ref_bytes_per_frame: float) -> VideoParams:
        """The stream is about to open: its first level, predicted from the compression-0 stream (``ref`` at
        ``ref_bytes_per_frame``, 0 = not measured: the bottom of the ladder)."""
        with self._lock:
            return self._fit_locked(ref, ref_bytes_per_frame)

    def _fit_locked(self, ref: VideoParams, ref_bytes_per_frame: float) -> VideoParams:
        """The ladder's first level predicted from ``ref`` at ``ref_bytes_per_frame``; this stream's meter starts
        again (call with the lock held)."""
        now = self._clock()
        self._ladder.set_budget(self._share(), now)
        self.meter.reset()
        return self._ladder.fit_from(ref, ref_bytes_per_frame, now)

    def on_frame(self, now: float) -> VideoParams | None:
        """A picture of the second stream arrived (its reader thread): at most every :data:`SHARE_PERIOD_S`,
        judge its measured rate against the share; new parameters when the ladder steps."""
        if now - self._checked < SHARE_PERIOD_S:
            return None
        self._checked = now
        rate = self.meter.rate(now)
        with self._lock:
            self._ladder.set_budget(self._share(), now)
            return self._ladder.update(now, rate.kbps, rate.fps, rate.bytes_per_frame, rate.frames)

    def _share(self) -> float:
        return max(1.0, float(self._total()) * MJPEG_SHARE)

    def _new_ladder(self) -> BandwidthController:
        config = BudgetConfig(
            max_compression=max(self._max_compression, self._requested.compression),
            fps_steps=SHARE_FPS_STEPS,
            min_fps=SHARE_MIN_FPS,
        )
        return BandwidthController(self._requested, self._share(), self._resolutions, config)
