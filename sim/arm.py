"""The UR arm as MuJoCo bodies whose frames *are* the standard-DH frames.

Body i carries joint i (a hinge about its local z); its frame is DH frame i-1 turned by q_i, so a
child's pose relative to its parent is `pos (a_{i-1}, 0, d_{i-1})`, `quat Rx(alpha_{i-1})`, and the
`flange` site (= tool0 = DH frame 6) sits at `(a6, 0, d6)` in the last link. FK of that site then
equals the DH FK to rounding (reference/ur-robots.md section 1.6). The kinematic numbers come from
`robot.kinematics` (the caller passes the DH arrays); this module only adds what MuJoCo needs on
top: collision capsules, inertials, joint ranges and position servos.

Collision capsules and masses are UR's / mujoco_menagerie's published values re-expressed in the DH
body frames (reference section 1.6 and 1.4). Inertia tensors are a solid-cylinder approximation
around each link's main capsule: only the position servos of the controller stand-in use them.
"""
from __future__ import annotations

from dataclasses import dataclass

import sim.gl_backend  # noqa: F401  (MUJOCO_GL before mujoco loads)
import mujoco
import numpy as np

__all__ = ["LINK_NAMES", "JOINT_NAMES", "ArmSpec", "arm_spec", "add_arm", "part_name", "split_segment"]

