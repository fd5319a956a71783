"""Check problems: the typed events the checks find and the problems a report lists.

An `Event` is one finding at one configuration or waypoint. `merge_events` reports runs of the
same problem (same kind and same joint/pair/factor) over consecutive waypoints once, with the
first and last waypoint and the worst value; a pair that breaks the clearance and then collides
is reported once, as the collision.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

__all__ = ["KINDS", "DEG", "Event", "Problem", "merge_events"]

KINDS = ("unreachable", "joint_limit", "singular", "collision", "speed", "clearance", "holds", "panel_collision",
         "load")
DEG = 180.0 / math.pi


@dataclass(frozen=True)
class Event:
    """One finding: the `waypoint` it belongs to, its `kind` (one of KINDS), `subject` (joint,
    geom pair label or factor), `value` (SI units; NaN where none), human `detail`, the geom
    `pair` for contacts and `config`, the index of the configuration in the checked `Dense`
    sequence (None for findings at the program level)."""

    waypoint: int
    kind: str
    subject: str
    value: float
    detail: str
    pair: tuple[str, str] | None = None
    config: int | None = None


@dataclass(frozen=True)
class Problem:
    """One problem: first `waypoint` (index), `kind` (one of KINDS), human `detail`; `last_waypoint`
    of the run, `subject` (joint, geom pair or factor), `value` the worst value (SI units);
    `config` the index of the first offending configuration in the checked `Dense` sequence (not
    in JSON; it may lie inside the move to `waypoint`)."""

    waypoint: int
    kind: str
    detail: str
    last_waypoint: int
    subject: str = ""
    value: float | None = None
    pair: tuple[str, str] | None = None
    config: int | None = field(default=None, compare=False)

    def to_json(self) -> dict:
        out = {"waypoint": int(self.waypoint), "kind": self.kind, "detail": self.detail,
               "last_waypoint": int(self.last_waypoint), "subject": self.subject,
               "value": None if self.value is None or not math.isfinite(self.value) else float(self.value)}
        if self.pair is not None:
            out["pair"] = list(self.pair)
        return out



def _worse(kind: str, new: float, old: float) -> bool:
    """Is `new` a worse value than `old` for this kind (distances and factors: smaller is worse)?"""
    if not math.isfinite(new):
        return False
    if not math.isfinite(old):
        return True
    return new < old if kind in ("collision", "clearance", "singular") else new > old


def merge_events(events) -> list[Problem]:
    """One problem per run of the same (kind, subject) over consecutive waypoints, worst value kept."""
    runs: dict = {}
    done = []
    for ev in sorted(events, key=lambda e: (e.kind, e.subject, e.waypoint, -1 if e.config is None else e.config)):
        wp, kind, subject, value, detail, pair, config = (ev.waypoint, ev.kind, ev.subject, ev.value, ev.detail,
                                                          ev.pair, ev.config)
        run = runs.get((kind, subject))
        if run is not None and wp <= run["last"] + 1:
            run["last"] = max(run["last"], wp)
            if _worse(kind, value, run["value"]):
                run["value"], run["detail"] = value, detail
            continue
        if run is not None:
            done.append(run)
        runs[(kind, subject)] = {"first": wp, "last": wp, "kind": kind, "subject": subject, "value": value,
                                 "detail": detail, "pair": pair, "config": config}
    done.extend(runs.values())
    problems = []
    for r in done:
        detail = r["detail"]
        if r["last"] > r["first"]:
            detail += f" (waypoints {r['first']}–{r['last']})"
        problems.append(Problem(waypoint=r["first"], kind=r["kind"], detail=detail, last_waypoint=r["last"],
                                subject=r["subject"], value=r["value"], pair=r["pair"], config=r["config"]))
    problems = _fold_clearance_into_collisions(problems)
    problems.sort(key=lambda p: (p.waypoint, KINDS.index(p.kind), p.subject))
    return problems


def _fold_clearance_into_collisions(problems: list[Problem]) -> list[Problem]:
    """A pair that collides also comes closer than the clearance just before and after: keep one
    problem (the collision, its first penetrating waypoint) and say where the near miss began."""
    hits = [p for p in problems if p.kind == "collision"]
    keep, closer = [], {}
    for p in problems:
        if p.kind == "clearance":
            c = next((h for h in hits if h.subject == p.subject and p.waypoint <= h.last_waypoint + 1
                      and p.last_waypoint >= h.waypoint - 1), None)
            if c is not None:
                closer[id(c)] = min(closer.get(id(c), p.waypoint), p.waypoint)
                continue
        keep.append(p)
    out = []
    for p in keep:
        if id(p) in closer and closer[id(p)] < p.waypoint:
            p = replace(p, detail=f"{p.detail}; inside the clearance from waypoint {closer[id(p)]}")
        out.append(p)
    return out
