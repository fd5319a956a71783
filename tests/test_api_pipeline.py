"""`import fabkit`: the six-line pipeline of docs/api.md on the built-in tri-fold and on a plain
untagged OBJ in millimetres, its CHECK report against the one `fabkit check` writes, and the
typed results (frozen, ok/problems, JSON)."""
from __future__ import annotations

import dataclasses
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

import fabkit
import fabkit.pipeline as fk
from fabkit.cli import main
from fabkit.io.jsonfile import to_jsonable

CELL = str(Path(__file__).resolve().parents[1] / "cells" / "ur5e_bench.toml")


def _cli(*argv) -> int:
    return main([str(a) for a in argv])


def _six_lines(panel, workdir):
    """The docs/api.md script (the demo's --small sizes: 4 fold states)."""
    relaxed = fk.relax(panel)
    flat = fk.unfold(relaxed)
    folds = fk.refold(flat, relaxed, frames=4)
    program = fk.plan(folds, CELL, workdir=workdir)
    report = fk.check(program)
    return relaxed, flat, folds, program, report


def _plain_mm_obj(tmp_path: Path) -> Path:
    """What a user brings: `fabkit generate reflect` without its `# fabkit` lines (no unit, no
    strip/middle tags), coordinates in millimetres."""
    tagged = tmp_path / "tagged.obj"
    assert _cli("generate", "reflect", "-o", tagged, "--columns", 8, "--rows", 2, "-q") == 0
    lines = []
    for line in tagged.read_text().splitlines():
        if line.startswith("# fabkit"):
            continue
        if line.startswith("v "):
            line = "v " + " ".join(repr(float(t) * 1000) for t in line.split()[1:4])
        lines.append(line)
    plain = tmp_path / "panel.obj"
    plain.write_text("\n".join(lines) + "\n")
    assert "fabkit" not in plain.read_text()
    return plain


def _assert_check_equals_cli(report, program, tmp_path: Path, render: Path | None = None) -> dict:
    cli_out = tmp_path / "cli_check.json"
    extra = [] if render is None else ["--render", render]
    assert _cli("check", program.path_file, "--cell", CELL, "-o", cli_out, "-q", *extra) == 0
    cli = json.loads(cli_out.read_text())
    assert json.loads(report.check_file.read_text()) == cli
    assert json.loads(json.dumps(to_jsonable(report.to_json()))) == cli
    return cli


def test_six_lines_on_the_trifold_give_the_check_report_of_fabkit_check(tmp_path):
    panel = fk.generate("trifold", resolution=6)
    relaxed, flat, folds, program, report = _six_lines(panel, tmp_path)
    for result in (panel, relaxed, flat, folds, program, report):
        assert result.ok and result.problems == (), result.problems
    from sim.render import select_gl_backend

    render = tmp_path / "cli.png" if select_gl_backend() is not None else None
    cli = _assert_check_equals_cli(report, program, tmp_path, render)
    if render is not None:  # fk.render draws what `fabkit check --render` draws: the same waypoint, the same pixels
        import imageio.v3 as iio

        drawn = fk.render(report, tmp_path / "api.png")
        assert drawn["path"] == str(tmp_path / "api.png") and 0 < drawn["waypoint"] < len(program.toolpath) - 1
        assert (iio.imread(tmp_path / "api.png") == iio.imread(render)).all()
        with pytest.raises(fabkit.InputError, match=r"\.png or \.mp4"):
            fk.render(report, tmp_path / "api.gif")
    assert cli["ok"] and cli["waypoints"] == len(program.toolpath) and cli["configs_checked"] > len(program.toolpath)
    assert cli["fold"]["path"] == str(program.fold_file)
    assert program.fold_file == tmp_path / "fold.fold" and program.path_file == tmp_path / "path.json"
    # the toolpath report: the numbers `fabkit toolpath --report` writes for the same FOLD file
    assert _cli("toolpath", program.fold_file, "--cell", CELL, "-o", tmp_path / "p2.json",
                "--report", tmp_path / "tp.json", "-q") == 0
    cli_tp = json.loads((tmp_path / "tp.json").read_text())
    ours = json.loads(json.dumps(program.to_json()))
    for key in ("toolpath_sha256", "waypoints", "grip_face", "branch", "cycle_time_s", "max_fold_joint_step_deg",
                "joint_speed_ratio", "min_singularity", "faces_tried", "states", "middle_row", "ok", "problems"):
        assert ours[key] == cli_tp[key], key


