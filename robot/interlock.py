"""The send interlock: nothing reaches the controller that was not checked as it is.

`clear_for_send(toolpath, check, cell)` runs before any connection is opened and raises
`InterlockError` (one line naming what differs) unless all of these hold:

1. the check report is a complete `fabkit.check/2` record that passed: `ok` true and no problems
   listed (`CheckFailedError` for a report that says it failed);
2. one toolpath, one cell, one FOLD: the toolpath's hash (recomputed from the document) equals the
   report's; the cell file's sha256 (recomputed from the file on disk when the cell came from one)
   equals the toolpath's and the report's; robot model and cell name agree; the FOLD file the
   toolpath was planned from still has the sha256 recorded in the toolpath and in the report;
3. defence in depth, whatever the hashes say: every joint target inside the robot's joint range,
   every speed, acceleration and blend radius inside the cell's limits, and the TCP and gripper
   output those of the cell;
4. the check itself, run again here on the exact toolpath, cell and FOLD about to be sent
   (`sim.check.check_toolpath`), passes and agrees with the report.

A program for several arms (`robot.arms_toolpath.ArmsToolpath`) goes through the same steps: its
hash covers every arm, the limits hold for every arm in the cell as that arm sees it, and the
check run again is the all-arms check (`sim.check_arms`).

Step 4 makes `robot` import `sim` (lazily, here only): the sender must not trust a report it can
recompute, and the check is MuJoCo's. `verify_start` is where the arm must stand before a send
(checked before anything on the controller is changed).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from robot.cell import Cell, file_sha256, pose_to_matrix
from robot.path_chunks import SendError, point_segment_distance_nd
from robot.toolpath import Toolpath, fold_file_of

__all__ = ["CHECK_FORMAT", "CHECK_KEYS", "InterlockError", "CheckFailedError", "Cleared", "clear_for_send",
           "limit_problems", "program_limit_problems", "verify_start", "StartTolerances"]

CHECK_FORMAT = "fabkit.check/2"
CHECK_KEYS = ("format", "toolpath_sha256", "cell_sha256", "fold", "ok", "problems", "robot", "cell", "waypoints")
#: Relative slack on the cell's limits (the planner caps at exactly the limit).
LIMIT_SLACK = 1e-9


class InterlockError(SendError):
    """The toolpath, cell, FOLD file and check report do not belong together; nothing was sent."""


class CheckFailedError(InterlockError):
    """The check report says the toolpath failed its check."""


@dataclass(frozen=True, eq=False)
class Cleared:
    """What passed the interlock: a private copy of the toolpath (made from the hashed document),
    its hash, the cell, the FOLD file and its hash, and how long the re-check took (s)."""

    toolpath: Toolpath
    sha256: str
    cell: Cell
    fold_path: Path | None
    fold_sha256: str | None
    recheck_s: float


def _short(h) -> str:
    return f"{str(h)[:12]}…" if isinstance(h, str) and len(h) > 12 else repr(h)


def check_record(check) -> dict:
    """The report as a dict (a `sim.check.CheckReport` or parsed CHECK.json); `InterlockError` if
    it is not a complete `fabkit.check/2` record."""
    if hasattr(check, "to_json"):
        check = check.to_json()
    if not isinstance(check, dict):
        raise InterlockError("the check report is not a JSON object")
    if check.get("format") != CHECK_FORMAT:
        raise InterlockError(f"the check report's format is {check.get('format')!r}, expected {CHECK_FORMAT!r} "
                             "(re-run `fabkit check`)")
    missing = [k for k in CHECK_KEYS if k not in check]
    if missing:
        raise InterlockError(f"the check report lacks {', '.join(missing)} (not a report `fabkit check` wrote)")
    if not isinstance(check["ok"], bool) or not isinstance(check["problems"], list):
        raise InterlockError("the check report's ok/problems are not a boolean and a list")
    return check


def limit_problems(tp: Toolpath, cell: Cell) -> list[str]:
    """Every way `tp` breaks the cell's limits or does not fit its robot and tool (empty: none)."""
    out = []
    lim, model = cell.limits, cell.model
    if tp.robot != model.name:
        out.append(f"the toolpath is for a {tp.robot}, the cell has a {model.name}")
    if not np.allclose(pose_to_matrix(tp.tcp), cell.tool.tcp, atol=1e-9):
        out.append(f"the toolpath's TCP {list(tp.tcp)} is not the cell's tool TCP")
    g = tp.grip
    if g is not None and (int(g.get("output", -1)) != cell.tool.grip_output
                          or str(g.get("kind", "tool")) != cell.tool.grip_output_kind):
        out.append(f"gripper output {g.get('kind')} {g.get('output')} is not the cell's "
                   f"{cell.tool.grip_output_kind} {cell.tool.grip_output}")
    lo, hi = np.asarray(model.q_min), np.asarray(model.q_max)
    vj = float(min(lim.joint_speed))
    up = 1 + LIMIT_SLACK
    for i, w in enumerate(tp.waypoints):
        q = np.asarray(w.q)
        bad = np.flatnonzero((q < lo) | (q > hi))
        if len(bad):
            j = int(bad[0])
            out.append(f"waypoint {i}: joint {j + 1} target {q[j]:.6g} rad outside the joint range "
                       f"[{lo[j]:.6g}, {hi[j]:.6g}]")
        if w.move == "movel":
            if w.v > lim.tcp_speed * up:
                out.append(f"waypoint {i}: TCP speed {w.v:.6g} m/s over the cell limit {lim.tcp_speed:.6g} m/s")
            if w.a > lim.tcp_accel * up:
                out.append(f"waypoint {i}: TCP acceleration {w.a:.6g} m/s^2 over the cell limit "
                           f"{lim.tcp_accel:.6g} m/s^2")
        else:
            if w.v > vj * up:
                out.append(f"waypoint {i}: joint speed {w.v:.6g} rad/s over the cell limit {vj:.6g} rad/s")
            if w.a > lim.joint_accel * up:
                out.append(f"waypoint {i}: joint acceleration {w.a:.6g} rad/s^2 over the cell limit "
                           f"{lim.joint_accel:.6g} rad/s^2")
        if w.r > lim.blend_radius * up:
            out.append(f"waypoint {i}: blend radius {w.r:.6g} m over the cell limit {lim.blend_radius:.6g} m")
    return out


