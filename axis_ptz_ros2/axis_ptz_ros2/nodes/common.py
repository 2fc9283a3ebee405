"""Shared ROS glue for every node: QoS, declarative parameters, the camera connection, messages.

This is the only place (with the node modules) that knows both the ROS-free layers and ROS messages.
"""

from __future__ import annotations

import dataclasses
import math
import re
import typing
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import TransformStamped
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSPolicyKind, QoSProfile, ReliabilityPolicy
from rclpy.qos_overriding_options import InvalidQosOverridesError, QoSOverridingOptions
from rclpy.time import Time as RosTime
from sensor_msgs.msg import CameraInfo, CompressedImage

from axis_ptz_ros2.optics import Intrinsics
from axis_ptz_ros2.streaming.jpeg import jpeg_components
from axis_ptz_ros2.transforms import Pose, Transform, quaternion_to_matrix
from axis_ptz_ros2.vapix import CameraConfig
from axis_ptz_ros2.vapix.credentials import load_credentials

_C = TypeVar("_C")

# ---------------------------------------------------------------------------------------------------------
# QoS
# ---------------------------------------------------------------------------------------------------------
#: Images and state: reliable (so default subscribers match), keep only the newest sample: a slow link drops
#: old frames instead of queueing them. Best-effort subscribers match it too.
STREAM_QOS = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
#: pictures the video writers and readers keep (see VIDEO_QOS): 0.33 s at 30 fps, 0.4 s at 25, more below
VIDEO_HISTORY = 10
#: H.264 access units (image_raw/ffmpeg, image_raw/foxglove): reliable, with a history of ten pictures on both
#: sides. Unlike a JPEG, an access unit replaced before its repair finished costs every picture up to the next IDR
#: (or intra-refresh wave); with depth 1 on 2 Mbit/s + 2 % loss the weak-link bench showed 832 kbit/s arriving but
#: 11.8 of 30 pictures/s shown; depth 2 still lost access units 6-27 times in 20 s. Depth 4 (133 ms at 30 fps)
#: was shorter than the 100-190 ms a repair takes on that link: 1080p30 passed through lost 11-22 access units in
#: 30 s (at d82297c; 1080p15, 267 ms of history, none). A history by time is what matters; a publisher's depth
#: is a count fixed when it is made, so it is the count that holds ~0.3 s at the fastest rate the stream node
#: asks for (30 fps). The weak-link profile's 50 ms heartbeat on these topics asks for repairs in time
#: (config/fastdds_weak_link.xml). A queue can grow to the history before anything is dropped: 0.33-0.4 s, which
#: the link adapter reads as congestion (streaming/feedback.py). qos_overrides change it per topic.
VIDEO_QOS = QoSProfile(depth=VIDEO_HISTORY, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
#: Commands: the newest wins; a small queue absorbs bursts.
COMMAND_QOS = QoSProfile(depth=5, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
#: Relative commands: each one is an offset, so none may be dropped: a queue deep enough for ~3 s of 30 Hz
#: steps while the node is busy (KEEP_LAST 5 dropped steps: a 300-step burst ended 7.5 degrees off).
RELATIVE_QOS = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
#: Consumer feedback (video/feedback): periodic reports, only the newest matters, never repaired late.
FEEDBACK_QOS = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.BEST_EFFORT)
#: Latched values (video/params): late joiners get the value in effect.
LATCHED_QOS = QoSProfile(
    depth=1,
    history=HistoryPolicy.KEEP_LAST,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)


#: The QoS policies every publisher lets a user override with ``qos_overrides.<topic>.publisher.<policy>``
#: parameters (rclpy's ``with_default_policies()`` are history, depth, reliability; durability as well, so that
#: a latched topic can be made volatile or a volatile one latched).
QOS_OVERRIDE_POLICIES: tuple[QoSPolicyKind, ...] = (
    QoSPolicyKind.HISTORY,
    QoSPolicyKind.DEPTH,
    QoSPolicyKind.RELIABILITY,
    QoSPolicyKind.DURABILITY,
)
#: How rclpy's errors name the policy: "policy `depth`" or the parameter's name.
_POLICY_RE = re.compile(r"policy `(\w+)`|qos_overrides\.[^\s']+\.publisher\.(\w+)")


def _check_qos_override(qos: QoSProfile) -> SetParametersResult:
    """rclpy checks the policy names; a keep-last depth of 0 is also refused (it would keep nothing)."""
    if qos.history == HistoryPolicy.KEEP_LAST and qos.depth < 1:
        return SetParametersResult(
            successful=False, reason=f"policy `depth`: {qos.depth} (keep_last needs a depth of at least 1)"
        )
    return SetParametersResult(successful=True)


def _copy_qos(q: QoSProfile) -> QoSProfile:
    """A copy of ``q`` (``copy.deepcopy`` cannot copy its durations)."""
    return QoSProfile(
        history=q.history,
        depth=q.depth,
        reliability=q.reliability,
        durability=q.durability,
        lifespan=q.lifespan,
        deadline=q.deadline,
        liveliness=q.liveliness,
        liveliness_lease_duration=q.liveliness_lease_duration,
        avoid_ros_namespace_conventions=q.avoid_ros_namespace_conventions,
    )


#: what rclpy raises when the middleware refuses an entity (e.g. a writer its XML profile cannot give)
MiddlewareRefused: type[Exception] = _rclpy.RCLError


def publisher(node: Node, msg_type: Any, topic: str, qos: QoSProfile | int, **kwargs: Any) -> Publisher:
    """``node.create_publisher`` with the standard QoS overrides (every publisher of the project goes here).

    The parameters ``qos_overrides.<resolved topic>.publisher.{history,depth,reliability,durability}`` (read-only,
    declared by rclpy's :class:`QoSOverridingOptions`, default: ``qos``) replace the policies at start-up, e.g.
    ``--ros-args -p qos_overrides./camera_info.publisher.reliability:=best_effort``. An invalid value raises
    :class:`ValueError` naming the parameter (:func:`run_nodes` prints it and exits 2).
    """
    options = QoSOverridingOptions(QOS_OVERRIDE_POLICIES, callback=_check_qos_override)
    # rclpy writes the overrides into the profile it is given: a copy, so the shared profiles stay as they are
    profile = _copy_qos(qos) if isinstance(qos, QoSProfile) else QoSProfile(depth=qos)
    try:
        return node.create_publisher(msg_type, topic, profile, qos_overriding_options=options, **kwargs)
    except MiddlewareRefused:
        raise  # the middleware refused the writer (e.g. its XML profile): not an override, the caller decides
    except (
        InvalidQosOverridesError,
        InvalidParameterTypeException,
        InvalidParameterValueException,
        RuntimeError,
        OverflowError,
        TypeError,
        ValueError,
    ) as err:
        prefix = f"qos_overrides.{node.resolve_topic_name(topic)}.publisher."
        m = _POLICY_RE.search(str(err))
        name = prefix + (m.group(1) or m.group(2) if m else "{history,depth,reliability,durability}")
        raise ValueError(f"invalid QoS override {name}: {err}") from None


#: ``sensor_msgs/CompressedImage.format`` of a colour JPEG, as ``compressed_image_transport`` writes it for a
#: bgr8 image; its decoder reads the part before ';' as the encoding of the decoded image and "compressed bgr" as
#: the order of the channels that OpenCV's ``imdecode`` returns (a colour JPEG always decodes to BGR).
JPEG_FORMAT_BGR8 = "bgr8; jpeg compressed bgr8"
#: The same for a one-component (greyscale) JPEG: it decodes to one channel, so the encoding must say mono8.
JPEG_FORMAT_MONO8 = "mono8; jpeg compressed mono8"


def jpeg_format(channels: int) -> str:
    """The ``CompressedImage.format`` of a JPEG with ``channels`` components (1 = mono8, else bgr8)."""
    return JPEG_FORMAT_MONO8 if channels == 1 else JPEG_FORMAT_BGR8


def jpeg_image_msg(jpeg: Any, frame_id: str, stamp: Time) -> CompressedImage:
    """A ``CompressedImage`` of JPEG bytes (``cv2.imencode``'s buffer or bytes) with the project's format string
    (colour or greyscale, read from the JPEG): the one builder of the nodes that encode their own pictures."""
    data = jpeg.tobytes() if hasattr(jpeg, "tobytes") else bytes(jpeg)
    msg = CompressedImage()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.format = jpeg_format_of(data)
    msg.data = data
    return msg


def jpeg_format_of(data: bytes | bytearray | memoryview) -> str:
    """The ``CompressedImage.format`` of these JPEG bytes (from the SOF header: greyscale or colour)."""
    return jpeg_format(jpeg_components(data) or 3)


# ---------------------------------------------------------------------------------------------------------
# Declarative parameters (one spec per node → descriptors, validation, README tables)
# ---------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ParamSpec:
    """One ROS parameter: its type comes from ``default``; ranges are enforced by rclpy itself."""

    name: str
    default: Any
    description: str
    unit: str = ""
    read_only: bool = False
    int_range: tuple[int, int] | None = None
    float_range: tuple[float, float] | None = None
    choices: tuple[str, ...] | None = None
    dynamic_typing: bool = False
    config: type | None = None  #: the ROS-free frozen config class this parameter fills (see :func:`snapshot`) ...
    field: str = ""  #: ... and its field there ('' = the parameter's name)

    def descriptor(self) -> ParameterDescriptor:
        """A full ParameterDescriptor (description with unit, range, read-only flag)."""
        text = self.description + (f" [{self.unit}]" if self.unit else "")
        if self.choices:
            text += " (one of: " + ", ".join(self.choices) + ")"
        d = ParameterDescriptor(description=text, read_only=self.read_only, dynamic_typing=self.dynamic_typing)
        if self.int_range is not None:
            d.integer_range = [IntegerRange(from_value=self.int_range[0], to_value=self.int_range[1], step=1)]
        if self.float_range is not None:
            d.floating_point_range = [
                FloatingPointRange(from_value=self.float_range[0], to_value=self.float_range[1], step=0.0)
            ]
        return d

    def check(self, value: Any) -> str | None:
        """Checks rclpy does not do (choices); returns a reason or None."""
        if self.choices is not None and value not in self.choices:
            return f"{self.name}={value!r} is not one of {', '.join(self.choices)}"
        return None

    def range_text(self) -> str:
        """Human-readable range for documentation."""
        if self.int_range:
            return f"{self.int_range[0]}…{self.int_range[1]}"
        if self.float_range:
            return f"{self.float_range[0]:g}…{self.float_range[1]:g}"
        if self.choices:
            return " / ".join(self.choices)
        return ""


def field_spec(config: type, field: str, description: str, unit: str = "", *, name: str = "", **kw: Any) -> ParamSpec:
    """The parameter ``name`` (default: ``field``) that fills ``config.field``; its default is that field's
    (one source for defaults: the ROS-free config class). A dotted ``field`` ("h264.bitrate_kbps") is a field of a
    nested config class (a field of ``config`` whose type is one)."""
    *outer, last = field.split(".")
    owner = config
    for part in outer:
        owner = _nested_type(owner, part)
    default = next(f.default for f in dataclasses.fields(owner) if f.name == last)
    return ParamSpec(name or field, default, description, unit, config=config, field=field, **kw)


def snapshot(config: type[_C], specs: Iterable[ParamSpec], values: Mapping[str, Any]) -> _C:
    """A frozen ``config`` from the parameter ``values`` of the specs that fill it (the others keep defaults);
    dotted fields fill nested config classes (:func:`field_spec`)."""
    return _build(config, {s.field or s.name: values[s.name] for s in specs if s.config is config})


def _build(config: type[_C], values: Mapping[str, Any]) -> _C:
    """``config(**values)``, a dotted key filling the nested config class of its first part."""
    direct: dict[str, Any] = {k: v for k, v in values.items() if "." not in k}
    nested: dict[str, dict[str, Any]] = {}
    for key, value in values.items():
        if "." in key:
            head, rest = key.split(".", 1)
            nested.setdefault(head, {})[rest] = value
    for head, sub in nested.items():
        direct[head] = _build(_nested_type(config, head), sub)
    return config(**direct)


def _nested_type(config: type, field: str) -> type:
    """The type of ``config.field``, a nested frozen config class."""
    nested = typing.get_type_hints(config)[field]
    if not (isinstance(nested, type) and dataclasses.is_dataclass(nested)):
        raise TypeError(f"{config.__name__}.{field} is not a nested config class")
    return nested


#: Parameter names someone may try for camera credentials. None is declared: a parameter is readable by anyone on
#: the ROS graph (``ros2 param get``) and a ``-p password:=…`` stays visible in the process list.
CREDENTIAL_PARAMETER_NAMES = frozenset({"password", "passwd", "pass", "camera_password", "username", "user"})


def warn_credential_parameters(node: Node) -> list[str]:
    """Warn loudly (once per node) about credentials given as parameters, which are never read; the value is not
    logged. Returns the offending names."""
    given = sorted(n for n in getattr(node, "_parameter_overrides", {}) if n.lower() in CREDENTIAL_PARAMETER_NAMES)
    if given:
        node.get_logger().error(
            f"parameter(s) {', '.join(given)} ignored: credentials are never read from parameters (anyone on the "
            "ROS graph can read a parameter, and the command line shows it in the process list). Give the camera "
            "user and password in a file only you can read (password_file / AXIS_PASSWORD_FILE, 'user:password') "
            "or in AXIS_USERNAME / AXIS_PASSWORD"
        )
    return given


def declare_params(node: Node, specs: Sequence[ParamSpec]) -> dict[str, Any]:
    """Declare every spec on ``node`` and return the values in effect (overrides applied); credentials given as
    parameters are refused loudly (:func:`warn_credential_parameters`)."""
    if not any(s.name in CREDENTIAL_PARAMETER_NAMES for s in specs):
        warn_credential_parameters(node)
    values: dict[str, Any] = {}
    for s in specs:
        p = node.declare_parameter(s.name, s.default, s.descriptor())
        values[s.name] = p.value
        reason = s.check(p.value)
        if reason:
            raise ValueError(f"invalid start-up parameter: {reason}")
    return values


def check_params(specs: Mapping[str, ParamSpec], params: Iterable[Parameter]) -> SetParametersResult:
    """An ``on_set_parameters`` helper: refuse unknown-choice values of the parameters we own."""
    for p in params:
        spec = specs.get(p.name)
        if spec is None:
            continue
        reason = spec.check(p.value)
        if reason:
            return SetParametersResult(successful=False, reason=reason)
    return SetParametersResult(successful=True)


def params_markdown(specs: Sequence[ParamSpec]) -> str:
    """A README table of the parameters (name, type, default, unit, range, description)."""
    rows = ["| parameter | type | default | unit | range | description |", "|---|---|---|---|---|---|"]
    for s in specs:
        kind = type(s.default).__name__
        ro = " (read-only)" if s.read_only else ""
        rows.append(f"| `{s.name}` | {kind} | `{s.default!r}` | {s.unit} | {s.range_text()} | {s.description}{ro} |")
    return "\n".join(rows)


# ---------------------------------------------------------------------------------------------------------
# Camera connection: the same read-only parameters on every node that talks to the camera
# ---------------------------------------------------------------------------------------------------------
CONNECTION_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("hostname", "127.0.0.1", "camera host name or address", read_only=True),
    ParamSpec("port", 80, "camera HTTP(S) port", int_range=(1, 65535), read_only=True),
    ParamSpec("use_https", False, "talk HTTPS to the camera", read_only=True),
    ParamSpec("verify_tls", True, "verify the camera's TLS certificate (HTTPS only)", read_only=True),
    ParamSpec("ca_file", "", "CA bundle file/directory for verify_tls ('' = system)", read_only=True),
    ParamSpec("camera", 1, "VAPIX camera number (camera=N)", int_range=(1, 16), read_only=True),
    ParamSpec(
        "auth",
        "auto",
        "HTTP authentication (auto: Digest; Basic only over HTTPS, else choose basic explicitly)",
        choices=("auto", "none", "basic", "digest"),
        read_only=True,
    ),
    ParamSpec(
        "password_file",
        "",
        "file with 'user:password' (else AXIS_USERNAME/AXIS_PASSWORD env; never a parameter)",
        read_only=True,
    ),
    ParamSpec("connect_timeout", 2.0, "TCP connect timeout", "s", float_range=(0.05, 60.0), read_only=True),
)


