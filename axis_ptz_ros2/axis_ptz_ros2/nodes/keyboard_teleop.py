"""``axis_keyboard_teleop``: drive the PTZ and the stream from a terminal (thesis §3.4.4, Table 5.3).

A terminal program in its own process. It reads keys in raw mode (``select`` on stdin, no thread), maps them
with the pure :mod:`axis_ptz_ros2.teleop.keymap`, and talks only through ROS interfaces:

* publishes ``ptz/cmd/relative`` (PtzCommand: REP-103 radians, NaN = axis unchanged) and ``ptz/cmd/velocity``
  (PtzVelocity zeros = stop: on ``x``/ESC and on exit);
* calls ``ptz/home`` (std_srvs/Trigger) and the stream node's ``video/set_params`` (SetVideoParams) and, on P,
  its ``still/capture`` (std_srvs/Trigger: a full-quality still on ``still/compressed``; the answer's size and
  resolution are printed);
* subscribes ``ptz/state`` and ``video/params`` (latched) for the live status line; its ``codec`` decides what
  the quality keys Y/H act on: the JPEG compression (MJPEG) or the H.264 bitrates (``h264_bitrate_kbps`` and
  ``h264_max_bitrate_kbps``, set together through ``video/set_params``).

The terminal is restored in ``finally`` — also on SIGTERM/SIGHUP, which are turned into a normal exit.
Namespaces and remaps: ``axis_keyboard_teleop --ros-args -r __ns:=/robot`` (or ``-r ptz/state:=…``).
"""

from __future__ import annotations

import math
import os
import select
import signal
import sys
import termios
import time
import tty
from types import FrameType
from typing import Any, TextIO

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future
from std_srvs.srv import Trigger

from axis_ptz_interfaces.msg import PtzCommand, PtzState, PtzVelocity, VideoParams
from axis_ptz_interfaces.srv import SetVideoParams
from axis_ptz_ros2.nodes.common import (
    COMMAND_QOS,
    LATCHED_QOS,
    RELATIVE_QOS,
    STREAM_QOS,
    ParamSpec,
    publisher,
)
from axis_ptz_ros2.nodes.live_params import LiveParams
from axis_ptz_ros2.nodes.runner import close_own_loop
from axis_ptz_ros2.teleop import keymap as km
from axis_ptz_ros2.teleop import status

PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("step", 1, "initial step size x (keys 1-9)", "deg", int_range=(1, 9)),
    ParamSpec(
        "resolutions",
        list(km.DEFAULT_RESOLUTIONS),
        "the camera's resolution list walked by T/G (WIDTHxHEIGHT)",
        "px",
    ),
    ParamSpec("service_timeout", 5.0, "give up waiting for a service answer after", "s", float_range=(0.1, 60.0)),
)

CSI_CLEAR_LINE = "\r\x1b[K"
#: s: the longest wait for ``still/capture`` (a full-resolution JPEG over a weak link takes a while)
STILL_WAIT_S = 30.0