def program_limit_problems(tp, cell: Cell) -> list[str]:
    """`limit_problems` of a one-arm toolpath, or of every arm of a program for several arms (each
    in the cell as it sees it, `robot.arm_cells.arm_cell`; messages start with the arm)."""
    if not hasattr(tp, "arms"):
        return limit_problems(tp, cell)
    from robot.arm_cells import arm_cell, arm_names

    if tuple(arm_names(cell)) != tuple(tp.arm_names):
        return [f"the program is for arms {', '.join(tp.arm_names)}, the cell has {', '.join(arm_names(cell))}"]
    return [f"arm {n}: {p}" for n, one in tp.arms for p in limit_problems(one, arm_cell(cell, n))]


def _fold_of(tp: Toolpath, check: dict, fold, base_dir) -> Path | None:
    """The FOLD file to verify: `fold`, else the report's, else the one the toolpath's source names."""
    if fold is not None:
        return Path(fold)
    if isinstance(check.get("fold"), dict) and isinstance(check["fold"].get("path"), str):
        if Path(check["fold"]["path"]).is_file():
            return Path(check["fold"]["path"])
    return fold_file_of(tp, base_dir)


def clear_for_send(toolpath: Toolpath, check, cell: Cell, *, fold: str | Path | None = None,
                   base_dir: str | Path | None = None) -> Cleared:
    """Run the interlock (module docstring); returns what may be sent or raises `InterlockError`."""
    from robot.arms_toolpath import toolpath_from_json

    doc = toolpath.to_json()
    tp = toolpath_from_json(doc, source="toolpath")  # a private copy of exactly the hashed document
    sha = doc["sha256"]
    rep = check_record(check)
    if not rep["ok"]:
        probs = [p for p in rep["problems"] if isinstance(p, dict)]
        first = probs[0] if probs else {}
        raise CheckFailedError(f"the check reports {len(rep['problems'])} problem(s)"
                               + (f", first at waypoint {first.get('waypoint')}: {first.get('kind')} "
                                  f"{first.get('detail', '')}" if first else ""))
    if rep["problems"]:
        raise InterlockError(f"the check says ok but lists {len(rep['problems'])} problem(s): not a report "
                             "`fabkit check` wrote")
    if rep["toolpath_sha256"] != sha:
        raise InterlockError(f"the check's toolpath_sha256 {_short(rep['toolpath_sha256'])} does not match the "
                             f"toolpath ({_short(sha)}): this check was made for another toolpath")
    if cell.source and Path(cell.source).is_file():
        now = file_sha256(cell.source)
        if now != cell.sha256:
            raise InterlockError(f"the cell file {cell.source} changed since it was loaded ({_short(cell.sha256)} "
                                 f"-> {_short(now)})")
    if tp.cell_sha256 != cell.sha256:
        raise InterlockError(f"the toolpath was planned in a cell file with sha256 {_short(tp.cell_sha256)}, "
                             f"this cell file {cell.source} has {_short(cell.sha256)} (re-plan and re-check)")
    if rep["cell_sha256"] != cell.sha256:
        raise InterlockError(f"the check was made in a cell file with sha256 {_short(rep['cell_sha256'])}, this "
                             f"cell file {cell.source} has {_short(cell.sha256)} (re-check)")
    if rep["robot"] != tp.robot or rep["cell"] != cell.name or tp.cell != cell.name:
        raise InterlockError(f"the check is for a {rep['robot']} in cell {rep['cell']!r}, the toolpath for a "
                             f"{tp.robot} in {tp.cell!r}, the cell is {cell.name!r}")
    if rep["waypoints"] != len(tp):
        raise InterlockError(f"the check covers {rep['waypoints']} waypoints, the toolpath has {len(tp)}")
    fold_path = _fold_of(tp, rep, fold, base_dir)
    fold_sha = None
    want = tp.fold_sha256
    checked = rep["fold"].get("sha256") if isinstance(rep["fold"], dict) else None
    if fold_path is not None:
        if not fold_path.is_file():
            raise InterlockError(f"the FOLD file {fold_path} the toolpath was planned from is not there")
        fold_sha = file_sha256(fold_path)
    if want is not None and fold_sha != want:
        raise InterlockError(f"the FOLD file {fold_path} has sha256 {_short(fold_sha)}, the toolpath was planned "
                             f"from {_short(want)} (the fold states changed)")
    if checked != fold_sha:
        raise InterlockError(f"the check used a FOLD file with sha256 {_short(checked)}, the toolpath's FOLD file "
                             f"{fold_path} has {_short(fold_sha)}")
    broken = program_limit_problems(tp, cell)
    if broken:
        more = f" (and {len(broken) - 1} more)" if len(broken) > 1 else ""
        raise InterlockError(f"{broken[0]}{more}")
    from sim.check import check_toolpath  # imported once per process, not counted as the check's time

    t0 = time.perf_counter()
    again = check_toolpath(tp, cell, fold=fold_path, use_panel=fold_path is not None)
    dt = time.perf_counter() - t0
    if not again.ok:
        p = again.problems[0]
        raise InterlockError(f"the check run again before sending finds {len(again.problems)} problem(s), first at "
                             f"waypoint {p.waypoint}: {p.kind} {p.detail}")
    if again.toolpath_sha256 != sha or again.cell_sha256 != cell.sha256 or \
            (again.fold or {}).get("sha256") != fold_sha:
        raise InterlockError("the check run again before sending does not agree with the report's hashes")
    return Cleared(toolpath=tp, sha256=sha, cell=cell, fold_path=fold_path, fold_sha256=fold_sha, recheck_s=dt)


