"""The check of a program for several arms (PATH.json `fabkit.toolpath/3`).

One arm at a time, each in the cell as it sees it (`robot.arm_cells.arm_cell`): reach, limits,
singularities, speeds, collisions and clearance of that arm and its tool against the obstacles and
the panel posed at the fold state of every configuration (`sim.check.run_toolpath_check`, the
one-arm check; for a sheet program also that arm's fold loads, `sim.check_loads`: the creases it
folds, its payload share, its cup and pad, with the panel posed in the compensated states). Then,
for the program as a whole:

- **arm against arm**: both arms in one MuJoCo model (`sim.model.build_cell_model(all_arms=True)`,
  `sim.arm_contacts`), at common times. The sender runs the arms in lockstep: every segment between
  two sync waypoints starts for both arms when both have finished the one before (and its gripper
  dwell), so inside a segment each arm is where its own time law puts it, and an arm that is done
  waits at the segment's end. Contacts closer than the cell's clearance are problems (`collision`
  when they touch, else `clearance`) naming both parts;
- **holds**: the clamp and both grips (PATH.json `holds`, a row per arm) in every fold state and
  between states (`sim.check_holds`), with the fractional fold state of each waypoint the same for
  every arm (the planner cuts both arms' fold moves alike);
- **lockstep**: every move that carries the panel takes the same time for every arm in the
  controller's motion model (`robot.motion`), within `LOCKSTEP_TOL_S`; otherwise the arms would
  pull the panel toward two different fold states (kind `holds`, subject "lockstep");
- the panel against the cell and itself (`sim.check_panel_collisions`) and the clamp footprint.

Problems found in one arm's check carry the arm's name in `subject` and `detail`; CHECK.json
`loads` holds every arm's load checks, each crease named with its arm, and `arms.<name>.loads` each
arm's own record.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from sim.problems import KINDS, Event, Problem, merge_events

__all__ = ["run_arms_check", "aligned_joints", "aligned_dense", "LOCKSTEP_TOL_S"]

#: Largest difference [s] between two arms' durations of a move that carries the panel.
LOCKSTEP_TOL_S = 0.002


def _segment_bounds(atp) -> list[tuple[int, int]]:
    b = [0, *atp.sync, len(atp) - 1]
    return [(x, y) for x, y in zip(b[:-1], b[1:]) if y > x]


def aligned_joints(atp, runs: dict) -> dict:
    """Every arm at common times of the lockstep program: {"joints": {arm: (M, 6)}, "waypoint" (M,)
    the waypoint each row belongs to (the later of the arms' moves), "at_waypoint" (M,) rows where
    the first arm stands on its waypoint, "state" (M,) the first arm's fractional fold state, "t"
    (M,) time from the start}."""
    names = list(runs)
    rows = {n: [] for n in names}
    wps, times, at, states, t0 = [], [], [], [], 0.0
    for k, (a, b) in enumerate(_segment_bounds(atp)):
        local = {}
        for n in names:
            d, prog = runs[n].dense, runs[n].program
            dwell = 0.0 if prog.dwell is None else float(prog.dwell[a])
            start = int(np.flatnonzero((d.waypoint == a) & d.at_waypoint)[0])
            sel = np.flatnonzero((d.waypoint > a) & (d.waypoint <= b))
            idx = np.r_[start, sel]
            t = np.maximum.accumulate(np.nan_to_num(d.t[idx] - d.t[start] - np.r_[0.0, np.full(len(sel), dwell)]))
            keep = np.r_[t[1:] > t[:-1], True]  # configurations at one moment: the last of them
            at_times = t[d.at_waypoint[idx]]
            idx, t = idx[keep], t[keep]
            local[n] = (t, d.q[idx], d.waypoint[idx], np.isin(t, at_times), d.state[idx])
        grid = np.unique(np.concatenate([local[n][0] for n in names]))
        if k > 0:  # the segment's start is the last row of the one before
            grid = grid[grid > 0]
        for n in names:
            t, q = local[n][:2]
            rows[n].append(np.column_stack([np.interp(grid, t, q[:, j]) for j in range(6)]))
        wps.append(np.max([local[n][2][np.clip(np.searchsorted(local[n][0], grid, side="left"), 0,
                                                   len(local[n][0]) - 1)] for n in names], axis=0))
        t_first, _, w_first, at_first, s_first = local[names[0]]
        on = np.isin(grid, t_first[at_first])
        wps[-1][on] = w_first[np.searchsorted(t_first, grid[on])]  # the first arm's own waypoint
        at.append(on)
        states.append(np.interp(grid, t_first, s_first))
        times.append(t0 + grid)
        t0 += float(grid[-1]) if len(grid) else 0.0
    return {"joints": {n: np.vstack(rows[n]) for n in names}, "waypoint": np.concatenate(wps),
            "at_waypoint": np.concatenate(at), "state": np.concatenate(states), "t": np.concatenate(times)}


def aligned_dense(aligned: dict):
    """The common moments as a `sim.interpolate.Dense` with every arm's joints side by side
    ((M, 6 x arms), the order of `build_cell_model(all_arms=True)`): what the renders draw."""
    from sim.interpolate import Dense

    t = aligned["t"]
    dt = np.r_[np.nan, np.diff(t)]
    return Dense(q=np.concatenate(list(aligned["joints"].values()), axis=1), waypoint=aligned["waypoint"],
                 at_waypoint=aligned["at_waypoint"], state=aligned["state"], dt=dt, move_v=np.zeros(len(t)), t=t)


def _arm_arm_events(atp, cell, runs) -> tuple[list[Event], float | None, tuple | None, int]:
    from sim.arm_contacts import arm_arm_contacts
    from sim.model import build_cell_model

    aligned = aligned_joints(atp, runs)
    joints, wp = aligned["joints"], aligned["waypoint"]
    clearance = float(cell.limits.clearance)
    hits = arm_arm_contacts(cell, joints, clearance=clearance, built=build_cell_model(cell, all_arms=True))
    events, worst, pair = [], None, None
    for h in hits:
        kind = "collision" if h.distance_m < 0 else "clearance"
        label = f"{h.pair[0]} × {h.pair[1]}"
        detail = (f"arm against arm: {label}, {-h.distance_m * 1e3:.1f} mm deep" if kind == "collision" else
                  f"arm against arm: {label} {h.distance_m * 1e3:.1f} mm apart, inside the clearance "
                  f"{clearance * 1e3:.0f} mm")
        events.append(Event(waypoint=int(wp[h.config]), kind=kind, subject=label, value=h.distance_m, detail=detail,
                            pair=h.pair))
        if worst is None or h.distance_m < worst:
            worst, pair = h.distance_m, h.pair
    return events, worst, pair, aligned


def _lockstep_problems(atp) -> tuple[list[Problem], dict]:
    from robot.holds_record import HOLDING_OPS
    from robot.motion import toolpath_cycle_time

    seg = {n: toolpath_cycle_time(tp).segments for n, tp in atp.arms}
    names = list(seg)
    ops = [w.op for w in atp.arms[0][1].waypoints]
    worst, out = 0.0, []
    for i in range(1, len(ops)):
        if ops[i] not in HOLDING_OPS:
            continue
        d = [float(seg[n][i - 1]) for n in names]
        gap = max(d) - min(d)
        worst = max(worst, gap)
        if gap > LOCKSTEP_TOL_S:
            out.append(Problem(waypoint=i, kind="holds", subject="lockstep", last_waypoint=i, value=gap,
                               detail="the arms take " + ", ".join(f"{n} {t:.3f} s" for n, t in zip(names, d))
                               + f" for the move into waypoint {i} while both hold the panel: they would pull it "
                               "toward different fold states"))
    return out, {"tolerance_s": LOCKSTEP_TOL_S, "max_mismatch_s": worst, "sync": list(atp.sync)}


def _labelled(p: Problem, arm: str) -> Problem:
    """`p` of one arm's check, named for the arm (its `config` indexes that arm's configurations:
    dropped)."""
    return replace(p, subject=f"{arm}: {p.subject}" if p.subject else arm, detail=f"arm {arm}: {p.detail}",
                   config=None)


def run_arms_check(atp, cell, *, fold=None, use_panel: bool = True, thickness=None, settings=None,
                   on_progress=None, base_dir=None):
    """Check `atp` (a `robot.arms_toolpath.ArmsToolpath`) in `cell` (module docstring); returns a
    `sim.check.ToolpathCheck` whose report covers every arm (`arms`, `lockstep` in CHECK.json),
    whose `dense` holds every arm at the common moments (`aligned_dense`: what the renders draw)
    and whose `program` is the first arm's."""
    from fabkit.errors import InputError
    from robot.arm_cells import arm_cell, arm_names
    from robot.two_arm_planner import lockstep_timing
    from sim.check import CheckSettings, ToolpathCheck, run_toolpath_check
    from sim.check_cup import cup_problems
    from sim.check_holds import check_holds, clamp_problems
    from sim.check_panel_collisions import check_panel_collisions_of_fold
    from sim.toolpath_program import load_source_fold

    settings = settings or CheckSettings()
    if tuple(arm_names(cell)) != atp.arm_names:
        raise InputError(f"the program is for arms {', '.join(atp.arm_names)}, the cell {cell.name!r} has "
                         f"{', '.join(arm_names(cell))}", source=cell.source or None)
    first = atp.arm(atp.arm_names[0])
    model, fold_path, fold_sha = load_source_fold(first, fold, base_dir=base_dir) if use_panel else (None, None, None)
    runs = {}
    for n in atp.arm_names:
        runs[n] = run_toolpath_check(atp.arm(n), arm_cell(cell, n), fold=fold_path, use_panel=model is not None,
                                     thickness=thickness, settings=settings, on_progress=on_progress,
                                     panel_checks=False)
    problems = [_labelled(p, n) for n, r in runs.items() for p in r.report.problems]
    placed = runs[atp.arm_names[0]].report
    events, worst, pair, aligned = _arm_arm_events(atp, _placed_cell(first, cell), runs)
    n_aligned = len(aligned["t"])
    problems += merge_events(events)
    lock, lock_record = _lockstep_problems(atp)
    problems += lock
    notes = [f"{len(atp.arm_names)} arms in lockstep: arm against arm checked at {n_aligned} common moments"]
    holds_rec = panel_rec = None
    if model is not None:
        states = {n: np.asarray(r.program.states) for n, r in runs.items()}
        ref = states[atp.arm_names[0]]
        if any(not np.allclose(s, ref, atol=1e-9) for s in states.values()):
            problems.append(Problem(waypoint=0, kind="holds", subject="lockstep", last_waypoint=len(atp) - 1,
                                    detail="the arms' waypoints are not at the same fold states"))
        holds = check_holds(first, model, ref, source=str(fold_path))
        pcell = _placed_cell(first, cell)
        panel = check_panel_collisions_of_fold(model, pcell, ref, holds.record["clamped_faces"], thickness=thickness)
        problems += list(holds.problems) + list(panel.problems)
        problems += list(clamp_problems(model, pcell, holds.record["clamped_faces"], len(atp)))
        holds_rec, panel_rec = holds.record, panel.record
        cup, cup_found = cup_problems(model, holds_rec, lambda arm: None if arm not in runs or
                                      runs[arm].report.loads is not None else  # a sheet's pads: sim.check_loads
                                      getattr(arm_cell(cell, arm).tool, "cup_radius", None))
        problems += cup_found
        if cup is not None:
            holds_rec = {**holds_rec, "cup_footprint": cup}
        notes += list(holds.notes)
    else:
        notes.append("no panel: the holds and the panel's own collisions were not checked")
    problems = tuple(sorted(problems, key=lambda p: (p.waypoint, KINDS.index(p.kind), p.subject)))
    clear = [(r.report.min_clearance_m, r.report.min_clearance_pair) for r in runs.values()
             if r.report.min_clearance_m is not None]
    if worst is not None:
        clear.append((worst, pair))
    min_c, min_pair = min(clear, key=lambda c: c[0]) if clear else (None, None)
    arms = {n: {"robot": atp.arm(n).robot, "toolpath_sha256": atp.arm(n).sha256, "ok": r.report.ok,
                **({"loads": r.report.loads} if r.report.loads is not None else {}),
                "min_clearance_m": r.report.min_clearance_m,
                "min_clearance_pair": list(r.report.min_clearance_pair) if r.report.min_clearance_pair else None,
                "cycle_time_s": r.report.cycle_time_s, "configs_checked": r.report.configs_checked,
                "along_path": r.report.along_path, "notes": list(r.report.notes)} for n, r in runs.items()}
    timing = lockstep_timing(atp)
    report = replace(placed, toolpath_sha256=atp.sha256, ok=not problems, problems=problems, min_clearance_m=min_c,
                     min_clearance_pair=tuple(min_pair) if min_pair else None, cycle_time_s=timing["total_s"],
                     configs_checked=sum(r.report.configs_checked for r in runs.values()) + n_aligned,
                     robot=atp.robot, cell=cell.name, cell_sha256=getattr(cell, "sha256", ""),
                     notes=tuple(notes) + placed.notes,
                     fold=None if fold_path is None else {"path": str(fold_path), "sha256": fold_sha},
                     holds=holds_rec, panel_collisions=panel_rec, arms=arms, loads=_merged_loads(runs),
                     lockstep={**lock_record, "arm_arm_min_distance_m": worst,
                               "arm_arm_pair": list(pair) if pair else None, "segments": timing["segments"],
                               "segment_times_s": timing["arms"]})
    r0 = runs[atp.arm_names[0]]
    return ToolpathCheck(report=report, dense=aligned_dense(aligned), program=r0.program, panel=r0.panel,
                         fold_path=fold_path)


