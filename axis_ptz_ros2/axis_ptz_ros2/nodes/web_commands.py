"""The web console's operator commands: the page's clicks, keys and video settings as the PTZ and stream nodes'
services (``ptz/center``, ``ptz/look_at``, ``ptz/move_relative``, ``ptz/home``, ``video/set_params``), the stream
node's ``max_bitrate_kbps`` parameter and ``ptz/cmd/velocity`` (stop).

Each call is bounded in time (:class:`~axis_ptz_ros2.nodes.bounded_calls.BoundedCalls`: the HTTP thread never
waits for good). ROS glue: the request bodies are parsed by :mod:`axis_ptz_ros2.web.api`, keys mapped by
:mod:`axis_ptz_ros2.teleop.keymap`, the panorama click resolved by :mod:`axis_ptz_ros2.web.panorama`, and the
answers worded by :mod:`axis_ptz_ros2.web.view`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from functools import partial
from typing import Any

from geometry_msgs.msg import PointStamped
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import PointCloud2
from std_srvs.srv import Trigger

from axis_ptz_interfaces.msg import PtzVelocity
from axis_ptz_interfaces.srv import CenterOnPixel, LookAt, MovePtz, SetVideoParams
from axis_ptz_ros2.config import RobotConfig
from axis_ptz_ros2.nodes.bounded_calls import BoundedCalls, ServiceError
from axis_ptz_ros2.nodes.common import COMMAND_QOS, publisher
from axis_ptz_ros2.nodes.link_monitor import FeedbackPublisher
from axis_ptz_ros2.teleop import keymap
from axis_ptz_ros2.teleop.keymap import Command as TeleopCommand
from axis_ptz_ros2.web import api
from axis_ptz_ros2.web.backend import CommandResult
from axis_ptz_ros2.web.panorama import cloud_msg_in_base, look_target
from axis_ptz_ros2.web.view import (
    ConsoleModel,
    budget_answer,
    in_turn,
    move_text,
    service_answer,
    video_answer,
    video_text,
)


class ConsoleCommands:
    """The operator's commands of one console node (see the module docstring)."""

    def __init__(
        self,
        node: Node,
        model: ConsoleModel,
        robot: RobotConfig,
        params: Callable[[], Mapping[str, Any]],
        feedback: FeedbackPublisher,
        cloud: Callable[[], PointCloud2 | None],
    ) -> None:
        """``params()``: the node's parameter snapshot in effect (``stream_node``; the live ones read at each use);
        ``cloud()``: the newest laser cloud (decoded only when a panorama click needs it)."""
        self._node = node
        self._model = model
        self._robot = robot
        self._params = params
        self._feedback = feedback
        self._cloud = cloud
        g = ReentrantCallbackGroup()
        self._center = node.create_client(CenterOnPixel, "ptz/center", callback_group=g)
        self._look_at = node.create_client(LookAt, "ptz/look_at", callback_group=g)
        self._move_rel = node.create_client(MovePtz, "ptz/move_relative", callback_group=g)
        self._home = node.create_client(Trigger, "ptz/home", callback_group=g)
        self._set_video = node.create_client(SetVideoParams, "video/set_params", callback_group=g)
        self._calls = BoundedCalls(node, lambda: float(self._param("service_timeout")), g)
        self._vel_pub = publisher(node, PtzVelocity, "ptz/cmd/velocity", COMMAND_QOS)
        self._commands: dict[str, Callable[[dict[str, Any]], CommandResult]] = {
            "center": self._cmd_center,
            "look_panorama": self._cmd_look_panorama,
            "key": self._cmd_key,
            "video": self._cmd_video,
            "home": lambda _body: self._cmd_home(),
            "decoder": self._cmd_decoder,
        }

    def _param(self, name: str) -> Any:  # noqa: ANN401 - a parameter's value
        return self._params()[name]

    def add_command(self, name: str, run: Callable[[dict[str, Any]], CommandResult]) -> None:
        """Another command of the page (the still: :mod:`~axis_ptz_ros2.nodes.web_still`)."""
        self._commands[name] = run

    def services_ready(self) -> dict[str, bool]:
        """The page's ``services`` section: which services answer."""
        return {
            "center": self._center.service_is_ready(),
            "look_at": self._look_at.service_is_ready(),
            "move_relative": self._move_rel.service_is_ready(),
            "home": self._home.service_is_ready(),
            "video": self._set_video.service_is_ready(),
        }

    def run(self, name: str, body: dict[str, Any]) -> CommandResult:
        """Run an operator command (bounded time; a service that does not answer becomes a refusal)."""
        try:
            return self._commands[name](body)
        except ServiceError as err:
            return CommandResult(False, str(err), err.status)

    def _answer(self, client: Any, request: Any, what: str) -> CommandResult:  # noqa: ANN401 - any service
        res = self._calls.call(client, request)
        return service_answer(res.success, res.message, what)

    def _cmd_home(self) -> CommandResult:
        return self._answer(self._home, Trigger.Request(), "going home")

    def _cmd_center(self, body: dict[str, Any]) -> CommandResult:
        c = api.center_request(body)
        req = CenterOnPixel.Request()
        req.target.u, req.target.v = c.click.x, c.click.y
        req.target.image_width, req.target.image_height = c.click.width, c.click.height
        req.target.zoom_delta = c.zoom_delta
        req.wait = False
        zd = c.zoom_delta
        what = f"centring on ({c.click.x:.0f}, {c.click.y:.0f})" + (f", zoom {zd:+.0f}" if zd else "")
        return self._answer(self._center, req, what)

    def _cmd_look_panorama(self, body: dict[str, Any]) -> CommandResult:
        click = api.pixel_click(body, "x", "y", "panorama")
        cloud, why = cloud_msg_in_base(self._cloud(), self._robot)
        target = look_target(click, self._robot, cloud, why, time.time())
        self._model.click(target.click)
        req = LookAt.Request()
        req.target = PointStamped()
        req.target.header.frame_id = self._robot.base_frame
        req.target.header.stamp = self._node.get_clock().now().to_msg()
        req.target.point.x, req.target.point.y, req.target.point.z = target.point
        req.zoom = float(self._param("look_zoom"))
        req.wait = False
        out = self._answer(self._look_at, req, target.message)
        out.extra["depth_source"] = target.depth_source
        out.extra["range_m"] = target.range_m
        return out

    def _cmd_decoder(self, body: dict[str, Any]) -> CommandResult:
        r = api.decoder_request(body)
        self._model.decoder(r.mode, r.decoded, r.errors, r.codec, r.note)
        self._feedback.add_errors(r.errors)  # the stream node answers decode errors with an IDR
        return CommandResult(True, "")

    def _cmd_key(self, body: dict[str, Any]) -> CommandResult:
        label, commands, step = self._model.key(api.key_request(body))
        if not commands:
            return CommandResult(True, f"{label}: step size x = {step}", extra={"step": step})
        result = in_turn(partial(self._run_teleop, c) for c in commands)
        if not result.ok:
            return result
        return CommandResult(True, f"{label}: {result.message}", extra={"step": step})

    def _run_teleop(self, c: TeleopCommand) -> CommandResult:
        if isinstance(c, keymap.RelativeMove):
            req = MovePtz.Request()
            req.command.pan, req.command.tilt, req.command.zoom = c.pan, c.tilt, c.zoom
            req.command.speed = math.nan
            req.wait = False
            return self._answer(self._move_rel, req, move_text(c))
        if isinstance(c, keymap.GoHome):
            return self._cmd_home()
        if isinstance(c, keymap.StopMotion):
            self._vel_pub.publish(PtzVelocity(pan_rate=0.0, tilt_rate=0.0, zoom_rate=0.0))
            return CommandResult(True, "stop")
        if isinstance(c, keymap.SetVideo):
            return self._set_video_params(
                c.fps, c.resolution, c.compression, c.h264_bitrate_kbps, c.h264_max_bitrate_kbps
            )
        if isinstance(c, keymap.TakeStill):
            return self.run("still", {}) if "still" in self._commands else CommandResult(False, "no still here", 404)
        if isinstance(c, keymap.Notice):
            return CommandResult(False, c.text, 409)
        return CommandResult(True, "help")  # ToggleHelp: the page shows its own help

    def _set_video_params(
        self, fps: int, resolution: str, compression: int, h264_kbps: int = 0, h264_max_kbps: int = 0
    ) -> CommandResult:
        req = SetVideoParams.Request(
            fps=fps,
            resolution=resolution,
            compression=compression,
            h264_bitrate_kbps=h264_kbps,
            h264_max_bitrate_kbps=h264_max_kbps,
        )
        res = self._calls.call(self._set_video, req)
        return video_answer(res.success, res.message, video_text(res.params))

    def _cmd_video(self, body: dict[str, Any]) -> CommandResult:
        v = api.video_request(body)
        steps: list[Callable[[], CommandResult]] = []
        if v.changes_stream:
            steps.append(lambda: self._set_video_params(v.fps, v.resolution, v.compression))
        if v.max_bitrate_kbps >= 0:
            steps.append(lambda: self._set_budget(v.max_bitrate_kbps))
        return in_turn(steps)

    def _stream_node_name(self) -> str:
        name = str(self._param("stream_node"))
        if name:
            return name
        node = self._node
        pubs = node.get_publishers_info_by_topic(node.resolve_topic_name("video/params"))
        if not pubs:
            raise ServiceError(503, "no stream node publishes video/params")
        info = pubs[0]
        return f"{info.node_namespace.rstrip('/')}/{info.node_name}"

    def _set_budget(self, kbps: int) -> CommandResult:
        r = self._calls.set_parameter(self._stream_node_name(), Parameter("max_bitrate_kbps", value=int(kbps)))
        return budget_answer(r.successful, r.reason, kbps)
