"""Send a program for several arms: one ur_rtde worker per controller, in lockstep.

Each arm has its own `robot.sender.ArmSender` (its worker process, preflight, RTDE watchdog,
chunked `movePath`s), run in a thread of its own. They share one `Lockstep`:

- every arm waits at waypoint 0 until all are ready, and at every sync waypoint of the program
  (`ArmsToolpath.sync`: the grip, each fold state, the release) until every arm has arrived, so
  all arms finish fold state k before any starts state k+1. A waiting arm keeps polling its
  controller (which kicks its watchdog and notices its faults);
- a fault of any arm (a protective or emergency stop, a stopped program, a stalled or dropped
  stream, its worker crashed or hung, a refused command), Ctrl-C or SIGTERM aborts the lockstep:
  every other arm's next poll (every `poll_s`) raises, and each arm stops as a single arm does
  (stopL, else the dashboard's `stop`). If this process dies, every controller's RTDE watchdog
  stops its arm;
- an arm whose controller stops answering (one ur_rtde call that does not return: e.g. a movePath
  whose control script the controller will not start under a protective stop, which ur_rtde waits
  for up to the call's timeout) cannot see its own fault; so every arm's poll also checks the
  others' last polls, and an arm silent for more than `silence_s` (default `PEER_SILENCE_S`) once
  the send is under way aborts the lockstep, naming it. An arm that finished its program is not
  watched.

`ArmsSendResult` names, per arm, the last waypoint it completed, and `resume_point` the
`--resume-from` that continues the send.

A resume (`SendSettings.resume_from` N) starts the arms from one sync point of the program: the
meeting point S is the first sync waypoint >= N (else the last waypoint). Each arm must either be
on its path into waypoint N (`robot.interlock.verify_start`, the one-arm rule) and moves on from
there, or stand at S (an arm that was waiting there for the other) and goes to S alone; any other
arm refuses the resume (`robot.path_chunks.SendError` naming the arm), and so does a resume
where no arm is on its path into N (every arm stands at S: N is S), before anything on any
controller changes: every arm's read-only preflight passes before any arm unlocks, powers on or
uploads. All arms meet at S, then go on in lockstep. Each arm's gripper and payload are those the
program has while moving toward its start (`robot.send_tool.ToolControl.holding_at`).
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field, replace

from robot.path_chunks import SendError
from robot.preflight import ControllerFault

__all__ = ["Lockstep", "ArmsSendResult", "ResumePoint", "resume_point", "resume_start", "send_in_lockstep",
           "SYNC_TIMEOUT_S", "PEER_SILENCE_S"]

#: Longest wait [s] at a sync waypoint for another arm that neither arrives nor faults.
SYNC_TIMEOUT_S = 120.0
#: Longest time [s] an arm under way may go without a state poll before the others stop: a movePath
#: upload took 0.12-0.42 s on the stand-ins on a loaded 2-core machine.
PEER_SILENCE_S = 2.0


class Lockstep:
    """The sync points and the abort flag shared by the arms of one send."""

    def __init__(self, arms, sync, poll_s: float = 0.02, timeout_s: float = SYNC_TIMEOUT_S,
                 silence_s: float = PEER_SILENCE_S):
        self.arms, self.sync = tuple(arms), tuple(int(k) for k in sync)
        self.poll_s, self.timeout_s, self.silence_s = float(poll_s), float(timeout_s), float(silence_s)
        self._beat: dict = {}  # arm -> monotonic time of its last poll, once under way
        self._finished: set = set()
        self._cv = threading.Condition()
        self._at = {a: -1 for a in self.arms}
        self._abort: tuple[str, str] | None = None
        self._ready: dict = {}  # arm -> whether it starts on its path into the resume waypoint

    @property
    def aborted(self) -> bool:
        return self._abort is not None

    @property
    def first_fault(self) -> tuple[str, str] | None:
        """(arm, reason) of the first fault, or None."""
        return self._abort

    def reason_for(self, arm: str) -> str:
        who, why = self._abort or ("?", "?")
        return why if who == arm else f"stopped because arm {who} stopped: {why}"

    def abort(self, arm: str, reason: str | None) -> None:
        with self._cv:
            if self._abort is None:
                self._abort = (arm, reason or "stopped")
            self._cv.notify_all()

    def beat(self, arm: str) -> None:
        """Arm `arm` polled its controller: raises `ControllerFault` on an abort, or (aborting the
        lockstep) when another arm under way has not polled for more than `silence_s`."""
        now = time.monotonic()
        with self._cv:
            if self._abort is None and self._at[arm] >= 0:
                self._beat[arm] = now
                for other, t in self._beat.items():
                    if other != arm and other not in self._finished and now - t > self.silence_s:
                        self._abort = (other, f"its controller did not answer for {now - t:.1f} s (a ur_rtde call "
                                              "did not return)")
                        self._cv.notify_all()
                        break
            if self._abort is not None:
                raise ControllerFault(self.reason_for(arm))

    def finished(self, arm: str) -> None:
        """Arm `arm` completed its program (it polls no more)."""
        with self._cv:
            self._finished.add(arm)

    def meet(self, arm: str, on_path: bool = True) -> bool:
        """Arm `arm` passed its read-only preflight (`on_path`: it starts on its path into the
        resume waypoint, not at the meeting point): wait until every arm has (nothing polled:
        nothing has been changed on any controller yet); returns whether any arm is on its path.
        Raises on an abort or the timeout."""
        with self._cv:
            self._ready[arm] = bool(on_path)
            self._cv.notify_all()
            deadline = time.monotonic() + self.timeout_s
            while True:
                if self._abort is not None:
                    raise ControllerFault(self.reason_for(arm))
                late = [a for a in self.arms if a not in self._ready]
                if not late:
                    return any(self._ready.values())
                if time.monotonic() > deadline:
                    raise ControllerFault(f"arm {late[0]} did not pass its preflight within {self.timeout_s:.0f} s")
                self._cv.wait(timeout=self.poll_s)

    def wait(self, arm: str, k: int, poll) -> None:
        """Arm `arm` has reached waypoint `k`: wait until every arm has, calling `poll()` (which
        raises on this arm's faults and on an abort) every `poll_s`."""
        with self._cv:
            self._at[arm] = max(self._at[arm], k)
            self._beat.setdefault(arm, time.monotonic())
            self._cv.notify_all()
        deadline = time.monotonic() + self.timeout_s
        while True:
            poll()
            with self._cv:
                if self._abort is not None:
                    raise ControllerFault(self.reason_for(arm))
                late = [a for a, at in self._at.items() if at < k]
                if not late:
                    return
                if time.monotonic() > deadline:
                    raise ControllerFault(f"arm {late[0]} did not reach waypoint {k} within {self.timeout_s:.0f} s")
                self._cv.wait(timeout=self.poll_s)


def meeting_point(sync, n: int, k: int) -> int:
    """The first sync waypoint >= `k` of a program of `n` waypoints (else its last waypoint)."""
    return next((int(s) for s in sync if int(s) >= k), n - 1)


def resume_start(wps, sync, k: int, q, tcp_pose, tol=None, arm: str = "a") -> int:
    """The waypoint arm `arm` (joints `q`, TCP `tcp_pose`) starts from when a lockstep send resumes
    at `k` (module docstring): `k` when it is on its path into waypoint `k`, the meeting point S when
    it stands at S; otherwise `SendError` naming the arm and how far off it is."""
    import numpy as np

    from robot.interlock import StartTolerances, verify_start

    tol = tol or StartTolerances()
    try:
        verify_start(wps, k, q, tcp_pose, tol)
        return k
    except SendError as exc:
        meet = meeting_point(sync, len(wps), k)
        if meet > k and float(np.abs(np.subtract(q, wps[meet].q)).max()) <= tol.joint_rad:
            return meet
        raise SendError(f"arm {arm}: {exc}") from None


@dataclass(frozen=True)
class ResumePoint:
    """Where a stopped lockstep send continues: `resume_from` (the `--resume-from`), `meet_at` the
    sync waypoint (or the last waypoint) where the arms meet again, `last_sync` the last sync
    waypoint every arm had reached (-1 for none)."""

    resume_from: int
    meet_at: int
    last_sync: int

    def describe(self) -> str:
        return (f"continue with --resume-from {self.resume_from} (each arm goes on to waypoint {self.meet_at}, "
                f"where the arms meet)")


def resume_point(atp, last_completed_per_arm: dict) -> ResumePoint | None:
    """The resume of a lockstep send of `atp` stopped with `last_completed_per_arm`: the waypoint
    after the earliest arm's last completed one; None when every arm completed the program."""
    n = len(atp)
    k = min(int(v) for v in last_completed_per_arm.values()) + 1
    if k >= n:
        return None
    k = max(k, 0)
    last_sync = max([int(s) for s in atp.sync if s < k] or [-1])
    return ResumePoint(resume_from=k, meet_at=meeting_point(atp.sync, n, k), last_sync=last_sync)


@dataclass
class ArmsSendResult:
    """A lockstep send: `ok`, `per_arm` {arm: `robot.sender.SendResult`}, `reason` (the first
    fault, naming its arm), `last_completed` the last waypoint every arm completed,
    `last_completed_per_arm`, and the arms' measures (largest final errors and rounding)."""

    ok: bool
    per_arm: dict
    total: int
    reason: str | None = None
    toolpath_sha256: str = ""
    elapsed_s: float = 0.0
    recheck_s: float = 0.0
    hosts: dict = field(default_factory=dict)
    resume: ResumePoint | None = None

    @property
    def last_completed_per_arm(self) -> dict:
        return {a: r.last_completed for a, r in self.per_arm.items()}

    @property
    def last_completed(self) -> int:
        return min(self.last_completed_per_arm.values())

    def _most(self, key):
        vals = [getattr(r, key) for r in self.per_arm.values() if getattr(r, key) is not None]
        return max(vals) if vals else None

    @property
    def final_error_m(self):
        return self._most("final_error_m")

    @property
    def final_error_rad(self):
        return self._most("final_error_rad")

    @property
    def quantisation_m(self):
        return self._most("quantisation_m") or 0.0

    @property
    def chunks_sent(self) -> int:
        return sum(r.chunks_sent for r in self.per_arm.values())

    def to_json(self) -> dict:
        return {"ok": self.ok, "reason": self.reason, "total": self.total, "toolpath_sha256": self.toolpath_sha256,
                "elapsed_s": self.elapsed_s, "recheck_s": self.recheck_s, "hosts": dict(self.hosts),
                "last_completed": self.last_completed, "last_completed_per_arm": self.last_completed_per_arm,
                "resume": None if self.resume is None else {"resume_from": self.resume.resume_from,
                                                            "meet_at": self.resume.meet_at,
                                                            "last_sync": self.resume.last_sync},
                "chunks_sent": self.chunks_sent, "final_error_m": self.final_error_m,
                "final_error_rad": self.final_error_rad, "quantisation_m": self.quantisation_m,
                "arms": {a: r.to_json() for a, r in self.per_arm.items()}}


def send_in_lockstep(cleared, settings, *, log=None, on_progress=None) -> ArmsSendResult:
    """Send a cleared `robot.arms_toolpath.ArmsToolpath` (`robot.interlock.clear_for_send`) to
    `settings.host` (first arm) and `settings.hosts` (the others), per the module docstring."""
    from robot.arm_cells import arm_cell
    from robot.interlock import Cleared
    from robot.send_options import is_host
    from robot.sender import ArmSender, SendResult

    atp = cleared.toolpath
    names = atp.arm_names
    hosts = (settings.host, *settings.hosts)
    if len(hosts) != len(names):
        raise SendError(f"a program for {len(names)} arms needs {len(names)} controller addresses, one --host per "
                        f"arm in the order {', '.join(names)}; got {len(hosts)}")
    if len(set(hosts)) != len(hosts) or not all(is_host(h) for h in hosts):
        raise SendError(f"--host: every arm needs its own controller address, got {', '.join(hosts)}")
    lock = Lockstep(names, atp.sync, settings.poll_s)
    write_lock = threading.Lock()
    done = {a: -1 for a in names}

    def arm_log(arm):
        def put(event):
            if log is not None:
                with write_lock:
                    log({**event, "arm": arm})
        return put

    def arm_progress(arm):
        def put(k, st):
            done[arm] = k
            if on_progress is not None:
                on_progress(min(done.values()), st)
        return put

    senders = {}
    for arm, host in zip(names, hosts):
        one = Cleared(toolpath=atp.arm(arm), sha256=cleared.sha256, cell=arm_cell(cleared.cell, arm),
                      fold_path=cleared.fold_path, fold_sha256=cleared.fold_sha256, recheck_s=cleared.recheck_s)
        senders[arm] = ArmSender(one, replace(settings, host=host, hosts=()), log=arm_log(arm),
                                 on_progress=arm_progress(arm), lockstep=lock, arm=arm)
    results, crashes = {}, {}

    def run(arm):
        try:
            results[arm] = senders[arm].run()
        except SendError as exc:  # refused before anything changed (a resume off its path)
            crashes[arm] = exc
            lock.abort(arm, str(exc))
        except BaseException as exc:  # a bug in one arm's thread must still stop the other arms
            crashes[arm] = exc
            lock.abort(arm, f"internal error: {exc!r}")

    t0 = time.monotonic()
    threads = [threading.Thread(target=run, args=(a,), name=f"fabkit-send-{a}", daemon=True) for a in names]
    for t in threads:
        t.start()
    try:
        while any(t.is_alive() for t in threads):
            for t in threads:
                t.join(0.05)
    except KeyboardInterrupt:
        lock.abort("all", "interrupted")
        for t in threads:
            t.join(30.0)
        raise
    if crashes:
        raise next(iter(crashes.values()))
    for arm in names:
        results.setdefault(arm, SendResult(ok=False, last_completed=-1, total=len(atp), reason="not run"))
    fault = lock.first_fault
    ok = all(r.ok for r in results.values())
    resume = None if ok else resume_point(atp, {a: r.last_completed for a, r in results.items()})
    return ArmsSendResult(ok=ok, resume=resume, per_arm=results, total=len(atp),
                          reason=None if ok else (f"arm {fault[0]}: {fault[1]}" if fault else
                                                  next(r.reason for r in results.values() if not r.ok)),
                          toolpath_sha256=cleared.sha256, elapsed_s=time.monotonic() - t0,
                          recheck_s=cleared.recheck_s, hosts=dict(zip(names, hosts)))
