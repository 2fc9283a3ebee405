"""The video controller's values, ROS-free: what is asked for (:class:`VideoSettings`, the stream node's live
video parameters field for field), what is in effect (:class:`VideoState`), and the records of its decisions for
the log (:class:`BudgetStep`, :class:`LinkJudgement`). The policy that reads and makes them is
:mod:`.controller`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.streaming.budget import BudgetConfig
from axis_ptz_ros2.streaming.feedback import Decision, FeedbackReport
from axis_ptz_ros2.streaming.meter import Rate
from axis_ptz_ros2.vapix.models import Resolution, VideoParams


@dataclass(frozen=True, slots=True)
class VideoSettings:
    """What is asked for: the stream node's live video parameters, field for field (their defaults are the
    parameters' defaults); the ``h264_*`` parameters fill :attr:`h264`."""

    fps: int = 15
    resolution: str = ""  # 'WIDTHxHEIGHT' or a CIF name; '' = the largest the camera lists
    compression: int = 30
    max_bitrate_kbps: int = 0  # hand-set budget, 0 = off
    budget_max_compression: int = 60
    budget_min_fps: int = 15
    adapt_to_link: bool = True
    link_release: float = 30.0  # s
    codec: str = "mjpeg"  # mjpeg | h264 (see :mod:`.controller`)
    # the encoder's: h264_bitrate_kbps (without feedback), h264_max_bitrate_kbps (the most a clear link may raise it
    # to), h264_keyframe_interval (<= 1 s applies), h264_reported_wave, h264_preset; the other fields keep
    # H264Settings' defaults
    h264: H264Settings = field(default_factory=H264Settings)

    def budget_config(self) -> BudgetConfig:
        """The budget ladder's shape."""
        return BudgetConfig(max_compression=int(self.budget_max_compression), min_fps=int(self.budget_min_fps))


@dataclass(frozen=True, slots=True)
class VideoState:
    """What is in effect (for ``video/params`` and diagnostics)."""

    params: VideoParams
    source: str  # cause of the parameters in effect: startup, parameter, service, bandwidth_budget
    budget_kbps: float  # the budget in force (0 = none), in either codec
    level: int  # the budget ladder's level (0 = the request)
    resolutions: tuple[Resolution, ...]  # the camera's list (the PAL 214's until learned), smallest first
    adapt: bool
    link_budget_kbps: float  # 0 while adaptation is off
    link_state: str  # "off" while adaptation is off
    link_queue_delay_s: float  # nan before the first judged report


@dataclass(frozen=True, slots=True)
class BudgetStep:
    """A switch of settings by the budget (for the log)."""

    before: int
    after: int
    params: VideoParams
    budget_kbps: float
    rate: Rate

    def __str__(self) -> str:
        """One debug line."""
        p, r = self.params, self.rate
        return (
            f"budget {self.budget_kbps:.0f} kbit/s: level {self.before} -> {self.after} ({p.resolution} @ {p.fps} "
            f"c{p.compression}); measured {r.kbps:.0f} kbit/s {r.fps:.1f} fps "
            f"{r.bytes_per_frame:.0f} B/frame over {r.span_s:.2f} s"
        )


@dataclass(frozen=True, slots=True)
class LinkJudgement:
    """A consumer's report as judged (for the log)."""

    decision: Decision
    report: FeedbackReport
    sent: Rate
    level: int

    def __str__(self) -> str:
        """One debug line."""
        d, r, s = self.decision, self.report, self.sent
        return (
            f"link {d.state}: budget {d.budget_kbps:.0f} kbit/s; {r.consumer} received "
            f"{r.fps:.1f} fps {r.kbps:.0f} kbit/s (queue {d.queue_delay_s * 1000:.0f} ms p95 "
            f"{d.median_queue_s * 1000:.0f} ms p50 {d.floor_queue_s * 1000:.0f} ms floor, "
            f"delivery {d.delivery:.2f}); sent {s.fps:.1f} fps {s.kbps:.0f} kbit/s; level {self.level}"
        )
