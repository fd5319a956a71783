"""PATH.json of a program for a cell with several arms (`fabkit.toolpath/3`).

One-arm programs stay `fabkit.toolpath/2` (`robot.toolpath`). A program for several arms is

    {"format": "fabkit.toolpath/3", "cell", "cell_sha256", "source",
     "arms": [{"name", "robot", "tcp", "waypoints": [...], "grip", "checks", "cycle_time_s"[, "payload"]}, ...],
     "sync": [waypoint indices], "holds", "placement", "units", "cycle_time_s", "lockstep", "sha256"}

Every arm has the same number of waypoints, and waypoint i of every arm has the same `op` and
`state`: index i is one step of the program for all arms. `sync` lists the waypoints at which
every arm waits until all have arrived (the grip, every fold state, the release): the lockstep
rule the sender follows (`robot.lockstep`), so all arms finish fold state k before any starts
state k+1. While the arms hold the panel, the moves between two sync points have the same
duration for every arm in the controller's motion model (their speeds and accelerations scale with
their lengths, no blends), so the arms pass the same fractional fold state at the same time.
`holds` is `robot.holds_record`'s record with a row per arm. `sha256` hashes the canonical JSON of
the whole document except itself, as for `/2`.

`ArmsToolpath.arm(name)` is one arm's program as a one-arm `robot.toolpath.Toolpath` (its own
waypoints, robot, TCP, grip; the shared source, holds and placement): what the check and the
sender run per arm. Readers of `/2` refuse `/3` by its format; `load_toolpath` reads either.
"""
from __future__ import annotations

import copy
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fabkit.errors import InputError
from fabkit.io.jsonfile import load_json
from robot.toolpath import FORMAT as ONE_ARM_FORMAT, OLD_FORMATS, Toolpath, document_sha256, finish_document

__all__ = ["FORMAT", "ArmsToolpath", "load_toolpath", "toolpath_from_json"]

FORMAT = "fabkit.toolpath/3"
ARM_KEYS = ("name", "robot", "tcp", "waypoints")
#: Per-arm extra keys (the rest of the document's extra keys are shared by every arm).
ARM_EXTRA = ("grip", "checks", "cycle_time_s", "payload")
REQUIRED = ("cell", "cell_sha256", "source", "arms", "sync", "sha256")


def _plain(value):
    return json.loads(json.dumps(value, allow_nan=False, default=lambda o: o.tolist() if hasattr(o, "tolist") else
                                 str(o)))


