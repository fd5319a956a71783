"""Robot cell descriptions (`cells/*.toml`): robot, tool, fixture, obstacles, limits; optional
further arms (`[[arms]]`, each carrying the same tool), the clamp (`[clamp]`: jaw pose, footprint
polygon, the obstacle carrying it), jigs (`[[jigs]]`: like the clamp, a pad that holds a wing
face fixed while the program engages it) and the suction cup's footprint radius (`tool.cup_radius`).
`[robot]` and every `[[arms]]` may name the arm's controller (`host`, an IP address or host name,
one controller per arm): what `fabkit send` connects to when no --host is given
(`robot.send_options.controller_hosts`).

`load_cell(path)` reads a TOML file, validates it once and returns a frozen `Cell`. Every problem
is one `InputError` line naming the file and the key (`tool.shapes[1].radius: ...`): unknown keys,
wrong types, wrong lengths, non-finite numbers and impossible values (negative sizes, speeds above
the robot's catalogue limits, a grip output that does not exist, ...).

Poses in the file are UR poses `[x, y, z, rx, ry, rz]` (metres + rotation vector in radians); in
memory they are 4x4 matrices. Frames: `robot.base_pose` is the robot base (DH frame 0 = the UR
controller's base frame) in the cell/world frame; `tool.tcp` and `tool.shapes` are in the flange
(tool0) frame; `fixture.pose` maps the panel frame (where the fold states live; the clamped face
sits there) to world; obstacles are in world. Shape sizes follow MuJoCo: box = half extents
(hx, hy, hz), cylinder/capsule = (radius, half_length) along the shape's local z, sphere = (radius,).
"""
from __future__ import annotations

import hashlib
import json
import tomllib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from fabkit.errors import InputError
from robot.toml_reader import TableReader, checked_number
from robot.kinematics import MODELS, URModel, get_model
from robot.rtde_limits import MAX_BLEND, MAX_JOINT_ACCEL, MAX_TOOL_ACCEL, MAX_TOOL_SPEED
from robot.send_options import is_host
from robot.ur_arm import HOME_Q

__all__ = ["Cell", "RobotMount", "Tool", "Shape", "Limits", "Clamp", "Jig", "load_cell", "parse_cell", "pose_to_matrix",
           "matrix_to_pose", "file_sha256", "SHAPE_KINDS"]

SHAPE_KINDS = ("box", "cylinder", "capsule", "sphere")
#: ur_rtde argument bounds (`robot.rtde_limits`): a cell may not ask for more than these.
MAX_TCP_SPEED, MAX_TCP_ACCEL = MAX_TOOL_SPEED, MAX_TOOL_ACCEL
MAX_CLEARANCE = 0.5        # m: more would make every cell "in collision"
MAX_TOOL_OUTPUT = {"tool": 1, "standard": 7}  # tool DO 0-1, standard (controller box) DO 0-7
#: Slack on catalogue joint speeds so that 3.14159 passes for 180 deg/s (rad/s).
SPEED_SLACK = 1e-4


def pose_to_matrix(pose) -> np.ndarray:
    """UR pose `[x, y, z, rx, ry, rz]` (m, rotation vector rad) -> 4x4 homogeneous matrix."""
    p = np.asarray(pose, dtype=np.float64).reshape(6)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(p[3:]).as_matrix()
    T[:3, 3] = p[:3]
    return T


def matrix_to_pose(T) -> np.ndarray:
    """4x4 homogeneous matrix (or `(n, 4, 4)`) -> UR pose `[x, y, z, rx, ry, rz]` (`(6,)` / `(n, 6)`)."""
    T = np.asarray(T, dtype=np.float64)
    rv = Rotation.from_matrix(T[..., :3, :3]).as_rotvec()
    return np.concatenate([T[..., :3, 3], rv], axis=-1)


@dataclass(frozen=True, eq=False)
class Shape:
    """A collision primitive: `kind` in SHAPE_KINDS, `pose` 4x4 in its parent frame, `size` (MuJoCo)."""

    name: str
    kind: str
    pose: np.ndarray
    size: tuple[float, ...]


@dataclass(frozen=True, eq=False)
class RobotMount:
    """The arm: `model` name ("ur5e" | "ur10e"), `base_pose` 4x4 base -> world, `home` joints (rad),
    `host` its controller's address (optional; `fabkit send` uses it when no --host is given)."""

    model: str
    base_pose: np.ndarray
    home: np.ndarray
    host: str | None = None

    @property
    def kinematics(self) -> URModel:
        return get_model(self.model)


