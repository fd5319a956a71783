"""The material library (TOML data + loader), `fabkit materials`, and springback calibration."""
import json
import math
import tomllib
from dataclasses import replace

import pytest

from fabkit.cli import main as fabkit_main
from fabkit.errors import InputError
from fabkit.materials import DATA_DIR, get_material, library, load_material, material_toml, parse_length, parse_material
from fabkit.materials.calibrate import calibrate
from fabkit.sheet import released_angle, sheet_spec, springback_ratio

REQUIRED = ["1100-H14", "3003-H14", "5052-H32", "6061-T6", "mild-steel", "304-stainless", "none"]


def test_library_has_the_materials_and_they_round_trip():
    lib = library()
    assert set(REQUIRED) <= set(lib)
    for name, m in lib.items():
        back = parse_material(tomllib.loads(material_toml(m)), "back.toml")
        assert replace(back, source="") == replace(m, source=""), name
    m = lib["5052-H32"]
    assert (m.yield_stress, m.uts, m.density) == (193e6, 228e6, 2680.0)
    assert m.youngs_modulus == pytest.approx(70.3e9) and m.flow_stress == pytest.approx(210.5e6)
    assert lib["none"].rigid and "grooved" not in lib["6061-T6"].preparations


def test_names_are_case_insensitive_and_paths_work(tmp_path):
    assert get_material("5052-h32").name == "5052-H32"
    assert get_material("Mild Steel").name == "mild-steel"
    p = tmp_path / "mine.toml"
    p.write_text((DATA_DIR / "3003-H14.toml").read_text().replace('name = "3003-H14"', 'name = "mine"'))
    assert get_material(str(p)).name == "mine"
    with pytest.raises(InputError, match="unknown material 'brass'.*5052-H32"):
        get_material("brass")


GOOD = (DATA_DIR / "5052-H32.toml").read_text()