@dataclass(frozen=True, eq=False)
class ArmsToolpath:
    """A program for several arms (module docstring): `arms` ((name, one-arm `Toolpath`), ...)
    whose waypoints line up, `sync` the waypoints where all arms wait for each other, `extra` the
    shared top-level keys (holds, placement, units, cycle time, lockstep)."""

    cell: str
    cell_sha256: str
    source: dict
    arms: tuple[tuple[str, Toolpath], ...]
    sync: tuple[int, ...]
    extra: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "source", _plain(self.source))
        set_(self, "extra", _plain(self.extra))
        set_(self, "sync", tuple(int(i) for i in self.sync))
        set_(self, "arms", tuple((str(n), tp) for n, tp in self.arms))

    @property
    def arm_names(self) -> tuple[str, ...]:
        return tuple(n for n, _ in self.arms)

    def arm(self, name: str) -> Toolpath:
        """Arm `name`'s program as a one-arm toolpath (with the shared keys)."""
        for n, tp in self.arms:
            if n == name:
                return tp
        raise KeyError(name)

    def __len__(self) -> int:
        return len(self.arms[0][1])

    @property
    def robot(self) -> str:
        """The arms' robot models joined by '+' (e.g. "ur10e+ur10e")."""
        return "+".join(tp.robot for _, tp in self.arms)

    @property
    def fold_sha256(self) -> str | None:
        s = self.source.get("sha256") if isinstance(self.source, dict) else None
        return s if isinstance(s, str) and len(s) == 64 else None

    @property
    def sha256(self) -> str:
        return document_sha256(self.to_json(with_hash=False))

    def to_json(self, with_hash: bool = True) -> dict:
        arms = []
        for name, tp in self.arms:
            entry = {"name": name, "robot": tp.robot, "tcp": list(tp.tcp),
                     "waypoints": [w.to_json() for w in tp.waypoints]}
            for k in ARM_EXTRA:
                if k in tp.extra:
                    entry[k] = copy.deepcopy(tp.extra[k])
            arms.append(entry)
        d = {"format": FORMAT, "cell": self.cell, "cell_sha256": self.cell_sha256,
             "source": copy.deepcopy(self.source), "arms": arms, "sync": list(self.sync)}
        return finish_document(d, self.extra, with_hash)

    @classmethod
    def build(cls, cell: str, cell_sha256: str, source: dict, arms, sync, extra: dict) -> "ArmsToolpath":
        """From per-arm toolpaths planned separately: each arm keeps its `ARM_EXTRA` keys and gets
        the shared `extra` keys (validated as a document would be)."""
        views = []
        for name, tp in arms:
            own = {k: v for k, v in tp.extra.items() if k in ARM_EXTRA}
            views.append((name, Toolpath(robot=tp.robot, cell=cell, tcp=tp.tcp, source=source,
                                         waypoints=tp.waypoints, extra={**extra, **own}, cell_sha256=cell_sha256)))
        out = cls(cell=cell, cell_sha256=cell_sha256, source=source, arms=tuple(views), sync=tuple(sync),
                  extra=extra)
        return cls.from_json(out.to_json(), source="planned program")

    @classmethod
    def from_json(cls, d: Any, source: str | None = None) -> "ArmsToolpath":
        """Validate and read a `/3` document; `InputError` naming the key on any problem."""
        def fail(msg):
            raise InputError(msg, source=source)

        if not isinstance(d, dict) or d.get("format") != FORMAT:
            fail(f"format is {d.get('format') if isinstance(d, dict) else None!r}, expected {FORMAT!r}")
        for key in REQUIRED:
            if key not in d:
                fail(f"{key}: missing")
        if not isinstance(d["arms"], list) or len(d["arms"]) < 2:
            fail("arms: expected a list of at least two arms (a one-arm program is fabkit.toolpath/2)")
        shared = {k: v for k, v in d.items() if k not in ("format", *REQUIRED)}
        arms, names = [], []
        for i, a in enumerate(d["arms"]):
            if not isinstance(a, dict) or any(k not in a for k in ARM_KEYS):
                fail(f"arms[{i}]: expected an object with {', '.join(ARM_KEYS)}")
            name = a["name"]
            if not isinstance(name, str) or not name or name in names:
                fail(f"arms[{i}].name: expected a name used once, got {name!r}")
            names.append(name)
            unknown = [k for k in a if k not in ARM_KEYS + ARM_EXTRA]
            if unknown:
                fail(f"arms[{i}].{unknown[0]}: unknown key")
            one = {"format": ONE_ARM_FORMAT, "robot": a["robot"], "cell": d["cell"], "cell_sha256": d["cell_sha256"],
                   "tcp": a["tcp"], "source": d["source"], "waypoints": a["waypoints"],
                   **shared, **{k: a[k] for k in ARM_EXTRA if k in a}}
            try:
                one["sha256"] = document_sha256(one)
                tp = Toolpath.from_json(one)
            except (InputError, TypeError, ValueError) as exc:
                fail(f"arms[{i}] ({name}): {getattr(exc, 'message', exc)}")
            arms.append((name, tp))
        n = len(arms[0][1])
        for name, tp in arms[1:]:
            if len(tp) != n:
                fail(f"arms: arm {name!r} has {len(tp)} waypoints, arm {names[0]!r} {n}: they must line up")
            for i, (w, w0) in enumerate(zip(tp.waypoints, arms[0][1].waypoints)):
                if (w.op, w.state) != (w0.op, w0.state):
                    fail(f"arms: waypoint {i} is {w.op} in state {w.state} for arm {name!r} and {w0.op} in state "
                         f"{w0.state} for arm {names[0]!r}: the arms' waypoints must line up")
        sync = d["sync"]
        if not (isinstance(sync, list) and all(isinstance(i, int) and not isinstance(i, bool) and 0 < i < n
                                               for i in sync) and sync == sorted(set(sync))):
            fail(f"sync: expected increasing waypoint indices in 1..{n - 1}")
        out = cls(cell=str(d["cell"]), cell_sha256=d["cell_sha256"], source=d["source"], arms=tuple(arms),
                  sync=tuple(sync), extra=shared)
        if d["sha256"] != out.sha256:
            fail("sha256 does not match the document (the file was edited after planning)")
        return out

    save = Toolpath.save  # PATH.json written atomically, as a one-arm toolpath is


def toolpath_from_json(d: Any, source: str | None = None):
    """A `Toolpath` (`fabkit.toolpath/2`) or an `ArmsToolpath` (`/3`) from a PATH.json document;
    any other format is refused (one line)."""
    fmt = d.get("format") if isinstance(d, dict) else None
    if fmt == FORMAT:
        return ArmsToolpath.from_json(d, source=source)
    if fmt == ONE_ARM_FORMAT or fmt in OLD_FORMATS:
        return Toolpath.from_json(d, source=source)
    raise InputError(f"format is {fmt!r}: fabkit reads {ONE_ARM_FORMAT!r} (one arm) and {FORMAT!r} (several arms)",
                     source=source)


def load_toolpath(path: str | Path):
    """Read PATH.json of either format (`toolpath_from_json`), with the coordinate checks of
    `Toolpath.load` for every arm."""
    from fabkit.io.validate import check_coordinates

    d = load_json(path, "JSON toolpath", missing="toolpath file not found")
    tp = toolpath_from_json(d, source=str(path))
    for _, one in (tp.arms if isinstance(tp, ArmsToolpath) else (("a", tp),)):
        check_coordinates([w.pose[:3] for w in one.waypoints], str(path), "waypoint")
    return tp