@dataclass(frozen=True, eq=False)
class Tool:
    """The gripper: `tcp` 4x4 in the flange frame, collision `shapes` in the flange frame, and the
    digital output that closes it (`grip_output` on the tool connector or the controller's standard
    outputs, `grip_output_kind` "tool" | "standard")."""

    tcp: np.ndarray
    shapes: tuple[Shape, ...]
    grip_output: int
    grip_output_kind: str
    cup_radius: float | None = None  # radius [m] of the suction cup's footprint on the panel (optional)
    pad: object | None = None        # `fabkit.sheet.pad.CupPad` of `[tool.pad]` (optional): the cups that hold


@dataclass(frozen=True, eq=False)
class Clamp:
    """Where the panel is clamped: `pose` 4x4 in world (z out of the jaw toward the panel; the
    clamped face's frame lands on it), `footprint` (k, 2) polygon [m] in the pose's xy plane that
    must stay on the clamped face, `obstacle` the obstacle carrying the clamp (touching the clamped
    face by design) or ""."""

    pose: np.ndarray
    footprint: np.ndarray
    obstacle: str = ""


@dataclass(frozen=True, eq=False)
class Jig:
    """A jig that holds a face of the panel fixed in the cell (a vacuum pad or a clamp on a stand):
    `name`, `pose` 4x4 in world (z out of the pad toward the panel), `footprint` (k, 2) polygon [m]
    in the pose's xy plane that must lie on the face it holds, `obstacle` the obstacle that is the
    jig's body (touching the held face by design; every arm and every other face must clear it)
    or "". Which face it holds, and when, is the program's (PATH.json `holds.jigs`)."""

    name: str
    pose: np.ndarray
    footprint: np.ndarray
    obstacle: str = ""


@dataclass(frozen=True)
class Limits:
    """Motion limits: TCP speed [m/s] and acceleration [m/s^2], joint speeds [rad/s] (6), joint
    acceleration [rad/s^2], the clearance [m] every robot/tool part keeps from obstacles, and the
    largest blend radius [m] the sender passes (optional in the file, default 0.02)."""

    tcp_speed: float
    tcp_accel: float
    joint_speed: tuple[float, ...]
    joint_accel: float
    clearance: float
    blend_radius: float = 0.02


@dataclass(frozen=True, eq=False)
class Cell:
    """A robot cell (module docstring); `fixture` is the panel frame -> world 4x4; `sha256` the
    hash of the cell file's bytes (`load_cell`) or of the canonical JSON of the parsed table
    (`parse_cell`): toolpaths and check reports record it, the sender compares it."""

    name: str
    description: str
    robot: RobotMount
    tool: Tool
    fixture: np.ndarray
    obstacles: tuple[Shape, ...]
    limits: Limits
    source: str
    sha256: str = ""
    clamp: Clamp | None = None
    extra_arms: tuple[tuple[str, RobotMount], ...] = ()  # (name, arm) of further arms, same tool
    jigs: tuple[Jig, ...] = ()

    def jig(self, name: str) -> Jig | None:
        """The jig called `name`, or None."""
        return next((j for j in self.jigs if j.name == name), None)

    @property
    def arms(self) -> tuple[tuple[str, RobotMount], ...]:
        """Every arm as (name, mount): the `[robot]` arm is "a", then `[[arms]]` by their names."""
        return (("a", self.robot),) + self.extra_arms

    @property
    def model(self) -> URModel:
        return self.robot.kinematics

    @property
    def world_to_base(self) -> np.ndarray:
        """4x4 mapping world coordinates into the robot base frame."""
        return np.linalg.inv(self.robot.base_pose)

    @property
    def panel_to_base(self) -> np.ndarray:
        """4x4 mapping the panel frame (fold states) into the robot base frame."""
        return self.world_to_base @ self.fixture


# ---- validation --------------------------------------------------------------------------------

def _shape(r: TableReader, default_name: str, need_name: bool) -> Shape:
    name = r.string("name", required=need_name, default=default_name)
    if need_name and not name.strip():
        r.fail("name", "must not be empty")
    kind = r.string("kind", choices=SHAPE_KINDS)
    pose = r.pose("pose", required=False)
    if kind == "box":
        size = tuple(r.vector("size", 3, lo=0.0, lo_open=True, unit="m"))
    elif kind == "sphere":
        size = (r.number("radius", lo=0.0, lo_open=True, unit="m"),)
    else:
        size = (r.number("radius", lo=0.0, lo_open=True, unit="m"),
                r.number("half_length", lo=0.0, lo_open=True, unit="m"))
    r.done()
    return Shape(name=name, kind=kind, pose=pose, size=size)


