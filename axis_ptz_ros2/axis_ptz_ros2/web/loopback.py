"""Which addresses and host names are the machine itself (ROS-free): :func:`is_loopback`.

The console binds 127.0.0.1 by default and then answers only loopback ``Host`` names (:mod:`.handler`); any other
bind needs a token and HTTPS (:mod:`.server`). Both ask this one function.
"""

from __future__ import annotations

import ipaddress


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and ``localhost`` (an IPv6 address may come in brackets)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False