def test_six_lines_on_a_plain_millimetre_obj(tmp_path):
    plain = _plain_mm_obj(tmp_path)
    panel = fk.load(plain, units="mm")
    assert panel.loaded.unit == "mm" and 0.5 < panel.mesh.size < 2.0  # read as mm, metres inside
    assert not {"strip", "middle"} & set(panel.mesh.face_data)
    work = tmp_path / "work"
    work.mkdir()
    relaxed, flat, folds, program, report = _six_lines(panel, work)
    assert all(r.ok for r in (relaxed, flat, folds, program)), [r.problems for r in (relaxed, flat, folds, program)]
    assert folds.sequence.summary()["driven_hinges"] > 0  # creases and middle row inferred
    cli = _assert_check_equals_cli(report, program, tmp_path)
    assert cli["ok"] == report.ok and len(cli["problems"]) == len(report.problems)


def test_the_api_and_the_cli_chain_make_the_same_program(tmp_path):
    """The whole CLI chain on the same tri-fold gives the same toolpath and check numbers; only the
    FOLD file's bytes (its title names the files) and so the hashes differ."""
    panel = fk.generate("trifold", resolution=6)
    api = tmp_path / "api"
    api.mkdir()
    *_, program, report = _six_lines(panel, api)
    c = tmp_path / "cli"
    c.mkdir()
    steps = [("generate", "trifold", "-o", c / "t.obj", "--resolution", 6),
             ("relax", c / "t.obj", "-o", c / "r.obj"),
             ("unfold", c / "r.obj", "-o", c / "flat.obj"),
             ("refold", c / "flat.obj", c / "r.obj", "-o", c / "fold.fold", "--frames", 4),
             ("toolpath", c / "fold.fold", "--cell", CELL, "-o", c / "path.json"),
             ("check", c / "path.json", "--cell", CELL, "-o", c / "check.json")]
    for argv in steps:
        assert _cli(*argv, "-q") == 0, argv
    cli = json.loads((c / "check.json").read_text())
    ours = json.loads(report.check_file.read_text())
    for key in ("toolpath_sha256", "fold"):
        cli.pop(key), ours.pop(key)
    assert ours == cli
    cli_tp = json.loads((c / "path.json").read_text())
    api_tp = json.loads(program.path_file.read_text())
    assert [w["q"] for w in api_tp["waypoints"]] == [w["q"] for w in cli_tp["waypoints"]]


def test_results_are_frozen_typed_and_json(tmp_path):
    panel = fk.generate("reflect", columns=6, rows=2)
    relaxed = fk.relax(panel)
    flat = fk.unfold(relaxed, max_error=1e-6)
    folds = fk.refold(flat, frames=3)
    results = {fabkit.Panel: panel, fabkit.Relaxed: relaxed, fabkit.Flat: flat, fabkit.Folds: folds}
    for kind, result in results.items():
        assert type(result) is kind and dataclasses.is_dataclass(result)
        assert isinstance(result.ok, bool) and isinstance(result.problems, tuple)
        with pytest.raises(dataclasses.FrozenInstanceError):
            result.ok = not result.ok
        data = json.loads(json.dumps(result.to_json()))
        assert data["ok"] is result.ok and data["problems"] == list(result.problems)
    assert folds.to_json()["summary"]["states"] == 3
    assert relaxed.to_json()["final"]["max_abs_angle_defect_rad"] == relaxed.result.max_defect


def test_a_missed_tolerance_is_the_cli_verdict_and_stops_the_next_stage(tmp_path):
    panel = fk.generate("trifold", resolution=4)
    relaxed = fk.relax(panel, max_move=1e-9)
    assert not relaxed.ok and len(relaxed.problems) == 1
    assert "more than --max-move 1e-09" in relaxed.problems[0]
    with pytest.raises(fabkit.InputError, match="unfold needs a result that passed"):
        fk.unfold(relaxed)
    flat = fk.unfold(fk.relax(panel), max_error=1e-30)
    assert not flat.ok and flat.problems[0].startswith("max relative length deviation")
    # the CLI says the same for the same tolerance
    obj = tmp_path / "t.obj"
    assert _cli("generate", "trifold", "-o", obj, "--resolution", 4, "-q") == 0
    assert _cli("relax", obj, "-o", tmp_path / "r.obj", "-q") == 0
    assert _cli("unfold", tmp_path / "r.obj", "-o", tmp_path / "f.obj", "--max-error", "1e-30",
                "--report", tmp_path / "u.json", "-q") == 1
    assert json.loads((tmp_path / "u.json").read_text())["problems"] == list(flat.problems)


