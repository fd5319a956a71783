"""The URScript subset the stand-in runs: fabkit's own programs and ur_rtde's injected paths.

Statements (one per line): `def NAME():` / `end`, comments, `set_tcp(p[...])`,
`movej(q|p[...], a=, v=, r=)`, `movel(p[...]|q, a=, v=, r=)`, `movep(...)`,
`set_tool_digital_out(n, b)`, `set_standard_digital_out(n, b)`, `set_configurable_digital_out(n, b)`,
`write_output_integer_register(n, v)`, `sleep(t)`, `textmsg(...)`, `sync()`,
`signal_async_progress(i)` (ur_rtde paths), `set_payload(m[, cog])` (also python-urx's tuple
form `set_payload(m, (x, y, z))`), `set_target_payload(m, cog[, inertia][, transition_time])`,
and the handshake's wait loops, with or without a time-out (`sim.ursim.script_waits`: wait, at
rest, until standard digital input n is True [or False]; `robot.arms_urscript`).
A `sec NAME(): ... end` program (no moves) runs beside the running program without stopping it.
Anything else is rejected with the line number, and the
program does not run (as a controller refuses a program that does not compile).

Consecutive moves run as one blended motion; register writes, digital outputs and textmsg between
moves run when the motion toward the next target begins (the controller's lookahead), while any
other statement (sleep, set_tcp) between moves brings the arm to rest first.
"""
from __future__ import annotations

import ast
import re
import threading
from dataclasses import dataclass

import numpy as np

from sim.ursim.motion import PlanError, Waypoint, plan_moves
from sim.ursim.script_waits import Halted, fold_wait_loops, run_wait

MOVES = ("movej", "movel", "movep")
#: Statements that take no time: run during a blended motion without stopping it.
INSTANT = ("write_output_integer_register", "set_tool_digital_out", "set_standard_digital_out",
           "set_configurable_digital_out", "textmsg", "set_payload", "set_target_payload")
_CALL = re.compile(r"^([A-Za-z_]\w*)\s*\((.*)\)\s*$")
_DEFAULTS = {"movej": (1.4, 1.05), "movel": (1.2, 0.25), "movep": (1.2, 0.25)}  # (a, v)


class ScriptError(Exception):
    """A statement the stand-in cannot compile (message names the line)."""


@dataclass(frozen=True)
class Statement:
    line: int
    name: str
    args: tuple
    kwargs: dict
    is_pose: bool = False  # first argument was written p[...]


def _parse_call(text: str, line: int) -> Statement:
    m = _CALL.match(text)
    if not m:
        raise ScriptError(f"line {line}: unsupported statement: {text.strip()[:80]}")
    name, inner = m.group(1), m.group(2)
    is_pose = inner.lstrip().startswith("p[")
    src = re.sub(r"(?<![\w\]])p\[", "[", inner)
    try:
        call = ast.parse(f"f({src})", mode="eval").body
        args = tuple(ast.literal_eval(a) for a in call.args)
        kwargs = {k.arg: ast.literal_eval(k.value) for k in call.keywords}
    except (SyntaxError, ValueError) as exc:
        raise ScriptError(f"line {line}: cannot evaluate the arguments of {name}(): {exc}") from None
    return Statement(line, name, args, kwargs, is_pose)


_ARITY = {"wait_standard_digital_in": 2, "set_tcp": 1, "set_tool_digital_out": 2, "set_standard_digital_out": 2,
          "set_configurable_digital_out": 2, "write_output_integer_register": 2, "sleep": 1,
          "signal_async_progress": 1, "sync": 0}


def parse_statements(lines: list[tuple[int, str]]) -> list[Statement]:
    """Parse body lines (line number, text) into statements; raises ScriptError."""
    out = []
    for item in lines:
        if isinstance(item, Statement):  # a wait loop, compiled by sim.ursim.script_waits
            out.append(item)
            continue
        no, raw = item
        text = raw.split("#", 1)[0].strip() if not raw.strip().startswith("textmsg") else raw.strip()
        if not text:
            continue
        st = _parse_call(text, no)
        if st.name in MOVES:
            if len(st.args) != 1 or len(st.args[0]) != 6 or set(st.kwargs) - {"a", "v", "r", "t"}:
                raise ScriptError(f"line {no}: {st.name} needs one 6-vector target and a=, v=, r= keywords")
            if st.kwargs.get("t", 0):
                raise ScriptError(f"line {no}: {st.name} with t= is not supported by the stand-in")
        elif st.name == "textmsg":
            pass
        elif st.name in ("set_payload", "set_target_payload"):
            _check_payload(st)
        elif st.name in _ARITY:
            if len(st.args) != _ARITY[st.name]:
                raise ScriptError(f"line {no}: {st.name} takes {_ARITY[st.name]} arguments")
        else:
            raise ScriptError(f"line {no}: unknown or unsupported function {st.name}()")
        out.append(st)
    return out