def _mount(rr: TableReader) -> RobotMount:
    model = rr.string("model", choices=tuple(MODELS))
    urm = get_model(model)
    base_pose = rr.pose("base_pose")
    home = rr.vector("home", 6, required=False, default=list(HOME_Q),
                     unit="rad")
    for i, q in enumerate(home):
        if not urm.q_min[i] <= q <= urm.q_max[i]:
            rr.fail("home", f"joint {i + 1} = {q:.12g} rad is outside [{urm.q_min[i]:.6g}, {urm.q_max[i]:.6g}]")
    host = rr.string("host", required=False, default="") or None
    if host is not None and not is_host(host):
        rr.fail("host", f"{host!r} is not an IP address or host name")
    return RobotMount(model, base_pose, home, host)


def _extra_arm(r: TableReader) -> tuple[str, RobotMount]:
    name = r.string("name")
    if not name.isidentifier() or not name.islower():
        r.fail("name", f"{name!r} must be a lower-case identifier (it prefixes the arm's MuJoCo names)")
    mount = _mount(r)
    r.done()
    return name, mount


def _footprint(r: TableReader) -> np.ndarray:
    raw = r.raw("footprint")
    if not isinstance(raw, list) or len(raw) < 3 or not all(isinstance(p, list) and len(p) == 2 for p in raw):
        r.fail("footprint", "expected a polygon: a list of at least 3 [x, y] points (m)")
    fp = np.array([[checked_number(x, f"{r.key('footprint')}[{i}]", r.source, unit="m") for x in p]
                   for i, p in enumerate(raw)])
    if np.abs(fp).max() > 1.0:
        r.fail("footprint", "a point is more than 1 m from the pose (millimetres?)")
    area = 0.5 * float(np.sum(fp[:, 0] * np.roll(fp[:, 1], -1) - np.roll(fp[:, 0], -1) * fp[:, 1]))
    if abs(area) < 1e-8:
        r.fail("footprint", "the polygon has no area")
    return fp


def _jig(r: TableReader, obstacle_names: list[str]) -> Jig:
    name = r.string("name")
    if not name.isidentifier():
        r.fail("name", f"{name!r} must be an identifier (PATH.json and CHECK.json name the jig by it)")
    return Jig(name=name, **_holding_pad(r, obstacle_names))


def _clamp(r: TableReader, obstacle_names: list[str]) -> Clamp:
    return Clamp(**_holding_pad(r, obstacle_names))


def _holding_pad(r: TableReader, obstacle_names: list[str]) -> dict:
    """The keys a clamp and a jig share: `pose`, `footprint` and the `obstacle` that is its body."""
    pose = r.pose("pose")
    fp = _footprint(r)
    obstacle = r.string("obstacle", required=False, default="")
    if obstacle and obstacle not in obstacle_names:
        r.fail("obstacle", f"{obstacle!r} is not one of the cell's obstacles")
    r.done()
    return {"pose": pose, "footprint": fp, "obstacle": obstacle}