class KeyboardTeleop(Node):
    """The ROS side of the teleop: publishers, clients, the state the status line shows."""

    def __init__(self, out: TextIO, **kwargs: Any) -> None:
        super().__init__("axis_keyboard_teleop", **kwargs)
        self._live = LiveParams(self, PARAMS)  # step, resolutions: the initial state; service_timeout: live
        p = self._live.params
        self.out = out
        self.state = km.TeleopState(step=int(p["step"]), resolutions=km.sort_resolutions(p["resolutions"]))
        self.ptz: PtzState | None = None
        self.video: VideoParams | None = None
        self.show_help = False
        self.quit = False
        self._status_dirty = True
        self._drawn = ""
        self._pending: list[tuple[float, str, Future]] = []
        self._rel_pub = publisher(self, PtzCommand, "ptz/cmd/relative", RELATIVE_QOS)
        self._vel_pub = publisher(self, PtzVelocity, "ptz/cmd/velocity", COMMAND_QOS)
        self._home = self.create_client(Trigger, "ptz/home")
        self._video_srv = self.create_client(SetVideoParams, "video/set_params")
        self._still_srv = self.create_client(Trigger, "still/capture")
        self.create_subscription(PtzState, "ptz/state", self._on_state, STREAM_QOS)
        self.create_subscription(VideoParams, "video/params", self._on_video, LATCHED_QOS)

    # ---- inputs ---------------------------------------------------------------------------------------
    def _on_state(self, msg: PtzState) -> None:
        self.ptz = msg
        self._status_dirty = True

    def _on_video(self, msg: VideoParams) -> None:
        self.video = msg
        # the camera's own list (published by the stream node) wins over the `resolutions` parameter
        self.state = km.with_video(self.state, msg)
        self._status_dirty = True

    # ---- keys -----------------------------------------------------------------------------------------
    def key(self, key: str) -> None:
        """Handle one key: update the state and send what the key map says."""
        commands, self.state = km.apply(key, self.state)
        self._status_dirty = True
        for c in commands:
            self.execute(c)

    def execute(self, c: km.Command) -> None:
        """Send one key-map command over ROS."""
        if isinstance(c, km.RelativeMove):
            self._rel_pub.publish(PtzCommand(pan=c.pan, tilt=c.tilt, zoom=c.zoom, speed=math.nan))
        elif isinstance(c, km.StopMotion):
            self.stop()
        elif isinstance(c, km.GoHome):
            if not self._home.service_is_ready():
                self.say("ptz/home is not available (is the PTZ node running?)")
                return
            self._track("home", self._home.call_async(Trigger.Request()))
        elif isinstance(c, km.SetVideo):
            if not self._video_srv.service_is_ready():
                self.say("video/set_params is not available (is the stream node running?)")
                return
            req = SetVideoParams.Request(
                fps=c.fps,
                resolution=c.resolution,
                compression=c.compression,
                h264_bitrate_kbps=c.h264_bitrate_kbps,
                h264_max_bitrate_kbps=c.h264_max_bitrate_kbps,
            )
            self._track("video", self._video_srv.call_async(req))
        elif isinstance(c, km.TakeStill):
            if not self._still_srv.service_is_ready():
                self.say("still/capture is not available (is the stream node running?)")
                return
            self.say("taking a still ...")
            self._track("still", self._still_srv.call_async(Trigger.Request()))
        elif isinstance(c, km.ToggleHelp):
            self.show_help = not self.show_help
            if self.show_help:
                self.print_help()
        elif isinstance(c, km.Quit):
            self.quit = True
        elif isinstance(c, km.Notice):
            self.say(c.text)

    def stop(self) -> None:
        """Zero velocity: stops continuous motion at once."""
        self._vel_pub.publish(PtzVelocity(pan_rate=0.0, tilt_rate=0.0, zoom_rate=0.0))

    def _track(self, what: str, fut: Future) -> None:
        self._pending.append((time.monotonic(), what, fut))

    def poll_services(self) -> None:
        """Report answers (and timeouts) of the service calls in flight."""
        timeout = float(self._live.params["service_timeout"])
        keep = []
        for t0, what, fut in self._pending:
            if fut.done():
                res = fut.result()
                if res is None:
                    self.say(f"{what}: no answer")
                elif what == "video":
                    if res.success:
                        self._on_video(res.params)
                    else:
                        self.say(f"video parameters refused: {res.message}")
                elif what == "still":
                    ok = res.success or res.message.startswith("still failed")  # (the node's own words)
                    self.say(res.message if ok else f"still failed: {res.message}")
                elif not res.success:
                    self.say(f"home failed: {res.message}")
            elif time.monotonic() - t0 > (wait := max(timeout, STILL_WAIT_S) if what == "still" else timeout):
                fut.cancel()
                self.say(f"{what}: no answer within {wait:g} s")
            else:
                keep.append((t0, what, fut))
        self._pending = keep

    # ---- terminal output ------------------------------------------------------------------------------
    def say(self, text: str) -> None:
        """A message line above the status line."""
        self.out.write(f"{CSI_CLEAR_LINE}{text}\r\n")
        self._status_dirty = True
        self._drawn = ""

    def print_help(self) -> None:
        """The key table."""
        self.out.write(CSI_CLEAR_LINE + "axis_keyboard_teleop keys (x = step size):\r\n")
        for line in km.help_lines():
            self.out.write(line + "\r\n")
        mode = "H.264 bitrate" if self.state.codec == "h264" else "MJPEG compression"
        self.out.write(f"  (the stream is {self.state.codec}: Y/H act on the {mode})\r\n")
        self._drawn = ""

    def status_line(self) -> str:
        """``pan … tilt … zoom … | video: … | step …`` (:func:`axis_ptz_ros2.teleop.status.status_line`)."""
        return status.status_line(self.ptz, self.video, self.state.step)

    def draw_status(self, force: bool = False) -> None:
        """Redraw the status line if its text changed (or after a message was printed above it)."""
        if not (self._status_dirty or force):
            return
        self._status_dirty = False
        line = self.status_line()
        if line == self._drawn and not force:
            return
        self._drawn = line
        self.out.write(CSI_CLEAR_LINE + line)
        self.out.flush()


