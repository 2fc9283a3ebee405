"""A tiny stand-in for the ``launch`` / ``launch_ros`` packages (not installable from PyPI here) that records
what a launch file declares, so a test can check it names only executables, nodes and parameters that exist.

Only the classes our launch files use exist, with only the keyword arguments the real classes accept: a launch
file importing anything else, or passing an unknown keyword, fails here as it would (or might) on a robot.
Substitutions are resolved with :func:`resolve`: launch arguments take their declared defaults (or the
values an include passes), ``FindPackageShare('axis_ptz_ros2')`` is :func:`share_dir`: a folder laid out as
``share/axis_ptz_ros2`` of a colcon install (the ROS package folder ``axis_ptz_ros2/``).
"""

from __future__ import annotations

import contextlib
import importlib.util
import sys
import types
from collections.abc import Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]


def share_dir() -> Path:
    """``share/axis_ptz_ros2`` of a colcon install: the ROS package folder holds the same ``launch/``, ``urdf/`` and
    ``config/`` (a link to the top-level ``config/``) that its ``setup.py`` installs there."""
    return ROOT / "axis_ptz_ros2"


class Recorded:
    """Base of every stand-in: keeps its positional and keyword arguments."""

    allowed: frozenset[str] = frozenset()

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        unknown = set(kwargs) - self.allowed
        if unknown:
            raise TypeError(f"{type(self).__name__}() got unexpected keyword arguments {sorted(unknown)}")
        self.args = args
        self.kwargs = kwargs

    def __repr__(self) -> str:
        return f"{type(self).__name__}{self.args}{self.kwargs}"


def _cls(name: str, allowed: set[str]) -> type[Recorded]:
    return type(name, (Recorded,), {"allowed": frozenset(allowed)})


_COND = {"condition"}
LaunchDescription = _cls("LaunchDescription", set())
DeclareLaunchArgument = _cls("DeclareLaunchArgument", {"default_value", "description", "choices"})
IncludeLaunchDescription = _cls("IncludeLaunchDescription", {"launch_arguments", *_COND})
GroupAction = _cls("GroupAction", {"actions", "scoped", "forwarding", "launch_configurations", *_COND})
IfCondition = _cls("IfCondition", set())
UnlessCondition = _cls("UnlessCondition", set())
LaunchConfiguration = _cls("LaunchConfiguration", {"default"})
PathJoinSubstitution = _cls("PathJoinSubstitution", set())
PythonExpression = _cls("PythonExpression", set())
Command = _cls("Command", {"on_stderr"})
TextSubstitution = _cls("TextSubstitution", {"text"})
PythonLaunchDescriptionSource = _cls("PythonLaunchDescriptionSource", set())
Node = _cls(
    "Node",
    {
        "package",
        "executable",
        "name",
        "namespace",
        "exec_name",
        "parameters",
        "remappings",
        "ros_arguments",
        "arguments",
        "output",
        "respawn",
        "respawn_delay",
        "emulate_tty",
        "additional_env",
        *_COND,
    },
)
PushRosNamespace = _cls("PushRosNamespace", {"namespace"})
FindPackageShare = _cls("FindPackageShare", set())
ParameterValue = _cls("ParameterValue", {"value_type"})

MODULES: dict[str, dict[str, Any]] = {
    "launch": {"LaunchDescription": LaunchDescription},
    "launch.actions": {
        "DeclareLaunchArgument": DeclareLaunchArgument,
        "IncludeLaunchDescription": IncludeLaunchDescription,
        "GroupAction": GroupAction,
    },
    "launch.conditions": {"IfCondition": IfCondition, "UnlessCondition": UnlessCondition},
    "launch.substitutions": {
        "LaunchConfiguration": LaunchConfiguration,
        "PathJoinSubstitution": PathJoinSubstitution,
        "PythonExpression": PythonExpression,
        "Command": Command,
        "TextSubstitution": TextSubstitution,
    },
    "launch.launch_description_sources": {"PythonLaunchDescriptionSource": PythonLaunchDescriptionSource},
    "launch_ros": {},
    "launch_ros.actions": {"Node": Node, "PushRosNamespace": PushRosNamespace},
    "launch_ros.substitutions": {"FindPackageShare": FindPackageShare},
    "launch_ros.parameter_descriptions": {"ParameterValue": ParameterValue},
}


