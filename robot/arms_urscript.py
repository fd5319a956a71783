"""URScript programs for a program of several arms: one per arm, meeting at every sync waypoint
through the controllers' standard digital I/O.

Each arm's program is its one-arm program (`robot.urscript.write_urscript`) with a handshake after
every sync waypoint of the program (`ArmsToolpath.sync`: the grip, each fold state, the release),
run at rest once the arm has arrived (and, at the grip, switched its gripper and dwelt). At the
j-th sync waypoint (j = 1, 2, ...) every arm sets its standard digital output `HANDSHAKE_OUTPUT`
to the level of j's parity (True for odd j, False for even j) and waits until its standard digital
input `HANDSHAKE_INPUT` shows the same level:

    set_standard_digital_out(6, True)         # j odd: "arm a is at sync waypoint j"
    while not get_standard_digital_in(6):     # until the other arm says the same
      sync()
    end

**Wiring** (two arms a and b): DO 6 of controller a to DI 6 of controller b, and DO 6 of b to DI 6
of a (24 V outputs into inputs, common 0 V). An arm's output shows the level of sync waypoint j
only once that arm has arrived there (it showed j - 1's level before, and it passed j - 1 only
when the other arm had arrived at j - 1), so neither arm leaves sync waypoint j before both have
reached it: the rule of the lockstep send (`robot.lockstep`). Both programs start by setting the
output to False and wait until the input is False, so both controllers must start from a reset
line; the programs end with the output False. Between sync waypoints each arm runs on its own
clock: the moves that carry the panel take the same time for both arms in the controller's motion
model (the planner makes them so), and both start a segment within a few controller ticks of each
other (the input is read every `sync()`, 2 ms on an e-Series). There is no time-out: an arm whose
partner faulted waits at its sync waypoint (stop it from its pendant).
"""
from __future__ import annotations

from robot.urscript import PROGRESS_REGISTER, write_urscript

__all__ = ["HANDSHAKE_OUTPUT", "HANDSHAKE_INPUT", "handshake_lines", "write_arm_urscripts", "arm_script_path"]

#: The standard digital output each arm raises/lowers at a sync waypoint, and the standard digital
#: input wired to the other arm's output (both 0-7; the grip output must be another one).
HANDSHAKE_OUTPUT = 6
HANDSHAKE_INPUT = 6


def handshake_lines(level: bool, output: int = HANDSHAKE_OUTPUT, input_: int = HANDSHAKE_INPUT) -> list[str]:
    """Set `output` to `level`, then wait (one `sync()` per tick) until `input_` shows it."""
    test = f"get_standard_digital_in({int(input_)})"
    return [f"set_standard_digital_out({int(output)}, {level})",
            f"while {'not ' if level else ''}{test}:", "  sync()", "end"]


def arm_script_path(path, arm: str):
    """Where arm `arm`'s program goes for `--script path`: `_<arm>` before the suffix
    (fold.script -> fold_a.script)."""
    from pathlib import Path

    path = Path(path)
    return path.with_name(f"{path.stem}_{arm}{path.suffix}")


def write_arm_urscripts(atp, *, progress_register: int = PROGRESS_REGISTER, output: int = HANDSHAKE_OUTPUT,
                        input_: int = HANDSHAKE_INPUT) -> dict[str, str]:
    """{arm: URScript program text} for a `robot.arms_toolpath.ArmsToolpath` (module docstring)."""
    if not (0 <= int(output) <= 7 and 0 <= int(input_) <= 7):
        raise ValueError(f"standard digital output {output} / input {input_}: both must be in 0..7")
    out = {}
    for name, tp in atp.arms:
        grip = tp.extra.get("grip") or {}
        if str(grip.get("kind", "tool")) == "standard" and int(grip.get("output", -1)) == int(output):
            from fabkit.errors import InputError

            raise InputError(f"arm {name}: the gripper uses standard digital output {output}, which the "
                             "two-arm programs' handshake needs", source="--script")
        after = {int(k): handshake_lines(j % 2 == 1, output, input_) for j, k in enumerate(atp.sync, start=1)}
        after[0] = handshake_lines(False, output, input_)  # start from a reset line
        after[len(tp) - 1] = [f"set_standard_digital_out({int(output)}, False)"]
        others = ", ".join(n for n in atp.arm_names if n != name)
        header = (f"arm {name} of {len(atp.arm_names)} ({', '.join(atp.arm_names)}); program sha256 {atp.sha256}",
                  f"handshake: at every sync waypoint {list(atp.sync)} standard DO {int(output)} = the sync's "
                  f"parity (odd True), then wait for standard DI {int(input_)} (wired to DO {int(output)} of arm "
                  f"{others}) to show it")
        out[name] = write_urscript(tp, program_name=f"fold_{atp.cell}_{name}", progress_register=progress_register,
                                   after_waypoint=after, header_extra=header)
    return out
