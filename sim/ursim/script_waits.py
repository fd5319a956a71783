"""The stand-in's handshake waits: a URScript loop that waits, at rest, for a standard digital
input, with or without a time-out (`robot.arms_urscript`'s handshake between two arms).

Two loop forms are compiled, each into one statement `wait_standard_digital_in(n, level)`:

    while [not ]get_standard_digital_in(N):      # wait until input N is True [False]
      sync()
    end

and the bounded form (VAR any identifier, T seconds):

    VAR = 0.0
    while [not ]get_standard_digital_in(N):
      sync()
      VAR = VAR + get_steptime()
      if VAR > T:
        ...                                      # set_standard_digital_out, stopj, textmsg, popup
        halt
      end
    end

The loop test runs once per controller tick (URScript's `sync()`); the bounded form counts the
ticks that passed times the controller period (`get_steptime()`: 2 ms on an e-Series, 8 ms on a
CB3), runs its `if` body once more than T seconds have passed, and `halt` ends the program (logged
"program NAME halted"). In that body `popup(text, ...)` is a log line on stderr (what the pendant
would show) and `stopj(a)` decelerates whatever motion there is (none at rest). Any other shape
of loop is refused with its line number by the parser (`sim.ursim.urscript`).
"""
from __future__ import annotations

import re

__all__ = ["fold_wait_loops", "run_wait", "Halted"]

_WAIT = re.compile(r"^while\s+(not\s+)?get_standard_digital_in\(\s*([0-7])\s*\)\s*:$")
_START = re.compile(r"^([A-Za-z_]\w*)\s*=\s*0(\.0*)?$")
_NUMBER = r"(\d+(?:\.\d*)?)"
#: The statements the time-out body may run.
_ABORT = ("set_standard_digital_out", "stopj", "textmsg", "popup", "halt")


class Halted(Exception):
    """`halt`: the program ends here (not an error)."""


def _bounded(body, i: int):
    """The bounded wait starting at body[i] -> (Statement, next index), or None."""
    from sim.ursim.urscript import ScriptError, Statement, _parse_call

    text = [ln.strip() for _, ln in body[i:i + 8]]
    m0 = _START.match(text[0]) if text else None
    if m0 is None or len(text) < 6:
        return None
    var = re.escape(m0.group(1))
    m1 = _WAIT.match(text[1])
    if not (m1 and text[2] == "sync()" and re.fullmatch(rf"{var}\s*=\s*{var}\s*\+\s*get_steptime\(\)", text[3])):
        return None
    m4 = re.fullmatch(rf"if\s+{var}\s*>\s*{_NUMBER}\s*:", text[4])
    if m4 is None:
        raise ScriptError(f"line {body[i + 4][0]}: the time-out test must be 'if {m0.group(1)} > SECONDS:'")
    then, j = [], i + 5
    while j < len(body) and body[j][1].strip() != "end":
        no, ln = body[j]
        st = Statement(no, "halt", (), {}) if ln.strip() == "halt" else _parse_call(ln.strip(), no)
        if st.name not in _ABORT:
            raise ScriptError(f"line {no}: {st.name}() is not supported in a handshake time-out")
        then.append(st)
        j += 1
    if j + 1 >= len(body) or body[j + 1][1].strip() != "end":
        raise ScriptError(f"line {body[i + 1][0]}: the handshake wait has no closing 'end' of its loop")
    if not then or then[-1].name != "halt":
        raise ScriptError(f"line {body[i + 4][0]}: a handshake time-out must end with 'halt'")
    no = body[i + 1][0]
    return Statement(no, "wait_standard_digital_in", (int(m1.group(2)), bool(m1.group(1))),
                     {"timeout": float(m4.group(1)), "then": tuple(then)}), j + 2


def fold_wait_loops(body: list) -> list:
    """Body lines (line number, text) with each wait loop replaced by its Statement."""
    from sim.ursim.urscript import ScriptError, Statement

    out, i = [], 0
    while i < len(body):
        no, ln = body[i]
        if ln.strip().startswith("wait_standard_digital_in"):
            raise ScriptError(f"line {no}: unsupported statement: {ln.strip()[:80]}")
        bounded = _bounded(body, i)
        if bounded is not None:
            out.append(bounded[0])
            i = bounded[1]
            continue
        m = _WAIT.match(ln.strip())
        if m and i + 2 < len(body) and body[i + 1][1].strip() == "sync()" and body[i + 2][1].strip() == "end":
            out.append(Statement(no, "wait_standard_digital_in", (int(m.group(2)), bool(m.group(1))), {}))
            i += 3
            continue
        out.append((no, ln))
        i += 1
    return out


def run_wait(program, st) -> None:
    """Run a wait statement of `program` (`sim.ursim.urscript.URScriptProgram`): one input test
    per tick; past the time-out, its body (raises `Halted` at `halt`, `Killed` if stopped)."""
    ctrl = program.ctrl
    bit, level = 1 << int(st.args[0]), bool(st.args[1])
    timeout = st.kwargs.get("timeout")
    ctrl.record("urscript", "wait_standard_digital_in", input=int(st.args[0]), value=level, timeout=timeout)
    start = tick = ctrl.tick_index
    while bool(ctrl.digital_in & bit) != level:
        program._check()
        tick = ctrl.wait_tick(tick)
        if timeout is not None and (tick - start) * ctrl.period > timeout:
            for abort in st.kwargs["then"]:
                _abort(program, abort)


def _abort(program, st) -> None:
    ctrl = program.ctrl
    if st.name == "halt":
        ctrl.log(f"program {program.name} halted (line {st.line})")
        raise Halted()
    if st.name == "popup":
        ctrl.log(f"popup: {' '.join(str(a) for a in st.args)}", popup=True)
    elif st.name == "stopj":
        with ctrl.lock:
            ctrl.arm.stop(float(st.args[0]) if st.args else 2.0)
    else:
        program._do(st)
