"""What a send is told (`SendSettings`) and what it reports (`SendResult`): `robot.sender`'s records."""
from __future__ import annotations

from dataclasses import dataclass, field

from robot.interlock import StartTolerances

__all__ = ["SendSettings", "SendResult"]


@dataclass(frozen=True)
class SendSettings:
    """How to send. Times in seconds; tolerances in metres and radians; `watchdog_hz`: the RTDE
    watchdog's minimum kick rate while the control script runs (0 = off, not recommended);
    `send_nice`: the nice value of the send loop thread and its ur_rtde worker while sending, when
    the OS allows (`robot.realtime`; 0 = leave it); `rt_priority`: ur_rtde's own real-time option
    (-1 = leave the scheduling alone)."""

    host: str
    chunk: int = 50
    resume_from: int = 0
    power_on: bool = False
    unlock: bool = False
    monitor_hz: float = 125.0
    poll_s: float = 0.02
    stall_s: float = 0.5
    call_timeout_s: float = 10.0
    connect_timeout_s: float = 20.0
    stop_decel: float = 2.0
    final_tol_m: float = 2e-4
    final_tol_rad: float = 2e-3
    start: StartTolerances = StartTolerances()
    watchdog_hz: float = 4.0
    rt_priority: int = -1
    send_nice: int = -10
    connect_retry_s: float = 3.0  # keep trying the dashboard this long (a controller still starting)
    hosts: tuple = ()  # a program for several arms: the controllers of the arms after the first (`host`)


@dataclass
class SendResult:
    """What happened: `ok`, `last_completed` (index of the last waypoint reached, -1 for none),
    `reason` (None when ok), the toolpath hash sent, and measurements (`recheck_s`: the check
    run again before sending)."""

    ok: bool
    last_completed: int
    total: int
    reason: str | None = None
    toolpath_sha256: str = ""
    chunks_sent: int = 0
    elapsed_s: float = 0.0
    recheck_s: float = 0.0
    final_error_m: float | None = None
    final_error_rad: float | None = None
    quantisation_m: float = 0.0
    quantisation_rad: float = 0.0
    blend_reduction_m: float = 0.0
    controller: str | None = None
    events: list = field(default_factory=list)

    def to_json(self) -> dict:
        return {k: v for k, v in self.__dict__.items()}
