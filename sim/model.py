"""The MuJoCo model of a robot cell, built with `mujoco.MjSpec` from a `robot.cell.Cell`.

World = the cell frame. Parts, each with its own collision bit (`sim.arm.BIT_*`):

- the UR arm at the cell's robot base pose, DH-exact (`sim.arm`), with a `flange` site;
- the tool: one body welded to the flange carrying the cell's tool shapes and a `tcp` site;
- the obstacles: static geoms named after the cell's obstacles;
- the panel (optional): one mocap body per face, each carrying that face's thin convex mesh
  (`sim.panel`); the check moves them to the fold state of every configuration it tests.

Contacts that can happen: arm-arm (self-collision, minus parent-child pairs and the base excludes),
arm-tool, arm or tool against obstacles and panel. The tool against its grip face is expected and
excluded. Obstacles and panel never collide with each other (both are static or mocap: MuJoCo
skips such pairs), so the panel's contact with its own fixture is not a problem here.

Clearance: the obstacle geoms carry a margin of the cell's clearance plus a window for measuring
the smallest distance, the panel pieces the clearance alone (mesh distance queries are costly and
a gripping tool is always near several faces); the arm and tool geoms carry none. MuJoCo uses the larger of the two
margins for a pair, so robot-versus-environment contacts are reported out to that distance while
self-contacts are reported only when the capsules really touch.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import sim.gl_backend  # noqa: F401  (MUJOCO_GL before mujoco loads)
import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from sim.arm import BIT_ARM, BIT_ENV, BIT_PANEL, BIT_TOOL, add_arm
from sim.panel import PanelModel, interpolate_poses

__all__ = ["GROUP_ARM", "GROUP_TOOL", "GROUP_ENV", "GROUP_PANEL", "CellNames",
           "build_cell_model", "clearance_window"]

GROUP_ARM, GROUP_TOOL, GROUP_ENV, GROUP_PANEL = 0, 1, 2, 3

#: Distances up to clearance + this are measured (for `min_clearance_m`) without being problems.
#: A wider window reports more near misses but costs narrow-phase time at every configuration.
CLEARANCE_WINDOW = 0.02


def clearance_window(clearance: float) -> float:
    """The margin put on obstacle and panel geoms: the cell's clearance plus a measuring window (m)."""
    return float(clearance) + CLEARANCE_WINDOW


@dataclass(frozen=True, eq=False)
class CellNames:
    """Names and ids in a built cell model (arrays indexed by MuJoCo geom id)."""

    geom: tuple[str, ...]
    geom_group: np.ndarray
    geom_face: np.ndarray
    joints: tuple[str, ...]
    flange_site: str
    tcp_site: str
    arm_bodies: tuple[str, ...]
    tool_body: str
    panel_bodies: tuple[str, ...] = ()
    grip_face: int | None = None
    margins: dict = field(default_factory=dict)
    spec: object = field(default=None, repr=False, compare=False)  # the MjSpec compiled (spec.to_xml(): MJCF)
    extra_arms: tuple = ()  # per further arm (all_arms=True): {"name", "joints", "bodies", "tool_body", "tcp_site"}


def _rgba(kind: str) -> list[float]:
    return {"tool": [0.85, 0.55, 0.15, 1], "env": [0.45, 0.5, 0.45, 0.6],
            "panel": [0.8, 0.82, 0.86, 1], "grip": [0.9, 0.75, 0.3, 1]}[kind]


def _pose_pos_quat(T) -> tuple[list[float], list[float]]:
    T = np.asarray(T, dtype=np.float64)
    x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
    return [float(v) for v in T[:3, 3]], [float(w), float(x), float(y), float(z)]


