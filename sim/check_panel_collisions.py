"""Does the folding panel hit the fixture, the table, the obstacles or itself? The panel part of
the check.

`sim.panel_collision` tests the panel of the FOLD file (placed by the cell's fixture, as the arm
check places it) against the cell's obstacles (MuJoCo, explicit pairs: MuJoCo never pairs static
and mocap bodies by itself) and against itself (exact triangle tests), at every fold state and
between states, sampled so no face corner moves more than 5 mm between samples. The clamped face,
and the faces that never move (they lie with it on the clamp, to 1 um in every state), against
the obstacle carrying the cell's clamp (`[clamp] obstacle`) touch by design and are exempt; so is
any face on the clamp's obstacle no deeper than the sheet thickness (the sheet lying on the post's
top next to the clamped face: CHECK.json lists them as `resting_on_clamp`). A face a jig holds
(`jig_holds`: {jig obstacle: [(face, (lowest, highest) held fold state), ...]}) against that
jig's body, in the states it holds it and no deeper than the sheet, is exempt the same way
(`resting_on_jig`); every other face against a jig's body is a collision.
Each colliding pair is one problem (kind "panel_collision") naming the pair, the fold states and
the worst depth, at the first waypoint whose move reaches that state. The tool and the arm against
the panel are the arm check's (`sim.check_events`).
"""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from sim.problems import Problem

__all__ = ["PanelCheck", "check_panel_collisions_of_fold", "RESTING_TOL"]

#: A face whose vertices stay this close [m] to their first position in every state rests with the
#: clamped face on the clamp.
RESTING_TOL = 1e-6


@dataclass(frozen=True)
class PanelCheck:
    """`record` CHECK.json's `panel_collisions` value; `problems` (kind "panel_collision")."""

    ok: bool
    record: dict
    problems: tuple[Problem, ...]


def _waypoint_of(states: np.ndarray, s: float) -> int:
    """The first waypoint whose move reaches fractional state s (the move that causes a contact)."""
    st = np.asarray(states, np.float64)
    hit = np.flatnonzero(st >= s - 1e-9)
    return int(hit[0]) if len(hit) else len(st) - 1


def _on_jig(c, jig_holds: dict, sheet: float) -> bool:
    """Is contact `c` the jig-held face lying on its jig's body, in states the jig holds it?"""
    if c.kind != "obstacle" or c.pair[1] not in jig_holds or c.depth_m > sheet + 1e-9:
        return False
    return any(c.pair[0] == f"face_{face}" and lo - 1e-9 <= c.state and c.last_state <= hi + 1e-9
               for face, (lo, hi) in jig_holds[c.pair[1]])


def check_panel_collisions_of_fold(fold_model, cell, states, clamped_faces=(), *, thickness: float | None = None,
                                   jig_holds: dict | None = None) -> PanelCheck:
    """Panel collisions of a refold FOLD model (`faces_fabkit:polygon` groups triangles into faces)
    in `cell`; `states` the fractional fold state of every waypoint, `clamped_faces` polygon ids
    exempt against the clamp's obstacle."""
    from fabkit.frames import fold_positions
    from sim.panel import DEFAULT_THICKNESS
    from sim.panel_collision import check_panel_collisions, collider_for_sequence

    from fabkit.hold_model_fold import fold_triangles

    tris, tri_face = fold_triangles(fold_model)
    positions = fold_positions(fold_model)
    clamp_obstacle = cell.clamp.obstacle if getattr(cell, "clamp", None) is not None else ""
    exempt_obstacles = list(cell.obstacles)
    fixed = [int(f) for f in clamped_faces if f in set(tri_face.tolist())]
    seq = SimpleNamespace(tris=tris, tri_face=tri_face, flat_vertices=np.asarray(fold_model.vertices_coords),
                          positions=positions, fixed_face=fixed[0] if fixed else -1)
    still = np.linalg.norm(positions - positions[:1], axis=2).max(axis=0) <= RESTING_TOL
    resting = sorted({int(f) for f, t in zip(tri_face, tris) if still[t].all()})
    collider = collider_for_sequence(seq, cell.fixture, exempt_obstacles, resting_faces=resting,
                                     clamp_obstacle=clamp_obstacle if fixed else "", thickness=thickness)
    report = check_panel_collisions(collider)
    sheet = DEFAULT_THICKNESS if thickness is None else thickness
    resting_on = [c for c in report.contacts if clamp_obstacle and c.kind == "obstacle"
                  and c.pair[1] == clamp_obstacle and c.depth_m <= sheet + 1e-9]
    on_jig = [c for c in report.contacts if _on_jig(c, jig_holds or {}, sheet)]
    contacts = [c for c in report.contacts if c not in resting_on and c not in on_jig]
    problems = []
    for c in contacts:
        where = f"fold state {c.state:g}" if c.state == c.last_state else f"fold states {c.state:g}-{c.last_state:g}"
        what = "the panel against itself" if c.kind == "self" else "the panel against the cell"
        problems.append(Problem(waypoint=_waypoint_of(states, c.state), kind="panel_collision",
                                subject=f"{c.pair[0]} × {c.pair[1]}", value=c.depth_m, pair=c.pair,
                                last_waypoint=_waypoint_of(states, c.last_state),
                                detail=f"{where}: {what}: {c.pair[0]} × {c.pair[1]}, {c.depth_m * 1000:.1f} mm deep"))
    record = {"ok": not contacts, "samples": report.samples, "states": report.states,
              "exempt": [[f"face_{f}", clamp_obstacle] for f in sorted(set(fixed[:1]) | set(resting))]
              if clamp_obstacle and fixed else [],
              "contacts": [{"kind": c.kind, "pair": list(c.pair), "state": c.state, "last_state": c.last_state,
                            "depth_m": c.depth_m} for c in contacts],
              "resting_on_clamp": [{"pair": list(c.pair), "depth_m": c.depth_m} for c in resting_on],
              **({"resting_on_jig": [{"pair": list(c.pair), "state": c.state, "last_state": c.last_state,
                                      "depth_m": c.depth_m} for c in on_jig]} if jig_holds else {})}
    return PanelCheck(not contacts, record, tuple(problems))