def test_not_a_fold_and_preset_rules_are_refused_as_the_cli_refuses_them():
    with pytest.raises(fabkit.InputError, match="--creases must be 1 or 2"):
        fk.generate("reflect", creases=3)
    with pytest.raises(fabkit.InputError, match="has no parameter --resolution"):
        fk.generate("reflect", resolution=6)
    a = fk.unfold(fk.generate("reflect", columns=6, rows=2, fold=30))
    b = fk.generate("reflect", columns=6, rows=2, fold=30, width=0.7)
    folds = fk.refold(a, b, frames=3)
    assert not folds.ok and folds.sequence is None and folds.model is None
    assert "worst_edge" in folds.to_json()


def test_import_fabkit_is_cheap_and_the_subpackages_stay_subpackages():
    code = ("import sys, fabkit, fabkit.pipeline as fk; "
            "heavy = [m for m in ('numpy', 'scipy', 'robot', 'sim') if m in sys.modules]; "
            "import fabkit.relax.solver as solver, fabkit.unfold.plot; from fabkit.refold import RefoldSolver; "
            "print(heavy, callable(fk.relax), callable(fk.unfold), callable(fk.refold), "
            "type(fabkit.relax).__name__, callable(solver.relax))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == "[] True True True module True"
    # fabkit reaches robot and sim only inside functions of the stage modules (and the CLI)
    root = Path(fabkit.__file__).parent
    reaching = set()
    for path in root.rglob("*.py"):
        text = path.read_text()
        assert not re.search(r"^(from|import) (robot|sim)\b", text, re.MULTILINE), path  # never at import time
        if re.search(r"^\s+(from|import) (robot|sim)\b", text, re.MULTILINE):
            reaching.add(path.relative_to(root).as_posix())
    reaching = {p for p in reaching if not p.startswith("commands/") and p != "cli.py"}
    assert reaching == {"pipeline.py", "toolpath_stage.py", "results.py"}, reaching


@pytest.mark.slow  # the stand-in plays the program in real time (~30 s)
def test_send_goes_through_the_safety_gate_to_the_stand_in(tmp_path):
    from _ursim import StandIn
    from robot.interlock import CheckFailedError

    panel = fk.generate("trifold", resolution=6)
    _, _, folds, program, report = _six_lines(panel, tmp_path)
    failed = dataclasses.replace(report, report=dataclasses.replace(report.report, ok=False), ok=False)
    with pytest.raises(CheckFailedError):
        fk.send(program, failed, host="127.0.0.1")  # refused before any connection
    with pytest.raises(fabkit.InputError, match=r"seconds in \(0, 5\]"):
        fk.send(program, report, host="127.0.0.1", stall=60)  # a stall limit that blunts the watchdog
    with pytest.raises(fabkit.InputError, match="not an IP address or host name"):
        fk.send(program, report, host="-robot-")
    # the dry run folds at the cell's TCP speed limit (38 s of motion at the default 0.05 m/s: 13.5 s)
    program = fk.plan(folds, CELL, workdir=tmp_path / "fast", fold_speed=0.25)
    report = fk.check(program)
    standin = StandIn("--cell", CELL, log=tmp_path / "ursim.log")
    try:
        sent = fk.send(program, report, host=standin.host, power_on=True)
        assert sent.ok and sent.problems == (), sent.problems
        assert sent.result.last_completed == len(program.toolpath) - 1
        assert sent.result.toolpath_sha256 == program.toolpath.sha256
        assert json.loads(json.dumps(to_jsonable(sent.to_json())))["ok"] is True
        final = standin.state()["q"]
        assert max(abs(a - b) for a, b in zip(final, program.toolpath.waypoints[-1]["q"])) < 1e-6
    finally:
        standin.stop()


def test_the_script_in_docs_api_runs_as_written(tmp_path, monkeypatch):
    """The first python block of docs/api.md, run in a folder holding panel.obj (plain, mm) and
    cells/; its CHECK report is the one `fabkit check` writes for its PATH.json."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "api.md").read_text()
    script = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    assert len([ln for ln in script.splitlines() if ln.strip() and not ln.startswith("import")]) == 6
    plain = _plain_mm_obj(tmp_path)
    assert plain == tmp_path / "panel.obj"
    (tmp_path / "cells").symlink_to(Path(CELL).parent)
    monkeypatch.chdir(tmp_path)
    scope: dict = {}
    exec(compile(script, "docs/api.md", "exec"), scope)
    report, program = scope["report"], scope["program"]
    assert report.ok, report.problems
    assert program.workdir == Path("out") and report.check_file == Path("out") / "check.json"
    _assert_check_equals_cli(report, program, tmp_path)


@pytest.mark.parametrize("panel, sheet", [
    ("trifold", ("--material", "5052-H32", "--thickness", "1mm")),
    ("plain-mm", ()),
    ("plain-mm", ("--material", "5052-H32", "--thickness", "1.6mm", "--tool-mass", "0.5",
                  "--design-surface", "mid")),
])
def test_fabkit_toolpath_writes_what_fk_plan_writes(tmp_path, panel, sheet, capsys):
    """`fabkit toolpath` is `fk.plan` on a FOLD file: the same PATH.json, URScript and report, byte
    for byte (the report differs only in the files it names), on the demo's tri-fold and on a plain
    millimetre OBJ, rigid and with a sheet."""
    source = fk.generate("trifold", resolution=6) if panel == "trifold" else fk.load(_plain_mm_obj(tmp_path), "mm")
    relaxed = fk.relax(source)
    folds = fk.refold(fk.unfold(relaxed), relaxed, frames=4)
    options = {sheet[i][2:].replace("-", "_"): sheet[i + 1] for i in range(0, len(sheet), 2)}
    if "tool_mass" in options:
        options["tool_mass"] = float(options["tool_mass"])
    program = fk.plan(folds, CELL, workdir=tmp_path / "api", **options)
    assert program.ok, program.problems
    assert (program.loads is not None) == bool(sheet)
    out = tmp_path / "cli"
    out.mkdir()
    argv = ["toolpath", program.fold_file, "--cell", CELL, "-o", out / "path.json", "--script", out / "p.script",
            "--report", out / "report.json", "-q", *sheet]
    capsys.readouterr()
    assert _cli(*argv) == 0
    err = capsys.readouterr().err
    assert (out / "path.json").read_bytes() == program.path_file.read_bytes()
    assert (out / "p.script").read_text() == program.urscript()
    report = json.loads((out / "report.json").read_text())
    assert report == json.loads(json.dumps(program.report(str(out / "path.json"), str(out / "p.script"))))
    assert report["input"] == str(program.fold_file) and report["ok"] and report["problems"] == []
    for note in program.notes:  # the CLI prints the stage's notes and load warnings
        assert f"fabkit toolpath: note: {note}" in err
    for line in ([] if program.loads is None else program.loads.failure_lines()):
        assert f"fabkit toolpath: warning: {line}" in err


def test_every_toolpath_option_is_a_plan_setting():
    """`fabkit toolpath`'s planning options are the fields of the one record `fk.plan` takes, and
    both refuse a bad value with the same message."""
    from fabkit.cli import build_parser
    from fabkit.toolpath_stage import PlanSettings

    options = vars(build_parser("toolpath").parse_args(["toolpath", "s.fold", "--cell", "c.toml", "-o", "p.json"]))
    files = {"command", "fold", "cell", "output", "script", "report", "quiet", "units", "progress_register",
             "handshake_timeout"}
    assert {k for k in options if not k.startswith("_")} - files == set(PlanSettings.field_names())
    with pytest.raises(fabkit.InputError, match=r"--approach.*not in \(0, 0.5\]"):
        PlanSettings(approach=-1.0).check()
    with pytest.raises(fabkit.InputError, match="unknown option"):
        fk.plan(fk.Folds(sequence=None, model=None, name="x", target_tol=1e-6, ok=True, problems=()), CELL,
                gripper_colour="red")
