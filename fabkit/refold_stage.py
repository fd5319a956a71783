"""The refold stage: a flat pattern and its folded target -> fold states, for `fk.refold` and
`fabkit refold`.

`refold_meshes(flat, target, ...)` takes the two meshes and the refold options as the command
takes them: `drive` "middle-row" (the paper's middle-row creases), "all", hinge ids, or a JSON
drive file; `steps` "crease0,crease1" / "strip1", a JSON schedule file, or hinge groups. It builds
the schedule, solves the states, and returns `fabkit.results.Folds` with the verdicts (target not
a fold of flat, a state not converged, the last state off target, faces passing through each
other) and the report `fabkit refold --report` writes (`Folds.to_json()`).
"""
from __future__ import annotations

import math
import time
from pathlib import Path

from fabkit.errors import InputError
from fabkit.verdicts import DEFAULT_TARGET_RTOL, MAX_REFOLD_FRAMES

__all__ = ["refold_meshes", "check_refold_options"]


def check_refold_options(frames: int, length_tol: float | None, target_tol: float) -> None:
    """Refuse options out of range (`InputError` naming the CLI option)."""
    if not (isinstance(frames, int) and 2 <= frames <= MAX_REFOLD_FRAMES):
        raise InputError(f"must be in 2..{MAX_REFOLD_FRAMES} (flat and target included), got {frames}",
                         source="--frames")
    for name, v in (("length_tol", length_tol), ("target_tol", target_tol)):
        if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise InputError(f"must be a positive number, got {v}", source="--" + name.replace("_", "-"))


def _drive_and_steps(solver, flat, drive, steps):
    """(driven hinges, notes, steps as hinge groups or None) from the options (module docstring)."""
    from fabkit.refold.sequence import load_drive_file, parse_steps

    notes: list = []
    file_steps = None
    if isinstance(drive, str) and drive in ("middle-row", "all"):
        driven, notes = solver.driven_hinges(drive)
    elif isinstance(drive, (str, Path)):
        if not Path(drive).is_file():
            raise InputError("not middle-row, all, or an existing JSON file", source=str(drive))
        driven, file_steps = load_drive_file(drive, flat, solver.panel)
    else:
        driven = drive
    if steps is None:
        return driven, notes, file_steps
    if file_steps is not None:
        raise InputError("the drive file already has steps", source="--steps")
    if isinstance(steps, (str, Path)) and Path(steps).is_file():  # a JSON schedule: its steps say what is driven
        if drive != "middle-row":
            raise InputError("give the driven hinges either in --drive or in the --steps file", source="--steps")
        driven, groups = load_drive_file(steps, flat, solver.panel)
        return driven, [], groups if groups is not None else [driven]
    if isinstance(steps, str):
        return driven, notes, parse_steps(steps, solver.panel, driven)
    return driven, notes, steps


def refold_meshes(flat, target, *, frames: int = 20, drive="middle-row", steps=None, fixed_face: int | None = None,
                  diagonal: str = "short", length_tol: float | None = None, target_tol: float = DEFAULT_TARGET_RTOL,
                  solver: str = "direct", intersections: bool = True, flat_name: str = "FLAT",
                  target_name: str = "TARGET", title: str | None = None, progress=None):
    """Fold states from the mesh `flat` (z = 0) to `target` (same vertices and faces) -> `Folds`
    (module docstring). `length_tol` None: `fabkit.refold.DEFAULT_LENGTH_RTOL`; `title` the FOLD
    file's `file_title` (default "refold of FLAT_NAME to TARGET_NAME"); `progress(n)` is called per
    state solved."""
    from fabkit.refold import DEFAULT_LENGTH_RTOL, NotAFoldError, RefoldSolver
    from fabkit.refold.export import to_fold_model
    from fabkit.refold.sequence import build_schedule
    from fabkit.results import Folds

    check_refold_options(frames, length_tol, target_tol)
    length_tol = DEFAULT_LENGTH_RTOL if length_tol is None else length_tol
    details = {"flat": flat_name, "drive": drive if isinstance(drive, str) else None,
               "steps": steps if isinstance(steps, str) else None, "length_tol": length_tol, "frames_per_step": frames}
    try:
        rs = RefoldSolver(flat, target, fixed_face=fixed_face, diagonal=diagonal, length_rtol=length_tol,
                          solver=solver, flat_name=flat_name, target_name=target_name)
    except NotAFoldError as exc:
        return Folds(sequence=None, model=None, name=target_name, target_tol=target_tol, ok=False,
                     problems=(str(exc),), details={**details, "worst_edge": list(exc.edge),
                                                    "worst_relative_length_difference": exc.relative})
    driven, notes, groups = _drive_and_steps(rs, flat, drive, steps)
    fractions, step_of_state = build_schedule(rs.panel, driven, groups, frames)
    t0 = time.perf_counter()
    seq = rs.solve(fractions, driven, step_of_state, check_intersections=intersections, progress=progress,
                   notes=notes)
    details.update({"structure": rs.structure.summary(flat), "seconds": time.perf_counter() - t0,
                    "max_relative_length_difference": rs.max_length_mismatch})
    problems = seq.problems(target_tol)
    name = title if title is not None else f"refold of {flat_name} to {target_name}"
    return Folds(sequence=seq, model=to_fold_model(seq, title=name), name=target_name, target_tol=target_tol,
                 ok=not problems, problems=tuple(problems), details=details)