def _merged_loads(runs: dict) -> dict | None:
    """CHECK.json `loads` of a sheet program for several arms: one arm's record shape (`sim.check_loads`)
    with every arm's checks per state, each crease named "arm <name>: <crease>", and `arms` {name:
    that arm's record}; None for a rigid program."""
    recs = {n: r.report.loads for n, r in runs.items() if r.report.loads is not None}
    if not recs:
        return None
    states: dict = {}
    for n, rec in recs.items():
        for row in rec["states"]:
            st = states.setdefault(row["state"], {"state": row["state"], "waypoints": row["waypoints"], "ok": True,
                                                  "checks": []})
            st["ok"] = st["ok"] and row["ok"]
            st["checks"] += [{**c, "crease": f"arm {n}: {c['crease']}", "arm": n} for c in row["checks"]]
    first = next(iter(recs.values()))
    return {"ok": all(r["ok"] for r in recs.values()), "arm": "+".join(r["arm"] for r in recs.values()),
            "sheet": first["sheet"], "recorded": all(r["recorded"] for r in recs.values()),
            "payload_kg": {n: r["payload_kg"] for n, r in recs.items()},
            "states": [states[k] for k in sorted(states)], "arms": recs}


def _placed_cell(tp, cell):
    from robot.panel_placement import placed_cell, placement_of

    return placed_cell(cell, placement_of(tp.extra))
