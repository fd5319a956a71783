"""Sheet materials as data: one TOML file per alloy and temper in `fabkit/materials/data/`.

`load_material(path)` reads and validates one file; `library()` gives every packaged material by
name; `get_material(name_or_path)` resolves what a user typed after `--material` (a packaged name,
case-insensitive, or a path to a `.toml` file, e.g. one written by `fabkit materials --calibrate`).
Every problem is one `InputError` naming the file and the field.

In memory everything is SI: Pa, m, kg/m^3. The files use the units their keys name
(`yield_stress_mpa`, `thicknesses_mm`, ...), the way handbooks print them.

A material is either `rigid` (the `none` material: no springback, no mass, no fold moment; the
design shape is programmed as is) or an elastic-plastic sheet with: density, Young's modulus,
Poisson's ratio, yield stress and UTS; a springback model (`elastic-plastic`, flow stress `yield`
or `mean` = (yield + UTS) / 2, and a calibration factor on the predicted springback); a K-factor
(a number, or `din6935`); the minimum inside bend radius of plain creases by thickness column; and
the crease preparations it allows (plain, grooved to a ligament, perforated).
"""
from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, replace
from pathlib import Path

from fabkit.errors import InputError

__all__ = ["Material", "CreasePrep", "PREPARATIONS", "DATA_DIR", "load_material", "parse_material", "library",
           "get_material", "parse_length", "crease_prep", "material_toml"]

DATA_DIR = Path(__file__).with_name("data")
PREPARATIONS = ("plain", "grooved", "perforated")
SPRINGBACK_MODELS = ("elastic-plastic",)
FLOW_STRESSES = ("yield", "mean")
_MPA, _GPA, _MM = 1e6, 1e9, 1e-3


@dataclass(frozen=True)
class CreasePrep:
    """How a crease is prepared: `kind` plain | grooved | perforated; `ligament` [m] left under a
    groove (grooved only); `uncut_fraction` of the crease length carried by the bridges (perforated)."""

    kind: str = "plain"
    ligament: float | None = None
    uncut_fraction: float | None = None

    def describe(self) -> str:
        if self.kind == "grooved":
            return f"grooved to a {self.ligament * 1000:g} mm ligament"
        if self.kind == "perforated":
            return f"perforated ({self.uncut_fraction:.0%} uncut)"
        return "plain (unscored)"


@dataclass(frozen=True)
class Material:
    """One sheet material (module docstring). SI units; `min_radius` rows are (thickness column
    upper bound [m], minimum inside radius as a multiple of t)."""

    name: str
    description: str
    rigid: bool = False
    family: str = ""
    alloy: str = ""
    temper: str = ""
    thicknesses: tuple[float, ...] = ()
    density: float = 0.0
    youngs_modulus: float = 0.0
    poisson_ratio: float = 0.0
    yield_stress: float = 0.0
    uts: float = 0.0
    springback_model: str = "elastic-plastic"
    flow_stress_rule: str = "mean"
    calibration: float = 1.0
    calibration_note: str = ""
    k_factor: float | str = "din6935"
    min_radius: tuple[tuple[float, float], ...] = ()
    min_radius_floor: float = 0.0
    preparations: tuple[str, ...] = ("plain",)
    groove_ligament: float | None = None
    perforation_uncut_fraction: float | None = None
    sources: tuple[str, ...] = ()
    source: str = ""

    @property
    def flow_stress(self) -> float:
        """The stress [Pa] the springback and fold-moment upper bound use."""
        return self.yield_stress if self.flow_stress_rule == "yield" else 0.5 * (self.yield_stress + self.uts)

    def with_calibration(self, factor: float, note: str, name: str | None = None) -> "Material":
        return replace(self, calibration=float(factor), calibration_note=note, name=name or self.name)

    def summary(self) -> dict:
        """JSON-ready description (files' units: mm, MPa, GPa)."""
        if self.rigid:
            return {"name": self.name, "rigid": True, "description": self.description, "source": self.source}
        return {
            "name": self.name, "rigid": False, "description": self.description, "family": self.family,
            "alloy": self.alloy, "temper": self.temper, "thicknesses_mm": [t / _MM for t in self.thicknesses],
            "density_kg_m3": self.density, "youngs_modulus_gpa": self.youngs_modulus / _GPA,
            "poisson_ratio": self.poisson_ratio, "yield_stress_mpa": self.yield_stress / _MPA,
            "uts_mpa": self.uts / _MPA, "springback": {"model": self.springback_model,
                                                        "flow_stress": self.flow_stress_rule,
                                                        "calibration": self.calibration,
                                                        "calibration_note": self.calibration_note},
            "k_factor": self.k_factor, "min_radius": [[c / _MM, m] for c, m in self.min_radius],
            "min_radius_floor_mm": self.min_radius_floor / _MM, "preparations": list(self.preparations),
            "groove_ligament_mm": None if self.groove_ligament is None else self.groove_ligament / _MM,
            "perforation_uncut_fraction": self.perforation_uncut_fraction, "sources": list(self.sources),
            "source": self.source,
        }


