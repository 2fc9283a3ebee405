"""Frozen settings snapshots built from a node's parameter values (ROS-free).

A settings class is a frozen dataclass without defaults whose ``PARAMS`` class attribute names the node
parameter behind each field; :func:`snapshot` builds one from the parameter values in effect. Defaults and
ranges therefore live in one place, the node's ``ParamSpec`` table; a parameter change builds a new snapshot
(readers never see a half-updated one).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import fields
from typing import Any, ClassVar, Protocol, TypeVar


class FromParams(Protocol):
    """A settings class: ``PARAMS`` maps each field to the node parameter it is read from."""

    PARAMS: ClassVar[Mapping[str, str]]


S = TypeVar("S", bound=FromParams)


def snapshot(cls: type[S], values: Mapping[str, Any]) -> S:
    """``cls`` from the parameter values (each field converted to its annotated scalar type)."""
    kinds = {"float": float, "int": int, "bool": bool, "str": str}
    args: dict[str, Any] = {}
    for f in fields(cls):  # type: ignore[arg-type]
        kind = kinds[f.type if isinstance(f.type, str) else f.type.__name__]
        args[f.name] = kind(values[cls.PARAMS[f.name]])
    return cls(**args)


def parameter_names(cls: type[FromParams]) -> frozenset[str]:
    """The parameters ``cls`` is built from."""
    return frozenset(cls.PARAMS.values())