class _Terminal:
    """Raw mode on a tty (restored by :meth:`restore`); a no-op for a pipe."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self.saved: list[Any] | None = None
        if os.isatty(fd):
            self.saved = termios.tcgetattr(fd)
            tty.setraw(fd, termios.TCSANOW)

    def restore(self) -> None:
        if self.saved is not None:
            termios.tcsetattr(self.fd, termios.TCSADRAIN, self.saved)
            self.saved = None


def _exit_on_signal(signum: int, _frame: FrameType | None) -> None:
    raise SystemExit(128 + signum)


def main(args: list[str] | None = None) -> int:
    """Entry point of ``axis_keyboard_teleop``."""
    argv = list(args) if args is not None else sys.argv
    # rclpy's own SIGINT handler would shut the context down inside the signal, before the stop below can go out
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    fd = sys.stdin.fileno()
    out = sys.stdout
    node: KeyboardTeleop | None = None
    executor = SingleThreadedExecutor()
    term: _Terminal | None = None
    for s in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(s, _exit_on_signal)
    code = 0
    try:
        node = KeyboardTeleop(out)
        executor.add_node(node)
        term = _Terminal(fd)
        out.write(CSI_CLEAR_LINE + "axis_keyboard_teleop: ? for help, Ctrl-C or Ctrl-Q to quit\r\n")
        last_draw = 0.0
        while not node.quit:
            ready, _, _ = select.select([fd], [], [], 0.02)
            if ready:
                data = os.read(fd, 1024)
                if not data:  # EOF (pipe closed)
                    break
                for key in km.split_keys(data.decode("utf-8", errors="replace")):
                    node.key(key)
                    if node.quit:
                        break
            executor.spin_once(timeout_sec=0.0)
            node.poll_services()
            now = time.monotonic()
            if now - last_draw >= 0.1:
                node.draw_status()
                last_draw = now
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ValueError as err:  # start-up parameter errors
        print(f"\r\nerror: {err}", file=sys.stderr)
        code = 2
    finally:
        for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):  # a second signal must not cut the stop short
            signal.signal(s, signal.SIG_IGN)
        if term is not None:
            term.restore()
        try:
            if node is not None:
                node.stop()  # never leave the head turning
                deadline = time.monotonic() + 0.2
                while time.monotonic() < deadline:  # let the stop go out on the wire
                    executor.spin_once(timeout_sec=0.02)
        finally:
            if node is not None:
                out.write("\r\n")
                out.flush()
            close_own_loop(executor, node)
    return code


if __name__ == "__main__":
    sys.exit(main())
