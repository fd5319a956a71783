"""Dashboard server (port 29999) of the controller stand-in: one text line in, one line out.

Replies are the controller's exact strings (reference ur-rtde.md §3.3); ur_rtde's DashboardClient
compares several of them verbatim (`Stopped`, `Starting program`, `Protective stop releasing`, ...).
`load` and `play` work on URScript files (`.script`, or a `.urp` with a `.script` of the same
name next to it) inside the programs directory given at start-up; a path that leaves it (an
absolute path elsewhere, `..`, a symbolic link out) is `File not found`. `shutdown` answers, then
stops the whole stand-in (as the controller PC powers off). An empty line or one the stand-in
does not know gets `could not understand: '<line>'`; a line over `clients.MAX_LINE` bytes gets
the same reply and the client is closed.
"""
from __future__ import annotations

import socket
import threading
from pathlib import Path

from sim.ursim.lines import serve_lines

from sim.ursim.controller import (ROBOT_IDLE, ROBOT_MODES, ROBOT_POWER_OFF, ROBOT_RUNNING, RUNTIME_PAUSED,
                                  RUNTIME_PLAYING, SAFETY_MODES)

BANNER = "Connected: Universal Robots Dashboard Server"


_OPERATIONAL_MODES = ("manual", "automatic")


def handle_command(ctrl, line: str, programs_dir: Path | None) -> str:
    """The reply to one dashboard command (e-Series dashboard server document)."""
    cmd = line.strip()
    low = cmd.lower()
    if not cmd:
        return "could not understand: ''"
    if low == "power on":
        with ctrl.lock:
            if ctrl.robot_mode == ROBOT_POWER_OFF and ctrl.safety_mode == 1:
                ctrl.robot_mode = ROBOT_IDLE
                ctrl.log("powered on (brakes engaged)")
        return "Powering on"
    if low == "power off":
        with ctrl.lock:
            ctrl.stop_program("power off")
            ctrl.robot_mode = ROBOT_POWER_OFF
        return "Powering off"
    if low == "brake release":
        with ctrl.lock:  # from power off the robot powers on first, then releases
            if ctrl.robot_mode in (ROBOT_POWER_OFF, ROBOT_IDLE, 4) and ctrl.safety_mode == 1:
                if ctrl.robot_mode == ROBOT_POWER_OFF:
                    ctrl.log("powered on by brake release")
                ctrl.robot_mode = ROBOT_RUNNING
                ctrl.log("brakes released")
        return "Brake releasing"
    if low == "version":
        return ".".join(str(v) for v in ctrl.cfg.version)
    if low == "get operational mode":
        with ctrl.lock:
            return ctrl.operational_mode
    if low.startswith("set operational mode"):
        arg = cmd[len("set operational mode"):].strip()
        if arg.lower() not in _OPERATIONAL_MODES:
            return f"Failed setting operational mode: {arg}"
        with ctrl.lock:
            ctrl.operational_mode = arg.upper()
            ctrl.operational_mode_by_dashboard = True
        return f"Operational mode '{arg}' is set"
    if low == "clear operational mode":
        with ctrl.lock:
            ctrl.operational_mode_by_dashboard = False
            mode = ctrl.operational_mode
        return f"No longer controlling the operational mode. Current operational mode: '{mode}'."
    with ctrl.lock:
        reply = _query(ctrl, low)
    return reply if reply is not None else _actions(ctrl, cmd, low, programs_dir)


def _query(ctrl, low: str) -> str | None:
    """Replies that read the state (called under the lock); None for the other commands."""
    if low == "robotmode":
        return f"Robotmode: {ROBOT_MODES.get(ctrl.robot_mode, 'NO_CONTROLLER')}"
    if low in ("safetystatus", "safetymode"):
        word = "Safetystatus" if low == "safetystatus" else "Safetymode"
        return f"{word}: {SAFETY_MODES.get(ctrl.safety_mode, 'FAULT')}"
    if low == "programstate":
        name = getattr(ctrl.program, "name", None) or (Path(ctrl.loaded_program).name if ctrl.loaded_program
                                                       else "<unnamed>")
        state = {RUNTIME_PLAYING: "PLAYING", RUNTIME_PAUSED: "PAUSED"}.get(ctrl.runtime_state, "STOPPED")
        return f"{state} {name}"
    if low == "running":
        return f"Program running: {'true' if ctrl.runtime_state == RUNTIME_PLAYING else 'false'}"
    if low == "unlock protective stop":
        return ctrl.unlock_protective_stop()
    return None


