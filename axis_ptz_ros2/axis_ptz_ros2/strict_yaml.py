"""YAML loading for configuration files that must not lose anything silently (ROS-free).

PyYAML's ``safe_load`` accepts a mapping with the same key twice and keeps the last value: a configuration
typo then goes unnoticed. :func:`load_strict` refuses duplicate keys (naming both lines) and turns every
parser error into a :class:`YamlError` (a ``ValueError``) that names the file and line, so callers can
report bad input without a traceback.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml


class YamlError(ValueError):
    """A YAML document could not be read; the message names the source and, where known, the line."""


class _StrictLoader(yaml.SafeLoader):  # type: ignore[misc]  # PyYAML ships no stubs
    """SafeLoader that refuses duplicate mapping keys."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: dict[Any, int] = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                hash(key)
            except TypeError:
                continue  # the base class reports unhashable keys
            line = key_node.start_mark.line + 1
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None,
                    None,
                    f"duplicate key {key!r} (first on line {seen[key]}, again on line {line}); "
                    "only one value per key is allowed",
                    key_node.start_mark,
                )
            seen[key] = line
        return dict(super().construct_mapping(node, deep=deep))


_StrictLoader.add_constructor(
    yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG,
    lambda loader, node: loader.construct_mapping(node, deep=True),
)


def loads_strict(text: str, source: str = "<string>") -> Any:
    """Parse YAML text; duplicate keys and syntax errors raise :class:`YamlError` naming ``source:line``."""
    try:
        return yaml.load(text, Loader=_StrictLoader)  # noqa: S506  (a SafeLoader subclass)
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark or err.context_mark
        where = f"{source}:{mark.line + 1}" if mark is not None else source
        problem = err.problem or str(err)
        raise YamlError(f"{where}: not valid YAML: {problem}") from err
    except yaml.YAMLError as err:
        raise YamlError(f"{source}: not valid YAML: {err}") from err


def read_text(path: str | Path, error: Callable[[str], Exception] = YamlError) -> str:
    """The UTF-8 text of a file; an unreadable or non-UTF-8 file raises ``error(message naming the file)``."""
    p = Path(path)
    try:
        return p.read_text(encoding="utf-8")
    except OSError as err:
        raise error(f"{p}: cannot read: {err.strerror or err}") from err
    except UnicodeDecodeError as err:
        raise error(f"{p}: not a UTF-8 text file ({err.reason})") from err


def load_strict(path: str | Path, error: Callable[[str], Exception] = YamlError) -> Any:
    """Read and parse a YAML file strictly (see :func:`loads_strict`); an unreadable file or bad YAML raises
    ``error`` (a :class:`YamlError` unless the caller names its own error type) with the YamlError's message."""
    p = Path(path)
    text = read_text(p, error)
    try:
        return loads_strict(text, str(p))
    except YamlError as err:
        if error is YamlError:
            raise
        raise error(str(err)) from err
