"""Dashboard server (port 29999) of the controller stand-in: one text line in, one line out.

Replies are the controller's exact strings (reference ur-rtde.md §3.3); ur_rtde's DashboardClient
compares several of them verbatim (`Stopped`, `Starting program`, `Protective stop releasing`, ...).
`load` and `play` work on URScript files (`.script`, or a `.urp` with a `.script` of the same
name next to it) in the programs directory given at start-up.
"""
from __future__ import annotations

import socket
import time
from pathlib import Path

from sim.ursim.lines import serve_lines

from sim.ursim.controller import (ROBOT_IDLE, ROBOT_MODES, ROBOT_POWER_OFF, ROBOT_RUNNING, RUNTIME_PAUSED,
                                  RUNTIME_PLAYING, SAFETY_MODES)

BANNER = "Connected: Universal Robots Dashboard Server"


def handle_command(ctrl, line: str, programs_dir: Path | None) -> str:
    """The reply to one dashboard command."""
    cmd = line.strip()
    low = cmd.lower()
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
        with ctrl.lock:
            if ctrl.robot_mode in (ROBOT_IDLE, 4) and ctrl.safety_mode == 1:
                ctrl.robot_mode = ROBOT_RUNNING
                ctrl.log("brakes released")
        return "Brake releasing"
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
    if low == "close safety popup":
        return "closing safety popup"
    if low == "close popup":
        return "closing popup"
    if low == "stop":
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
    if low.startswith("addtolog "):
        ctrl.log(f"dashboard log: {cmd[9:]}")
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
    if programs_dir is None:
        return None
    p = Path(name)
    p = p if p.is_absolute() else programs_dir / p
    if p.suffix == ".urp":
        p = p.with_suffix(".script")
    return p if p.is_file() else None


def _load(ctrl, name: str, programs_dir: Path | None) -> str:
    path = _resolve(programs_dir, name)
    if path is None:
        return f"File not found: {name}"
    with ctrl.lock:
        ctrl.loaded_program = str(path)
    return f"Loading program: {name}"


def _play(ctrl, programs_dir: Path | None) -> str:
    with ctrl.lock:
        if ctrl.runtime_state == RUNTIME_PAUSED:
            ctrl.paused = False
            return "Starting program"
        if not ctrl.loaded_program or not ctrl.can_move():
            return "Failed to execute: play"
        path = ctrl.loaded_program
    from sim.ursim.script_ports import program_from_text

    program = program_from_text(ctrl, Path(path).read_text(encoding="utf-8", errors="replace"), Path(path).name)
    return "Starting program" if ctrl.start_program(program) else "Failed to execute: play"


def serve_dashboard(ctrl, listener: socket.socket, programs_dir: Path | None = None) -> None:
    """Answer dashboard commands with the controller's replies; `quit` ends the client."""
    def answer(text: str) -> tuple[str | None, bool]:
        if not text:
            return None, False
        reply = handle_command(ctrl, text, programs_dir)
        ctrl.log(f"dashboard: {text!r} -> {reply!r}")
        if ctrl.reply_delay:
            time.sleep(ctrl.reply_delay)
        return reply, text.lower() == "quit"

    serve_lines(ctrl, listener, "dashboard", answer, banner=BANNER)
