"""URScript program text for a planned toolpath.

The program is one complete `def <name>(): ... end` block (what the controller's script ports run
when sent as text; the text starts with `def`): a header comment inside it (source hash, robot,
cell, units), `set_tcp`, the gripper output
switched off, then per waypoint a progress write to an output integer register followed by the move
(`movej` to the joint solution, `movel` to the TCP pose, each with a/v/r), the gripper switched on
after the `grip` waypoint and off after `release`, each followed by a dwell. The register finally
holds the number of waypoints (done). When the toolpath has a `payload` record (a sheet material was
given), `set_payload(mass, cog)` declares the tool at the start and after the release, and tool +
panel after the grip (kg, metres in the flange frame).

Numbers are printed so that they read back as the same double (shortest round-trip decimal, never
exponent notation, never the 6 significant digits of iostream defaults). Names from input files
(cell, panel, source) only reach the program through `sanitise_identifier` (letters, digits and
underscores) or `sanitise_comment` (a whitelist without line breaks), so no input can inject script
text.
"""
from __future__ import annotations

import math
import re

import numpy as np

from robot.toolpath import Toolpath

__all__ = ["PROGRESS_REGISTER", "format_number", "sanitise_identifier", "sanitise_comment", "write_urscript"]

#: Output integer register the program writes its progress to (waypoint index; len(waypoints) when
#: done). 0-2 and 12-23 are used by ur_rtde's control script and default recipes, so 3 is free.
PROGRESS_REGISTER = 3
#: Longest program name we emit (the controller accepts longer, keep it readable).
MAX_NAME = 40

_COMMENT_OK = re.compile(r"[^A-Za-z0-9 _.,:;/=+()\[\]-]")


