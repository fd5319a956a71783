"""Malformed OBJ / FOLD / PATH.json / CHECK.json / cell TOML inputs for every subcommand that reads them
(hypothesis, bounded): never exit 3, never a traceback, never a file left behind after a refusal, never
a temporary file left, and the input never changed. Runs in-process through `fabkit.cli.main`.

Inputs are mutations of a real pipeline run's files (a line or key dropped, a value replaced by any
JSON / TOML / OBJ token, the file cut short) plus free-form OBJ text: what a careless edit, another
tool or a truncated download gives.
"""
from __future__ import annotations

import json
import tempfile
from datetime import timedelta
from pathlib import Path

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from cli_inputs import make_inputs, run, snapshot, temp_files

SETTINGS = settings(max_examples=10, deadline=timedelta(seconds=30), derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                           HealthCheck.function_scoped_fixture])
PANELS_SMALL = ["--rows", "2", "--cols", "2", "--jobs", "1", "--no-plots", "--levels", "2",
                "--columns-per-panel", "2", "--max-rounds", "1"]

_inputs: dict[str, Path] = {}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    return make_inputs(tmp_path_factory.mktemp("inputs"))


# ---- strategies ---------------------------------------------------------------------------------

numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10, 10),
                    st.sampled_from([1e300, -1e300, 1e-300, 1e7, 0.0, -0.0]))
json_values = st.recursive(st.one_of(st.none(), st.booleans(), numbers, st.text(max_size=6)),
                           lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner,
                                                                                       max_size=3),
                           max_leaves=12)
obj_tokens = st.one_of(numbers.map(repr), st.integers(-3, 40).map(str),
                       st.sampled_from(["", "nan", "inf", "1/2/3", "x", "-", "1e999", "0", "v", "f"]),
                       st.text(alphabet="0123456789.-e/ x", max_size=6))


@st.composite
def mutated_lines(draw, text: str, tokens) -> str:
    """`text` with a few lines dropped, duplicated, cut, or one token replaced; or cut short."""
    lines = text.splitlines()
    for _ in range(draw(st.integers(1, 3))):
        if not lines:
            break
        i = draw(st.integers(0, len(lines) - 1))
        op = draw(st.sampled_from(["drop", "dup", "token", "insert", "cut"]))
        if op == "drop":
            del lines[i]
        elif op == "dup":
            lines.insert(i, lines[i])
        elif op == "token":
            words = lines[i].split(" ")
            words[draw(st.integers(0, len(words) - 1))] = draw(tokens)
            lines[i] = " ".join(words)
        elif op == "insert":
            lines.insert(i, " ".join(draw(st.lists(tokens, min_size=1, max_size=5))))
        else:
            lines = lines[:i]
    out = "\n".join(lines) + "\n"
    if draw(st.booleans()) and len(out) > 2:
        out = out[:draw(st.integers(1, len(out) - 1))]  # a truncated download
    return out


@st.composite
def mutated_json(draw, text: str) -> str:
    """A JSON document with one key dropped or replaced, one list element replaced, or cut short."""
    doc = json.loads(text)
    op = draw(st.sampled_from(["drop", "replace", "element", "cut", "not-an-object"]))
    if op == "cut":
        return text[:draw(st.integers(0, len(text) - 1))]
    if op == "not-an-object":
        return json.dumps(draw(json_values))
    key = draw(st.sampled_from(sorted(doc)))
    if op == "drop":
        del doc[key]
    elif op == "replace":
        doc[key] = draw(json_values)
    else:
        target = doc[key]
        while isinstance(target, list) and target and isinstance(target[0], (list, dict)) and draw(st.booleans()):
            target = target[draw(st.integers(0, len(target) - 1))]
        if isinstance(target, list) and target:
            target[draw(st.integers(0, len(target) - 1))] = draw(json_values)
        elif isinstance(target, dict) and target:
            target[draw(st.sampled_from(sorted(target)))] = draw(json_values)
        else:
            doc[key] = draw(json_values)
    return json.dumps(doc)


toml_tokens = st.sampled_from(['""', "1e999", "-1", "nan", "inf", '"x"', "[1, 2]", "[]", "0", "{}", "true",
                               "[[1,2,3]]", "1e300", "=", "[", "'''"])


# ---- the property ------------------------------------------------------------------------------

def check_run(argv_of, content: str, name: str, files: Path) -> None:
    """Write `content` as `name`, run `argv_of(bad, f, out)`, assert the contract."""
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        bad = tmp / "in" / name
        bad.parent.mkdir()
        bad.write_text(content, encoding="utf-8", errors="surrogatepass")
        out = tmp / "out"
        out.mkdir()
        before = snapshot(files, bad.parent)
        code, err = run(argv_of(str(bad), lambda n: str(files / n), str(out)))
        assert code != 3 and "Traceback" not in err and "internal error" not in err, err
        if code == 2:
            assert list(out.iterdir()) == [], (err, list(out.iterdir()))
            assert len([ln for ln in err.splitlines() if ln.strip()]) == 1, err
        assert temp_files(out, bad.parent, files) == []
        assert snapshot(files, bad.parent) == before