#: Body names of the six moving links (UR's link names), base first.
LINK_NAMES = ("base", "shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
#: Joint names in controller order (q1..q6).
JOINT_NAMES = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")

# Collision bits (MuJoCo: a pair collides if (contype1 & conaffinity2) or (contype2 & conaffinity1)).
BIT_ARM, BIT_TOOL, BIT_ENV, BIT_PANEL = 1, 2, 4, 8


@dataclass(frozen=True)
class ArmSpec:
    """Everything MuJoCo needs for one UR model besides the DH table.

    `capsules[i]`: tuple of (name, radius, from(3), to(3)) in body i's frame (i = 0 is the static
    base). `mass`/`com`: UR's published link masses (kg) and centres of mass in the body frame (m).
    `torque`: peak joint torques (N m) used as actuator force ranges; `kp`/`kv`: servo gains.
    Joint ranges and speed limits are the kinematic model's (`robot.kinematics.URModel`).
    """

    name: str
    capsules: tuple
    mass: tuple
    com: tuple
    torque: tuple
    kp: tuple
    kv: tuple
    base_radius: float
    base_height: float


# reference/ur-robots.md section 1.6 (capsules, base cylinder), 1.4 (masses, COM in body frame),
# 1.3 (torques), 1.5 (servo gains of mujoco_menagerie's models).
_SPECS = {
    "ur5e": ArmSpec(
        name="ur5e",
        capsules=(
            (),
            (("shoulder", 0.060, (0, 0, 0.063), (0, 0, 0.183)),),
            (("upper_arm_housing", 0.060, (0, 0, 0.158), (0, 0, 0.038)),
             ("upper_arm", 0.050, (0, 0, 0.138), (-0.400, 0, 0.138))),
            (("elbow", 0.055, (0, 0, 0.147), (0, 0, 0.027)),
             ("forearm", 0.038, (-0.010, 0, 0.007), (-0.390, 0, 0.007))),
            (("wrist_1", 0.040, (0, 0, 0.127), (0, 0, -0.013)),),
            (("wrist_2", 0.040, (0, 0, -0.020), (0, 0, 0.0997)),
             ("wrist_2_cross", 0.040, (0, 0.060, 0.0997), (0, -0.019, 0.0997))),
            (("wrist_3", 0.040, (0, 0, 0.060), (0, 0, 0.0996)),),
        ),
        mass=(3.761, 8.058, 2.846, 1.37, 1.3, 0.365),
        com=((0, -0.00193, 0.13689), (-0.2125, 0, 0.11336), (-0.2422, 0, 0.0265),
             (0, -0.01634, 0.1315), (0, 0.01634, 0.0979), (0, 0, 0.09844)),
        torque=(150, 150, 150, 28, 28, 28),
        kp=(2000, 2000, 2000, 500, 500, 500),
        kv=(400, 400, 400, 100, 100, 100),
        base_radius=0.075,
        base_height=0.09,
    ),
    "ur10e": ArmSpec(
        name="ur10e",
        capsules=(
            (),
            (("shoulder", 0.078, (0, 0, 0.051), (0, 0, 0.211)),),
            (("upper_arm_housing", 0.078, (0, 0, 0.206), (0, 0, 0.046)),
             ("upper_arm", 0.060, (0, 0, 0.176), (-0.600, 0, 0.176))),
            (("elbow", 0.058, (0, 0, 0.184), (0, 0, 0.054)),
             ("forearm", 0.043, (-0.010, 0, 0.039), (-0.570, 0, 0.039))),
            (("wrist_1", 0.050, (0, 0, 0.169), (0, 0, 0.029)),),
            (("wrist_2", 0.046, (0, 0, -0.015), (0, 0, 0.1199)),
             ("wrist_2_cross", 0.046, (0, 0.071, 0.1199), (0, -0.015, 0.1199))),
            (("wrist_3", 0.046, (0, 0, 0.077), (0, 0, 0.1166)),),
        ),
        mass=(7.369, 13.051, 3.989, 2.1, 1.98, 0.615),
        com=((0.021, -0.027, 0.1807), (-0.2327, 0, 0.158), (-0.33155, 0, 0.068),
             (0, -0.018, 0.18115), (0, 0.018, 0.11285), (0, 0, 0.09055)),
        torque=(330, 330, 150, 54, 54, 54),
        kp=(5000, 5000, 5000, 5000, 5000, 5000),
        kv=(500, 500, 500, 500, 500, 500),
        base_radius=0.095,
        base_height=0.09,
    ),
}


#: Long capsules are split into pieces no longer than this (m). The pieces' union is exactly the
#: capsule, but each has a small bounding sphere, so MuJoCo's bounding-sphere filter passes far
#: fewer (arm piece, panel face) pairs on to the expensive convex narrow phase.
MAX_CAPSULE_LENGTH = 0.1
#: Separator between a part's name and its piece number ("upper_arm~2"); reports use the part name.
PART_SEP = "~"


def part_name(geom_name: str) -> str:
    """The part a geom belongs to: its name without the piece number of a split capsule."""
    return geom_name.split(PART_SEP, 1)[0]


def split_segment(p0, p1, max_length: float) -> list[tuple[list[float], list[float]]]:
    """`p0 -> p1` cut into equal consecutive pieces no longer than `max_length`."""
    a, b = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    n = max(1, int(np.ceil(np.linalg.norm(b - a) / max_length)))
    pts = [a + (b - a) * k / n for k in range(n + 1)]
    return [(pts[k].tolist(), pts[k + 1].tolist()) for k in range(n)]


def arm_spec(model_name: str) -> ArmSpec:
    """The collision/inertial/actuator data of a UR model ("ur5e" or "ur10e")."""
    try:
        return _SPECS[model_name.lower()]
    except KeyError:
        raise ValueError(f"no MuJoCo arm data for robot model {model_name!r} (have {sorted(_SPECS)})") from None


def _rx_quat(alpha: float) -> list[float]:
    return [float(np.cos(alpha / 2)), float(np.sin(alpha / 2)), 0.0, 0.0]


def _cylinder_inertia(mass: float, radius: float, p0, p1) -> list[float]:
    """Full inertia [ixx, iyy, izz, ixy, ixz, iyz] of a solid cylinder along p0->p1 (about its COM)."""
    axis = np.asarray(p1, float) - np.asarray(p0, float)
    length = float(np.linalg.norm(axis))
    a = axis / length if length > 0 else np.array([0.0, 0.0, 1.0])
    i_axis = 0.5 * mass * radius**2
    i_perp = mass * (radius**2 / 4 + length**2 / 12)
    inertia = i_perp * (np.eye(3) - np.outer(a, a)) + i_axis * np.outer(a, a)
    return [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]


def add_arm(spec: mujoco.MjSpec, parent, model, *, margin: float = 0.0, prefix: str = "") -> dict:
    """Add a UR arm under `parent` (an MjsBody placed at the robot base) and return its names.

    `model`: a `robot.kinematics.URModel` (DH rows `d`, `a`, `alpha`, ranges `q_min`/`q_max`). Every collision geom
    gets `margin` (m) so contacts closer than it are reported with their distance. Adds the
    base-shoulder and base-upper_arm excludes (a body hanging off a static body is not
    parent-filtered; those capsules overlap by construction), joint ranges, and position actuators
    with the published torque limits. Returns {"bodies", "joints", "geoms", "flange_site"}.
    """
    spec.compiler.degree = False  # joint ranges in radians (MJCF's default unit is degrees)
    data = arm_spec(model.name)
    d, a, alpha = (np.asarray(x, float).reshape(6) for x in (model.d, model.a, model.alpha))
    ranges = np.column_stack([model.q_min, model.q_max]).astype(float)
    names = {"bodies": [], "joints": [], "geoms": [], "flange_site": prefix + "flange"}

    base = parent.add_body(name=prefix + LINK_NAMES[0])
    names["bodies"].append(base.name)
    g = base.add_geom(name=prefix + "base", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                      size=[data.base_radius, data.base_height / 2, 0], pos=[0, 0, data.base_height / 2],
                      contype=BIT_ARM, conaffinity=BIT_ARM | BIT_TOOL, margin=margin,
                      rgba=[0.25, 0.27, 0.3, 1])
    names["geoms"].append(g.name)

    body = base
    for i in range(6):
        pos = [0.0, 0.0, 0.0] if i == 0 else [a[i - 1], 0.0, d[i - 1]]
        quat = [1.0, 0.0, 0.0, 0.0] if i == 0 else _rx_quat(alpha[i - 1])
        body = body.add_body(name=prefix + LINK_NAMES[i + 1], pos=pos, quat=quat)
        caps = data.capsules[i + 1]
        main = max(caps, key=lambda c: np.linalg.norm(np.subtract(c[3], c[2])) * c[1])
        body.mass = data.mass[i]
        body.ipos = list(data.com[i])
        body.fullinertia = _cylinder_inertia(data.mass[i], main[1], main[2], main[3])
        body.explicitinertial = True
        joint = body.add_joint(name=prefix + JOINT_NAMES[i], type=mujoco.mjtJoint.mjJNT_HINGE,
                               axis=[0, 0, 1], range=list(ranges[i]), armature=0.1)
        joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
        names["bodies"].append(body.name)
        names["joints"].append(joint.name)
        # The shoulder housing only turns about the base axis and is symmetric about it: its
        # distance to the environment (the mounting table) is the same in every configuration, a
        # property of the cell layout rather than of the motion, so it is kept out of environment
        # contacts (the static base cylinder is too: MuJoCo never pairs static geoms).
        affinity = BIT_ARM | BIT_TOOL | BIT_PANEL | (0 if i == 0 else BIT_ENV)
        for cname, radius, p0, p1 in caps:
            for k, (a0, a1) in enumerate(split_segment(p0, p1, MAX_CAPSULE_LENGTH)):
                g = body.add_geom(name=prefix + cname + (f"{PART_SEP}{k + 1}" if k else ""),
                                  type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[radius, 0, 0], fromto=[*a0, *a1],
                                  contype=BIT_ARM, conaffinity=affinity,
                                  margin=margin, rgba=[0.55, 0.6, 0.68, 1])
                names["geoms"].append(g.name)
        act = spec.add_actuator(name=prefix + JOINT_NAMES[i], target=joint.name,
                                trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_position(kp=float(data.kp[i]), kv=float(data.kv[i]))
        act.forcerange = [-float(data.torque[i]), float(data.torque[i])]
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.ctrlrange = list(ranges[i])
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
    body.add_site(name=names["flange_site"], pos=[a[5], 0.0, d[5]], quat=_rx_quat(alpha[5]),
                  size=[0.01, 0, 0])
    names["flange_body"] = body.name
    for other in (LINK_NAMES[1], LINK_NAMES[2]):
        spec.add_exclude(bodyname1=base.name, bodyname2=prefix + other)
    return names
