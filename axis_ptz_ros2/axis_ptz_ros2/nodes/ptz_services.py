"""The PTZ node's services and its ``ptz/move`` action: request fields in, answers (and feedback) out.

Every request becomes an order through :class:`~axis_ptz_ros2.ptz.requests.Requests` (refused with the reason
when invalid) and is followed with :class:`~axis_ptz_ros2.ptz.goals.Follower`: a service answers once the camera
accepted the order (``wait`` false) or the head arrived (``wait`` true), within ``timeout_s`` or else the
``wait_timeout`` parameter; a goal runs with feedback until it arrives, is cancelled (the head stops) or is
pre-empted by a newer goal (:class:`~axis_ptz_ros2.ptz.goals.GoalBook`). Services run in one mutually exclusive
group of their own (they never block topic commands), goals in a reentrant group. ROS glue: the policy is
``ptz/``'s. The message → order helpers here also serve the node's command topics.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from geometry_msgs.msg import PointStamped
from rclpy.action.server import ActionServer, CancelResponse, GoalResponse, ServerGoalHandle
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node
from std_srvs.srv import Trigger

from axis_ptz_interfaces.action import PtzMove
from axis_ptz_interfaces.msg import PixelTarget, PtzCommand, PtzState
from axis_ptz_interfaces.srv import AreaZoom, CenterOnPixel, ListPresets, LookAt, MovePtz, Preset, SetZoom
from axis_ptz_ros2.ptz.backend import PtzBackend
from axis_ptz_ros2.ptz.command_slot import CommandSlot
from axis_ptz_ros2.ptz.commander import Commander
from axis_ptz_ros2.ptz.goals import Follower, GoalBook, GoalStatus, wait_timeout
from axis_ptz_ros2.ptz.orders import Order, Progress, wait_accepted
from axis_ptz_ros2.ptz.requests import MoveGoal, Requests
from axis_ptz_ros2.ptz.state import StateSample


def move_order(req: Requests, label: str, c: PtzCommand, *, relative: bool) -> Order:
    """The order of a ``PtzCommand`` (``ptz/cmd/absolute|relative``, ``ptz/move_absolute|relative``)."""
    return req.move(label, c.pan, c.tilt, c.zoom, c.speed, relative=relative)


def center_order(req: Requests, t: PixelTarget) -> Order:
    """The order of a ``PixelTarget`` (``ptz/cmd/center``, ``ptz/center``)."""
    return req.center(t.u, t.v, t.image_width, t.image_height, t.zoom_delta)


def look_at_order(req: Requests, msg: PointStamped, zoom: float) -> Order:
    """The order of a point to look at (``ptz/cmd/look_at``, ``ptz/look_at``)."""
    return req.look_at((msg.point.x, msg.point.y, msg.point.z), msg.header.frame_id, zoom)


class PtzServices:
    """The services and the ``ptz/move`` action server of one PTZ node (see the module docstring)."""

    def __init__(
        self,
        node: Node,
        req: Requests,
        cmd: Commander,
        follower: Follower,
        slot: CommandSlot,
        backend: PtzBackend,
        state_msg: Callable[[StateSample], PtzState],
        params: Callable[[], Mapping[str, Any]],
    ) -> None:
        """``params()``: the node's parameter snapshot in effect, taken at each call (``wait_timeout`` is live;
        ``timeout``)."""
        self._req, self._cmd, self._follower = req, cmd, follower
        self._slot, self._backend = slot, backend
        self._state_msg = state_msg
        self._params = params
        self._goals = GoalBook()
        s = MutuallyExclusiveCallbackGroup()
        node.create_service(MovePtz, "ptz/move_absolute", self._srv_absolute, callback_group=s)
        node.create_service(MovePtz, "ptz/move_relative", self._srv_relative, callback_group=s)
        node.create_service(CenterOnPixel, "ptz/center", self._srv_center, callback_group=s)
        node.create_service(AreaZoom, "ptz/area_zoom", self._srv_area_zoom, callback_group=s)
        node.create_service(SetZoom, "ptz/set_zoom", self._srv_set_zoom, callback_group=s)
        node.create_service(LookAt, "ptz/look_at", self._srv_look_at, callback_group=s)
        node.create_service(Trigger, "ptz/home", self._srv_home, callback_group=s)
        node.create_service(Preset, "ptz/preset", self._srv_preset, callback_group=s)
        node.create_service(ListPresets, "ptz/list_presets", self._srv_list_presets, callback_group=s)
        self._action_server = ActionServer(
            node,
            PtzMove,
            "ptz/move",
            execute_callback=self._execute_move,
            goal_callback=lambda _goal: GoalResponse.ACCEPT,
            handle_accepted_callback=self._accept_move,
            cancel_callback=lambda _goal: CancelResponse.ACCEPT,
            callback_group=ReentrantCallbackGroup(),
        )

    def destroy(self) -> None:
        """Destroy the action server (before the node)."""
        self._action_server.destroy()

    # -- services -------------------------------------------------------------------------------------
    def _timeout(self, timeout_s: float) -> float:
        return wait_timeout(timeout_s, float(self._params()["wait_timeout"]))

    def _finish(self, order: Order, wait: bool, timeout_s: float, resp: Any) -> Any:
        """Fill ``resp`` (success, message, state) for a motion service."""
        resp.success, resp.message, sample = self._follower.follow(order, wait, self._timeout(timeout_s))
        if hasattr(resp, "state"):
            if sample is not None:
                resp.state = self._state_msg(sample)
            if not wait and order.target is not None:  # not waiting: the answer shows where the head is sent
                for axis, value in order.target.commanded().items():
                    setattr(resp.state, axis, value)
        return resp

    def _srv_absolute(self, req: MovePtz.Request, resp: MovePtz.Response) -> MovePtz.Response:
        order = move_order(self._req, "absolute", req.command, relative=False)
        return self._finish(order, req.wait, req.timeout_s, resp)

    def _srv_relative(self, req: MovePtz.Request, resp: MovePtz.Response) -> MovePtz.Response:
        order = move_order(self._req, "relative", req.command, relative=True)
        return self._finish(order, req.wait, req.timeout_s, resp)

    def _srv_center(self, req: CenterOnPixel.Request, resp: CenterOnPixel.Response) -> CenterOnPixel.Response:
        return self._finish(center_order(self._req, req.target), req.wait, req.timeout_s, resp)

    def _srv_area_zoom(self, req: AreaZoom.Request, resp: AreaZoom.Response) -> AreaZoom.Response:
        order = self._req.area_zoom((req.u_min, req.v_min, req.u_max, req.v_max), req.image_width, req.image_height)
        return self._finish(order, req.wait, req.timeout_s, resp)

    def _srv_set_zoom(self, req: SetZoom.Request, resp: SetZoom.Response) -> SetZoom.Response:
        return self._finish(self._req.set_zoom(req.zoom, req.magnification, req.hfov), req.wait, req.timeout_s, resp)

    def _srv_look_at(self, req: LookAt.Request, resp: LookAt.Response) -> LookAt.Response:
        return self._finish(look_at_order(self._req, req.target, req.zoom), req.wait, req.timeout_s, resp)

    def _srv_home(self, req: Trigger.Request, resp: Trigger.Response) -> Trigger.Response:
        """Answers when the head has arrived at the home pose (or why it did not), within wait_timeout."""
        resp.success, resp.message, _ = self._follower.follow(
            self._cmd.home(), True, float(self._params()["wait_timeout"])
        )
        return resp

    def _srv_preset(self, req: Preset.Request, resp: Preset.Response) -> Preset.Response:
        resp.success, resp.message = self._follower.preset(req.action, req.name, req.wait, self._timeout(req.timeout_s))
        return resp

    def _srv_list_presets(self, req: ListPresets.Request, resp: ListPresets.Response) -> ListPresets.Response:
        out: list[Any] = []
        b = self._backend
        ticket = self._slot.submit("list_presets", lambda: out.extend(b.list_presets()), supersedable=False)
        resp.success, resp.message = wait_accepted(ticket, "", float(self._params()["timeout"]))
        resp.numbers = [int(pr.number) for pr in out]
        resp.names = [str(pr.name) for pr in out]
        return resp

    # -- ptz/move action ------------------------------------------------------------------------------
    def _goal_order(self, g: PtzMove.Goal) -> Order:
        """The order of a ptz/move goal (refused with the reason when the goal is invalid)."""
        c, pt = g.command, g.point.point
        return self._req.goal(
            MoveGoal(g.kind, (c.pan, c.tilt, c.zoom, c.speed), g.magnification, g.hfov, (pt.x, pt.y, pt.z),
                     g.point.header.frame_id, g.preset)
        )  # fmt: skip

    def _accept_move(self, goal: ServerGoalHandle) -> None:
        """Submit the goal's order now (a valid one pre-empts the running goal)."""
        self._goals.accept(bytes(goal.goal_id.uuid), self._goal_order(goal.request))
        goal.execute()

    def _execute_move(self, goal: ServerGoalHandle) -> PtzMove.Result:
        """Follow the goal's order with feedback (ptz.goals: cancel stops the head, a newer goal pre-empts)."""
        key = bytes(goal.goal_id.uuid)

        def feedback(step: Progress) -> None:
            assert step.sample is not None
            fb = PtzMove.Feedback(state=self._state_msg(step.sample))
            fb.pan_error, fb.tilt_error, fb.zoom_error = (float(e) for e in step.error)
            goal.publish_feedback(fb)

        try:
            order = self._goals.take(key)
            end = self._follower.run_goal(
                order if order is not None else self._goal_order(goal.request),
                self._timeout(goal.request.timeout_s),
                lambda: goal.is_cancel_requested,
                lambda: self._goals.preempted(key),
                feedback,
            )
            result = PtzMove.Result(success=end.status is GoalStatus.SUCCEEDED, message=end.message)
            if end.sample is not None:
                result.state = self._state_msg(end.sample)
            if end.status is GoalStatus.SUCCEEDED:
                goal.succeed()
            elif end.status is GoalStatus.CANCELED:
                goal.canceled()
            else:
                goal.abort()
            return result
        finally:
            self._goals.finish(key)