OBJ_COMMANDS = {
    "info": lambda bad, f, out: ["info", bad, "--report", f"{out}/r.json"],
    "relax": lambda bad, f, out: ["relax", bad, "-o", f"{out}/r.obj", "--max-seconds", "2", "--report",
                                  f"{out}/r.json"],
    "unfold": lambda bad, f, out: ["unfold", bad, "-o", f"{out}/flat.obj", "--svg", f"{out}/f.svg"],
    "refold-flat": lambda bad, f, out: ["refold", bad, f("relaxed.obj"), "-o", f"{out}/s.fold", "--frames", "3"],
    "refold-target": lambda bad, f, out: ["refold", f("flat.obj"), bad, "-o", f"{out}/s.fold", "--frames", "3"],
    "panels": lambda bad, f, out: ["panels", bad, "-o", f"{out}/p", *PANELS_SMALL],
}


@SETTINGS
@given(data=st.data(), command=st.sampled_from(sorted(OBJ_COMMANDS)))
def test_malformed_obj(files, data, command):
    source = "canopy.obj" if command == "panels" else "relaxed.obj"
    text = (files / source).read_text()
    content = data.draw(st.one_of(mutated_lines(text, obj_tokens),
                                  st.lists(st.tuples(st.sampled_from(["v", "f", "#", "vn", "o"]),
                                                     st.lists(obj_tokens, max_size=4)), max_size=8)
                                  .map(lambda ls: "\n".join(k + " " + " ".join(t) for k, t in ls))))
    check_run(OBJ_COMMANDS[command], content, "bad.obj", files)


FOLD_COMMANDS = {
    "info": lambda bad, f, out: ["info", bad, "--frame", "-1", "--report", f"{out}/r.json"],
    "toolpath": lambda bad, f, out: ["toolpath", bad, "--cell", f("cell.toml"), "-o", f"{out}/p.json",
                                     "--script", f"{out}/p.script"],
}


@settings(SETTINGS, max_examples=6)
@given(data=st.data(), command=st.sampled_from(sorted(FOLD_COMMANDS)))
def test_malformed_fold(files, data, command):
    content = data.draw(mutated_json((files / "fold.fold").read_text()))
    check_run(FOLD_COMMANDS[command], content, "bad.fold", files)


def _still_passes(check_text: str, path_text: str) -> bool:
    """True when a mutated CHECK/PATH pair would still be accepted (send would then drive an arm)."""
    try:
        c, p = json.loads(check_text), json.loads(path_text)
        return (isinstance(c, dict) and isinstance(p, dict) and c.get("ok") is True
                and c.get("format") == "fabkit.check/2" and c.get("toolpath_sha256") == p.get("sha256")
                and p == json.loads(_inputs["path"]))
    except (ValueError, AttributeError):
        return False


@settings(SETTINGS, max_examples=8)
@given(data=st.data(), command=st.sampled_from(["check", "send"]))
def test_malformed_toolpath(files, data, command):
    _inputs["path"] = (files / "path.json").read_text()
    content = data.draw(mutated_json(_inputs["path"]))
    if command == "send":
        assume(not _still_passes((files / "check.json").read_text(), content))
        argv = lambda bad, f, out: ["send", bad, "--check", f("check.json"), "--cell", f("cell.toml"), "--host", "127.0.0.9",  # noqa: E731
                                    "--report", f"{out}/s.json"]
    else:
        argv = lambda bad, f, out: ["check", bad, "--cell", f("cell.toml"), "--fold", f("fold.fold"),  # noqa: E731
                                    "-o", f"{out}/c.json"]
    check_run(argv, content, "bad.json", files)


@SETTINGS
@given(data=st.data())
def test_malformed_check_report(files, data):
    _inputs["path"] = (files / "path.json").read_text()
    content = data.draw(mutated_json((files / "check.json").read_text()))
    assume(not _still_passes(content, _inputs["path"]))
    check_run(lambda bad, f, out: ["send", f("path.json"), "--check", bad, "--cell", f("cell.toml"), "--host", "127.0.0.9",
                                   "--report", f"{out}/s.json"], content, "bad.json", files)


def _cell_is_valid(text: str) -> bool:
    import tomllib

    from fabkit.errors import InputError
    from robot.cell import parse_cell

    try:
        parse_cell(tomllib.loads(text), "cell")
        return True
    except (InputError, tomllib.TOMLDecodeError):
        return False


@SETTINGS
@given(data=st.data(), command=st.sampled_from(["toolpath", "check", "demo"]))
def test_malformed_cell(files, data, command):
    content = data.draw(mutated_lines((files / "cell.toml").read_text(), toml_tokens))
    if command == "demo":  # a valid cell would run the whole pipeline: only broken ones here
        assume(not _cell_is_valid(content))
    argv = {
        "toolpath": lambda bad, f, out: ["toolpath", f("fold.fold"), "--cell", bad, "-o", f"{out}/p.json"],
        "check": lambda bad, f, out: ["check", f("path.json"), "--cell", bad, "--fold", f("fold.fold"),
                                      "-o", f"{out}/c.json"],
        "demo": lambda bad, f, out: ["demo", "--out", f"{out}/d", "--cell", bad, "--small", "--no-render",
                                     "--no-dry-run"],
    }[command]
    check_run(argv, content, "cell.toml", files)
