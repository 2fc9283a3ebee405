"""The video pipeline: one object from the camera to the frames a node publishes. ROS-free.

:class:`VideoPipeline` owns the parts of the stream node's video path and hands every frame out through one
callback, ``on_frame(frame, outlets)`` (:class:`~axis_ptz_ros2.media.frame.EncodedFrame`, a JPEG or an H.264 access
unit, and the :class:`Outlet` set it goes to). The node declares its parameters, forwards changes
(:meth:`VideoPipeline.apply`), consumers' reports (:meth:`VideoPipeline.on_report`) and its subscribers
(:meth:`VideoPipeline.set_demand`), publishes what it is handed and tells ``video/params`` when ``on_params()``
says so. Decisions flow down, frames flow up:

* :class:`~.controller.VideoController` decides what is in effect; its announcements reach the readers here
  (:meth:`~.reader.StreamReader.refresh`), never through the node;
* :class:`~.discovery.CameraDiscovery` learns what the camera is and its sizes;
* :class:`~.reader.StreamReader` reads the camera's MJPEG (``image_raw/compressed``, ``camera_info``, and in h264
  mode the transcoder's input);
* a second reader streams the MJPEG share (:mod:`.mjpeg_share`) while H.264 is in effect (the codec is h264 and
  H.264 can be produced: the camera's own passed through, or PyAV to transcode) and the MJPEG topic has a subscriber;
  without it the MJPEG topic is the main stream at the request, as with codec mjpeg;
* :class:`~.h264.H264Stage` makes the H.264 stream, from the JPEGs (a camera that cannot stream H.264, the 214) or
  from :class:`~.rtsp_source.RtspH264Source` (the camera's own, passed through);
* what the encoder and the camera's RTSP stream are to do (:class:`~axis_ptz_ros2.media.h264_settings.H264Settings`,
  the RTSP request with the size :class:`~.passthrough_size.PassthroughSize` picks with ``resolution`` auto) is
  decided here whenever something it depends on changes (a parameter, a report, a budget step, the 1 Hz tick)
  and pushed down: neither the stage nor the RTSP source asks the controller per frame;
* a new H.264 viewer gets start points (:class:`~.start_points.StartPoints`); whether the encoder's intra-refresh
  wave may be long (:class:`~.long_wave.LongWave`, ``h264_reported_wave``).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Collection
from dataclasses import replace
from enum import IntFlag
from typing import Any

from axis_ptz_ros2.camera_models import CameraProfile
from axis_ptz_ros2.media import pyav
from axis_ptz_ros2.media.frame import JPEG, EncodedFrame
from axis_ptz_ros2.media.h264_settings import H264Settings
from axis_ptz_ros2.streaming.controller import VideoController
from axis_ptz_ros2.streaming.discovery import CameraDiscovery
from axis_ptz_ros2.streaming.feedback import FeedbackReport
from axis_ptz_ros2.streaming.h264 import H264Stage
from axis_ptz_ros2.streaming.jpeg import jpeg_sof
from axis_ptz_ros2.streaming.long_wave import LongWave
from axis_ptz_ros2.streaming.meter import BitrateMeter
from axis_ptz_ros2.streaming.passthrough_size import PassthroughSize
from axis_ptz_ros2.streaming.reader import ReaderConfig, StreamReader, StreamState
from axis_ptz_ros2.streaming.rtsp_source import RtspH264Source, media_request, passthrough_source
from axis_ptz_ros2.streaming.start_points import StartPoints
from axis_ptz_ros2.streaming.status import (
    LogLine,
    LogThrottle,
    h264_diagnostic_values,
    h264_mode_line,
    reader_event_line,
    wave_line,
)
from axis_ptz_ros2.streaming.video_types import VideoSettings
from axis_ptz_ros2.streaming.wall_clock import WallClockSteps
from axis_ptz_ros2.vapix import VapixClient
from axis_ptz_ros2.vapix.models import Resolution


def _h264_possible(settings: VideoSettings, supported: bool | None) -> bool:
    """Whether H.264 can be produced for ``settings``: the camera's own passed through (``supported``: whether it
    streams H.264, None until asked) or transcoded with a usable PyAV (:mod:`~axis_ptz_ros2.media.pyav`, checked
    only when the codec asked for is H.264)."""
    return settings.codec != "h264" or supported is True or pyav.usable()


class Outlet(IntFlag):
    """Where a frame goes: the MJPEG topic (from the main stream, or from the MJPEG share's: each on its own
    thread), ``camera_info`` (its size and stamp), the H.264 topics."""

    NONE = 0
    IMAGE = 1
    CAMERA_INFO = 2
    H264 = 4
    SHARE_IMAGE = 8


class VideoPipeline:
    """The stream node's video path (see the module docstring); control methods are thread-safe."""

    def __init__(
        self,
        client: VapixClient,
        settings: VideoSettings,
        reader_config: ReaderConfig,
        *,
        camera: int,
        model_file: str,
        rtsp_port: int,
        lazy: bool,
        on_frame: Callable[[EncodedFrame, Outlet], None],
        on_params: Callable[[], None],
        on_profile: Callable[[CameraProfile, bool], None],
        log: Callable[[LogLine], None],
    ) -> None:
        """``on_frame(frame, outlets)``: a frame to publish (reader, share or RTSP thread); ``on_params()``: what is
        in effect changed (read :attr:`video`); ``log``: lines to log (throttled here). Raises ValueError (a
        start-up error) if ``settings`` ask for what no camera could stream. Nothing runs until :meth:`start`."""
        self._on_frame = on_frame
        self._on_params = on_params
        self._log_out = log
        self._throttle = LogThrottle()
        self._lazy = lazy
        meter = BitrateMeter(reader_config.meter_window_s)
        self.video = VideoController(
            settings, meter, camera=camera, on_change=self._on_decision, h264_possible=_h264_possible(settings, None)
        )
        self._h264 = self.video.h264_settings()  # what the encoder is to do (pushed: read on the frame path)
        self._stream_size: Resolution | None = None  # passed through with resolution auto: the size asked for
        self._rtsp_request = media_request(self.video.current, self._h264)
        self._image = self._info = False  # the main stream's JPEGs go on the MJPEG topic / feed camera_info
        self._demand = (False, False, 0)  # the node's subscribers: MJPEG topic, camera_info, H.264 topics
        self._viewers: Callable[[], frozenset[str]] = frozenset
        self._told_mode = False
        self._update_lock = threading.RLock()  # demand from the node's threads and the RTSP source's
        self._push_lock = threading.Lock()
        self.transcode = False  # codec h264 from a camera that cannot stream it: the MJPEG feeds the stage
        self._seq = 0
        self.share_published = 0  # JPEGs of the MJPEG share handed out
        self.discovery = CameraDiscovery(
            client,
            model_file,
            lambda: self.video.current,
            on_profile=on_profile,
            on_resolutions=self._on_resolutions,
            on_problem=lambda text: self._log(LogLine("warn", text, "resolutions", 30.0)),
        )
        self.reader = StreamReader(
            self.discovery.open,
            self._on_jpeg,
            lambda: self.video.current,  # the controller owns the parameters; the reader follows
            reader_config,
            on_event=self._on_reader_event,
            active=False,
            meter=meter,
        )
        self.share_reader = StreamReader(
            lambda params, timeout: client.open_mjpeg(params, timeout),
            self._on_share_jpeg,
            lambda: self.video.mjpeg.current,
            reader_config,
            on_event=self._on_share_event,
            active=False,
            meter=self.video.mjpeg.meter,
        )
        self.stage = H264Stage(
            lambda: self._h264, self._on_access_unit, on_problem=lambda t: self._log(LogLine("warn", t, "h264", 10.0))
        )
        self.size = PassthroughSize()  # the size the camera's own H.264 is asked for with resolution auto
        self.rtsp: RtspH264Source = passthrough_source(
            client,
            rtsp_port,
            lambda: self._rtsp_request,
            self.stage,
            reader_config,
            on_supported=self._on_supported,
            on_event=lambda text: self._log(LogLine("warn", text, "rtsp", 10.0)),
        )
        self.starts = StartPoints(self.stage)
        self.wave = LongWave()  # whether the intra-refresh wave may be h264_reported_wave
        self.host_clock = WallClockSteps()  # the frames' stamps are on this host's wall clock: its steps

    # -- decisions down (any thread) ---------------------------------------------------------------------------
    def check(self, settings: VideoSettings, names: Collection[str]) -> str | None:
        """Why ``settings`` cannot be used (None = fine): the node's on-set validation."""
        return self.video.check(settings, names)

    def apply(self, settings: VideoSettings, names: Collection[str], source: str, lazy: bool) -> None:
        """New parameters (after a set): the controller decides, the readers and the H.264 side follow."""
        self._lazy = lazy
        self.video.set_h264_possible(_h264_possible(settings, self.rtsp.supported))  # (before: one switch at most)
        self.video.apply(settings, names, source)
        self._update()

    def set_demand(self, image: int, info: int, h264: int, viewers: Callable[[], frozenset[str]]) -> bool:
        """The node's subscriber counts (MJPEG topic, ``camera_info``, the two H.264 topics together) and who the
        H.264 subscribers are (asked only when there are more of them); returns whether the main reader runs."""
        self._demand = (image > 0, info > 0, h264)
        self._viewers = viewers
        return self._update()

    def on_report(self, report: FeedbackReport, decode_errors: int, about_h264: bool, about_mjpeg: bool,
                  subscribed: Callable[[str], bool]) -> str | None:  # fmt: skip
        """A consumer's report on ``video/feedback`` (about an H.264 topic or none named, or the MJPEG topic):
        start points and IDRs for its losses, then the link's judgement (the MJPEG share's reports do not judge
        the link in h264 mode); returns the judgement's debug line."""
        if about_h264:
            self.starts.report(report.consumer, report.frames, decode_errors)
            self.wave.report(report.consumer, decode_errors, time.monotonic())
        if self.video.h264 and about_mjpeg:
            return None
        self._watch_host_clock()
        judgement = self.video.feedback(report, subscribed)
        if judgement is not None and judgement.decision.state == "congested":
            self.wave.congested(time.monotonic())
        self._decide()
        return None if judgement is None else str(judgement)

    def on_still(self, now: float, nbytes: int) -> None:
        """A still of ``nbytes`` goes out on the link now (monotonic ``now``): counted against the budget, and in
        h264 mode the encoder told at once to leave it room until :meth:`still_crossed`
        (:meth:`.controller.VideoController.on_still`)."""
        self.video.on_still(now, nbytes)
        self._decide()

    def still_crossed(self, now: float) -> None:
        """The still has crossed (every reader acknowledged it, or the wait ended): the encoder's target is back."""
        self.video.still_crossed(now)
        self._decide()

    def tick(self) -> None:
        """1 Hz: the reader's watchdog, the link adapter's hold and release, the passthrough size's holds."""
        self.reader.check_watchdog()
        self._watch_host_clock()
        self.video.tick()
        self._decide()

    def _watch_host_clock(self) -> None:
        """A step of this host's wall clock (NTP, chrony) moved the stamps: the link's reports wait it out."""
        step = self.host_clock.check()
        if step:
            self.video.host_clock_stepped()
            text = (
                f"this host's clock stepped by {step / 1e9:+.3f} s: the stamps follow it; the link's reports are not "
                "judged until their delays are all on the new clock"
            )
            self._log(LogLine("warn", text, "clock"))

    def _on_decision(self) -> None:
        """The controller's announcement (any thread, serialised): the readers follow (the MJPEG share's too: a new
        request rebuilds its ladder), the H.264 side is told, the node publishes ``video/params``."""
        self.reader.refresh()
        self.share_reader.refresh()
        self._push()
        self._on_params()

    def _push(self) -> None:
        """What the encoder and the camera's RTSP stream are to do now, for them to read (serialised: the last
        one written was decided last)."""
        with self._push_lock:
            h264 = self.video.h264_settings()
            h264 = replace(h264, long_wave=self.wave.allowed(time.monotonic()))
            params = self.video.current
            if self._stream_size is not None:
                params = replace(params, resolution=self._stream_size)
            wave = self._h264.effective_keyframe_interval
            self._h264 = h264
            self._rtsp_request = media_request(params, h264)
        if self.transcode and h264.refresh == "intra" and h264.effective_keyframe_interval != wave:
            self._log(LogLine("info", wave_line(h264)))

    def _decide(self) -> None:
        """Re-decide what the H.264 side is to do; passed through with ``resolution`` auto and the camera's sizes
        known, the size that reads best at the bitrate in force (shown on ``video/params``)."""
        self._push()
        video = self.video
        if not (video.h264 and self._demand[2] > 0 and self.rtsp.supported):
            return  # not passed through now
        params = video.current
        size: Resolution | None = None
        if not str(video.settings.resolution).strip() and video.resolutions_known:
            listed = video.state().resolutions
            size = self.size.update(time.monotonic(), listed, params.resolution, params.fps, self._h264.bitrate_kbps)
        self._stream_size = size
        video.set_stream_size(size)  # (announced when it changed: _on_decision)
        self._push()

    def _update(self) -> bool:
        """Follow the node's demand (an IDR and start points for a new H.264 viewer); returns whether the main
        reader runs."""
        with self._update_lock:
            return self._update_locked()

    def _update_locked(self) -> bool:
        image, info, h264 = self._demand
        asked_h264 = self.video.settings.codec == "h264"
        self.video.set_h264_possible(_h264_possible(self.video.settings, self.rtsp.supported))
        video_h264 = self.video.h264  # in effect: asked for and can be produced
        self._image, self._info = image and not video_h264, info
        self._set_share(image and video_h264)
        self.starts.count(h264, self._viewers)
        self.wave.set_viewers(self.starts.viewers if h264 > 0 else frozenset())
        self._decide()  # before the RTSP source plays: its request is decided
        # asked for: the camera is still asked whether it streams H.264 (passed through, no PyAV needed), and without
        # PyAV the stage says once what it needs
        encode = asked_h264 and h264 > 0
        supported = self.rtsp.supported  # None until asked (on the first activation)
        self.transcode = encode and supported is False
        if encode and supported is not None and not self._told_mode:
            self._told_mode = True
            self._log(LogLine("info", h264_mode_line(supported)))
        self.stage.set_active(encode)
        self.rtsp.set_active(encode)
        active = not self._lazy or self._image or self._info or self.transcode
        self.reader.set_active(active)
        return active

    def _set_share(self, active: bool) -> None:
        """Run the MJPEG share's stream or stop it; the encoder's bitrate makes room for it."""
        share = self.video.mjpeg
        if active == share.active:
            return
        if active:
            share.start(self.video.current, self.reader.meter.rate(time.monotonic()).bytes_per_frame)
        share.active = active
        self.share_reader.refresh()
        self.share_reader.set_active(active)
        self._push()

    def _on_supported(self, _supported: bool) -> None:
        """The camera has said whether it streams H.264 (RTSP thread): the mode follows, a size is chosen."""
        self._update()

    def _on_resolutions(self, listed: tuple[Resolution, ...]) -> None:
        self.video.learn_resolutions(listed)
        self._decide()

    # -- frames up (reader, share and RTSP threads) --------------------------------------------------------------
    def _on_jpeg(self, jpeg: bytes, arrival_ns: int) -> None:
        """Hot path (reader thread): a camera JPEG out (MJPEG topic, ``camera_info``), into the stage when
        transcoding, then the budget's judgement."""
        outlets = (Outlet.IMAGE if self._image else Outlet.NONE) | (Outlet.CAMERA_INFO if self._info else Outlet.NONE)
        if outlets:
            self._on_frame(self._jpeg_frame(jpeg, arrival_ns), outlets)
        if self.transcode:
            self.stage.on_jpeg(jpeg, arrival_ns)
        step = self.video.on_frame(time.monotonic())
        if step is not None:
            self._log(LogLine("debug", str(step)))

    def _jpeg_frame(self, jpeg: bytes, arrival_ns: int) -> EncodedFrame:
        sof = jpeg_sof(jpeg)  # one walk of the header
        if sof is None:
            res = self.video.current.resolution
            width, height, grey = res.width, res.height, False
        else:
            width, height, grey = sof[0], sof[1], sof[2] == 1
        self._seq += 1
        return EncodedFrame(jpeg, True, self._seq, width, height, arrival_ns, JPEG, grey)

    def _on_share_jpeg(self, jpeg: bytes, arrival_ns: int) -> None:
        """Hot path (the share's reader thread): its JPEG on the MJPEG topic; the share's ladder judges it."""
        self._on_frame(self._jpeg_frame(jpeg, arrival_ns), Outlet.SHARE_IMAGE)
        self.share_published += 1
        if self.video.mjpeg.on_frame(time.monotonic()) is not None:
            self.share_reader.refresh()  # the ladder stepped: reconnect with its parameters

    def _on_access_unit(self, frame: EncodedFrame) -> None:
        """An access unit from the stage (reader or RTSP thread): out on the H.264 topics, counted for the link's
        judgement; a start point for a viewer when one is due."""
        self._on_frame(frame, Outlet.H264)
        now = time.monotonic()
        self.video.on_h264_frame(now, len(frame.data))
        if self.starts.repeat_due(now):
            self.stage.request_idr()

    def _on_reader_event(self, state: StreamState, message: str) -> None:
        """Reader state changes and errors (reader thread); an IDR first after a reconnect while transcoding."""
        if state is StreamState.STREAMING:
            self._throttle.forget("reconnect")
            if self.transcode:
                self.stage.discontinuity()
        line = reader_event_line(state, message, self.video.current, self.reader.config.auth_retry_s)
        if line is not None:
            self._log(line)

    def _on_share_event(self, state: StreamState, message: str) -> None:
        if message and state is not StreamState.STREAMING:
            self._log(LogLine("warn", f"MJPEG share stream ({state}): {message}", "mjpeg-share", 10.0))

    def _log(self, line: LogLine) -> None:
        if self._throttle.allow(line):
            self._log_out(line)

    # -- diagnostics, lifetime -----------------------------------------------------------------------------------
    def h264_settings(self) -> H264Settings:
        """What the encoder (or the camera, passed through) was last told to do."""
        return self._h264

    def diagnostics(self) -> dict[str, Any]:
        """The H.264 side's and the MJPEG share's values (h264 mode; empty otherwise)."""
        if not self.video.h264:
            return {}
        s = self.video.settings
        values = h264_diagnostic_values(
            self.stage.active,
            self._h264.bitrate_kbps,
            self.stage.stats,
            self.rtsp.stats,
            self.rtsp.supported,
            s.h264.bitrate_kbps,
            s.h264.max_bitrate_kbps,
            self.stage.keyframe_interval if self.transcode else self._rtsp_request.keyframe_interval,
        )
        share = self.video.mjpeg
        if not share.active:
            return values | {"mjpeg share": "off (no MJPEG subscriber)"}
        p = share.current
        return values | {
            "mjpeg share [kbit/s]": round(share.budget_kbps),
            "mjpeg share stream": f"{p.resolution} @ {p.fps} fps, compression {p.compression}",
            "mjpeg share sent [kbit/s]": round(share.meter.rate(time.monotonic()).kbps),
        }

    def start(self) -> None:
        """Start the threads (the readers and the RTSP source idle until there is demand); discovery learns the
        camera even while nobody subscribes (``video/params`` lists its sizes)."""
        self._update()
        self.reader.start()
        self.share_reader.start()
        self.rtsp.start()
        self.discovery.start()

    def stop(self, timeout_s: float = 1.5) -> None:
        """Stop and join every thread (the streams closed from outside)."""
        self.discovery.stop(0.0)  # no new attempt from here on (joined below, once the reader has stopped)
        self.rtsp.stop(timeout_s)
        self.share_reader.stop(timeout_s)
        self.reader.stop(timeout_s)
        self.discovery.stop(2.0)