class _Fields:
    """Reads one table of a material file; every failure names the file and the field."""

    def __init__(self, table: dict, source: str, prefix: str = ""):
        self.table, self.source, self.prefix = table, source, prefix
        self.seen: set[str] = set()

    def fail(self, key: str, message: str):
        raise InputError(f"{self.prefix}{key}: {message}", source=self.source)

    def get(self, key: str, kind, required: bool = True, default=None):
        self.seen.add(key)
        if key not in self.table:
            if required:
                self.fail(key, "missing")
            return default
        v = self.table[key]
        if kind is float:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                self.fail(key, f"must be a finite number, got {v!r}")
            return float(v)
        if not isinstance(v, kind):
            self.fail(key, f"must be a {kind.__name__}, got {type(v).__name__}")
        return v

    def positive(self, key: str, required: bool = True, default=None, hi: float | None = None) -> float | None:
        v = self.get(key, float, required, default)
        if v is None:
            return None
        if v <= 0 or (hi is not None and v > hi):
            self.fail(key, f"must be in (0, {hi:g}], got {v:g}" if hi is not None else f"must be > 0, got {v:g}")
        return v

    def strings(self, key: str, required: bool = True, default=()) -> tuple[str, ...]:
        v = self.get(key, list, required, list(default))
        if not all(isinstance(s, str) for s in v):
            self.fail(key, "must be a list of strings")
        return tuple(v)

    def sub(self, key: str, required: bool = True) -> "_Fields":
        t = self.get(key, dict, required, {})
        return _Fields(t, self.source, f"{self.prefix}{key}.")

    def done(self) -> None:
        extra = sorted(set(self.table) - self.seen)
        if extra:
            self.fail(extra[0], "unknown field")