def _actions(ctrl, cmd: str, low: str, programs_dir: Path | None) -> str:
    if low == "close safety popup":
        return "closing safety popup"
    if low == "close popup":
        return "closing popup"
    if low == "stop":
        with ctrl.lock:
            if ctrl.runtime_state == 1 and ctrl.program is None:
                return "Stopped"
            ctrl.stop_program("dashboard stop")
        return "Stopped"
    if low == "pause":
        with ctrl.lock:
            if ctrl.runtime_state != RUNTIME_PLAYING:
                return "Failed to execute: pause"
            ctrl.paused = True
        return "Pausing program"
    if low == "play":
        return _play(ctrl, programs_dir)
    if low.startswith("load "):
        return _load(ctrl, cmd[5:].strip(), programs_dir)
    if low == "get loaded program":
        return f"Loaded program: {ctrl.loaded_program}" if ctrl.loaded_program else "No program loaded"
    if low == "polyscopeversion":
        v = ctrl.cfg.version
        return f"URSoftware {v[0]}.{v[1]}.{v[2]}.{v[3]} (Nov 21 2026)"
    if low == "get serial number":
        return ctrl.cfg.serial
    if low == "get robot model":
        return ctrl.model.name[:-1].upper() if ctrl.model.name.endswith("e") else ctrl.model.name.upper()
    if low == "is in remote control":
        return "true" if ctrl.cfg.remote_control else "false"
    if low == "isprogramsaved":
        return f"true {Path(ctrl.loaded_program).name if ctrl.loaded_program else '<unnamed>'}"
    if low == "addtolog" or low.startswith("addtolog "):
        text = cmd[8:].strip()
        if not text:
            return "No log message to add"
        ctrl.log(f"dashboard log: {text}")
        return "Added log message"
    if low.startswith("popup "):
        return "showing popup"
    if low == "restart safety":
        with ctrl.lock:
            ctrl.safety_mode = 1
            ctrl.robot_mode = ROBOT_POWER_OFF
        return "Restarting safety"
    if low == "quit":
        return "Disconnected"
    if low == "shutdown":
        return "Shutting down"
    return f"could not understand: '{cmd}'"


def _resolve(programs_dir: Path | None, name: str) -> Path | None:
    """The program file `name` names inside `programs_dir`, or None (outside, missing, not a file)."""
    if programs_dir is None or not name or "\0" in name:
        return None
    root = programs_dir.resolve()
    p = Path(name)
    p = p if p.is_absolute() else root / p
    if p.suffix == ".urp":
        p = p.with_suffix(".script")
    try:
        p = p.resolve()
        p.relative_to(root)
    except (ValueError, OSError, RuntimeError):
        return None
    return p if p.is_file() else None


def _load(ctrl, name: str, programs_dir: Path | None) -> str:
    path = _resolve(programs_dir, name)
    if path is None:
        return f"File not found: {name}"
    with ctrl.lock:
        ctrl.loaded_program = str(path)
    return f"Loading program: {name}"


def _play(ctrl, programs_dir: Path | None) -> str:
    from sim.ursim.script_ports import MAX_SCRIPT, program_from_text

    with ctrl.lock:
        if ctrl.runtime_state == RUNTIME_PAUSED:
            ctrl.paused = False
            return "Starting program"
        if not ctrl.loaded_program or not ctrl.can_move():
            return "Failed to execute: play"
        path = Path(ctrl.loaded_program)
    try:
        with open(path, "rb") as fh:
            data = fh.read(MAX_SCRIPT + 1)
    except OSError:
        return "Failed to execute: play"
    if len(data) > MAX_SCRIPT:
        ctrl.log(f"play: {path.name} is over {MAX_SCRIPT} bytes: refused")
        return "Failed to execute: play"
    program = program_from_text(ctrl, data.decode("utf-8", "replace"), path.name)
    if program is None:  # does not compile: the controller refuses to play it
        return "Failed to execute: play"
    return "Starting program" if ctrl.start_program(program) else "Failed to execute: play"


def serve_dashboard(ctrl, loop, listener: socket.socket, programs_dir: Path | None = None, shutdown=None) -> None:
    """Answer dashboard commands with the controller's replies (late by the `slow` fault's delay);
    `quit` ends the client, `shutdown` ends the client and then calls `shutdown()` (the stand-in
    stops)."""
    def answer(text: str) -> tuple[str | None, bool]:
        reply = handle_command(ctrl, text, programs_dir)
        ctrl.log(f"dashboard: {text[:80]!r} -> {reply[:80]!r}")
        low = text.lower()
        if low == "shutdown" and shutdown is not None:
            threading.Timer(0.05, shutdown).start()  # after the reply is on its way
        return reply, low in ("quit", "shutdown")

    def delay() -> float:
        with ctrl.lock:
            return ctrl.reply_delay

    serve_lines(ctrl, loop, listener, "dashboard", answer, banner=BANNER,
                too_long=lambda head: f"could not understand: '{head}...'", delay=delay)
