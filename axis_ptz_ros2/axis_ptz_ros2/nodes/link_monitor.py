"""Consumer-side feedback for the video over a weak link.

:class:`FeedbackPublisher` is what a node that *views* the video adds to its image callback: it measures what
arrives (frames/s, kbit/s, delay from the stream node's stamp to receipt) and publishes it on
``video/feedback`` twice a second, which the stream node turns into a bandwidth budget
(:mod:`axis_ptz_ros2.streaming.feedback`). The web console does this for the PTZ image it relays.

``axis_link_monitor`` is the same as a node of its own, for viewers that do not report (e.g. a generic image
viewer on the operator's station). Run it on the *operator's* host only where nothing else reports: every
subscriber across the link receives its own copy of each frame, so a second subscriber doubles the video's
share of the link.

What it watches follows the stream by default (``codec`` = ``auto``): the codec the stream node announces on
``video/params`` (latched), switched when it changes, the old subscription dropped (:mod:`axis_ptz_ros2.codec_follow`);
until ``video/params`` is heard it subscribes to no video and sends no report (a report of nothing received would
read as a dead link). A monitor left at MJPEG while the robot streams H.264 pulled the transcoder's compression-0
JPEGs at full rate over a 2 Mbit/s link and starved the H.264 viewer (issue 40). ``codec`` = ``mjpeg`` or ``h264``
fixes the choice.

Watching H.264, the monitor subscribes to the H.264 topic (``h264_topic``, ``FFMPEGPacket``) and
decodes what arrives (:class:`~axis_ptz_ros2.streaming.receiver.AccessUnitReceiver`): access units lost on the way
or that do not decode are reported as ``decode_errors``, and the stream node answers them with an IDR. The first
access unit that cannot be shown after a picture was is reported at once, not at the next period: every access
unit until the IDR is lost to the viewer, and waiting for the period (0.25 s on average) cost ~8 of them.
"""

from __future__ import annotations

import time
from collections import deque
from typing import Any

from ffmpeg_image_transport_msgs.msg import FFMPEGPacket
from rclpy.node import Node
from rclpy.subscription import Subscription
from sensor_msgs.msg import CompressedImage

from axis_ptz_interfaces.msg import LinkFeedback
from axis_ptz_ros2.codec_follow import CHOICES
from axis_ptz_ros2.media.pyav import PyAvUnavailableError
from axis_ptz_ros2.nodes.codec_follow import follow_stream_codec, no_events
from axis_ptz_ros2.nodes.common import (
    FEEDBACK_QOS,
    STREAM_QOS,
    VIDEO_QOS,
    ParamSpec,
    publisher,
    stamp_s,
)
from axis_ptz_ros2.nodes.live_params import LiveParams
from axis_ptz_ros2.nodes.runner import run_nodes
from axis_ptz_ros2.streaming.receive_meter import ReceiveMeter
from axis_ptz_ros2.streaming.receiver import AccessUnitReceiver, PtsGaps
from axis_ptz_ros2.streaming.wall_clock import WallClockSteps

#: s: reports of a loss that just began at most this often (besides the periodic ones)
URGENT_MIN_INTERVAL_S = 0.1

PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("image_topic", "image_raw/compressed", "JPEG topic whose reception is reported", read_only=True),
    ParamSpec(
        "codec",
        "auto",
        "which video to watch: auto = the codec the stream node announces on video/params (switched when it "
        "changes; no video subscribed until it is heard), mjpeg = image_topic, h264 = h264_topic",
        choices=CHOICES,
        read_only=True,
    ),
    ParamSpec(
        "h264_topic", "image_raw/ffmpeg", "H.264 topic (FFMPEGPacket) watched when the codec is h264", read_only=True
    ),
    ParamSpec("feedback_topic", "video/feedback", "where the reports go (the stream node listens)", read_only=True),
    ParamSpec("period", 0.5, "report period", "s", float_range=(0.05, 10.0), read_only=True),
    ParamSpec("window", 2.0, "measurement window of a report", "s", float_range=(0.1, 30.0), read_only=True),
)


