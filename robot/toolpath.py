"""PATH.json: the toolpath file format, its typed records and the hash that identifies it.

A toolpath (`fabkit.toolpath/2`) is `{"format", "robot", "cell", "cell_sha256", "tcp", "source",
"waypoints": [{"pose", "q", "move", "v", "a", "r", "state", "op"}], "sha256", ...}` plus additive
keys (`units`, `grip` (output, kind, dwell times, face), `cycle_time_s`, `checks`). Poses are TCP
poses in the robot base frame ([x, y, z, rx, ry, rz], m and rotation vector rad); `q` in rad;
movel v/a in m/s, m/s^2, movej v/a in rad/s, rad/s^2; r in m. `source` names the FOLD file the
fold states came from and its sha256; `cell_sha256` is the sha256 of the cell file's bytes.

`sha256` hashes everything that decides motion: the canonical JSON of the whole document except
`sha256` itself (`json.dumps(doc, sort_keys=True, separators=(",", ":"))`, floats as Python repr,
numbers normalised to the record types below). Editing any key - the TCP, the gripper output, the
robot, the cell hash, the FOLD hash, any waypoint field, the motion parameters - changes it. An
older `fabkit.toolpath/1` file, whose hash covered the waypoints only, is refused: re-plan it.

Waypoints are frozen `Waypoint` records (tuples inside), so a planned toolpath cannot change in
memory between the check and the send; `source` and the extra keys are deep copies, and the
hash is recomputed from the document every time it is asked for.

The planner lives in `robot.planner`; its public names are also reachable from here.
"""
from __future__ import annotations

import copy
import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fabkit.errors import InputError
from fabkit.io.jsonfile import load_json
from robot import kinematics as K

__all__ = ["FORMAT", "OLD_FORMATS", "OPS", "MOVES", "Waypoint", "Toolpath", "canonical_json", "document_sha256",
           "fold_file_of",
           "PlanOptions", "PlanningError", "PlanResult", "grip_offset", "tcp_targets", "plan_toolpath", "plan_panel",
           "check_toolpath_kinematics"]

FORMAT = "fabkit.toolpath/2"
OLD_FORMATS = ("fabkit.toolpath/1",)
OPS = ("home", "approach", "grip", "fold", "release", "retract")
MOVES = ("movej", "movel")
WAYPOINT_KEYS = ("pose", "q", "move", "v", "a", "r", "state", "op")
REQUIRED_KEYS = ("robot", "cell", "cell_sha256", "tcp", "source", "waypoints", "sha256")
#: Bounds past which a number is bad input rather than a motion to check (m, rad, SI rates).
MAX_POSITION_M = 10.0
MAX_ROTATION_RAD = 4 * math.pi
MAX_JOINT_RAD = 4 * math.pi
MAX_RATE = 1000.0


def canonical_json(doc: dict) -> str:
    """The canonical JSON text the toolpath hash is taken over (sorted keys, no spaces, float repr)."""
    return json.dumps(doc, sort_keys=True, separators=(",", ":"), allow_nan=False)


def finish_document(d: dict, extra: dict, with_hash: bool) -> dict:
    """`d` (a PATH.json document's own keys) with the `extra` records added (copies; `d`'s keys
    win) and, `with_hash`, its whole-document sha256."""
    for k, v in extra.items():
        d.setdefault(k, copy.deepcopy(v))
    if with_hash:
        d["sha256"] = document_sha256(d)
    return d


def document_sha256(doc: dict) -> str:
    """sha256 of a PATH.json document without its `sha256` key."""
    body = {k: v for k, v in doc.items() if k != "sha256"}
    return hashlib.sha256(canonical_json(body).encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class Waypoint:
    """One waypoint (module docstring for units). Read-only; `w["q"]` reads a field by its
    PATH.json key."""

    pose: tuple[float, ...]
    q: tuple[float, ...]
    move: str
    v: float
    a: float
    r: float
    state: int
    op: str

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "pose", tuple(float(x) for x in np.asarray(self.pose, dtype=np.float64).reshape(-1)))
        set_(self, "q", tuple(float(x) for x in np.asarray(self.q, dtype=np.float64).reshape(-1)))
        set_(self, "move", str(self.move))
        set_(self, "op", str(self.op))
        for k in ("v", "a", "r"):
            set_(self, k, float(getattr(self, k)))
        set_(self, "state", int(self.state))

    def __getitem__(self, key: str):
        if key not in WAYPOINT_KEYS:
            raise KeyError(key)
        return getattr(self, key)

    def to_json(self) -> dict:
        return {"pose": list(self.pose), "q": list(self.q), "move": self.move, "v": self.v, "a": self.a,
                "r": self.r, "state": self.state, "op": self.op}

    @classmethod
    def of(cls, w: "Waypoint | dict") -> "Waypoint":
        return w if isinstance(w, Waypoint) else cls(**{k: w[k] for k in WAYPOINT_KEYS})


