"""Grip faces chosen through the checker: the first face that plans *and passes the check*.

The planner (`robot.grip_choice.plan_panel`) tries the middle-row faces from the largest motion down
and takes the first that plans; a face that plans can still fail the check (the arm or the tool
hits the panel, a wing left free). `checked_acceptor` gives the planner the full check of each
candidate (`sim.check.check_toolpath`, exactly what `fabkit check` runs, panel from the FOLD
file), so the first face whose program passes is chosen. At most `MAX_CHECKS` candidates are
checked per grip side, and per plan at most `MAX_CHECKS["regrip"]` programs in phases (each check takes a fraction of a second to seconds; the planner tries
every face on the front side before the back side, `robot.grip_choice`); when none passes, the
planner returns the first that planned and the check stage names its problems.
"""
from __future__ import annotations

from pathlib import Path

from robot.regrip_choice import REGRIP_CHECKS

__all__ = ["checked_acceptor", "MAX_CHECKS"]

#: Candidates checked at most per plan and grip side (programs in phases: `robot.regrip_choice`).
MAX_CHECKS = {"front": 4, "back": 1, "regrip": REGRIP_CHECKS}


def checked_acceptor(cell, fold_file: str | Path, max_checks: dict | None = None):
    """`accept(PlanResult) -> problem or None` for `plan_panel`: None when the candidate's toolpath
    passes the check in `cell` with the panel of `fold_file`, else its first problem (and after
    `max_checks[side]` checks on a grip side, default `MAX_CHECKS`, every further candidate on that
    side is refused unchecked). A cell with jigs: the candidate is checked with the faces its jigs
    hold (`robot.jig_holds`), as the toolpath is written."""
    from fabkit.io.fold import load_fold
    from robot.jig_holds import with_jig_holds
    from sim.check import check_toolpath

    budget = {**MAX_CHECKS, **(max_checks or {})}
    done: dict[str, list[int]] = {}
    fold_model = load_fold(fold_file) if getattr(cell, "jigs", ()) else None

    def accept(res) -> str | None:
        side = ("regrip" if "phases" in res.toolpath.extra  # a program in phases (robot.phased_planner)
                else str(res.toolpath.extra.get("grip", {}).get("side", "front")))
        checked = done.setdefault(side, [])
        if len(checked) >= budget.get(side, 0):
            return (f"not checked (the first {budget.get(side, 0)} candidates that planned on the {side} side "
                    "were checked)")
        checked.append(res.grip_face)
        tp = res.toolpath if fold_model is None else with_jig_holds(res.toolpath, cell, fold_model)  # as written
        report = check_toolpath(tp, cell, fold=fold_file)
        clearances[res.toolpath.sha256] = report.min_clearance_m
        if report.ok:
            return None
        p = report.problems[0]
        more = f" (+{len(report.problems) - 1} more)" if len(report.problems) > 1 else ""
        return f"{side} side: check: waypoint {p.waypoint}: {p.kind}: {p.detail}{more}"

    clearances: dict[str, float | None] = {}
    accept.clearances = clearances   # toolpath sha256 -> the check's least clearance [m] (None: none in its window)
    return accept
