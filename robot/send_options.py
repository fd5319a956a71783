"""Checks of what a send is asked to do, made before anything is loaded or connected: the
controller address and the options whose wrong values would blunt a safety (a stall limit of
minutes would let a frozen controller go unnoticed). `fabkit send` and `fabkit.send` both ask
`send_option_problem`; the messages name the CLI options (`--host`, `--chunk`, `--stall`)."""
from __future__ import annotations

import ipaddress
import math
import re

#: longest stall limit [s]: a frozen controller must be noticed within seconds, never switched off
MAX_STALL_S = 5.0

_HOST_LABEL = re.compile(r"^(?!-)[A-Za-z0-9-]{1,63}(?<!-)$")


def is_host(text: str) -> bool:
    """An IPv4/IPv6 address or an RFC 1123 host name."""
    try:
        ipaddress.ip_address(text)
        return True
    except ValueError:
        pass
    return len(text) <= 253 and all(_HOST_LABEL.match(label) for label in text.rstrip(".").split("."))


def send_option_problem(host: str | None, chunk: int, stall_s: float) -> tuple[str, str] | None:
    """The first thing wrong with these send options as `(option, message)`, None when all is well."""
    if not host:
        return "host", "no controller address: give --host or set FABKIT_UR_HOST"
    if chunk < 2:
        return "chunk", "a chunk needs at least 2 waypoints"
    if not (math.isfinite(stall_s) and 0 < stall_s <= MAX_STALL_S):
        return "stall", f"must be a number of seconds in (0, {MAX_STALL_S:g}], got {stall_s}"
    if not is_host(host):
        return "host", f"{host!r} is not an IP address or host name"
    return None