def parse_cell(data: dict, source: str) -> Cell:
    """Validate a parsed TOML document (see `load_cell`)."""
    top = TableReader(data, "", source)
    name = top.string("name")
    if not name.strip():
        top.fail("name", "must not be empty")
    description = top.string("description", required=False)

    rr = top.table_("robot")
    robot = _mount(rr)
    model = robot.model
    rr.done()

    tr = top.table_("tool")
    tcp = tr.pose("tcp")
    if np.linalg.norm(tcp[:3, 3]) > 1.0:
        tr.fail("tcp", f"TCP is {np.linalg.norm(tcp[:3, 3]):.6g} m from the flange (more than 1 m)")
    kind = tr.string("grip_output_kind", required=False, default="tool", choices=("tool", "standard"))
    grip = tr.integer("grip_output", lo=0, hi=MAX_TOOL_OUTPUT[kind])
    shapes = tuple(_shape(s, f"tool_{i}", False) for i, s in enumerate(tr.tables("shapes")))
    cup = tr.number("cup_radius", required=False, default=None, lo=0.0, lo_open=True, hi=0.5, unit="m") \
        if tr.has("cup_radius") else None
    pad = _pad(tr.table_("pad")) if tr.has("pad") else None
    tr.done()

    fr = top.table_("fixture")
    fixture = fr.pose("pose")
    fr.done()

    obstacles = tuple(_shape(o, "", True) for o in top.tables("obstacles"))
    names = [o.name for o in obstacles]
    for i, n in enumerate(names):
        if n in names[:i]:
            raise InputError(f"obstacles[{i}].name: {n!r} is used twice", source=source)
    clamp = _clamp(top.table_("clamp"), names) if top.has("clamp") else None
    extra = tuple(_extra_arm(a) for a in top.tables("arms"))
    jigs = tuple(_jig(j, names) for j in top.tables("jigs"))
    for i, j in enumerate(jigs):
        if j.name in [k.name for k in jigs[:i]]:
            raise InputError(f"jigs[{i}].name: {j.name!r} is used twice", source=source)
    arm_names = ["a"] + [n for n, _ in extra]
    for i, n in enumerate(arm_names):
        if n in arm_names[:i]:
            raise InputError(f"arms[{i - 1}].name: {n!r} is used twice (the [robot] arm is \"a\")", source=source)
    hosts = [robot.host] + [m.host for _, m in extra]
    for i, h in enumerate(hosts):
        if h is not None and h in hosts[:i]:
            where = "robot.host" if i == 0 else f"arms[{i - 1}].host"
            raise InputError(f"{where}: {h!r} is arm {arm_names[hosts.index(h)]}'s controller too (one controller "
                             "per arm)", source=source)

    lr = top.table_("limits")
    limits = Limits(
        tcp_speed=lr.number("tcp_speed", lo=0.0, lo_open=True, hi=MAX_TCP_SPEED, unit="m/s"),
        tcp_accel=lr.number("tcp_accel", lo=0.0, lo_open=True, hi=MAX_TCP_ACCEL, unit="m/s^2"),
        joint_speed=tuple(lr.vector("joint_speed", 6, lo=0.0, lo_open=True, unit="rad/s")),
        joint_accel=lr.number("joint_accel", lo=0.0, lo_open=True, hi=MAX_JOINT_ACCEL, unit="rad/s^2"),
        clearance=lr.number("clearance", lo=0.0, hi=MAX_CLEARANCE, unit="m"),
        blend_radius=lr.number("blend_radius", required=False, default=0.02, lo=0.0, hi=MAX_BLEND, unit="m"),
    )
    for arm_model in dict.fromkeys([model] + [m.model for _, m in extra]):
        for i, (v, vmax) in enumerate(zip(limits.joint_speed, get_model(arm_model).joint_speed_max)):
            if v > vmax + SPEED_SLACK:
                lr.fail("joint_speed", f"joint {i + 1} = {v:.12g} rad/s exceeds the {arm_model}'s {vmax:.6g} rad/s")
    lr.done()
    top.done()
    return Cell(name=name, description=description, robot=robot,
                tool=Tool(tcp=tcp, shapes=shapes, grip_output=grip, grip_output_kind=kind, cup_radius=cup,
                          pad=pad),
                fixture=fixture, obstacles=obstacles, limits=limits, source=source, clamp=clamp,
                extra_arms=extra, jigs=jigs, sha256=_data_sha256(data))


def _data_sha256(data: dict) -> str:
    """sha256 of a parsed cell table's canonical JSON (TOML dates and times as text)."""
    text = json.dumps(data, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def load_cell(path: str | Path) -> Cell:
    """Read and validate a cell TOML file; `InputError` (one line, file + key) on any problem."""
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise InputError("cell file not found", source=str(path)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read cell file: {exc}", source=str(path)) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML: {exc}", source=str(path)) from None
    return replace(parse_cell(data, str(path)), sha256=hashlib.sha256(text.encode("utf-8")).hexdigest())


def file_sha256(path: str | Path) -> str:
    """sha256 of a file's bytes (cell and FOLD files are identified by it)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _pad(r: TableReader):
    """`[tool.pad]`: `cup_diameter` [m], `cups` (cup centres [[x, y], ...] in the TCP frame's xy
    plane, m), optional `vacuum` [Pa below ambient, default 60000] and `safety` [default 2.5]."""
    from fabkit.sheet.pad import CupPad

    d = r.number("cup_diameter", lo=0.0, lo_open=True, hi=0.5, unit="m")
    raw = r.raw("cups")
    if not isinstance(raw, list) or not raw or not all(isinstance(p, list) and len(p) == 2 for p in raw):
        r.fail("cups", "expected a list of at least one [x, y] cup centre (m)")
    c = np.array([[checked_number(x, f"{r.key('cups')}[{i}]", r.source, unit="m") for x in p] for i, p in enumerate(raw)])
    if np.abs(c).max() > 0.5:
        r.fail("cups", "a cup centre is more than 0.5 m from the TCP (millimetres?)")
    if len(c) > 1:
        gap = np.linalg.norm(c[:, None] - c[None], axis=2)[np.triu_indices(len(c), 1)].min()
        if gap < d:
            r.fail("cups", f"two cups {gap * 1000:.1f} mm apart overlap ({d * 1000:.1f} mm lips)")
    vac = r.number("vacuum", required=False, default=60e3, lo=0.0, lo_open=True, hi=101325.0, unit="Pa")
    safety = r.number("safety", required=False, default=2.5, lo=1.0, hi=10.0)
    r.done()
    return CupPad(c, d, vac, safety)