_INSECURE_TLS_WARNED: list[bool] = []  # once per process (axis_camera composes two nodes)


def camera_config_from_params(p: Mapping[str, Any], timeout_s: float) -> CameraConfig:
    """A :class:`CameraConfig` from the CONNECTION_PARAMS values, credentials from the environment or file.

    ``use_https`` with ``verify_tls`` false logs one warning per process: the camera is then not authenticated.
    """
    if bool(p["use_https"]) and not bool(p["verify_tls"]) and not _INSECURE_TLS_WARNED:
        _INSECURE_TLS_WARNED.append(True)
        rclpy.logging.get_logger("axis_ptz_ros2").warning(
            f"verify_tls is false: the certificate of the camera at {p['hostname']} is NOT checked, so anyone "
            "on the path can impersonate it (set ca_file to the camera's certificate instead)"
        )
    user, password = load_credentials(str(p["password_file"]), warn=rclpy.logging.get_logger("axis_ptz_ros2").error)
    verify: bool | str = str(p["ca_file"]) if p["ca_file"] and p["verify_tls"] else bool(p["verify_tls"])
    return CameraConfig(
        host=str(p["hostname"]),
        port=int(p["port"]),
        use_https=bool(p["use_https"]),
        verify_tls=verify,
        username=user,
        password=password,
        camera=int(p["camera"]),
        timeout_s=timeout_s,
        connect_timeout_s=float(p["connect_timeout"]),
        auth=str(p["auth"]),
    )


