"""Fold loads against what the arm and the vacuum cup are rated for, per fold state.

For every crease the arm folds in a state, the fold moment M (`fabkit.sheet.loads.fold_moment`,
the high end of the range: plane strain with the flow stress) must come from the wrench the arm
applies at the grip, at lever arm d from the crease. Two extremes are checked, since a
position-controlled arm's split between them depends on the pose:

- couple: the wrist turns the gripped face about the crease, M as a couple through one wrist joint
  (compared with the wrist rating: UR5e 28 N m, UR10e 54 N m);
- force: F = M / d at the grip, plus the payload's weight, against the rated payload's weight
  (UR5e 5 kg, UR10e 10 kg), and, when the cup has to pull (the face folds away from the cup),
  against the pad's usable holding force; pushing is contact in compression and needs no vacuum.

When the cup pulls, the pad's lips also carry the fold as a tilt: the sheet turns about the crease
relative to the rigid pad, and M must stay within the pad's moment of resistance about the crease
(`fabkit.sheet.pad.CupPad.moment_capacity` at lever d, worst pad orientation: the cups' holding
forces times their lever arms, the lip farthest from the crease lifting first).
The pad is the cell's `[tool.pad]`, else one cup of the `suction_cup` shape's diameter.

In a two-arm program each arm carries the creases between the clamp and its grip that no other
arm's grip lies before (`toolpath_loads(other_grips=)`), with its own share of the panel as payload
(`robot.arms_sheet`).

A failed check names the crease, the state and the remedy (groove the crease to a ligament that
fits, a bigger arm, push instead of pull, a bigger pad, two arms). Not modelled: the arm's own
link weights and the dynamic loads of acceleration (the ratings include them at the catalogue's
conditions), friction in the fixture.
`joint_torques` gives the static joint torques of a wrench at a pose (J^T w) for a closer look.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fabkit.sheet.loads import GRAVITY, PLANE_STRAIN, FoldMoment, VacuumCup
from fabkit.sheet.pad import CupPad, single_cup_pad
from robot.kinematics import fk_frames

__all__ = ["ArmRating", "ARM_RATINGS", "arm_rating", "CreaseLoad", "LoadVerdict", "LoadReport", "check_fold_loads",
           "joint_torques", "cup_of_cell", "pad_of_cell", "ligament_for_moment", "payload_record", "toolpath_loads"]


@dataclass(frozen=True)
class ArmRating:
    """Catalogue ratings: `payload` [kg], joint torques [N m] (base, shoulder, elbow, wrists 1-3)."""

    model: str
    payload: float
    joint_torques: tuple[float, ...]

    @property
    def wrist_torque(self) -> float:
        return min(self.joint_torques[3:])


#: UR e-Series ratings (UR manuals; Universal_Robots_ROS2_Description joint_limits.yaml, tag 2.4.5).
ARM_RATINGS = {
    "ur5e": ArmRating("ur5e", 5.0, (150.0, 150.0, 150.0, 28.0, 28.0, 28.0)),
    "ur10e": ArmRating("ur10e", 10.0, (330.0, 330.0, 150.0, 54.0, 54.0, 54.0)),
}


def arm_rating(model: str) -> ArmRating:
    try:
        return ARM_RATINGS[str(model).lower()]
    except KeyError:
        raise ValueError(f"no ratings for robot model {model!r} (known: {', '.join(ARM_RATINGS)})") from None


def cup_of_cell(cell, vacuum: float = 60e3, safety: float = 2.5) -> VacuumCup:
    """The cell's vacuum cup: lip diameter twice the tool's `cup_radius` (the lip on the panel, what
    the check's footprint uses) when the cell declares it, else twice the radius of its
    `suction_cup` tool shape (the rigid holder stands for the lip), or of the last cylinder."""
    radius = getattr(cell.tool, "cup_radius", None)
    if radius is not None:
        return VacuumCup(diameter=2 * float(radius), vacuum=vacuum, safety=safety)
    cyl = [s for s in cell.tool.shapes if s.kind == "cylinder"]
    named = [s for s in cyl if "cup" in s.name]
    shape = (named or cyl or [None])[-1]
    if shape is None:
        raise ValueError(f"cell {cell.name} has no cylinder tool shape to take the cup diameter from")
    return VacuumCup(diameter=2 * shape.size[0], vacuum=vacuum, safety=safety)


def pad_of_cell(cell) -> CupPad:
    """The cell's vacuum pad: `[tool.pad]` when declared, else one cup (`cup_of_cell`)."""
    pad = getattr(cell.tool, "pad", None)
    return pad if pad is not None else single_cup_pad(cup_of_cell(cell))


def ligament_for_moment(material, length: float, moment: float) -> float:
    """The ligament t_l [m] whose high fold moment over `length` equals `moment` [N m]."""
    return math.sqrt(4 * moment / (PLANE_STRAIN * material.flow_stress * length))


@dataclass(frozen=True)
class CreaseLoad:
    """One crease the arm folds in a state: its `moment`, lever arm `lever` [m] from the crease to
    the grip point, and whether the cup must `pull` (the face folds away from the cup side)."""

    moment: FoldMoment
    lever: float
    pull: bool = False


@dataclass(frozen=True)
class LoadVerdict:
    """One check in one state: `check` (wrist | payload | cup), `crease`, `demand` and `capacity`
    (N m or N), `ok`, and the `remedy` when not ok."""

    state: int
    crease: str
    check: str
    demand: float
    capacity: float
    unit: str
    ok: bool
    remedy: str = ""

    def text(self) -> str:
        verdict = "ok" if self.ok else f"EXCEEDED; remedy: {self.remedy}"
        return (f"state {self.state}, {self.crease}: {self.check} {self.demand:.1f} {self.unit} of "
                f"{self.capacity:.1f} {self.unit}: {verdict}")


@dataclass(frozen=True)
class LoadReport:
    """Verdicts of every check in every state; `ok` when none is exceeded."""

    arm: ArmRating
    cup: VacuumCup
    payload_mass: float
    verdicts: tuple[LoadVerdict, ...] = field(default_factory=tuple)
    pad: CupPad | None = None

    @property
    def ok(self) -> bool:
        return all(v.ok for v in self.verdicts)

    @property
    def failures(self) -> list[LoadVerdict]:
        return [v for v in self.verdicts if not v.ok]

    def failure_runs(self) -> list[tuple[str, str, list[LoadVerdict]]]:
        """The exceeded checks grouped by crease and check: `(crease, check, verdicts by state)`."""
        seen: dict = {}
        for v in self.failures:
            seen.setdefault((v.crease, v.check), []).append(v)
        return [(crease, check, vs) for (crease, check), vs in seen.items()]

    def failure_lines(self) -> list[str]:
        """One line per crease and exceeded check: its states, the worst demand and the remedy."""
        out = []
        for crease, check, vs in self.failure_runs():
            worst = max(vs, key=lambda v: v.demand)
            out.append(f"load check: {crease}, states {','.join(str(v.state) for v in vs)}: {check} "
                       f"{worst.demand:.1f} {worst.unit} of {worst.capacity:.1f} {worst.unit}; remedy: {worst.remedy}")
        return out

    def summary(self) -> dict:
        return {"ok": self.ok, "arm": self.arm.model, "rated_payload_kg": self.arm.payload,
                "wrist_torque_nm": self.arm.wrist_torque, "cup": self.cup.summary(),
                "pad": (self.pad or single_cup_pad(self.cup)).summary(),
                "payload_kg": self.payload_mass,
                "verdicts": [{"state": v.state, "crease": v.crease, "check": v.check, "demand": v.demand,
                              "capacity": v.capacity, "unit": v.unit, "ok": v.ok, "remedy": v.remedy}
                             for v in self.verdicts],
                "problems": [v.text() for v in self.failures]}


def _floor(x: float, step: float) -> float:
    return math.floor(x / step + 1e-9) * step


def _remedy(material, cl: CreaseLoad, allowed: float, arm: ArmRating, bigger_by: str, extra: str = "",
            two_arms: bool = True) -> str:
    """Remedy text: the preparation that brings the crease's moment to `allowed` [N m] (the smallest
    moment every arm check of this crease accepts), a bigger arm (`bigger_by` wrist or payload),
    `extra`, two arms."""
    m = cl.moment
    parts = []
    if material is not None and not material.rigid and m.high > 0 and allowed > 0:
        if "grooved" in material.preparations:
            lig = _floor(ligament_for_moment(material, m.length, allowed) * 1000, 0.01)
            parts.append(f"groove the crease to a ligament of at most {lig:.2f} mm")
        else:
            frac = _floor(allowed / m.high * 100, 1)
            parts.append(f"perforate the crease to at most {frac:.0f} % uncut ({material.name} must not be grooved)")
    key = (lambda r: r.wrist_torque) if bigger_by == "wrist" else (lambda r: r.payload)
    bigger = [r for r in ARM_RATINGS.values() if key(r) > key(arm)] if bigger_by in ("wrist", "payload") else []
    if bigger:
        parts.append(f"a bigger arm ({bigger[0].model})")
    if extra:
        parts.append(extra)
    if two_arms:
        parts.append("two arms sharing the fold")
    return "; ".join(parts)


def check_fold_loads(states, arm: ArmRating, cup: VacuumCup, *, payload_mass: float,
                     material=None, pad: CupPad | None = None, two_arms_remedy: bool = True) -> LoadReport:
    """Check every `CreaseLoad` of every state (`states`: a sequence of sequences, index = state).

    payload_mass [kg]: tool + panel. material: names the remedy (ligament or perforation). pad: the
    cups that hold (default: `cup` alone). two_arms_remedy: name "two arms sharing the fold" among
    the remedies (not for an arm of a two-arm program, whose arms fold a crease each)."""
    pad = single_cup_pad(cup) if pad is None else pad
    verdicts: list[LoadVerdict] = []
    weight = payload_mass * GRAVITY
    rated = arm.payload * GRAVITY
    for s, loads in enumerate(states):
        for cl in loads:
            m = cl.moment
            if m.high <= 0:
                continue
            lever = max(cl.lever, 1e-6)
            force = m.high / lever
            allowed = min(arm.wrist_torque, max(rated - weight, 0.0) * lever)
            verdicts.append(LoadVerdict(s, m.crease, "wrist couple", m.high, arm.wrist_torque, "N m",
                                        m.high <= arm.wrist_torque,
                                        _remedy(material, cl, allowed, arm, "wrist", two_arms=two_arms_remedy)))
            d_need = m.high / (rated - weight) if rated > weight else math.inf
            verdicts.append(LoadVerdict(
                s, m.crease, "fold force + payload weight", force + weight, rated, "N", force + weight <= rated,
                _remedy(material, cl, allowed, arm, "payload",
                        f"grip at least {math.ceil(d_need * 1000)} mm from the crease" if math.isfinite(d_need) else "",
                        two_arms=two_arms_remedy)))
            if cl.pull:
                need = force + weight
                d_cup = math.sqrt(4 * need * pad.safety / (math.pi * pad.vacuum * pad.count))
                many = f"{pad.count} cups of at least" if pad.count > 1 else "a cup of at least"
                verdicts.append(LoadVerdict(
                    s, m.crease, "cup pull", need, pad.usable_force, "N", need <= pad.usable_force,
                    f"push instead of pull (a pad in compression needs no vacuum), or {many} "
                    f"{math.ceil(d_cup * 1000)} mm at {pad.vacuum / 1000:g} kPa"))
                tilt = pad.moment_capacity(lever)
                verdicts.append(LoadVerdict(
                    s, m.crease, "cup tilt", m.high, tilt, "N m", m.high <= tilt,
                    _remedy(material, cl, min(allowed, tilt), arm, "pad",
                            f"push instead of pull; a bigger pad (more or larger cups, spread across the crease: "
                            f"this one resists {tilt:.1f} N m at {lever * 1000:.0f} mm)", two_arms=two_arms_remedy)))
    return LoadReport(arm=arm, cup=cup, payload_mass=float(payload_mass), verdicts=tuple(verdicts), pad=pad)


def joint_torques(model, q, point, force, couple=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Static joint torques [N m] (6,) that balance a wrench the arm applies: `force` [N] at `point`
    [m] plus `couple` [N m], all in the robot base frame (tau_i = z_i . ((p - o_i) x F + C))."""
    F = fk_frames(model, np.asarray(q, np.float64).reshape(6))
    f = np.asarray(force, np.float64)
    c = np.asarray(couple, np.float64)
    p = np.asarray(point, np.float64)
    tau = np.empty(6)
    for i in range(6):
        z, o = F[i, :3, 2], F[i, :3, 3]
        tau[i] = z @ (np.cross(p - o, f) + c)
    return tau


def payload_record(cell, waypoints, panel_mass: float, panel_cog, tool_mass: float) -> dict:
    """The payload the program declares (JSON-ready): the tool alone (`tool_*`, before the grip and
    after the release) and tool + panel (`held_*`, between them); CoG [m] in the flange (tool0)
    frame. The tool's CoG is taken half-way to the TCP; the panel's is its centre in the panel
    frame at the grip waypoint. The whole panel is counted although the clamp carries part of it:
    an upper bound on what the arm holds."""
    from robot.cell import pose_to_matrix

    tcp = np.asarray(cell.tool.tcp, np.float64)
    tool_cog = tcp[:3, 3] / 2
    grip = next((w for w in waypoints if w["op"] == "grip"), None)
    if grip is None or panel_mass <= 0:
        held_mass, held_cog = tool_mass, tool_cog
    else:
        flange = pose_to_matrix(grip["pose"]) @ np.linalg.inv(tcp)      # flange in the base frame
        cog_base = cell.panel_to_base @ np.append(np.asarray(panel_cog, np.float64), 1.0)
        panel_in_flange = (np.linalg.inv(flange) @ cog_base)[:3]
        held_mass = tool_mass + panel_mass
        held_cog = (tool_mass * tool_cog + panel_mass * panel_in_flange) / held_mass
    return {"tool_mass_kg": float(tool_mass), "tool_cog_m": [float(x) for x in tool_cog],
            "panel_mass_kg": float(panel_mass), "held_mass_kg": float(held_mass),
            "held_cog_m": [float(x) for x in held_cog], "frame": "flange (tool0)",
            "note": "held = tool + the whole panel (the clamp carries part of it); tool CoG half-way to the TCP"}


def toolpath_loads(spec, model, creases, grip_face: int, cell, payload_mass: float,
                   side: str = "front", other_grips=()) -> LoadReport:
    """The load check of a fold program: every crease the arm folds (`fabkit.sheet.creases.arm_folds`,
    from the design FOLD `model`) in every state, on the cell's arm and cup gripping `side`.
    `other_grips`: faces other arms hold (a two-arm program); a crease between the clamp and such a
    face that lies nearer the clamp than this arm's grip (its creases a strict part of this arm's)
    is folded by that arm, not this one."""
    from fabkit.sheet.creases import arm_folds
    from fabkit.sheet.loads import fold_moment

    fixed = model.file_data.get("fabkit:fixed_face")
    fixed = None if fixed is None else int(fixed)
    folds = arm_folds(model, creases, grip_face, fixed, side=side)
    mine = {f.crease.name for f in folds}
    for g in other_grips:
        theirs = {f.crease.name for f in arm_folds(model, creases, int(g), fixed, side=side)}
        if theirs < mine:
            folds = [f for f in folds if f.crease.name not in theirs]
    states: list[list[CreaseLoad]] = [[] for _ in range(model.n_frames)]
    for f in folds:
        states[f.state].append(CreaseLoad(fold_moment(spec, f.crease.length, f.crease.name), f.lever, f.pull))
    pad = pad_of_cell(cell)
    return check_fold_loads(states, arm_rating(cell.model.name), pad.cup, payload_mass=payload_mass,
                            material=spec.material, pad=pad, two_arms_remedy=not other_grips)
