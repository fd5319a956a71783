"""Checks of what a send is asked to do, made before anything is loaded or connected: the
controller address and the options whose wrong values would blunt a safety (a stall limit of
minutes would let a frozen controller go unnoticed). `fabkit send` and `fabkit.send` both ask
`send_option_problem`; the messages name the CLI options (`--host`, `--chunk`, `--stall`).

Which controllers (`controller_hosts`): the given addresses (--host, `fk.send(host=, hosts=)`) when
any are given, one per arm of the program, in its arm order; else the cell's (`host` in `[robot]`
and each `[[arms]]`) when it names one for every arm of the program; else `$FABKIT_UR_HOST` for a
one-arm program. Given addresses replace the cell's entirely, never some of them."""
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


def controller_hosts(given, cell, arm_names, env: str | None = None) -> tuple[tuple[str, ...], str]:
    """(addresses in the order of `arm_names`, where they came from: "--host" | "cell" | "env") by
    the rule of the module docstring; `InputError` (source "--host") when there are none or the
    cell names some arms' controllers only."""
    from fabkit.errors import InputError

    given = tuple(h for h in (given or ()) if h)
    if given:
        return given, "--host"
    mounts = dict(cell.arms)
    named = {n: mounts[n].host for n in arm_names if n in mounts and mounts[n].host}
    if len(named) == len(arm_names):
        return tuple(named[n] for n in arm_names), "cell"
    if named:
        missing = [n for n in arm_names if n not in named]
        raise InputError(f"the cell names the controller of arm {', '.join(named)} but not of arm "
                         f"{', '.join(missing)}: add host to its table, or give one --host per arm", source="--host")
    if env and len(arm_names) == 1:
        return (env,), "env"
    raise InputError("no controller address: give --host (one per arm), name each arm's host in the cell, or set "
                     "FABKIT_UR_HOST", source="--host")