# ---------------------------------------------------------------------------------------------------------
# Messages
# ---------------------------------------------------------------------------------------------------------
def stamp_from_ns(ns: int) -> Time:
    """A ROS time from integer nanoseconds (e.g. ``time.time_ns()``)."""
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def stamp_s(stamp: Time) -> float:
    """Seconds of a message stamp through rclpy's ``Time.from_msg`` (integer nanoseconds, divided exactly; the clock
    type is not kept): :func:`stamp_from_ns` back, in seconds. A negative ``sec`` (rclpy refuses it) is 0.0: none."""
    return RosTime.from_msg(stamp).nanoseconds / 1_000_000_000 if stamp.sec >= 0 else 0.0


def camera_info_msg(intr: Intrinsics, frame_id: str, stamp: Time) -> CameraInfo:
    """``sensor_msgs/CameraInfo`` for a pinhole without distortion (plumb_bob zeros)."""
    m = CameraInfo()
    m.header.frame_id = frame_id
    m.header.stamp = stamp
    m.width, m.height = int(intr.width), int(intr.height)
    m.distortion_model = "plumb_bob"
    m.d = [0.0, 0.0, 0.0, 0.0, 0.0]
    m.k = [intr.fx, 0.0, intr.cx, 0.0, intr.fy, intr.cy, 0.0, 0.0, 1.0]
    m.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    m.p = [intr.fx, 0.0, intr.cx, 0.0, 0.0, intr.fy, intr.cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    return m


def pose_msg(P: Pose, parent: str, child: str, stamp: Time) -> TransformStamped:
    """``geometry_msgs/TransformStamped`` (parent → child) of a :class:`~axis_ptz_ros2.geometry.Pose`
    ``T_parent_child`` (the PTZ node's 20 Hz path: plain floats, no matrices)."""
    m = TransformStamped()
    m.header.frame_id = parent
    m.header.stamp = stamp
    m.child_frame_id = child
    t, q = m.transform.translation, m.transform.rotation
    t.x, t.y, t.z = P.t
    q.x, q.y, q.z, q.w = P.q
    return m


def transform_msg(T: Transform, parent: str, child: str, stamp: Time) -> TransformStamped:
    """``geometry_msgs/TransformStamped`` (parent → child) from a :class:`Transform` ``T_parent_child`` (its
    :class:`~axis_ptz_ros2.geometry.Pose`: one conversion from rotation matrix to quaternion, in the geometry)."""
    return pose_msg(Pose.from_transform(T), parent, child, stamp)


def transform_from_msg(msg: TransformStamped) -> Transform:
    """Inverse of :func:`transform_msg`: ``TransformStamped`` → :class:`Transform` ``T_parent_child``."""
    q, t = msg.transform.rotation, msg.transform.translation
    return Transform(quaternion_to_matrix(q.x, q.y, q.z, q.w), np.array([t.x, t.y, t.z], dtype=np.float64))


def diagnostic(
    node: Node, name: str, level: int | bytes, message: str, values: Mapping[str, Any], hardware_id: str = ""
) -> DiagnosticArray:
    """A one-status ``DiagnosticArray`` stamped now (level: 0..3 or DiagnosticStatus.OK/WARN/ERROR/STALE)."""
    arr = DiagnosticArray()
    arr.header.stamp = node.get_clock().now().to_msg()
    lvl = level if isinstance(level, bytes) else bytes([level])
    st = DiagnosticStatus(level=lvl, name=name, message=message, hardware_id=hardware_id)
    for k, v in values.items():
        if isinstance(v, float):
            v = "nan" if math.isnan(v) else f"{v:.3f}"
        st.values.append(KeyValue(key=str(k), value=str(v)))
    arr.status = [st]
    return arr