def parse_material(data: dict, source: str) -> Material:
    """Validate the parsed TOML of one material file (module docstring)."""
    f = _Fields(data, source)
    name = f.get("name", str)
    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.+-]*", name):
        f.fail("name", f"{name!r} must be letters, digits and . _ + - (no spaces)")
    description = f.get("description", str, required=False, default="")
    rigid = f.get("rigid", bool, required=False, default=False)
    if rigid:
        f.done()
        return Material(name=name, description=description, rigid=True, source=source)
    family, alloy, temper = (f.get(k, str) for k in ("family", "alloy", "temper"))
    thick = f.get("thicknesses_mm", list)
    if not thick or not all(isinstance(t, (int, float)) and not isinstance(t, bool) and 0 < t <= 50 for t in thick):
        f.fail("thicknesses_mm", "must be a non-empty list of thicknesses in (0, 50] mm")
    density = f.positive("density_kg_m3", hi=25000)
    E = f.positive("youngs_modulus_gpa", hi=1000) * _GPA
    nu = f.get("poisson_ratio", float)
    if not 0 <= nu < 0.5:
        f.fail("poisson_ratio", f"must be in [0, 0.5), got {nu:g}")
    sy = f.positive("yield_stress_mpa", hi=5000) * _MPA
    uts = f.positive("uts_mpa", hi=5000) * _MPA
    if uts < sy:
        f.fail("uts_mpa", f"{uts / _MPA:g} MPa is below the yield stress {sy / _MPA:g} MPa")
    sources = f.strings("sources", required=False)

    sb = f.sub("springback")
    model = sb.get("model", str)
    if model not in SPRINGBACK_MODELS:
        sb.fail("model", f"unknown model {model!r} (known: {', '.join(SPRINGBACK_MODELS)})")
    flow = sb.get("flow_stress", str, required=False, default="mean")
    if flow not in FLOW_STRESSES:
        sb.fail("flow_stress", f"must be one of {', '.join(FLOW_STRESSES)}, got {flow!r}")
    cal = sb.positive("calibration", hi=20)
    cal_note = sb.get("calibration_note", str, required=False, default="")
    sb.done()

    bend = f.sub("bend")
    kf = bend.table.get("k_factor", "din6935")
    bend.seen.add("k_factor")
    if isinstance(kf, str):
        if kf != "din6935":
            bend.fail("k_factor", f"must be a number in [0, 0.5] or \"din6935\", got {kf!r}")
    elif isinstance(kf, bool) or not isinstance(kf, (int, float)) or not 0 <= kf <= 0.5:
        bend.fail("k_factor", f"must be a number in [0, 0.5] or \"din6935\", got {kf!r}")
    else:
        kf = float(kf)
    rows = bend.get("min_radius", list)
    ok = bool(rows) and all(isinstance(r, list) and len(r) == 2 and all(
        isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x >= 0 for x in r)
        for r in rows)
    if not ok or any(rows[i][0] >= rows[i + 1][0] for i in range(len(rows) - 1)) or rows[0][0] <= 0:
        bend.fail("min_radius", "must be rows [thickness column mm > 0, multiple of t >= 0] in increasing thickness")
    floor = bend.get("min_radius_floor_mm", float, required=False, default=0.0)
    if floor < 0:
        bend.fail("min_radius_floor_mm", f"must be >= 0, got {floor:g}")
    bend.done()

    cr = f.sub("crease")
    preps = cr.strings("preparations")
    bad = [p for p in preps if p not in PREPARATIONS]
    if bad or "plain" not in preps:
        cr.fail("preparations", f"must include \"plain\" and name only {', '.join(PREPARATIONS)}")
    lig = cr.positive("groove_ligament_mm", required="grooved" in preps, hi=50)
    uncut = cr.positive("perforation_uncut_fraction", required="perforated" in preps, hi=1.0)
    cr.done()
    f.done()
    return Material(
        name=name, description=description, family=family, alloy=alloy, temper=temper,
        thicknesses=tuple(float(t) * _MM for t in thick), density=density, youngs_modulus=E, poisson_ratio=nu,
        yield_stress=sy, uts=uts, springback_model=model, flow_stress_rule=flow, calibration=cal,
        calibration_note=cal_note, k_factor=kf, min_radius=tuple((r[0] * _MM, float(r[1])) for r in rows),
        min_radius_floor=floor * _MM, preparations=preps, groove_ligament=None if lig is None else lig * _MM,
        perforation_uncut_fraction=uncut, sources=sources, source=source)


def load_material(path: str | Path) -> Material:
    """Read and validate one material TOML file (`InputError` naming the file and field)."""
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", source=str(path)) from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"not valid TOML: {exc}", source=str(path)) from None
    return parse_material(data, str(path))


def library(directory: str | Path = DATA_DIR) -> dict[str, Material]:
    """Every material in `directory` (default: the packaged ones) by name, sorted by name."""
    out: dict[str, Material] = {}
    for p in sorted(Path(directory).glob("*.toml")):
        m = load_material(p)
        if m.name.lower() in {k.lower() for k in out}:
            raise InputError(f"name {m.name!r} is used by two files", source=str(p))
        out[m.name] = m
    return dict(sorted(out.items(), key=lambda kv: kv[0].lower()))


def get_material(name: str | Path) -> Material:
    """A packaged material by name (case-insensitive; spaces count as '-'), or a `.toml` file."""
    text = str(name)
    if text.endswith(".toml") or "/" in text:
        return load_material(text)
    lib = library()
    want = text.strip().lower().replace(" ", "-")
    for k, m in lib.items():
        if k.lower() == want:
            return m
    raise InputError(f"unknown material {text!r} (known: {', '.join(lib)}; or a path to a .toml file)",
                     source="--material")


_LENGTH = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(mm|m|in)\s*$")


