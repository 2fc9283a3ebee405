"""Where the camera's credentials come from: the environment or a file, never a readable parameter. ROS-free.

``AXIS_USERNAME`` / ``AXIS_PASSWORD``, or a file with ``user:password`` on its first line (``password_file``,
else ``AXIS_PASSWORD_FILE``). Nothing here is logged; a credentials file that others can read is reported once
per file and process (by name and mode, never its content).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

_OPEN_FILES_REPORTED: set[str] = set()


def load_credentials(
    password_file: str = "", *, warn: Callable[[str], None] = lambda _text: None
) -> tuple[str | None, str | None]:
    """Camera credentials ``(user, password)``: from ``password_file`` (or ``AXIS_PASSWORD_FILE``) when one is
    named, else ``AXIS_USERNAME``/``AXIS_PASSWORD`` (a password without a user is ``root``'s); ``(None, None)``
    for anonymous access. ``warn(text)``: a credentials file others can read (once per file). Raises ValueError
    for a file without ``user:password`` on its first line, OSError for one that cannot be read."""
    path = password_file or os.environ.get("AXIS_PASSWORD_FILE", "")
    if path:
        file = Path(path).expanduser()
        mode = file.stat().st_mode & 0o777
        if mode & 0o077 and str(file) not in _OPEN_FILES_REPORTED:
            _OPEN_FILES_REPORTED.add(str(file))
            warn(
                f"the credentials file {file} can be read by others (mode {mode:o}): anyone with an account on "
                f"this machine can read the camera's password; chmod 600 {file}"
            )
        text = file.read_text(encoding="utf-8").splitlines()
        first = text[0].strip() if text else ""
        if ":" not in first:
            raise ValueError("credentials file must contain 'user:password' on its first line")
        user, _, pw = first.partition(":")
        return user, pw
    env_user = os.environ.get("AXIS_USERNAME")
    env_pw = os.environ.get("AXIS_PASSWORD")
    if env_pw is not None and not env_user:
        env_user = "root"
    return env_user, env_pw