@pytest.mark.parametrize("edit,field", [
    (("yield_stress_mpa = 193", "yield_stress_mpa = -193"), "yield_stress_mpa"),
    (("uts_mpa = 228", "uts_mpa = 100"), "uts_mpa"),
    (("poisson_ratio = 0.33", "poisson_ratio = 0.6"), "poisson_ratio"),
    (("density_kg_m3 = 2680", "density_kg_m3 = \"heavy\""), "density_kg_m3"),
    (("calibration = 2.47", "calibration = 0"), "springback.calibration"),
    (("model = \"elastic-plastic\"", "model = \"magic\""), "springback.model"),
    (("k_factor = \"din6935\"", "k_factor = 0.9"), "bend.k_factor"),
    (("[[0.4, 0.0], [0.8, 0.0]", "[[0.8, 0.0], [0.4, 0.0]"), "bend.min_radius"),
    (("preparations = [\"plain\", \"grooved\", \"perforated\"]", "preparations = [\"scored\"]"),
     "crease.preparations"),
    (("temper = \"H32\"\n", "temper = \"H32\"\ncolour = \"silver\"\n"), "colour"),
    (("name = \"5052-H32\"", "name = \"5052 H32\""), "name"),
    (("thicknesses_mm = [0.5,", "thicknesses_mm = [-0.5,"), "thicknesses_mm"),
])
def test_bad_material_files_name_file_and_field(tmp_path, edit, field, capsys):
    assert edit[0] in GOOD
    p = tmp_path / "bad.toml"
    p.write_text(GOOD.replace(edit[0], edit[1], 1))
    with pytest.raises(InputError) as exc:
        load_material(p)
    assert str(exc.value).startswith(f"{p}: {field}:")
    assert fabkit_main(["materials", str(p)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(p) in err and field in err


def test_missing_field_and_broken_toml(tmp_path):
    p = tmp_path / "m.toml"
    p.write_text(GOOD.replace("youngs_modulus_gpa = 70.3\n", ""))
    with pytest.raises(InputError, match="youngs_modulus_gpa: missing"):
        load_material(p)
    p.write_text("name = [")
    with pytest.raises(InputError, match="not valid TOML"):
        load_material(p)


def test_lengths_need_a_unit():
    assert parse_length("1mm") == pytest.approx(1e-3) and parse_length("1.6 mm") == pytest.approx(1.6e-3)
    assert parse_length("0.002m") == pytest.approx(2e-3) and parse_length("0.0625in") == pytest.approx(1.5875e-3)
    for bad in ("1", "1 cm", "-1mm", "0mm", "60mm"):
        with pytest.raises(InputError, match="--thickness"):
            parse_length(bad)
    assert parse_length("0mm", "--bend-radius", allow_zero=True) == 0.0


def test_materials_command_lists_and_reports(tmp_path, capsys):
    rep = tmp_path / "r.json"
    assert fabkit_main(["materials", "--report", str(rep)]) == 0
    out = capsys.readouterr().out
    for name in REQUIRED:
        assert name in out
    doc = json.loads(rep.read_text())
    names = [m["name"] for m in doc["materials"]]
    assert set(REQUIRED) <= set(names)
    al = next(m for m in doc["materials"] if m["name"] == "5052-H32")
    assert al["yield_stress_mpa"] == 193 and al["springback"]["calibration"] == 2.47


def _synthetic(factor, folds=((90.0,), (45.0,), (120.0,))):
    """Test folds as a sheet with springback factor `factor` would measure them."""
    base = get_material("3003-H14")
    spec = sheet_spec(replace(base, calibration=factor), 1.5e-3, inside_radius=3e-3)
    rows = []
    for (p,) in folds:
        rows.append({"programmed_deg": p, "measured_deg": math.degrees(released_angle(spec, math.radians(p)))})
    return {"material": "3003-H14", "thickness_mm": 1.5, "inside_radius_mm": 3.0, "name": "3003-H14-cal",
            "folds": rows}


def test_calibration_recovers_a_known_factor():
    cal = calibrate(_synthetic(1.7), "cal.toml")
    assert cal.factor == pytest.approx(1.7, rel=1e-12) and cal.rms_residual < 1e-12
    m = cal.material
    assert m.name == "3003-H14-cal" and m.calibration == pytest.approx(1.7)
    spec = sheet_spec(m, 1.5e-3, inside_radius=3e-3)
    assert springback_ratio(spec) == pytest.approx(1 - 1.7 * (1 - springback_ratio(spec, calibrated=False)))


def test_calibrate_command_writes_a_material_the_toolchain_reads(tmp_path, capsys):
    data = _synthetic(2.2)
    lines = [f'material = "{data["material"]}"', "thickness_mm = 1.5", "inside_radius_mm = 3.0",
             'name = "3003-H14-cal"']
    for f in data["folds"]:
        lines += ["[[folds]]", f"programmed_deg = {f['programmed_deg']!r}", f"measured_deg = {f['measured_deg']!r}"]
    src = tmp_path / "folds.toml"
    src.write_text("\n".join(lines) + "\n")
    out = tmp_path / "cal.toml"
    assert fabkit_main(["materials", "--calibrate", str(src), "-o", str(out), "-q"]) == 0
    m = load_material(out)
    assert m.calibration == pytest.approx(2.2, rel=1e-9) and m.name == "3003-H14-cal"
    assert get_material(str(out)).calibration == m.calibration


@pytest.mark.parametrize("edit,message", [
    ({"folds": [{"programmed_deg": 90, "measured_deg": 95}]}, "folds\\[0\\]: measured 95 deg is more folded"),
    ({"folds": []}, "folds: needs at least one"),
    ({"material": "none"}, "rigid"),
    ({"thickness_mm": -1}, "thickness_mm"),
    ({"crease": "grooved", "ligament_mm": 2.0}, "not thinner"),
    ({"colour": "red"}, "colour: unknown field"),
])
def test_bad_calibration_files(edit, message, tmp_path, capsys):
    data = {**_synthetic(1.5), **edit}
    with pytest.raises(InputError, match=message):
        calibrate(data, "folds.toml")
    src = tmp_path / "c.toml"
    src.write_text("material = 3\n")
    out = tmp_path / "o.toml"
    assert fabkit_main(["materials", "--calibrate", str(src), "-o", str(out)]) == 2
    assert not out.exists() and "c.toml" in capsys.readouterr().err