def parse_length(text: str, source: str = "--thickness", allow_zero: bool = False) -> float:
    """'1mm', '1.6 mm', '0.002m', '0.0625in' -> metres, in (0, 50] mm ([0, 50] with `allow_zero`).
    A bare number is refused: the unit must be said."""
    m = _LENGTH.match(str(text))
    if not m:
        raise InputError(f"{text!r} is not a length with a unit (e.g. 1mm, 1.6 mm, 0.002m)", source=source)
    v = float(m.group(1)) * {"mm": 1e-3, "m": 1.0, "in": 0.0254}[m.group(2)]
    if not (math.isfinite(v) and (0 <= v if allow_zero else 0 < v) and v <= 0.05):
        raise InputError(f"{text!r} must be in {'[0' if allow_zero else '(0'}, 50] mm", source=source)
    return v


def crease_prep(material: Material, kind: str = "plain", ligament: float | None = None,
                uncut_fraction: float | None = None, thickness: float | None = None) -> CreasePrep:
    """A crease preparation the material allows, with the material's defaults filled in
    (`InputError` naming the material when it is not allowed or does not fit the thickness)."""
    if kind not in PREPARATIONS:
        raise InputError(f"unknown crease preparation {kind!r} (choose {', '.join(PREPARATIONS)})", source="--crease")
    if material.rigid:
        return CreasePrep("plain")
    if kind not in material.preparations:
        raise InputError(f"{material.name} does not allow {kind} creases (allowed: "
                         f"{', '.join(material.preparations)})", source="--crease")
    if kind == "grooved":
        lig = material.groove_ligament if ligament is None else float(ligament)
        if not (lig is not None and math.isfinite(lig) and lig > 0):
            raise InputError(f"a groove ligament must be > 0, got {lig}", source="--ligament")
        if thickness is not None and lig >= thickness:
            raise InputError(f"a {lig * 1000:g} mm ligament is not thinner than the {thickness * 1000:g} mm sheet",
                             source="--ligament")
        return CreasePrep("grooved", ligament=lig)
    if kind == "perforated":
        u = material.perforation_uncut_fraction if uncut_fraction is None else float(uncut_fraction)
        if not (u is not None and 0 < u <= 1):
            raise InputError(f"the uncut fraction must be in (0, 1], got {u}", source="--uncut-fraction")
        return CreasePrep("perforated", uncut_fraction=u)
    return CreasePrep("plain")


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(float(v)) if isinstance(v, float) else str(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return "[" + ", ".join(_toml_value(x) for x in v) + "]"


def material_toml(m: Material, header: str = "") -> str:
    """The material as a TOML file `load_material` reads back to an equal `Material` (but `source`)."""
    s = m.summary()
    lines = [f"# {line}" for line in header.splitlines()]
    lines.append(f"name = {_toml_value(m.name)}")
    if m.rigid:
        return "\n".join(lines + ["rigid = true", f"description = {_toml_value(m.description)}"]) + "\n"
    for k in ("family", "alloy", "temper", "description", "thicknesses_mm", "density_kg_m3", "youngs_modulus_gpa",
              "poisson_ratio", "yield_stress_mpa", "uts_mpa", "sources"):
        lines.append(f"{k} = {_toml_value(s[k])}")
    lines += ["", "[springback]", f"model = {_toml_value(m.springback_model)}",
              f"flow_stress = {_toml_value(m.flow_stress_rule)}", f"calibration = {_toml_value(m.calibration)}",
              f"calibration_note = {_toml_value(m.calibration_note)}", "", "[bend]",
              f"k_factor = {_toml_value(m.k_factor)}", f"min_radius = {_toml_value(s['min_radius'])}"]
    if m.min_radius_floor:
        lines.append(f"min_radius_floor_mm = {_toml_value(s['min_radius_floor_mm'])}")
    lines += ["", "[crease]", f"preparations = {_toml_value(m.preparations)}"]
    if m.groove_ligament is not None:
        lines.append(f"groove_ligament_mm = {_toml_value(s['groove_ligament_mm'])}")
    if m.perforation_uncut_fraction is not None:
        lines.append(f"perforation_uncut_fraction = {_toml_value(m.perforation_uncut_fraction)}")
    return "\n".join(lines) + "\n"
