"""URScript programs for a program of several arms: one per arm, meeting at every sync waypoint
through the controllers' standard digital I/O, with a bounded wait.

Each arm's program is its one-arm program (`robot.urscript.write_urscript`) with a handshake after
every sync waypoint of the program (`ArmsToolpath.sync`: the grip, each fold state, the release),
run at rest once the arm has arrived (and, at the grip, switched its gripper and dwelt). At the
j-th sync waypoint (j = 1, 2, ...) every arm sets its standard digital output `HANDSHAKE_OUTPUT`
to the level of j's parity (True for odd j, False for even j) and waits until its standard digital
input `HANDSHAKE_INPUT` shows the same level, for at most the time-out:

    set_standard_digital_out(6, True)         # j odd: "arm a is at sync waypoint j"
    fabkit_waited = 0.0
    while not get_standard_digital_in(6):     # until the other arm says the same
      sync()
      fabkit_waited = fabkit_waited + get_steptime()
      if fabkit_waited > 10.9:                # the other arm did not come
        set_standard_digital_out(6, False)    # back to j - 1's level: "do not pass j"
        stopj(2.0)
        textmsg("fabkit: arm a halted at sync waypoint 7 ...")
        popup("arm a halted at sync waypoint 7 ...", title="fabkit two-arm handshake", error=True)
        halt
      end
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
other (the input is read every `sync()`, 2 ms on an e-Series).

**Time-out.** An arm that waits longer than the time-out at a sync waypoint (its partner stopped,
faulted or was paused) puts its output back to the level it showed before (so a partner that
arrives later does not pass that sync waypoint alone), stops (`stopj`: it is at rest there), logs
and shows an error popup naming the sync waypoint and the partner, and halts its program. The
gripper stays as it is (a half-folded panel stays held). A partner that arrives later waits its own
time-out at the same sync waypoint and halts with the same message: both arms stand still. The
time-out (`default_timeout`) is the longest segment between two sync waypoints of any arm in the
controller's motion model (`robot.two_arm_planner.lockstep_timing`, moves and dwells) plus
`TIMEOUT_MARGIN_S`: an arm that runs the program at full speed arrives at most that segment's
duration after the other (both leave the previous sync waypoint together). The start line and the
first sync waypoint also wait `START_WINDOW_S` longer: they cover starting the two programs, one
after the other.

Limits: if the partner arrives within one wire delay (a controller tick plus the line's switching
time) of the time-out, it can see the output before it is put back and pass while the waiting
arm halts; the other arm's halted program then leaves it standing, holding the panel. The handshake
output must keep its level when a program stops (the controller's I/O setup, not "set low on
program stop"): a line that drops to False would read as an even sync waypoint's level.
"""
from __future__ import annotations

import math

from robot.urscript import PROGRESS_REGISTER, format_number, sanitise_comment, write_urscript

__all__ = ["HANDSHAKE_OUTPUT", "HANDSHAKE_INPUT", "TIMEOUT_MARGIN_S", "START_WINDOW_S", "default_timeout",
           "handshake_lines", "write_arm_urscripts", "arm_script_path"]

#: The standard digital output each arm raises/lowers at a sync waypoint, and the standard digital
#: input wired to the other arm's output (both 0-7; the grip output must be another one).
HANDSHAKE_OUTPUT = 6
HANDSHAKE_INPUT = 6
#: Added [s] to the longest segment between sync waypoints for the default time-out: the two
#: controllers' start and I/O latencies (milliseconds) with room to spare.
TIMEOUT_MARGIN_S = 2.0
#: Added [s] to the time-out of the start line and the first sync waypoint: the time to start the
#: second program after the first (two pendants, or the dashboard server's `play` on both).
START_WINDOW_S = 10.0
#: Deceleration of the `stopj` before the halt [rad/s^2] (the arm is at rest at a sync waypoint).
STOP_DECELERATION = 2.0
_WAITED = "fabkit_waited"


def default_timeout(atp) -> float:
    """The handshake time-out [s] of program `atp` (module docstring): its longest segment between
    sync waypoints, over all arms, plus `TIMEOUT_MARGIN_S`, rounded up to 0.1 s."""
    from robot.two_arm_planner import lockstep_timing

    longest = max(max(per) for per in lockstep_timing(atp)["arms"].values())
    return math.ceil((longest + TIMEOUT_MARGIN_S) * 10.0 - 1e-9) / 10.0