@dataclass(frozen=True)
class StartTolerances:
    """How close the arm must be to the path before a send starts or resumes: TCP position (m),
    tool orientation (rad) and joints (rad). A resume also stays under a quarter of the segment
    into the resume waypoint, so one waypoint off is always told apart."""

    position_m: float = 0.0005
    rotation_rad: float = 0.005
    joint_rad: float = 0.01


def verify_start(wps, k: int, q, tcp_pose, tol: StartTolerances = StartTolerances()) -> None:
    """`SendError` unless the arm (joints `q`, TCP `tcp_pose`) is where a send from waypoint `k` may
    start: at waypoint 0 for a fresh start; on the segment into waypoint `k` for a resume (position
    and orientation along a movel, within blend allowances; joints along a movej)."""
    q = np.asarray(q, dtype=np.float64)
    if k == 0:
        off = np.abs(q - np.asarray(wps[0].q))
        if off.max() > tol.joint_rad:
            j = int(np.argmax(off))
            raise SendError(f"the arm is not at waypoint 0 (joint {j + 1} is {off[j]:.4f} rad away): move it there "
                            f"first (the check did not cover a move from here)")
        return
    a, b = wps[k - 1], wps[k]
    where = f"--resume-from {k}"
    if b.move == "movej":
        d = point_segment_distance_nd(q, a.q, b.q)
        if d > tol.joint_rad:
            raise SendError(f"{where}: the joints are {d:.4f} rad from the joint move between waypoints {k - 1} "
                            f"and {k} (allowed {tol.joint_rad} rad); move the arm there first")
        return
    p = np.asarray(tcp_pose[:3], dtype=np.float64)
    ends = min(_pieces_into(wps, k), key=lambda piece: _piece_distance(p, piece))
    d, t = _piece_distance(p, ends), _piece_t(p, ends)
    # a blended corner leaves the polyline by at most r sin(turn / 2)
    allow = tol.position_m + _blend_offset(wps, k - 1)
    length = float(np.linalg.norm(np.subtract(b.pose[:3], a.pose[:3])))
    if length > 0:
        allow = min(allow, 0.25 * length)
    if d > allow:
        raise SendError(f"{where}: the TCP is {d * 1e3:.2f} mm from the path into waypoint {k} (allowed "
                        f"{allow * 1e3:.2f} mm); give the waypoint after the last completed one, or move the arm "
                        "there first")
    (_, Ra, qa), (_, Rb, qb) = ends
    expect = Slerp([0.0, 1.0], Rotation.concatenate([Ra, Rb]))([t])[0]
    ang = float((expect.inv() * Rotation.from_rotvec(np.asarray(tcp_pose[3:], dtype=np.float64))).magnitude())
    allow_rad = tol.rotation_rad + _blend_turn(wps, k - 1)
    if ang > allow_rad:
        raise SendError(f"{where}: the tool is turned {math.degrees(ang):.2f}° from the path into waypoint {k} "
                        f"(allowed {math.degrees(allow_rad):.2f}°); move the arm there first")
    dq = float(np.max(np.abs(q - (qa + t * (qb - qa)))))
    if dq > tol.joint_rad + 0.25 * float(np.max(np.abs(np.subtract(b.q, a.q)))):
        raise SendError(f"{where}: the joints are {dq:.3f} rad from the path into waypoint {k} (another arm "
                        "configuration?); move the arm there first")


