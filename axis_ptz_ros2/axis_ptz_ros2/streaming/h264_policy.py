"""How the budgets in force become the H.264 encoder's settings, and which codec settings are valid. ROS-free.

The video controller (:mod:`.controller`) holds the budgets; these functions turn them into an
:class:`~axis_ptz_ros2.media.h264_settings.H264Settings` target:

* without any feedback ``h264_bitrate_kbps`` applies, so a viewer that reports nothing still gets the full
  picture; a budget lowers it; and where consumers report a clear link, the link adapter's budget may raise it up
  to the ceiling ``h264_max_bitrate_kbps`` (at most :data:`H264_BUDGET_FRACTION` of the budget: a margin under
  what the link was measured to carry). A ceiling equal to ``h264_bitrate_kbps`` never raises it
  (:func:`h264_target_kbps`);
* the encoder's VBV buffer, which bounds its largest picture, follows the bitrate; with periodic IDRs and a link
  budget it is at most :data:`IDR_LINK_S` of the budget (:func:`h264_vbv_kbit`).
"""

from __future__ import annotations

from typing import Final

from axis_ptz_ros2.media.limits import BITRATE_RANGE_KBPS, CODECS, VBV_BUFFER_S
from axis_ptz_ros2.streaming.budget import BudgetConfig
from axis_ptz_ros2.streaming.video_types import VideoSettings

#: the encoder's own parameters, which fill ``VideoSettings.h264``. They change what the camera is asked for only
#: when its own H.264 is passed through (its bitrate and GOP: :func:`~.rtsp_source.media_request`), never its JPEGs
H264_FIELDS: Final = frozenset(
    {"h264_bitrate_kbps", "h264_max_bitrate_kbps", "h264_keyframe_interval", "h264_reported_wave", "h264_preset"}
)
#: above ``h264_bitrate_kbps`` the encoder targets at most this fraction of the link adapter's budget (the MJPEG
#: ladder's aim after a step down, :attr:`~.budget.BudgetConfig.down_fraction`)
H264_BUDGET_FRACTION: Final = BudgetConfig().down_fraction
#: s: with periodic IDRs and a link budget, the encoder's VBV buffer (its largest picture, an IDR) is at most this
#: long on the link (:func:`h264_vbv_kbit`)
IDR_LINK_S: Final = 0.06


def check_h264(settings: VideoSettings) -> str | None:
    """The reason the codec settings cannot be used (None = fine): the codec, and the bitrates against the
    parameters' range (narrower than the encoder's, which :class:`~axis_ptz_ros2.media.h264_settings.H264Settings`
    checks with the preset and the keyframe interval when it is made)."""
    if settings.codec not in CODECS:
        return f"codec={settings.codec!r} is not one of {', '.join(CODECS)}"
    low, high = BITRATE_RANGE_KBPS
    h264 = settings.h264
    if not low <= h264.bitrate_kbps <= high:
        return f"h264_bitrate_kbps={h264.bitrate_kbps} is outside {low}…{high} kbit/s"
    if not low <= h264.max_bitrate_kbps <= high:
        return f"h264_max_bitrate_kbps={h264.max_bitrate_kbps} is outside {low}…{high} kbit/s"
    return None


def h264_target_kbps(start: int, ceiling: int, link_kbps: float, hand_kbps: float = 0.0) -> tuple[int, int]:
    """The H.264 bitrate to target now and the highest one to expect (what an encoder opens with as its VBV
    ``maxrate``, so a live change up to it needs no re-open), in kbit/s.

    ``start`` (``h264_bitrate_kbps``) applies without any budget; the link adapter's budget ``link_kbps`` (0 = no
    feedback) lowers it when under it and, above it, raises it to :data:`H264_BUDGET_FRACTION` of the budget, up to
    ``ceiling`` (``h264_max_bitrate_kbps``; at or below ``start``: never above ``start``); the hand-set budget
    ``hand_kbps`` (``max_bitrate_kbps``, 0 = off) caps it. Never below the encoder's floor."""
    ceiling = max(ceiling, start)
    kbps = start
    if link_kbps > 0:
        kbps = max(min(start, int(link_kbps)), min(ceiling, int(link_kbps * H264_BUDGET_FRACTION)))
    if hand_kbps > 0:
        kbps = min(kbps, int(hand_kbps))
    kbps = max(BITRATE_RANGE_KBPS[0], kbps)
    # the ceiling is announced only once the link lets the target past the start: an encoder re-opened for it
    # (an IDR) once, when it is needed, not on every budget that merely lowers the bitrate
    top = ceiling if link_kbps * H264_BUDGET_FRACTION > start else start
    return kbps, max(top, kbps)


def h264_vbv_kbit(kbps: int, link_kbps: float, refresh: str) -> int:
    """The encoder's VBV buffer in kbit: :data:`~axis_ptz_ros2.media.limits.VBV_BUFFER_S` of the bitrate ``kbps``
    targeted now; with periodic IDRs (``refresh`` ``"idr"``) and a link budget ``link_kbps`` (0 = none), at most
    :data:`IDR_LINK_S` of it.

    The buffer bounds the largest picture. With an IDR every second the pictures behind each IDR waited for it to
    cross the link: on 1 Mbit/s with 2 % loss, IDRs of ~114 kbit (a buffer opened at 1000 kbit/s and kept while the
    bitrate followed the link down) reached the operator 125-216 ms after capture, every second; hence the cap.
    With x264's intra refresh (the default) there is no periodic IDR to bound, and the cap only starved the
    encoder: x264 cannot change the buffer on an open encoder, so the buffer chosen when it re-opened at its
    ceiling (the first step past ``h264_bitrate_kbps``, budget ~1200 kbit/s: 72 kbit) stayed, and the encoder
    made 929 kbit/s of a 1500 kbit/s target (35.75 dB; 1235 kbit/s and 36.68 dB with 0.15 s of the bitrate:
    ``python bench/encoder_tradeoff.py --only node --kbps 1500 --link-kbps 1200`` / ``4000`` at 7b0f370). An IDR
    on demand still re-opens the encoder with the buffer wanted then (:meth:`~axis_ptz_ros2.media.encoder.
    H264Encoder.set_vbv`): 0.15 s of a bitrate that is at most 0.9 x the budget."""
    vbv = kbps * VBV_BUFFER_S
    if link_kbps > 0 and refresh == "idr":
        vbv = min(vbv, link_kbps * IDR_LINK_S)
    return max(1, round(vbv))