def handshake_lines(level: bool, output: int = HANDSHAKE_OUTPUT, input_: int = HANDSHAKE_INPUT, *,
                    timeout_s: float | None = None, previous: bool = False, message: str = "") -> list[str]:
    """Set `output` to `level`, then wait (one `sync()` per tick) until `input_` shows it. With
    `timeout_s`: after that long, put `output` back to `previous`, stop, `textmsg` and `popup`
    `message` (whitelisted text), and halt the program."""
    test = f"get_standard_digital_in({int(input_)})"
    head = [f"set_standard_digital_out({int(output)}, {level})"]
    loop = [f"while {'not ' if level else ''}{test}:", "  sync()"]
    if timeout_s is None:
        return head + loop + ["end"]
    if not (math.isfinite(timeout_s) and timeout_s > 0):
        raise ValueError(f"handshake time-out {timeout_s!r} s is not a positive number of seconds")
    text = sanitise_comment(message, 200)
    return head + [f"{_WAITED} = 0.0"] + loop + [
        f"  {_WAITED} = {_WAITED} + get_steptime()",
        f"  if {_WAITED} > {format_number(timeout_s)}:",
        f"    set_standard_digital_out({int(output)}, {previous})",
        f"    stopj({format_number(STOP_DECELERATION)})",
        f'    textmsg("fabkit: {text}")',
        f'    popup("{text}", title="fabkit two-arm handshake", error=True, blocking=False)',
        "    halt",
        "  end",
        "end"]


def arm_script_path(path, arm: str):
    """Where arm `arm`'s program goes for `--script path`: `_<arm>` before the suffix
    (fold.script -> fold_a.script)."""
    from pathlib import Path

    path = Path(path)
    return path.with_name(f"{path.stem}_{arm}{path.suffix}")


def write_arm_urscripts(atp, *, progress_register: int = PROGRESS_REGISTER, output: int = HANDSHAKE_OUTPUT,
                        input_: int = HANDSHAKE_INPUT, timeout_s: float | None = None,
                        start_window_s: float = START_WINDOW_S) -> dict[str, str]:
    """{arm: URScript program text} for a `robot.arms_toolpath.ArmsToolpath` (module docstring).
    `timeout_s`: the handshake time-out (default `default_timeout(atp)`); the start line and the
    first sync waypoint wait `start_window_s` longer."""
    if not (0 <= int(output) <= 7 and 0 <= int(input_) <= 7):
        raise ValueError(f"standard digital output {output} / input {input_}: both must be in 0..7")
    timeout = default_timeout(atp) if timeout_s is None else float(timeout_s)
    if not (math.isfinite(timeout) and timeout > 0 and math.isfinite(start_window_s) and start_window_s >= 0):
        raise ValueError(f"handshake time-out {timeout_s!r} s / start window {start_window_s!r} s: the time-out "
                         "must be positive, the window at least 0")
    first = timeout + float(start_window_s)
    out = {}
    for name, tp in atp.arms:
        grip = tp.extra.get("grip") or {}
        if str(grip.get("kind", "tool")) == "standard" and int(grip.get("output", -1)) == int(output):
            from fabkit.errors import InputError

            raise InputError(f"arm {name}: the gripper uses standard digital output {output}, which the "
                             "two-arm programs' handshake needs", source="--script")
        others = ", ".join(n for n in atp.arm_names if n != name)

        def halted(where: str, limit: float) -> str:
            return (f"arm {name} halted at {where}: arm {others} did not arrive within {format_number(limit)} s "
                    f"(DO/DI {int(output)} handshake)")
        after = {}
        for j, k in enumerate(atp.sync, start=1):
            limit = first if j == 1 else timeout
            after[int(k)] = handshake_lines(j % 2 == 1, output, input_, timeout_s=limit, previous=j % 2 == 0,
                                            message=halted(f"sync waypoint {int(k)} ({j} of {len(atp.sync)})",
                                                           limit))
        after[0] = handshake_lines(False, output, input_, timeout_s=first, previous=False,  # from a reset line
                                   message=halted("the start (waypoint 0, waiting for a reset line)", first))
        after[len(tp) - 1] = [f"set_standard_digital_out({int(output)}, False)"]
        header = (f"arm {name} of {len(atp.arm_names)} ({', '.join(atp.arm_names)}); program sha256 {atp.sha256}",
                  f"handshake: at every sync waypoint {list(atp.sync)} standard DO {int(output)} = the sync's "
                  f"parity (odd True), then wait for standard DI {int(input_)} (wired to DO {int(output)} of arm "
                  f"{others}) to show it",
                  f"handshake time-out {format_number(timeout)} s ({format_number(first)} s at the start and the "
                  "first sync waypoint): then DO back, stopj, popup, halt")
        out[name] = write_urscript(tp, program_name=f"fold_{atp.cell}_{name}", progress_register=progress_register,
                                   after_waypoint=after, header_extra=header)
    return out