class FeedbackPublisher:
    """Measure the frames a node receives and report them on ``video/feedback`` (see the module docstring).

    Call :meth:`watch` when the node subscribes to the video (or let the first :meth:`add` do it) and
    :meth:`stop` when it unsubscribes; :meth:`add` from the image callback. While watching it reports twice a
    second, also when nothing arrives (frames = 0, ``gap_s`` = time since the last frame or since watching
    began): a link so swamped that no frame gets through must still be reported.
    """

    def __init__(
        self,
        node: Node,
        image_topic: str = "image_raw/compressed",
        feedback_topic: str = "video/feedback",
        period_s: float = 0.5,
        window_s: float = 2.0,
        callback_group: Any = None,
    ) -> None:
        """Create the publisher and the report timer on ``node``."""
        self._node = node
        self._topic = node.resolve_topic_name(image_topic)
        self._meter = ReceiveMeter(node.get_fully_qualified_name(), window_s)
        self._pub = publisher(node, LinkFeedback, feedback_topic, FEEDBACK_QOS)
        self._timer = node.create_timer(period_s, self._report, callback_group=callback_group)
        self._since: float | None = None
        self._first_rx: float | None = None  # the first frame since watching began
        self._errors: deque[tuple[float, int]] = deque()
        self.lost = 0  # access units that never arrived, a running count (H.264: set by the node)
        self._last_urgent = -1e18
        self.reports = 0
        self.wall = time.time  #: the arrivals' clock (this host's wall clock, as the stream node's stamps) ...
        self.host_clock = WallClockSteps()  #: ... and its steps, which the kept arrivals follow

    @property
    def topic(self) -> str:
        """The (resolved) video topic whose reception is reported (the reports' ``header.frame_id``)."""
        return self._topic

    def retarget(self, image_topic: str) -> None:
        """The node watches another topic now (another codec): reports stop until :meth:`watch` and start afresh
        (frames, bytes and losses of the old codec say nothing of the new one)."""
        self.stop()
        self._topic = self._node.resolve_topic_name(image_topic)
        self._meter = ReceiveMeter(self._meter.consumer, self._meter.window_s)
        self._errors.clear()
        self.lost = 0  # a restarted running count (the stream node takes it as such)

    def watch(self) -> None:
        """The node subscribed to the video: report from now on (idempotent)."""
        if self._since is None:
            self._since = self.wall()
            self._first_rx = None

    def stop(self) -> None:
        """The node unsubscribed: no more reports until :meth:`watch` or the next frame."""
        self._since = None
        self._first_rx = None

    def add(self, msg: CompressedImage, nbytes: int | None = None, rx: float | None = None) -> None:
        """One image received now, or at ``rx`` (wall clock, s: its arrival, before any decoding) (any thread)."""
        if rx is None:
            self._clock_step(self.host_clock.check())
            rx = self.wall()
        else:  # read before this call (before the decoding), perhaps before a step: on the clock as it is now
            step, moved = self.host_clock.check_read(round(rx * 1e9))
            if self._clock_step(step):
                rx = moved / 1e9
        self.watch()
        if self._first_rx is None:
            self._first_rx = rx
        stamp = stamp_s(msg.header.stamp)
        if stamp <= 0:
            return
        self._meter.add(rx, stamp, len(msg.data) if nbytes is None else nbytes)

    def add_errors(self, count: int, urgent: bool = False) -> None:
        """``count`` frames received now could not be shown (H.264: lost before them, corrupt, or waiting for
        an IDR); ``urgent``: report now (a loss that just began), at most every :data:`URGENT_MIN_INTERVAL_S`."""
        if count > 0:
            self._clock_step(self.host_clock.check())
            now = self.wall()
            self._errors.append((now, count))
            if urgent and now - self._last_urgent >= URGENT_MIN_INTERVAL_S:
                self._last_urgent = now
                self._report()

    def _clock_step(self, step_ns: int) -> float:
        """This host's wall clock (NTP, chrony) stepped by ``step_ns`` (0: it did not, as :attr:`host_clock` found):
        every arrival kept moves with it (a step is no delay on the link: before, +0.5 s read as a 0.5 s queue for
        10 s, and the stream node cut the video). Returns the step (s), 0 for none."""
        step = step_ns / 1e9
        if step:
            self._meter.clock_stepped(step)
            self._errors = deque((t + step, n) for t, n in self._errors)
            self._since = None if self._since is None else self._since + step
            self._first_rx = None if self._first_rx is None else self._first_rx + step
            self._last_urgent += step
        return step

    def _report(self) -> None:
        self._clock_step(self.host_clock.check())
        since = self._since
        if since is None:
            return
        now = self.wall()
        first = self._first_rx
        if first is not None and now - first < self._meter.window_s:
            # frames arrive, but for less than a window: its rates would read as a narrow link (weak-link bench:
            # the first report of a new monitor, 7 of 30 fps, cut the H.264 budget to 161 kbit/s)
            return
        while self._errors and self._errors[0][0] <= now - self._meter.window_s:
            self._errors.popleft()
        r = self._meter.report(now)
        msg = LinkFeedback()
        msg.header.stamp = self._node.get_clock().now().to_msg()
        msg.header.frame_id = self._topic
        msg.consumer = r.consumer
        msg.window_s = float(self._meter.window_s)
        msg.frames = r.frames
        msg.fps = float(r.fps)
        msg.kbps = float(r.kbps)
        msg.delay_p95_s = float(r.delay_p95_s)
        msg.delay_p50_s = float(r.delay_p50_s)
        msg.delay_floor_s = float(r.delay_floor_s)
        msg.delay_min_s = float(r.delay_min_s)
        msg.gap_s = float(min(r.gap_s, now - since))
        msg.decode_errors = sum(n for _t, n in self._errors)
        msg.lost = self.lost
        self._pub.publish(msg)
        self.reports += 1


