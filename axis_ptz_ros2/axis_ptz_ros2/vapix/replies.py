"""VAPIX request paths and reply text (ROS-free): the query string of a request, the camera's ``Error:`` bodies, reply
bytes as text (reference ``vapix.md`` §2.1, §4)."""

from __future__ import annotations

import re
from collections.abc import Mapping
from urllib.parse import quote

__all__ = ["build_path", "decode_text", "parse_error_body"]

_HTML_ERROR = re.compile(r"(?is)Error:\s*(.*?)\s*</body>")


def build_path(path: str, args: Mapping[str, str]) -> str:
    """``path?k=v&…`` with RFC 3986 percent-encoding (spaces as ``%20``; ``,`` kept, §2.1)."""
    if not args:
        return path
    query = "&".join(f"{quote(k, safe='')}={quote(v, safe=',-._~')}" for k, v in args.items())
    return f"{path}?{query}"


def parse_error_body(text: str) -> str | None:
    """The camera message of an ``Error:`` body (same-line, next-line or old HTML form), else None."""
    stripped = text.strip()
    if stripped.startswith("Error"):
        first, _, rest = stripped.partition("\n")
        message = first[len("Error") :].lstrip(":").strip()
        if not message:
            message = next((line.strip() for line in rest.splitlines() if line.strip()), "")
        return message or "(no message)"
    match = _HTML_ERROR.search(text)
    if match and stripped[:1] == "<":
        return re.sub(r"<[^>]+>", "", match.group(1)).strip() or "(no message)"
    return None


def decode_text(body: bytes) -> str:
    """A reply's bytes as text: UTF-8, else Latin-1 (older firmware)."""
    try:
        return body.decode("utf-8")
    except UnicodeDecodeError:
        return body.decode("latin-1")
