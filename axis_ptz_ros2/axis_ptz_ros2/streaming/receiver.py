"""The operator side of the H.264 stream: access units with the stage's ``pts`` in, pictures out. ROS-free.

What the subscribers of :mod:`.h264`'s stream share (the republisher, the link monitor, the web console):
:class:`PtsGaps` counts access units lost on the way from the stage's ``pts``; :class:`AccessUnitReceiver` decodes
them (:class:`~axis_ptz_ros2.media.decoder.H264Decoder`), shows nothing from a loss or a join until the next IDR,
and counts what it could not show (what a consumer reports as ``decode_errors``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

U8Array = npt.NDArray[np.uint8]


class PtsGaps:
    """Access units lost on the way, counted from the stage's ``pts`` (one more per access unit): a running count,
    what a consumer reports as ``LinkFeedback.lost`` (the link monitor through :class:`AccessUnitReceiver`, the web
    console, which relays the access units to the browser undecoded)."""

    def __init__(self) -> None:
        self.lost = 0
        self._last: int | None = None

    def see(self, pts: int) -> bool:
        """Record ``pts``; True when it does not follow the previous one (access units lost, or a restarted stream
        whose pts went back, which adds nothing to :attr:`lost`)."""
        last, self._last = self._last, pts
        if last is None or pts == last + 1:
            return False
        self.lost += max(pts - last - 1, 0)
        return True


@dataclass(slots=True)
class ReceiverStats:
    """What a receiver saw since it was made; :attr:`lost` is read from the receiver's :class:`PtsGaps`."""

    access_units: int = 0
    pictures: int = 0
    unusable: int = 0  # received but not shown: corrupt, or waiting for an IDR after a loss or on joining
    gaps: PtsGaps = field(default_factory=PtsGaps, repr=False)  # the receiver's pts gaps

    @property
    def lost(self) -> int:
        """Access units missing between two received ones (pts gaps)."""
        return self.gaps.lost


class AccessUnitReceiver:
    """The subscriber's side (republisher, link monitor): access units with the stage's pts in, pictures out.

    A gap in ``pts`` (a message lost or overwritten on the way) makes the decoder wait for the next IDR: the
    pictures predicted from the missing one would be wrong, and none is shown. Every access unit received but
    not shown counts as unusable; :meth:`take_unusable` hands the count since the last call (what the link
    monitor reports as ``decode_errors``, which makes the stream node send an IDR).
    """

    def __init__(self) -> None:
        """A fresh decoder that waits for an IDR. Raises
        :class:`~axis_ptz_ros2.media.pyav.PyAvUnavailableError` without a usable PyAV (the decoder needs it; the
        rest of this module does not, so the nodes that use it start and say so)."""
        from axis_ptz_ros2.media.decoder import H264Decoder  # noqa: PLC0415 - PyAV, imported when first needed

        self._decoder = H264Decoder()
        self._gaps = PtsGaps()
        self._pending_unusable = 0
        self.stats = ReceiverStats(gaps=self._gaps)

    @property
    def decoder_errors(self) -> int:
        """Access units FFmpeg (or the bitstream checks) refused."""
        return self._decoder.stats.decode_errors

    def feed(self, data: bytes, pts: int | None = None) -> DecodedImage | None:
        """One access unit; the picture (BGR) or None when it cannot be shown."""
        self.stats.access_units += 1
        if pts is not None and self._gaps.see(pts):
            self._decoder.mark_discontinuity()  # also a restarted stream (pts back to a lower value)
        picture = self._decoder.decode(data)
        if picture is None:
            self.stats.unusable += 1
            self._pending_unusable += 1
            return None
        self.stats.pictures += 1
        return DecodedImage(picture.image, picture.keyframe, picture.capture_ns)

    def take_unusable(self) -> int:
        """Unusable access units since the last call."""
        n = self._pending_unusable
        self._pending_unusable = 0
        return n


@dataclass(frozen=True, slots=True)
class DecodedImage:
    """A decoded picture: BGR (height, width, 3) uint8, IDR or not, capture stamp from the SEI [ns]."""

    image: U8Array
    keyframe: bool
    capture_ns: int | None