class LinkMonitorNode(Node):
    """``axis_link_monitor``: subscribe to the stream's video and report its reception on ``video/feedback``."""

    def __init__(self, **kwargs: Any) -> None:
        """``kwargs`` go to :class:`rclpy.node.Node`."""
        super().__init__("axis_link_monitor", **kwargs)
        p = LiveParams(self, PARAMS).params  # all read-only: read once
        self._topics = {"mjpeg": str(p["image_topic"]), "h264": str(p["h264_topic"])}
        self.receiver: AccessUnitReceiver | None = None
        self._sub: Subscription | None = None
        self._showing = False  # the last access unit was shown (a loss after it is reported at once)
        self._gaps = PtsGaps()  # without a decoder (no usable PyAV): losses from the pts, no decode errors
        self._pyav_told = False
        self.codec = ""  # the video watched now: mjpeg, h264, '' = none (waiting for video/params)
        self.follower = follow_stream_codec(self, str(p["codec"]), self._watch)
        first = self.follower.codec or "mjpeg"
        self.feedback = FeedbackPublisher(
            self, self._topics[first], str(p["feedback_topic"]), float(p["period"]), float(p["window"])
        )
        self._watch(self.follower.codec)

    def _watch(self, codec: str) -> None:
        """Subscribe to the video of ``codec`` ('' = none), dropping the old subscription first."""
        if codec == self.codec and (self._sub is not None or not codec):
            return
        if self._sub is not None:
            self.destroy_subscription(self._sub)
            self._sub = None
        self.codec = codec
        self.receiver = None
        self._showing = False
        self._gaps = PtsGaps()
        if not codec:
            self.feedback.stop()
            return
        topic = self._topics[codec]
        self.feedback.retarget(topic)
        if codec == "h264":
            try:
                self.receiver = AccessUnitReceiver()  # a new subscription waits for an IDR
            except PyAvUnavailableError as err:
                if not self._pyav_told:
                    self._pyav_told = True
                    self.get_logger().error(f"{err}; reporting what arrives and what is lost, not what decodes")
            self._sub = self.create_subscription(
                FFMPEGPacket, topic, self._on_packet, VIDEO_QOS, event_callbacks=no_events()
            )
        else:
            self._sub = self.create_subscription(
                CompressedImage, topic, self.feedback.add, STREAM_QOS, event_callbacks=no_events()
            )
        self.feedback.watch()

    def _on_packet(self, msg: FFMPEGPacket) -> None:
        """Decode; every access unit that arrives counts as received (it crossed the link), what cannot be shown
        counts as decode errors (the stream node answers with an IDR). Counting only the pictures shown made a
        single loss look like a narrow link — every access unit up to the next IDR is unusable — and the
        adapter stepped the bitrate down to its floor on a 2 Mbit/s link (weak-link bench, 488faa0)."""
        rx = self.feedback.wall()  # the arrival: the decoding's time is no delay on the link
        data = bytes(msg.data)
        if self.receiver is None:
            self._gaps.see(int(msg.pts))
            self.feedback.lost = self._gaps.lost
            self.feedback.add(msg, len(data), rx)
            return
        shown = self.receiver.feed(data, int(msg.pts)) is not None
        self.feedback.lost = self.receiver.stats.lost
        self.feedback.add(msg, len(data), rx)
        self.feedback.add_errors(self.receiver.take_unusable(), urgent=self._showing and not shown)
        self._showing = shown


def main(args: list[str] | None = None) -> int:
    """``axis_link_monitor``."""
    return run_nodes([LinkMonitorNode], args)


if __name__ == "__main__":
    raise SystemExit(main())
