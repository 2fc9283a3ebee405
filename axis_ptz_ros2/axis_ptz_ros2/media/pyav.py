"""PyAV, checked once: the one place that knows which PyAV the H.264 code needs and how a user gets it (ROS-free).

The H.264 modules (:mod:`.encoder`, :mod:`.decoder`, :mod:`.transcoder`) call :func:`require` before they import
``av``: a missing PyAV, or one older than :data:`MIN_VERSION` (Ubuntu 24.04's ``python3-av`` is 11.0, which lacks
``av.VideoCodecContext``, ``max_b_frames``, colour-range conversion and the ``Interpolation`` flags used here), raises
:class:`PyAvUnavailableError` with one sentence naming the version needed and how to install it, instead of an
``ImportError``/``AttributeError`` deep inside the first frame. The nodes catch it, say it once, and keep serving
MJPEG. ``pyproject.toml`` declares the same minimum (a test compares the two).
"""

from __future__ import annotations

import functools
import importlib
import importlib.metadata
import re
from typing import Final

from axis_ptz_ros2.media.errors import MediaError

MIN_VERSION: Final = (18, 0)  # Interpolation as flags (decoder.TO_BGR); VideoCodecContext 13.1; color ranges 12.0
HOW_TO_GET: Final = (
    "on a Jazzy robot: rosdep install with the project's rosdep source (README, 'On a Jazzy robot'); "
    "elsewhere: pip install 'av>=18.0'"
)


class PyAvUnavailableError(MediaError, ImportError):
    """PyAV is missing or too old for the H.264 path (the message says which version is needed and how to get it)."""


def _parse(version: str) -> tuple[int, ...]:
    """``"18.1.0"`` → ``(18, 1)``; ``"11.0.0-4build1"`` → ``(11, 0)``; unparseable → ``()`` (older than any)."""
    m = re.match(r"(\d+)(?:\.(\d+))?", version)
    return (int(m.group(1)), int(m.group(2) or 0)) if m else ()


def problem() -> str | None:
    """Why PyAV cannot serve the H.264 path here, or None when it can."""
    need = ".".join(map(str, MIN_VERSION))
    try:
        av = importlib.import_module("av")
    except ImportError as err:
        return f"H.264 needs PyAV >= {need}, which is not installed ({err.__class__.__name__}: {err}); {HOW_TO_GET}"
    found = str(getattr(av, "__version__", "") or _metadata_version())
    if _parse(found) < MIN_VERSION:
        return f"H.264 needs PyAV >= {need}, found {found or 'an unknown version'}; {HOW_TO_GET}"
    return None


def _metadata_version() -> str:
    try:
        return importlib.metadata.version("av")
    except importlib.metadata.PackageNotFoundError:
        return ""


def require() -> None:
    """Raise :class:`PyAvUnavailableError` unless PyAV is installed and new enough (checked once per process)."""
    why = _problem_once()
    if why is not None:
        raise PyAvUnavailableError(why)


def usable() -> bool:
    """Whether PyAV can serve the H.264 path here (checked once per process, like :func:`require`)."""
    return _problem_once() is None


_problem_once = functools.cache(problem)