@contextlib.contextmanager
def standin_modules() -> Iterator[None]:
    """Install the stand-in modules in ``sys.modules`` for the duration (the real ones, if any, restored)."""
    saved = {name: sys.modules.get(name) for name in MODULES}
    try:
        for name, attrs in MODULES.items():
            mod = types.ModuleType(name)
            mod.__dict__.update(attrs)
            if "." not in name:
                mod.__path__ = []  # a package
            sys.modules[name] = mod
        yield
    finally:
        for name, old in saved.items():
            if old is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = old


def load_launch_file(path: Path) -> Recorded:
    """Import a launch file under the stand-ins and return its ``generate_launch_description()``."""
    with standin_modules():
        spec = importlib.util.spec_from_file_location(f"launchfile_{path.stem.replace('.', '_')}", path)
        assert spec is not None
        assert spec.loader is not None
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        ld = mod.generate_launch_description()
    assert isinstance(ld, LaunchDescription), f"{path.name}: generate_launch_description() must return one"
    return ld


def actions(ld: Recorded) -> list[Recorded]:
    """The actions of a LaunchDescription (GroupAction contents flattened)."""
    out: list[Recorded] = []
    for a in ld.args[0] if ld.args else []:
        out.append(a)
        if isinstance(a, GroupAction):
            out.extend(actions(LaunchDescription(a.args[0] if a.args else a.kwargs.get("actions", []))))
    return out


def declared_arguments(ld: Recorded) -> dict[str, Any]:
    """Launch argument name → default value (substitution or text)."""
    return {a.args[0]: a.kwargs.get("default_value") for a in actions(ld) if isinstance(a, DeclareLaunchArgument)}


def resolve(value: Any, args: dict[str, Any]) -> str:
    """Text of a substitution (or list of them) given the launch arguments' values."""
    if isinstance(value, bool | int | float):  # a plain parameter value, as launch_ros passes it on
        return str(value)
    if isinstance(value, str):
        return value
    if isinstance(value, list | tuple):
        return "".join(resolve(v, args) for v in value)
    if isinstance(value, LaunchConfiguration):
        name = value.args[0]
        if name not in args:
            raise KeyError(f"LaunchConfiguration({name!r}) is not a declared launch argument")
        return resolve(args[name], args)
    if isinstance(value, PathJoinSubstitution):
        return "/".join(resolve(v, args) for v in value.args[0])
    if isinstance(value, FindPackageShare):
        pkg = resolve(value.args[0], args)
        if pkg != "axis_ptz_ros2":
            raise KeyError(f"FindPackageShare({pkg!r}): only our own package's files are known here")
        return str(share_dir())
    if isinstance(value, TextSubstitution):
        return str(value.kwargs.get("text", value.args[0] if value.args else ""))
    if isinstance(value, PythonExpression):
        return str(eval(resolve(value.args[0], args), {}, {}))  # noqa: S307 - our own launch files
    if isinstance(value, Command):
        return "$(" + resolve(value.args[0], args) + ")"
    if isinstance(value, ParameterValue):
        return resolve(value.args[0], args)
    raise TypeError(f"cannot resolve {value!r}")


def condition_true(action: Recorded, args: dict[str, Any]) -> bool:
    """Whether an action's condition holds with these launch arguments (no condition = true)."""
    cond = action.kwargs.get("condition")
    if cond is None:
        return True
    v = resolve(cond.args[0], args).strip().lower()
    if v not in ("true", "false", "1", "0"):
        raise ValueError(f"condition value {v!r} is not a boolean")
    truth = v in ("true", "1")
    return truth if isinstance(cond, IfCondition) else not truth