_GEOM_TYPES = {"box": mujoco.mjtGeom.mjGEOM_BOX, "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
               "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE, "sphere": mujoco.mjtGeom.mjGEOM_SPHERE}


def shape_size(shape) -> list[float]:
    """MuJoCo `size` (3,) of a cell primitive (`robot.cell.Shape.size` already follows MuJoCo)."""
    size = [float(v) for v in shape.size]
    return size + [0.0] * (3 - len(size))


def add_primitive(body, name: str, shape, **kw):
    """Add a cell primitive (`robot.cell.Shape`, pose in the body's frame) as a geom of an MjSpec body."""
    pos, quat = _pose_pos_quat(shape.pose)
    return body.add_geom(name=name, type=_GEOM_TYPES[shape.kind], size=shape_size(shape), pos=pos, quat=quat, **kw)


_add_primitive = add_primitive


def build_cell_model(cell, panel_state: PanelModel | None = None, *, state: float = 0.0, all_arms: bool = False):
    """Build and compile the cell model. Returns `(MjModel, CellNames)`.

    `cell`: a `robot.cell.Cell`. `panel_state`: the panel pieces with their per-state world poses
    (`sim.panel.PanelModel`), posed at fold state `state`; None = no panel. `all_arms`: also add the
    cell's further arms (`cell.extra_arms`), each with its own tool, names prefixed `<name>_`, joints
    after the first arm's in qpos; arm-arm and tool-tool contacts between arms are paired.
    """
    from robot.kinematics import get_model

    spec = mujoco.MjSpec()
    spec.modelname = f"fabkit_{cell.name}"
    spec.compiler.degree = False
    spec.visual.global_.offwidth = 1280
    spec.visual.global_.offheight = 960
    window = clearance_window(cell.limits.clearance)
    # Panel pieces are convex meshes: a mesh pair inside the margin costs a full distance query
    # (~30 us against ~3 us outside), and a gripping tool has many faces near it, so the panel
    # margin is the clearance itself; obstacles get the wider measuring window.
    panel_margin = float(cell.limits.clearance)
    spec.add_texture(name="sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX, builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
                     rgb1=[0.93, 0.94, 0.96], rgb2=[0.55, 0.6, 0.68], width=64, height=64)
    world = spec.worldbody
    world.add_light(name="sun", pos=[0, 0, 4], dir=[0, 0, -1], type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL, castshadow=False,
                    diffuse=[0.7, 0.7, 0.7])
    world.add_light(name="key", pos=[2, -2, 3], dir=[-1, 1, -1.5], diffuse=[0.4, 0.4, 0.4], castshadow=False)
    world.add_geom(name="floor_visual", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[4, 4, 0.05],
                   contype=0, conaffinity=0, rgba=[0.92, 0.92, 0.9, 1], group=2)

    # robot
    pos, quat = _pose_pos_quat(cell.robot.base_pose)
    mount = world.add_body(name="robot_mount", pos=pos, quat=quat)
    arm = add_arm(spec, mount, get_model(cell.robot.model), margin=0.0)

    # tool: its own body welded to the flange (so "tool x grip face" can be excluded on its own)
    flange_body = spec.body(arm["flange_body"])
    flange_site = spec.site(arm["flange_site"])
    tool = flange_body.add_body(name="tool", pos=list(flange_site.pos), quat=list(flange_site.quat))
    tool.mass = 1e-3
    tool.inertia = [1e-6, 1e-6, 1e-6]
    tool.explicitinertial = True
    for i, shape in enumerate(cell.tool.shapes):
        _add_primitive(tool, shape.name or f"tool_{i}", shape,
                       contype=BIT_TOOL, conaffinity=BIT_ARM | BIT_ENV | BIT_PANEL, margin=0.0,
                       rgba=_rgba("tool"))
    tcp_pos, tcp_quat = _pose_pos_quat(cell.tool.tcp)
    tool.add_site(name="tcp", pos=tcp_pos, quat=tcp_quat, size=[0.008, 0, 0], rgba=[1, 0, 0, 1])

    extra = []
    for arm_name, mount_spec in (cell.extra_arms if all_arms else ()):
        pre = f"{arm_name}_"
        pos, quat = _pose_pos_quat(mount_spec.base_pose)
        mount_b = world.add_body(name=pre + "robot_mount", pos=pos, quat=quat)
        arm_b = add_arm(spec, mount_b, get_model(mount_spec.model), margin=0.0, prefix=pre)
        fsite = spec.site(arm_b["flange_site"])
        tool_b = spec.body(arm_b["flange_body"]).add_body(name=pre + "tool", pos=list(fsite.pos),
                                                          quat=list(fsite.quat))
        tool_b.mass = 1e-3
        tool_b.inertia = [1e-6, 1e-6, 1e-6]
        tool_b.explicitinertial = True
        for i, shape in enumerate(cell.tool.shapes):
            add_primitive(tool_b, pre + (shape.name or f"tool_{i}"), shape, contype=BIT_TOOL,
                          conaffinity=BIT_ARM | BIT_TOOL | BIT_ENV | BIT_PANEL, margin=0.0, rgba=_rgba("tool"))
        tool_b.add_site(name=pre + "tcp", pos=tcp_pos, quat=tcp_quat, size=[0.008, 0, 0], rgba=[1, 0, 0, 1])
        extra.append({"name": arm_name, "joints": tuple(arm_b["joints"]), "bodies": tuple(arm_b["bodies"]),
                      "tool_body": pre + "tool", "tcp_site": pre + "tcp"})

    # obstacles
    for ob in cell.obstacles:
        _add_primitive(world, ob.name, ob, contype=BIT_ENV, conaffinity=0, margin=window, gap=0.0,
                       rgba=_rgba("env"))

    # panel
    panel_bodies: list[str] = []
    grip = None
    if panel_state is not None:
        grip = panel_state.grip_face
        P, Qt = interpolate_poses(panel_state.pos, panel_state.quat, state)
        ids = panel_state.face_ids or tuple(range(len(panel_state.pieces)))
        for f, verts in enumerate(panel_state.pieces.local_vertices):
            spec.add_mesh(name=f"face_{ids[f]}_mesh", uservert=np.asarray(verts, float).ravel().tolist())
            body = world.add_body(name=f"panel_face_{ids[f]}", mocap=True, pos=list(P[f]), quat=list(Qt[f]))
            body.add_geom(name=f"face_{ids[f]}", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"face_{ids[f]}_mesh",
                          contype=BIT_PANEL, conaffinity=0, margin=panel_margin,
                          rgba=_rgba("grip" if f == grip else "panel"))
            panel_bodies.append(body.name)
        if grip is not None:
            spec.add_exclude(bodyname1="tool", bodyname2=panel_bodies[grip])

    m = spec.compile()
    geom_names = tuple(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom_{g}" for g in range(m.ngeom))
    body_of = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in m.geom_bodyid]
    group = np.full(m.ngeom, -1, dtype=np.int64)
    face = np.full(m.ngeom, -1, dtype=np.int64)
    for g in range(m.ngeom):
        if m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0:
            continue
        if body_of[g] in arm["bodies"] or any(body_of[g] in e["bodies"] for e in extra):
            group[g] = GROUP_ARM
        elif body_of[g] == "tool" or any(body_of[g] == e["tool_body"] for e in extra):
            group[g] = GROUP_TOOL
        elif body_of[g] in panel_bodies:
            group[g] = GROUP_PANEL
            face[g] = panel_bodies.index(body_of[g])
        else:
            group[g] = GROUP_ENV
    group.setflags(write=False)
    face.setflags(write=False)
    names = CellNames(geom=geom_names, geom_group=group, geom_face=face, joints=tuple(arm["joints"]),
                      flange_site=arm["flange_site"], tcp_site="tcp", arm_bodies=tuple(arm["bodies"]),
                      tool_body="tool", panel_bodies=tuple(panel_bodies), grip_face=grip,
                      margins={"environment_m": window, "panel_m": panel_margin,
                               "clearance_m": float(cell.limits.clearance)}, spec=spec,
                      extra_arms=tuple(extra))
    return m, names