def _end(w) -> tuple:
    return np.asarray(w.pose[:3], dtype=np.float64), Rotation.from_rotvec(w.pose[3:]), np.asarray(w.q)


def _pieces_into(wps, k: int) -> list:
    """The stretches of path the arm may be on when the controller has begun the move into waypoint
    k: the segment k-1 -> k, and, when waypoint k-1 is blended, the last r of the segment into it
    (the blend begins there, and with it the move into k). Each piece is ((p, R, q), (p, R, q))."""
    a, b = _end(wps[k - 1]), _end(wps[k])
    pieces = [(a, b)]
    if k >= 2 and wps[k - 1].r > 0 and wps[k - 1].move == "movel":
        z = _end(wps[k - 2])
        length = float(np.linalg.norm(a[0] - z[0]))
        if length > 0:
            s = max(0.0, 1.0 - wps[k - 1].r / length)
            start = (z[0] + s * (a[0] - z[0]), Slerp([0.0, 1.0], Rotation.concatenate([z[1], a[1]]))([s])[0],
                     z[2] + s * (a[2] - z[2]))
            pieces.append((start, a))
    return pieces


def _piece_t(p, piece) -> float:
    (pa, _, _), (pb, _, _) = piece
    seg = pb - pa
    n2 = float(np.dot(seg, seg))
    return 0.0 if n2 == 0 else float(np.clip(np.dot(p - pa, seg) / n2, 0.0, 1.0))


def _piece_distance(p, piece) -> float:
    (pa, _, _), (pb, _, _) = piece
    return float(np.linalg.norm(p - (pa + _piece_t(p, piece) * (pb - pa))))


def _blend_turn(wps, i: int) -> float:
    """How far a blend at waypoint i can turn the tool off the piecewise slerp (rad): the rotation
    over the blend's length on either side; 0 without a blend."""
    if i <= 0 or i >= len(wps) - 1 or wps[i].r <= 0:
        return 0.0
    out = 0.0
    for j, k in ((i - 1, i), (i, i + 1)):
        length = float(np.linalg.norm(np.subtract(wps[k].pose[:3], wps[j].pose[:3])))
        turn = (Rotation.from_rotvec(wps[j].pose[3:]).inv() * Rotation.from_rotvec(wps[k].pose[3:])).magnitude()
        out += float(turn) * min(1.0, wps[i].r / length) if length > 0 else 0.0
    return out


def _blend_offset(wps, i: int) -> float:
    """How far a blend at waypoint i can leave the polyline (m): r sin(turn / 2); 0 at the ends."""
    if i <= 0 or i >= len(wps) - 1 or wps[i].r <= 0:
        return 0.0
    u = np.subtract(wps[i].pose[:3], wps[i - 1].pose[:3])
    v = np.subtract(wps[i + 1].pose[:3], wps[i].pose[:3])
    nu, nv = np.linalg.norm(u), np.linalg.norm(v)
    if nu == 0 or nv == 0:
        return 0.0
    turn = math.acos(float(np.clip(np.dot(u, v) / (nu * nv), -1.0, 1.0)))
    return float(wps[i].r * math.sin(turn / 2))