def _plain(value):
    """A JSON value as plain Python data (deep copy; numpy scalars and arrays become numbers/lists)."""
    return json.loads(json.dumps(value, allow_nan=False, default=lambda o: o.tolist() if hasattr(o, "tolist") else
                                 str(o)))


@dataclass(frozen=True, eq=False)
class Toolpath:
    """A planned toolpath (module docstring): robot model, cell name and cell file hash, TCP in the
    flange frame ([6] UR pose), `source` (the FOLD file and its hash), waypoints (`Waypoint`), and
    the additive top-level keys (`extra`: units, grip output, cycle time, checks)."""

    robot: str
    cell: str
    tcp: tuple[float, ...]
    source: dict
    waypoints: tuple[Waypoint, ...]
    extra: dict = field(default_factory=dict)
    cell_sha256: str = ""

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "waypoints", tuple(Waypoint.of(w) for w in self.waypoints))
        set_(self, "tcp", tuple(float(x) for x in self.tcp))
        set_(self, "source", _plain(self.source))
        set_(self, "extra", _plain(self.extra))

    @property
    def sha256(self) -> str:
        """The hash over the whole document (recomputed on every call: nothing escapes it)."""
        return document_sha256(self.to_json(with_hash=False))

    def __len__(self) -> int:
        return len(self.waypoints)

    @property
    def poses(self) -> np.ndarray:
        return np.array([w.pose for w in self.waypoints]).reshape(-1, 6)

    @property
    def joints(self) -> np.ndarray:
        return np.array([w.q for w in self.waypoints]).reshape(-1, 6)

    @property
    def grip(self) -> dict | None:
        """The gripper record (`output`, `kind`, dwell times), or None for a toolpath without one."""
        g = self.extra.get("grip")
        return copy.deepcopy(g) if isinstance(g, dict) and "output" in g else None

    @property
    def fold_sha256(self) -> str | None:
        """The source FOLD file's sha256 as recorded at planning, or None."""
        s = self.source.get("sha256") if isinstance(self.source, dict) else None
        return s if isinstance(s, str) and len(s) == 64 else None

    def to_json(self, with_hash: bool = True) -> dict:
        d = {"format": FORMAT, "robot": self.robot, "cell": self.cell, "cell_sha256": self.cell_sha256,
             "tcp": list(self.tcp), "source": copy.deepcopy(self.source),
             "waypoints": [w.to_json() for w in self.waypoints]}
        return finish_document(d, self.extra, with_hash)

    @classmethod
    def from_json(cls, d: Any, source: str | None = None) -> "Toolpath":
        """Validate and read a PATH.json document; `InputError` (naming the key) on any problem,
        including a `sha256` that does not match the document and an older format."""
        def fail(msg):
            raise InputError(msg, source=source)

        if not isinstance(d, dict):
            fail("not a toolpath: expected a JSON object")
        if d.get("format") in OLD_FORMATS:
            fail(f"format {d['format']} is an older toolpath whose hash does not cover the TCP, cell and "
                 "gripper: re-plan it with `fabkit toolpath`")
        if d.get("format") != FORMAT:
            fail(f"format is {d.get('format')!r}, expected {FORMAT!r}")
        for key in REQUIRED_KEYS:
            if key not in d:
                fail(f"{key}: missing")
        if not isinstance(d["robot"], str) or d["robot"] not in K.MODELS:
            fail(f"robot: {d['robot']!r} is not one of {', '.join(K.MODELS)}")
        if not (isinstance(d["tcp"], list) and len(d["tcp"]) == 6 and all(_is_num(x) for x in d["tcp"])
                and all(abs(x) <= MAX_POSITION_M for x in d["tcp"])):
            fail("tcp: expected 6 finite numbers")
        if not isinstance(d["source"], dict):
            fail("source: expected an object")
        if not isinstance(d["cell"], str):
            fail("cell: expected a string")
        if not (isinstance(d["cell_sha256"], str) and len(d["cell_sha256"]) == 64):
            fail("cell_sha256: expected the 64-digit sha256 of the cell file")
        if not isinstance(d["waypoints"], list) or not d["waypoints"]:
            fail("waypoints: expected a non-empty list")
        for i, w in enumerate(d["waypoints"]):
            _check_waypoint(w, i, fail)
        extra = {k: v for k, v in d.items() if k not in ("format", *REQUIRED_KEYS)}
        try:
            tp = cls(robot=d["robot"], cell=str(d["cell"]), tcp=tuple(d["tcp"]), source=d["source"],
                     waypoints=tuple(Waypoint.of(w) for w in d["waypoints"]), extra=extra,
                     cell_sha256=d["cell_sha256"])
        except ValueError as exc:  # non-finite numbers in the extra keys
            fail(f"not valid toolpath data: {exc}")
        if d["sha256"] != tp.sha256:
            fail("sha256 does not match the document (the file was edited after planning)")
        return tp

    def save(self, path: str | Path) -> None:
        """Write PATH.json atomically."""
        from fabkit.io.atomic import atomic_write

        with atomic_write(path) as fh:
            json.dump(self.to_json(), fh, indent=1, allow_nan=False)
            fh.write("\n")

    @classmethod
    def load(cls, path: str | Path) -> "Toolpath":
        from fabkit.io.validate import check_coordinates

        d = load_json(path, "JSON toolpath", missing="toolpath file not found")
        tp = cls.from_json(d, source=str(path))
        check_coordinates([w.pose[:3] for w in tp.waypoints], str(path), "waypoint")
        return tp


