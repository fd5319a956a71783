"""Grip faces chosen through the checker: the first face that plans *and passes the check*.

The planner (`robot.planner.plan_panel`) tries the middle-row faces from the largest motion down
and takes the first that plans; a face that plans can still fail the check (the arm or the tool
hits the panel, a wing left free). `checked_acceptor` gives the planner the full check of each
candidate (`sim.check.check_toolpath`, exactly what `fabkit check` runs, panel from the FOLD
file), so the first face whose program passes is chosen. At most `max_checks` candidates are
checked (each check takes seconds); when none passes, the planner returns the first that planned
and the check stage names its problems.
"""
from __future__ import annotations

from pathlib import Path

__all__ = ["checked_acceptor", "MAX_CHECKS"]

#: Candidates checked at most per plan.
MAX_CHECKS = 4


def checked_acceptor(cell, fold_file: str | Path, max_checks: int = MAX_CHECKS):
    """`accept(PlanResult) -> problem or None` for `plan_panel`: None when the candidate's toolpath
    passes the check in `cell` with the panel of `fold_file`, else its first problem (and after
    `max_checks` checks every further candidate is refused unchecked)."""
    from fabkit.io.fold import load_fold
    from robot.jig_holds import with_jig_holds
    from sim.check import check_toolpath

    done = []
    fold_model = load_fold(fold_file) if getattr(cell, "jigs", ()) else None

    def accept(res) -> str | None:
        if len(done) >= max_checks:
            return f"not checked (the first {max_checks} candidates that planned were checked)"
        done.append(res.grip_face)
        tp = res.toolpath if fold_model is None else with_jig_holds(res.toolpath, cell, fold_model)  # as written
        report = check_toolpath(tp, cell, fold=fold_file)
        if report.ok:
            return None
        p = report.problems[0]
        more = f" (+{len(report.problems) - 1} more)" if len(report.problems) > 1 else ""
        return f"check: waypoint {p.waypoint}: {p.kind}: {p.detail}{more}"

    return accept
