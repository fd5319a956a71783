"""The `fabkit generate` presets: procedural input meshes with their parameters and rules.

`PRESETS` maps a preset name to its builder and its parameters (`Param`: type, default, help,
sign); `build_preset(name, **params)` checks the parameters (types, signs, the reflect preset's
rules, a face budget) and builds the mesh. `fabkit generate` and `fabkit.generate()` both build
through here; the messages name the CLI options (`--fold`, ...), which are the keyword names.
The builders (in `fabkit.generate`) are imported when a preset is built, so reading the table
(`fabkit generate --help`) loads no numpy.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

from fabkit.errors import InputError

@dataclass(frozen=True)
class Param:
    kind: type  # int or float
    default: object  # None: computed by the preset
    help: str
    positive: bool = False


def _deg(x: float) -> float:
    return math.radians(x)


def _build_reflect(p: dict):
    """Reflect preset; fills the computed defaults into `p` (so the report shows what was built)."""
    from fabkit.generate.reflect import MirrorPlane, reflect_panel

    k = p["creases"]
    if k not in (1, 2):
        raise InputError(f"--creases must be 1 or 2, got {k}", source="preset reflect")
    # the builder speaks radians; check the degrees here so the message names what the user typed
    if not 0 < p["arc"] < 360:
        raise InputError(f"--arc must be between 0 and 360 degrees, got {p['arc']:g}", source="preset reflect")
    for name in ("fold", "fold2"):
        if p[name] is not None and not 0 < abs(p[name]) < 180:
            raise InputError(f"--{name} must be non-zero and between -180 and 180 degrees, got {p[name]:g}",
                             source="preset reflect")
    for name in ("skew", "skew2"):
        if p[name] is not None and not abs(p[name]) < 90:
            raise InputError(f"--{name} must be between -90 and 90 degrees, got {p[name]:g}", source="preset reflect")
    width = p["width"]
    if k == 1:
        extra = [f"--{n}" for n in ("offset2", "fold2", "skew2") if p[n] is not None]
        if extra:
            raise InputError(f"{', '.join(extra)} need --creases 2", source="preset reflect")
    if p["offset"] is None:
        p["offset"] = width / (2 if k == 1 else 4)
    planes = [MirrorPlane(p["offset"], _deg(p["fold"]), _deg(p["skew"]))]
    if k == 2:
        p["offset2"] = 3 * width / 5 if p["offset2"] is None else p["offset2"]
        p["fold2"] = -p["fold"] if p["fold2"] is None else p["fold2"]
        p["skew2"] = p["skew"] if p["skew2"] is None else p["skew2"]
        planes.append(MirrorPlane(p["offset2"], _deg(p["fold2"]), _deg(p["skew2"])))
    return reflect_panel(radius=p["radius"], arc=_deg(p["arc"]), width=width, planes=planes,
                         columns=p["columns"], rows=p["rows"])


def _build_trifold(p: dict):
    from fabkit.generate.trifold import trifold_panel

    p["height"] = p["depth"] if p["height"] is None else p["height"]
    return trifold_panel(length=p["length"], depth=p["depth"], height=p["height"], bevel=p["bevel"],
                         extrude=p["extrude"], resolution=p["resolution"], rows=p["rows"])


def _build_canopy(p: dict):
    from fabkit.panels.surface import canopy_lowpoly

    return canopy_lowpoly(length=p["length"], width=p["width"], height=p["height"], arch=p["arch"], wave=p["wave"],
                          waves=p["waves"], stations=p["stations"], sweep=p["sweep"])


def _build_pleated(p: dict):
    from fabkit.generate.pleated import pleated_vault

    return pleated_vault(rows=p["rows"], fold=_deg(p["fold"]), radius=p["radius"], arc=_deg(p["arc"]),
                         length=p["length"], columns=p["columns"], rows_per_band=p["rows_per_band"])


def _build_cube(p: dict):
    from fabkit.generate.polyhedra import cube
    from fabkit.generate.subdivide import catmull_clark

    return catmull_clark(cube(p["size"]), p["subdivide"])


def _build_prism(p: dict):
    from fabkit.generate.polyhedra import prism
    from fabkit.generate.subdivide import catmull_clark

    return catmull_clark(prism(p["sides"], p["radius"], p["height"]), p["subdivide"])


def _build_grid(p: dict):
    from fabkit.generate.polyhedra import grid

    return grid(p["nx"], p["ny"], p["size_x"], p["size_y"])


PRESETS: dict[str, tuple[Callable, dict[str, Param]]] = {
    "reflect": (_build_reflect, {
        "radius": Param(float, 0.5, "cylinder radius [m]", True),
        "arc": Param(float, 60.0, "angle the strip spans around the cylinder axis [deg]", True),
        "width": Param(float, 0.6, "length of the generators [m]", True),
        "creases": Param(int, 1, "number of creases (1 or 2)", True),
        "offset": Param(float, None, "height of crease 1 on the middle generator [m]"),
        "fold": Param(float, 60.0, "fold angle of crease 1 at the middle (valley +) [deg]"),
        "skew": Param(float, 0.0, "slope of crease 1 in the development at the middle [deg]"),
        "offset2": Param(float, None, "height of crease 2 on the middle generator [m]"),
        "fold2": Param(float, None, "fold angle of crease 2 [deg]"),
        "skew2": Param(float, None, "slope of crease 2 [deg]"),
        "columns": Param(int, 24, "quads along the creases", True),
        "rows": Param(int, 4, "quads across each strip", True),
    }),
    "trifold": (_build_trifold, {
        "length": Param(float, 1.6, "box length along the creases [m]", True),
        "depth": Param(float, 0.8, "box depth [m]", True),
        "height": Param(float, None, "box height [m] (default: depth)", True),
        "bevel": Param(float, 0.2, "Conway bevel fraction, in (0, 1/2)", True),
        "extrude": Param(float, 0.12, "width of the outer strips [m]", True),
        "resolution": Param(int, 16, "columns along the creases (rounded up to a power of 2)", True),
        "rows": Param(int, 1, "rows of faces per strip (a power of 2)", True),
    }),
    "canopy": (_build_canopy, {
        "length": Param(float, 6.0, "canopy length along x [m]", True),
        "width": Param(float, 2.4, "canopy width [m]", True),
        "height": Param(float, 2.2, "ridge height [m]", True),
        "arch": Param(float, 0.5, "extra rise of the ridge above the wave [m]"),
        "wave": Param(float, 0.35, "amplitude of the ridge wave [m]"),
        "waves": Param(int, 2, "wave periods along the canopy", True),
        "stations": Param(int, 9, "low-poly vertices along the canopy (>= 3)", True),
        "sweep": Param(float, 0.3, "sideways sweep of the ridge [m]"),
    }),
    "pleated": (_build_pleated, {
        "rows": Param(int, 14, "bands = creases, an even number", True),
        "fold": Param(float, 40.0, "fold angle of every crease at the vault's middle [deg]", True),
        "radius": Param(float, 1.5, "vault radius [m]", True),
        "arc": Param(float, 90.0, "angle the vault spans around its axis [deg]", True),
        "length": Param(float, 6.0, "vault length along its axis [m]", True),
        "columns": Param(int, 42, "quads around the vault (panels per band x columns per panel)", True),
        "rows_per_band": Param(int, 8, "quads along the axis per band, even (the crease in the middle)", True),
    }),
    "cube": (_build_cube, {
        "size": Param(float, 1.0, "edge length [m]", True),
        "subdivide": Param(int, 0, "Catmull-Clark levels"),
    }),
    "prism": (_build_prism, {
        "sides": Param(int, 6, "sides of the base polygon", True),
        "radius": Param(float, 0.5, "circumradius of the base [m]", True),
        "height": Param(float, 1.0, "prism height [m]", True),
        "subdivide": Param(int, 0, "Catmull-Clark levels"),
    }),
    "grid": (_build_grid, {
        "nx": Param(int, 10, "quads along x", True),
        "ny": Param(int, 10, "quads along y", True),
        "size_x": Param(float, 1.0, "extent along x [m]", True),
        "size_y": Param(float, 1.0, "extent along y [m]", True),
    }),
}

MAX_FACES = 5_000_000  # refuse absurd resolutions before allocating them


def convert_param(preset: str, name: str, raw, spec: Param):
    """One parameter value (a string as typed, or a number) checked against its `Param`."""
    opt = f"--{name.replace('_', '-')}"
    try:
        if isinstance(raw, bool) or not isinstance(raw, (str, int, float)):
            raise ValueError
        if spec.kind is float:
            value = float(raw)
        elif isinstance(raw, str):
            value = int(raw, 10)
        elif float(raw).is_integer():
            value = int(raw)
        else:
            raise ValueError
    except (ValueError, OverflowError):
        kind = "a number" if spec.kind is float else "an integer"
        raise InputError(f"{opt} must be {kind}, got {raw!r}", source=f"preset {preset}") from None
    if spec.kind is float and not math.isfinite(value):
        raise InputError(f"{opt} must be finite, got {raw!r}", source=f"preset {preset}")
    if spec.positive and value <= 0:
        raise InputError(f"{opt} must be positive, got {raw}", source=f"preset {preset}")
    if spec.kind is int and value < 0:
        raise InputError(f"{opt} must not be negative, got {raw}", source=f"preset {preset}")
    return value


def resolve_params(preset: str, given: dict) -> dict:
    """Preset parameters from `given` ({name: value}, None = not given): defaults filled, types and
    signs checked, parameters the preset does not have refused."""
    if preset not in PRESETS:
        raise InputError(f"unknown preset {preset!r}; choose one of: {', '.join(PRESETS)}")
    _, params = PRESETS[preset]
    given = {k: v for k, v in given.items() if v is not None}
    foreign = sorted(set(given) - set(params))
    if foreign:
        opts = ", ".join(f"--{n.replace('_', '-')}" for n in foreign)
        raise InputError(f"preset {preset} has no parameter {opts} (it takes: "
                         f"{', '.join('--' + n.replace('_', '-') for n in params)})")
    out = {}
    for name, spec in params.items():
        out[name] = convert_param(preset, name, given[name], spec) if name in given else spec.default
    return out


def estimate_faces(preset: str, p: dict) -> int:
    if preset == "reflect":
        return p["columns"] * p["rows"] * (p["creases"] + 1)
    if preset == "grid":
        return p["nx"] * p["ny"]
    if preset == "canopy":
        return 2 * p["stations"]
    if preset == "pleated":
        return p["rows"] * p["rows_per_band"] * p["columns"]
    if preset in ("cube", "prism"):
        base = 6 if preset == "cube" else 2 * p["sides"]
        return base * 4 ** min(p["subdivide"], 20)
    if preset == "trifold":
        return 3 * p["resolution"] * p["rows"]
    return 0


def build_preset(preset: str, **params):
    """Build preset `preset` with `params` (numbers or strings; missing ones take the defaults)
    -> `(mesh, parameters used)` (computed defaults filled in). Raises `InputError` naming the
    preset for unknown presets or parameters, bad values and meshes over `MAX_FACES` faces."""
    p = resolve_params(preset, params)
    if estimate_faces(preset, p) > MAX_FACES:
        raise InputError(f"these parameters make about {estimate_faces(preset, p):,} faces, more than the "
                         f"{MAX_FACES:,} fabkit generates; lower the resolution", source=f"preset {preset}")
    build, _ = PRESETS[preset]
    try:
        mesh = build(p)
    except InputError as exc:
        raise InputError(exc.message, source=f"preset {preset}") from None
    return mesh, p