def _is_num(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _check_waypoint(w, i, fail) -> None:
    where = f"waypoints[{i}]"
    if not isinstance(w, dict):
        fail(f"{where}: expected an object")
    for k in WAYPOINT_KEYS:
        if k not in w:
            fail(f"{where}.{k}: missing")
    for k in ("pose", "q"):
        if not (isinstance(w[k], list) and len(w[k]) == 6 and all(_is_num(x) for x in w[k])):
            fail(f"{where}.{k}: expected 6 finite numbers")
    if any(abs(x) > MAX_POSITION_M for x in w["pose"][:3]) or math.hypot(*w["pose"][3:]) > MAX_ROTATION_RAD:
        fail(f"{where}.pose: {w['pose']} is not a TCP pose near a robot (more than {MAX_POSITION_M:g} m or "
             "4 pi rad)")
    if any(abs(x) > MAX_JOINT_RAD for x in w["q"]):
        fail(f"{where}.q: {w['q']} has a joint beyond 4 pi rad")
    if not isinstance(w["move"], str) or w["move"] not in MOVES:
        fail(f"{where}.move: {w['move']!r} is not movej or movel")
    if not isinstance(w["op"], str) or w["op"] not in OPS:
        fail(f"{where}.op: {w['op']!r} is not one of {', '.join(OPS)}")
    for k in ("v", "a"):
        if not (_is_num(w[k]) and 0 < w[k] <= MAX_RATE):
            fail(f"{where}.{k}: expected a positive number (at most {MAX_RATE:g})")
    if not (_is_num(w["r"]) and 0 <= w["r"] <= MAX_RATE):
        fail(f"{where}.r: expected a number >= 0")
    if not (isinstance(w["state"], int) and not isinstance(w["state"], bool) and w["state"] >= 0):
        fail(f"{where}.state: expected an integer >= 0")


def fold_file_of(tp: Toolpath, base_dir: str | Path | None = None) -> Path | None:
    """The FOLD file a toolpath's `source` names (a string value ending in .fold), resolved against
    `base_dir` (the PATH.json's folder) when relative and there; None if the source names none."""
    src = tp.source
    values = [src] if isinstance(src, str) else list(src.values()) if isinstance(src, dict) else []
    for v in values:
        if isinstance(v, str) and v.lower().endswith(".fold"):
            p = Path(v)
            if not p.is_absolute() and base_dir is not None and (Path(base_dir) / p).exists():
                return Path(base_dir) / p
            return p
    return None


_PLANNER_NAMES = ("PlanOptions", "PlanningError", "PlanResult", "grip_offset", "tcp_targets", "plan_toolpath",
                  "plan_panel", "check_toolpath_kinematics")


def __getattr__(name: str):
    """The planner's public names (`robot.planner`; `plan_panel` from `robot.grip_choice`), loaded on
    first use (they import this module)."""
    if name in _PLANNER_NAMES:
        from robot import grip_choice, planner

        return getattr(grip_choice if name == "plan_panel" else planner, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

