"""The verdicts of the relax and unfold stages, and the default tolerances and limits the CLI and
the API share, in one light module.

`fabkit relax` / `fabkit unfold` and `fabkit.relax()` / `fabkit.unfold()` take their verdicts from
here, so the CLI and the API say the same thing with the same tolerances. The messages name the
CLI options (`--max-move`, `--max-error`), which are the API's `max_move` / `max_error`. No
numpy or solver import: a subcommand's `--help` reads the defaults without loading the solvers.
(The refold verdict is `FoldSequence.problems`, the check verdict `sim.check.CheckReport`.)
"""
from __future__ import annotations

#: default largest vertex move, as a share of the panel size (bounding-box diagonal)
DEFAULT_MAX_MOVE = 0.05


def moved_too_far(result, panel_size: float, max_move: float = DEFAULT_MAX_MOVE) -> bool:
    """Did a vertex move more than `max_move` x `panel_size` (metres)?"""
    return result.max_displacement > max_move * panel_size


def relax_problems(result, panel_size: float, max_move: float = DEFAULT_MAX_MOVE) -> list[str]:
    """The verdict of a `RelaxResult` on a panel of size `panel_size` [m]: [] when it converged and
    stayed within `max_move` of the panel size, else the one line `fabkit relax` prints."""
    limit = max_move * panel_size
    if moved_too_far(result, panel_size, max_move):
        return [f"a vertex moved {result.max_displacement * 1e3:.4g} mm, more than --max-move {max_move:g} "
                f"x the panel size {panel_size:.4g} m = {limit * 1e3:.4g} mm: the relaxed panel is another shape "
                f"({'converged' if result.converged else result.message})"]
    return [] if result.converged else [result.message]


#: default largest relative edge/diagonal length deviation (0.1 %: 0.6 mm on a 600 mm panel)
DEFAULT_MAX_ERROR = 1e-3


def development_problems(dev, max_error: float | None = DEFAULT_MAX_ERROR) -> list[str]:
    """The verdicts on a `Development` ([] when good); `max_error` None skips the deviation limit."""
    problems = []
    if max_error is not None and dev.max_relative_deviation > max_error:
        problems.append(f"max relative length deviation {dev.max_relative_deviation:.3g} exceeds --max-error "
                        f"{max_error:.3g}")
    if dev.n_flipped:
        problems.append(f"{dev.n_flipped} faces flipped in the development (first: {int(dev.flipped_faces[0])})")
    if dev.outline_self_overlaps:
        problems.append("the outline of the development overlaps itself")
    if not dev.converged:
        problems.append(f"the solver did not converge: {dev.message}")
    return problems


def check_unfold_options(method: str, norm: float, max_error: float | None, crease_angle: float | None) -> None:
    """Refuse unfold options out of range (`InputError` naming the CLI option): `max_error` > 0,
    `norm` >= 2 (isometric only), `crease_angle` in (0, 180) degrees."""
    import math

    from fabkit.errors import InputError

    if max_error is not None and not (math.isfinite(max_error) and max_error > 0):
        raise InputError(f"must be a positive number, got {max_error}", source="--max-error")
    if not (math.isfinite(norm) and norm >= 2):
        raise InputError(f"must be a number >= 2, got {norm}", source="--norm")
    if norm != 2 and method != "isometric":
        raise InputError("only the isometric method has a spring-energy exponent", source="--norm")
    if crease_angle is not None and not (math.isfinite(crease_angle) and 0 < crease_angle < 180):
        raise InputError(f"must be in (0, 180) degrees, got {crease_angle}", source="--crease-angle")


#: default largest distance of the last refolded state to the target, relative to the panel size
DEFAULT_TARGET_RTOL = 1e-6

#: most states per folding step: far more than a robot program needs, small enough to fit in memory
MAX_REFOLD_FRAMES = 10_000