def _check_payload(st: Statement) -> None:
    n = len(st.args)
    allowed = {"set_payload": (1, 2), "set_target_payload": (2, 4)}[st.name]
    extra = set(st.kwargs) - ({"inertia", "transition_time"} if st.name == "set_target_payload" else set())
    if not allowed[0] <= n <= allowed[1] or extra:
        raise ScriptError(f"line {st.line}: {st.name} takes {allowed[0]}-{allowed[1]} arguments")
    try:
        mass = float(st.args[0])
        cog = None if n < 2 else [float(x) for x in st.args[1]]
    except (TypeError, ValueError):
        raise ScriptError(f"line {st.line}: {st.name}: mass and CoG must be numbers") from None
    if not np.isfinite(mass) or not 0 <= mass <= 1000 or (cog is not None and (len(cog) != 3 or not np.all(np.isfinite(cog)))):
        raise ScriptError(f"line {st.line}: {st.name}: needs a mass in 0-1000 kg and a CoG [x, y, z]")


def parse_program(text: str) -> tuple[str, list[Statement]]:
    """A whole `def NAME(): ... end` program -> (name, statements); raises ScriptError."""
    lines = text.replace("\r\n", "\n").split("\n")
    numbered = [(i + 1, ln) for i, ln in enumerate(lines) if ln.strip() and not ln.strip().startswith("#")]
    if not numbered:
        raise ScriptError("empty program")
    first_no, first = numbered[0]
    m = re.match(r"^(def|sec)\s+(\w+)\s*\(\s*\)\s*:\s*$", first.strip())
    if not m:
        # a bare statement sent to the primary/secondary port runs as a one-line program
        return "<statement>", parse_statements(numbered)
    if numbered[-1][1].strip() != "end":
        raise ScriptError(f"line {numbered[-1][0]}: program {m.group(2)} has no closing 'end'")
    body = fold_wait_loops(numbered[1:-1])
    for no, ln in (b for b in body if not isinstance(b, Statement)):
        if ln.strip() == "end" or re.match(r"^\s*(def|sec|thread|while|if|for)\b", ln):
            raise ScriptError(f"line {no}: nested blocks are not supported by the stand-in: {ln.strip()[:60]}")
    statements = parse_statements(body)
    if m.group(1) == "sec" and any(st.name in MOVES or st.name == "sleep" for st in statements):
        raise ScriptError(f"line {first_no}: a secondary program (sec) cannot move the arm or sleep")
    return ("sec " if m.group(1) == "sec" else "") + m.group(2), statements


def waypoint_of(st: Statement, progress: int = -1) -> Waypoint:
    a_def, v_def = _DEFAULTS[st.name]
    target = tuple(float(x) for x in st.args[0])
    kw = st.kwargs
    a, v, r = float(kw.get("a", a_def)), float(kw.get("v", v_def)), float(kw.get("r", 0.0))
    if st.name == "movej":
        return Waypoint("movej", v, a, r, pose=target if st.is_pose else None,
                        q=None if st.is_pose else target, progress=progress)
    if st.is_pose:
        return Waypoint(st.name, v, a, r, pose=target, progress=progress)
    return Waypoint(st.name, v, a, r, q=target, progress=progress)


def path_waypoints(statements: list[Statement]) -> list[Waypoint]:
    """ur_rtde's injected path (`signal_async_progress(i)` before each move) as waypoints."""
    out, progress = [], -1
    for st in statements:
        if st.name == "signal_async_progress":
            progress = int(st.args[0])
        elif st.name in MOVES:
            out.append(waypoint_of(st, progress))
            progress = -1
        elif st.name != "textmsg":
            raise ScriptError(f"line {st.line}: unexpected {st.name}() in an injected path")
    return out


def resolve_fk_targets(ctrl, waypoints: list[Waypoint]) -> list[Waypoint]:
    """movel/movep given joint targets move linearly to their forward kinematics (URScript)."""
    from robot import kinematics as K
    from sim.ursim.motion import matrix_to_pose

    out = []
    for w in waypoints:
        if w.kind != "movej" and w.q is not None:
            pose = matrix_to_pose(K.fk_tcp(ctrl.model, np.asarray(w.q), ctrl.tcp))
            w = Waypoint(w.kind, w.v, w.a, w.r, pose=tuple(pose), progress=w.progress)
        out.append(w)
    return out


def _wp_values(w: Waypoint) -> dict:
    """A waypoint's numbers for `Controller.record`."""
    out = {"q": w.q} if w.q is not None else {"pose": w.pose}
    out.update(v=w.v, a=w.a, r=w.r)
    return out


def record_waypoints(ctrl, source: str, waypoints: list[Waypoint]) -> None:
    for w in waypoints:
        ctrl.record(source, w.kind, **_wp_values(w))


class Killed(Exception):
    """The program was stopped while a statement was running."""


