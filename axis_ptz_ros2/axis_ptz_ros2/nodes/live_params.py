"""One way for every node to hold its parameters: a frozen snapshot, validated as a whole, swapped after the set.

In the spirit of generate_parameter_library's ``ParamListener``, on the project's :class:`ParamSpec` tables
(:mod:`~axis_ptz_ros2.nodes.common`):

* :class:`LiveParams` declares the node's specs (:func:`declare_params`: descriptors, ranges, read-only flags,
  the start-up choice check) and holds the values in effect as a :class:`Params` snapshot (a read-only mapping;
  lists become tuples). Readers take ``listener.params``: no copies, no mirrors, no ``get_parameter`` per use.
* The on-set callback builds the *candidate* snapshot (current values + the proposed changes of the node's own
  parameters), checks the choices of the changed ones, then runs the node's validators on the candidate as a
  whole (a multi-parameter set is judged together); it refuses with the first reason and mutates nothing.
* The post-set callback (run by rclpy only once every on-set callback accepted and the values are stored) swaps
  the snapshot and calls the node's one ``on_change(names)`` with the names that were set.

So ``ros2 param get`` and ``listener.params`` always agree: a refused set changes neither, an accepted one both.
A node's runtime state that comes from elsewhere (e.g. the PTZ node's stream size from ``video/params``) is kept
in the node, never written back into its own parameters.
"""

from __future__ import annotations

import array
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any, TypeVar

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from axis_ptz_ros2.nodes.common import ParamSpec, declare_params, snapshot

_C = TypeVar("_C")

#: A whole-snapshot rule: ``(candidate, changed names) -> reason to refuse, or None``. It must not mutate anything.
Validator = Callable[["Params", frozenset[str]], "str | None"]
#: Called after an accepted set with the names of the node's parameters that were set.
OnChange = Callable[[frozenset[str]], None]


def _frozen(value: Any) -> Any:  # noqa: ANN401 - a parameter value
    """Array values as tuples (a snapshot shares nothing mutable)."""
    if isinstance(value, (list, array.array)):
        return tuple(value)
    return value


class Params(Mapping[str, Any]):
    """A frozen snapshot of a node's parameter values (read-only mapping name -> value)."""

    __slots__ = ("_values",)
    _values: dict[str, Any]

    def __init__(self, values: Mapping[str, Any]) -> None:
        object.__setattr__(self, "_values", {k: _frozen(v) for k, v in values.items()})

    def __setattr__(self, name: str, value: Any) -> None:  # noqa: ANN401
        raise AttributeError("a parameter snapshot is read-only")

    def __getitem__(self, name: str) -> Any:  # noqa: ANN401 - a parameter value
        return self._values[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def __repr__(self) -> str:
        return f"Params({self._values!r})"

    def replace(self, changes: Mapping[str, Any]) -> Params:
        """A new snapshot: these values over this one's (names must be known)."""
        unknown = set(changes) - set(self._values)
        if unknown:
            raise KeyError(f"unknown parameter(s): {', '.join(sorted(unknown))}")
        return Params({**self._values, **changes})


class LiveParams:
    """Declares ``specs`` on ``node`` and keeps a validated frozen snapshot of their values (see module docstring).

    ``validate``: whole-snapshot rules (more can be added with :meth:`add_validator`, e.g. by the process that
    owns the node); ``on_change``: the node's one reaction to an accepted set. Start-up values are checked by
    :func:`declare_params` (choices) and by the node itself where building its objects checks more.
    """

    def __init__(
        self,
        node: Node,
        specs: Sequence[ParamSpec],
        *,
        validate: Validator | None = None,
        on_change: OnChange | None = None,
    ) -> None:
        self.specs: tuple[ParamSpec, ...] = tuple(specs)
        self._by_name = {s.name: s for s in self.specs}
        self._params = Params(declare_params(node, self.specs))
        self._validators: list[Validator] = [validate] if validate is not None else []
        self._on_change = on_change
        node.add_on_set_parameters_callback(self._on_set)
        node.add_post_set_parameters_callback(self._post_set)

    @property
    def params(self) -> Params:
        """The values in effect now (what ``ros2 param get`` returns); a new object after every accepted set."""
        return self._params

    def config(self, cls: type[_C], params: Params | None = None) -> _C:
        """The ROS-free frozen ``cls`` filled by the specs that name it (:func:`snapshot`), from ``params``
        (default: the current snapshot)."""
        return snapshot(cls, self.specs, self._params if params is None else params)

    def add_validator(self, validate: Validator) -> None:
        """Another whole-snapshot rule, run after the ones before it."""
        self._validators.append(validate)

    def _own(self, params: Sequence[Parameter]) -> dict[str, Any]:
        return {p.name: p.value for p in params if p.name in self._by_name and p.type_ != Parameter.Type.NOT_SET}

    def candidate(self, params: Sequence[Parameter]) -> tuple[Params, frozenset[str]]:
        """The snapshot these parameters would make, and the names of the node's own among them."""
        changes = self._own(params)
        return self._params.replace(changes), frozenset(changes)

    def _on_set(self, params: list[Parameter]) -> SetParametersResult:
        """on-set: judge the candidate snapshot as a whole; nothing is mutated here."""
        candidate, names = self.candidate(params)
        if not names:
            return SetParametersResult(successful=True)
        for p in params:  # the choices first, in the order given (the reason names the parameter)
            spec = self._by_name.get(p.name)
            reason = spec.check(candidate[p.name]) if spec is not None else None
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        for validate in self._validators:
            reason = validate(candidate, names)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _post_set(self, params: list[Parameter]) -> None:
        """post-set (the values are stored): swap the snapshot, then tell the node which names were set."""
        candidate, names = self.candidate(params)
        if not names:
            return
        self._params = candidate
        if self._on_change is not None:
            self._on_change(names)