def format_number(x: float) -> str:
    """The shortest decimal that reads back as exactly `x`, without an exponent (URScript literal)."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot write {x!r} into a URScript program")
    if x == 0.0:
        return "0.0"
    return np.format_float_positional(x, unique=True, trim="0")


def sanitise_identifier(name: str, prefix: str = "fabkit_") -> str:
    """A URScript identifier made of `prefix` and the letters, digits and underscores of `name`."""
    body = re.sub(r"[^A-Za-z0-9_]+", "_", str(name)).strip("_")
    ident = (prefix + body)[:MAX_NAME].rstrip("_") or prefix.rstrip("_") or "fabkit"
    if not ident[0].isalpha():
        ident = "p_" + ident
    return ident


def sanitise_comment(text: str, limit: int = 120) -> str:
    """Text safe inside a `#` comment: one line, whitelisted characters, at most `limit` long."""
    return _COMMENT_OK.sub("_", str(text))[:limit]


def _list(values) -> str:
    return "[" + ", ".join(format_number(v) for v in values) + "]"


def write_urscript(tp: Toolpath, *, program_name: str | None = None, progress_register: int = PROGRESS_REGISTER,
                   grip_output: int | None = None, grip_output_kind: str | None = None,
                   grip_dwell: float | None = None, release_dwell: float | None = None,
                   after_waypoint: dict | None = None, header_extra: tuple = ()) -> str:
    """The URScript program for `tp` (see module docstring). Gripper settings default to the
    toolpath's `grip` record (from the cell). `after_waypoint` {i: [script lines]}: lines run at
    rest after waypoint i (after its gripper switch and dwell; its move gets blend radius 0), and
    `header_extra` further header comment lines: what `robot.arms_urscript` adds for one arm of a
    program for several arms. A program for several arms itself is refused (`InputError`): it is
    one script per arm (`robot.arms_urscript.write_arm_urscripts`)."""
    if not isinstance(tp, Toolpath):
        from fabkit.errors import InputError

        raise InputError("a program for several arms is one URScript program per arm "
                         "(robot.arms_urscript.write_arm_urscripts)", source="--script")
    after_waypoint = after_waypoint or {}
    grip = dict(tp.extra.get("grip", {}))
    out_no = int(grip.get("output", 0) if grip_output is None else grip_output)
    kind = str(grip.get("kind", "tool") if grip_output_kind is None else grip_output_kind)
    if kind not in ("tool", "standard"):
        raise ValueError(f"grip output kind {kind!r} is not 'tool' or 'standard'")
    if not 0 <= int(progress_register) <= 47:
        raise ValueError(f"output integer register {progress_register} is outside 0..47")
    g_dwell = float(grip.get("grip_dwell_s", 0.5) if grip_dwell is None else grip_dwell)
    r_dwell = float(grip.get("release_dwell_s", 0.5) if release_dwell is None else release_dwell)
    setter = "set_tool_digital_out" if kind == "tool" else "set_standard_digital_out"
    name = sanitise_identifier(program_name if program_name is not None else f"fold_{tp.cell}")
    src = tp.source or {}
    header = [
        f"fabkit fold program {name}",
        f"toolpath sha256: {sanitise_comment(tp.sha256)}",
        f"source: {sanitise_comment(src.get('file', ''))} sha256 {sanitise_comment(src.get('sha256', ''))}",
        f"grip face: {sanitise_comment(src.get('grip_face', ''))}  fold states: {sanitise_comment(src.get('states', ''))}",
        f"robot: {sanitise_comment(tp.robot)}  cell: {sanitise_comment(tp.cell)}",
        "units: metres, radians, seconds; poses are TCP poses in the robot base frame (rotation vectors);",
        "movel a/v in m/s^2 and m/s, movej a/v in rad/s^2 and rad/s, blend radius r in m",
        f"progress: output integer register {int(progress_register)} = index of the waypoint being moved to, "
        f"{len(tp)} when done",
        f"gripper: {setter}({out_no}, True) after the grip waypoint, False after release",
        *(sanitise_comment(h, 200) for h in header_extra),
    ]
    # the text starts with `def` (a controller's script port runs it as one program), header inside
    lines = [f"def {name}():"] + [f"  # {h}" for h in header] + [
        f"  set_tcp(p{_list(tp.tcp)})",
        f"  {setter}({out_no}, False)",
    ]
    payload = tp.extra.get("payload")  # sheet payload (robot.loads.payload_record): tool, tool + panel held
    if payload:
        for key in ("tool_mass_kg", "held_mass_kg"):
            if not 0.0 <= float(payload[key]) <= 50.0:
                raise ValueError(f"payload {key} {payload[key]!r} is not a mass in [0, 50] kg")
        tool_payload = f"  set_payload({format_number(payload['tool_mass_kg'])}, {_list(payload['tool_cog_m'])})"
        held_payload = f"  set_payload({format_number(payload['held_mass_kg'])}, {_list(payload['held_cog_m'])})"
        lines.append(tool_payload)
    for i, w in enumerate(tp.waypoints):
        lines.append(f"  # waypoint {i}: {sanitise_comment(w['op'])}, fold state {int(w['state'])}")
        lines.append(f"  write_output_integer_register({int(progress_register)}, {i})")
        a, v = format_number(w["a"]), format_number(w["v"])
        r = "0.0" if i in after_waypoint else format_number(w["r"])  # at rest where more follows
        if w["move"] == "movej":
            lines.append(f"  movej({_list(w['q'])}, a={a}, v={v}, r={r})")
        elif w["move"] == "movel":
            lines.append(f"  movel(p{_list(w['pose'])}, a={a}, v={v}, r={r})")
        else:  # Toolpath validation makes this unreachable
            raise ValueError(f"waypoint {i}: unknown move {w['move']!r}")
        if w["op"] == "grip":
            lines.append(f"  {setter}({out_no}, True)")
            lines.append(f"  sleep({format_number(g_dwell)})")
            if payload:
                lines.append(held_payload)
        elif w["op"] == "release":
            lines.append(f"  {setter}({out_no}, False)")
            lines.append(f"  sleep({format_number(r_dwell)})")
            if payload:
                lines.append(tool_payload)
        lines += [f"  {line}" for line in after_waypoint.get(i, ())]
    lines.append(f"  write_output_integer_register({int(progress_register)}, {len(tp)})")
    lines.append("end")
    return "\n".join(lines) + "\n"