class URScriptProgram:
    """Runs parsed statements in a thread against the controller (one program at a time)."""

    def __init__(self, ctrl, name: str, statements: list[Statement]):
        self.ctrl = ctrl
        self.name = name
        self.statements = statements
        self.running = False
        self._killed = threading.Event()
        self._thread = threading.Thread(target=self._main, name=f"urscript-{name}", daemon=True)

    @property
    def secondary(self) -> bool:
        """A `sec` program: runs beside the main program (`run_beside`), never replaces it."""
        return self.name.startswith("sec ")

    def run_beside(self) -> None:
        """Run a secondary program's statements at once (they take no time)."""
        for st in self.statements:
            self._do(st)
        self.ctrl.log(f"secondary program {self.name[4:]} done")

    def start(self) -> None:
        self.running = True
        self._thread.start()

    def kill(self, reason: str) -> None:
        if self.running:
            self.running = False
            self._killed.set()
            self.ctrl.log(f"program {self.name} stopped: {reason}")

    def _main(self) -> None:
        ctrl = self.ctrl
        ctrl.log(f"program {self.name} started")
        try:
            i, sts = 0, self.statements
            while i < len(sts):
                if sts[i].name in MOVES:
                    i = self._move_group(i)
                else:
                    self._do(sts[i])
                    i += 1
            ctrl.log(f"program {self.name} finished")
        except (Killed, Halted):
            pass
        except PlanError as exc:
            ctrl.runtime_error(str(exc), self)
        finally:
            with ctrl.lock:
                self.running = False

    def _move_group(self, i: int) -> int:
        """Run the moves from statement i as one blended motion; returns the next statement index.

        Instant statements between moves (register writes, digital outputs, textmsg) do not break
        the blend: as with the controller's lookahead, each runs when the motion toward the next
        move's target begins. Anything else (sleep, set_tcp, ...) ends the group at rest.
        """
        sts = self.statements
        moves, actions, pending, j, end = [], {}, [], i, i
        while j < len(sts) and (sts[j].name in MOVES or sts[j].name in INSTANT):
            if sts[j].name in MOVES:
                actions[len(moves)] = pending
                moves.append(waypoint_of(sts[j], progress=len(moves)))
                pending, end = [], j + 1
            else:
                pending.append(sts[j])
            j += 1
        record_waypoints(self.ctrl, "urscript", moves)
        self._move(moves, actions)
        return end  # instant statements after the last move run normally

    def _instant(self, st: Statement) -> None:
        """An instant statement, run from the controller tick (must not block)."""
        try:
            self._do(st)
        except (Killed, PlanError) as exc:
            self.ctrl.log(f"program {self.name}: {exc}")

    def _check(self) -> None:
        if self._killed.is_set():
            raise Killed()

    def _move(self, waypoints: list[Waypoint], actions: dict | None = None) -> None:
        ctrl = self.ctrl
        done = threading.Event()
        actions = actions or {}

        def marker(k):
            for st in actions.get(k, ()):
                self._instant(st)
        with ctrl.lock:
            self._check()
            traj = plan_moves(ctrl.model, ctrl.tcp, ctrl.arm.q.copy(), resolve_fk_targets(ctrl, waypoints),
                              ctrl.period, joint_accel_max=ctrl.arm.joint_accel_max)
            ctrl.arm.run(traj, on_marker=marker, on_done=lambda ok: done.set())
        while not done.wait(0.05):
            self._check()
        self._check()

    def _do(self, st: Statement) -> None:
        ctrl = self.ctrl
        self._check()
        name, args = st.name, st.args
        if name == "textmsg":
            ctrl.log("textmsg: " + " ".join(str(a) for a in args))
        elif name == "set_tcp":
            ctrl.set_tcp(args[0])
            ctrl.record("urscript", "set_tcp", pose=args[0])
        elif name in ("set_standard_digital_out", "set_configurable_digital_out", "set_tool_digital_out"):
            n, val = int(args[0]), bool(args[1])
            limit, shift = {"set_standard_digital_out": (8, 0), "set_configurable_digital_out": (8, 8),
                            "set_tool_digital_out": (2, 16)}[name]
            if not 0 <= n < limit:
                raise PlanError(f"line {st.line}: {name}: output {n} does not exist")
            with ctrl.lock:
                bit = 1 << (n + shift)
                ctrl.digital_out = (ctrl.digital_out | bit) if val else (ctrl.digital_out & ~bit)
            ctrl.record("urscript", name, output=n, value=val)
        elif name == "write_output_integer_register":
            n = int(args[0])
            if not 0 <= n < 48:
                raise PlanError(f"line {st.line}: write_output_integer_register: register {n} does not exist")
            with ctrl.lock:
                ctrl.out_int[n] = int(args[1])
        elif name in ("set_payload", "set_target_payload"):
            inertia = st.kwargs.get("inertia", args[2] if len(args) > 2 else None)
            try:
                ctrl.set_payload(float(args[0]), None if len(args) < 2 else [float(x) for x in args[1]],
                                 inertia if name == "set_target_payload" else None, source="urscript")
            except ValueError as exc:
                raise PlanError(f"line {st.line}: {name}: {exc}") from None
        elif name == "sleep":
            if self._killed.wait(max(0.0, float(args[0]))):
                raise Killed()
        elif name in ("sync", "signal_async_progress"):
            ctrl.wait_tick(ctrl.tick_index)
        elif name == "wait_standard_digital_in":  # one loop test per tick, as the controller's sync()
            run_wait(self, st)
