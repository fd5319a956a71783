"""The send interlock, without a controller: a fold program planned and checked by the CLI is refused
by `fabkit send` and by the library's `send_toolpath` - before any connection - when anything that
decides motion changed after the check (each PATH.json key, the cell file, the FOLD file), when the
check is forged, and when the program breaks the cell's limits even with a matching forged check.
The library and the CLI give the same CHECK.json; a user script sends without a `__main__` guard."""
import copy
import dataclasses
import json
import math
import random
import re
import select
import socket
import subprocess
import sys
import textwrap

import pytest

from _ursim import ROOT, free_loopback_hosts
from fabkit.cli import main as fabkit_main
from fabkit.io.fold import save_fold
from fold_fixtures import folded_grid_model
from robot.cell import load_cell
from robot.interlock import InterlockError
from robot.sender import SendError, SendSettings, send_toolpath
from robot.toolpath import Toolpath, document_sha256


def fabkit(capsys, *args):
    capsys.readouterr()
    rc = fabkit_main([str(a) for a in args])
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    """grid.fold (strip 2 folds up 60 deg) -> `fabkit toolpath` -> `fabkit check`, in a copy of the
    bench cell; and a failing program (the far wing of a two-wing fold: the near wing is held by
    nothing) with its failed check."""
    d = tmp_path_factory.mktemp("interlock")
    (d / "cell.toml").write_bytes((ROOT / "cells" / "ur5e_bench.toml").read_bytes())
    save_fold(folded_grid_model(n_states=9, angles=[0.0, math.radians(60)], clamp_strip=0, triangulate=True),
              d / "grid.fold")
    save_fold(folded_grid_model(n_states=9, angles=[math.radians(60)] * 2, clamp_strip=1, triangulate=True),
              d / "wings.fold")
    for argv in (["toolpath", d / "grid.fold", "--cell", d / "cell.toml", "-o", d / "path.json", "-q"],
                 ["check", d / "path.json", "--cell", d / "cell.toml", "-o", d / "check.json", "-q"],
                 ["toolpath", d / "wings.fold", "--cell", d / "cell.toml", "-o", d / "far.json", "--grip-face", "6",
                  "-q"]):
        assert fabkit_main([str(a) for a in argv]) == 0, argv
    assert fabkit_main(["check", str(d / "far.json"), "--cell", str(d / "cell.toml"), "-o", str(d / "far_check.json"),
                        "-q"]) == 1
    return d


@pytest.fixture
def listener():
    """A loopback address whose dashboard and RTDE ports are ours: the test asserts they saw no
    connection attempt."""
    host = free_loopback_hosts(random.Random())[0]
    socks = []
    for port in (29999, 30004):
        s = socket.socket()
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind((host, port))
        s.listen(8)
        socks.append(s)
    yield host, socks
    for s in socks:
        s.close()


def assert_no_connection(socks):
    ready, _, _ = select.select(socks, [], [], 0.2)
    assert not ready, "the sender connected to the controller"


def _reseal(doc):
    return {**doc, "sha256": document_sha256(doc)}


def _edits():
    def wp(key, f):
        def edit(d):
            w = d["waypoints"][5]
            w[key] = f(w[key])
        return edit

    def at(key, f):
        def edit(d):
            d[key] = f(d[key])
        return edit

    def grip(d):
        d["grip"]["output"] = 1 - d["grip"]["output"]

    return {
        "tcp": at("tcp", lambda t: t[:2] + [t[2] - 0.1] + t[3:]),
        "grip.output": grip,
        "robot": at("robot", lambda r: "ur10e"),
        "q": wp("q", lambda q: [q[0] + 0.01] + q[1:]),
        "pose": wp("pose", lambda p: p[:2] + [p[2] + 0.001] + p[3:]),
        "v": wp("v", lambda v: v * 0.5),
        "a": wp("a", lambda a: a * 0.5),
        "r": wp("r", lambda r: r + 0.0005),
        "move": wp("move", lambda m: "movej" if m == "movel" else "movel"),
        "op": wp("op", lambda o: "retract" if o != "retract" else "fold"),
    }


@pytest.mark.parametrize("key", list(_edits()))
def test_an_edit_after_the_check_is_refused_before_any_connection(job, tmp_path, listener, capsys, key):
    host, socks = listener
    doc = json.loads((job / "path.json").read_text())
    edited = copy.deepcopy(doc)
    _edits()[key](edited)
    assert edited != doc
    cell = load_cell(job / "cell.toml")
    check = json.loads((job / "check.json").read_text())
    # the file edited and its stored hash kept; the file edited and re-sealed with a new hash
    for name, data in (("kept", edited), ("resealed", _reseal(edited))):
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps(data))
        rc, out, err = fabkit(capsys, "send", path, "--check", job / "check.json", "--cell", job / "cell.toml",
                              "--host", host)
        assert rc == 2 and err.count("\n") == 1, err
        assert ("sha256 does not match the document" if name == "kept" else "made for another toolpath") in err
    # the library, given the edited toolpath in memory
    tp = Toolpath.load(job / "path.json")
    if key in ("tcp", "robot"):
        other = dataclasses.replace(tp, **{key: tuple(edited[key]) if key == "tcp" else edited[key]})
    elif key == "grip.output":
        other = dataclasses.replace(tp, extra={**tp.extra, "grip": edited["grip"]})
    else:
        wps = list(tp.waypoints)
        wps[5] = dataclasses.replace(wps[5], **{key: edited["waypoints"][5][key]})
        other = dataclasses.replace(tp, waypoints=tuple(wps))
    with pytest.raises(InterlockError, match="made for another toolpath"):
        send_toolpath(other, check, cell, SendSettings(host=host), base_dir=job)
    assert_no_connection(socks)


def test_a_changed_cell_file_or_fold_file_is_refused(job, tmp_path, listener, capsys):
    host, socks = listener
    d = tmp_path
    for name in ("path.json", "check.json", "cell.toml", "grid.fold"):
        (d / name).write_bytes((job / name).read_bytes())
    check = json.loads((d / "check.json").read_text())
    check["fold"]["path"] = str(d / "grid.fold")
    (d / "check.json").write_text(json.dumps(check))
    argv = ["send", d / "path.json", "--check", d / "check.json", "--cell", d / "cell.toml", "--host", host]
    tp = Toolpath.load(d / "path.json")

    cell = load_cell(d / "cell.toml")
    (d / "cell.toml").write_text((job / "cell.toml").read_text() + "\n# a comment\n")
    rc, out, err = fabkit(capsys, *argv)
    assert rc == 2 and "planned in a cell file with sha256" in err and err.count("\n") == 1, err
    with pytest.raises(InterlockError, match="changed since it was loaded"):  # loaded before the edit
        send_toolpath(tp, check, cell, SendSettings(host=host))
    (d / "cell.toml").write_bytes((job / "cell.toml").read_bytes())

    (d / "grid.fold").write_text((job / "grid.fold").read_text() + " ")
    rc, out, err = fabkit(capsys, *argv)
    assert rc == 2 and "the fold states changed" in err and err.count("\n") == 1, err
    with pytest.raises(InterlockError, match="the fold states changed"):
        send_toolpath(tp, check, load_cell(d / "cell.toml"), SendSettings(host=host))
    (d / "grid.fold").unlink()
    rc, out, err = fabkit(capsys, *argv)
    assert rc == 2 and "is not there" in err
    assert_no_connection(socks)


def _forge(job, tmp_path, change):
    data = json.loads((job / "check.json").read_text())
    data = change(data) or data
    path = tmp_path / "forged.json"
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize("change, words", [
    (lambda c: c.update(problems=[{"waypoint": 9, "kind": "collision", "detail": "wrist_3 × face_4"}]),
     "says ok but lists 1 problem"),
    (lambda c: {k: c[k] for k in ("format", "ok", "toolpath_sha256")}, "the check report lacks cell_sha256"),
    (lambda c: c.update(format="fabkit.check/1"), "re-run `fabkit check`"),
    (lambda c: c.update(cell_sha256="1" * 64), "the check was made in a cell file with sha256 111111111111"),
    (lambda c: c.update(robot="ur10e"), "the check is for a ur10e"),
    (lambda c: c.update(cell="ur10e_fold_table"), "in cell 'ur10e_fold_table'"),
    (lambda c: c["fold"].update(sha256="2" * 64), "the check used a FOLD file with sha256 222222222222"),
    (lambda c: c.update(fold=None), "the check used a FOLD file with sha256 None"),
])
def test_forged_checks_are_refused(job, tmp_path, listener, capsys, change, words):
    host, socks = listener
    forged = _forge(job, tmp_path, change)
    rc, out, err = fabkit(capsys, "send", job / "path.json", "--check", forged, "--cell", job / "cell.toml", "--host",
                          host)
    assert rc == 2 and words in err and err.count("\n") == 1, err
    with pytest.raises(InterlockError, match=re.escape(words)):
        send_toolpath(Toolpath.load(job / "path.json"), json.loads(forged.read_text()), load_cell(job / "cell.toml"),
                      SendSettings(host=host), base_dir=job)
    assert_no_connection(socks)


def test_over_the_cell_speed_limit_is_refused_even_with_a_matching_forged_check(job, tmp_path, listener, capsys):
    host, socks = listener
    cell = load_cell(job / "cell.toml")
    doc = json.loads((job / "path.json").read_text())
    k = next(i for i, w in enumerate(doc["waypoints"]) if w["op"] == "fold")
    doc["waypoints"][k]["v"] = 2.9  # the cell allows 0.25 m/s
    doc = _reseal(doc)
    (tmp_path / "fast.json").write_text(json.dumps(doc))
    forged = _forge(job, tmp_path, lambda c: c.update(toolpath_sha256=doc["sha256"]))
    rc, out, err = fabkit(capsys, "send", tmp_path / "fast.json", "--check", forged, "--cell", job / "cell.toml",
                          "--fold", job / "grid.fold", "--host", host)
    assert rc == 2 and err.count("\n") == 1
    assert f"waypoint {k}: TCP speed 2.9 m/s over the cell limit 0.25 m/s" in err
    with pytest.raises(InterlockError, match="TCP speed 2.9 m/s over the cell limit"):
        send_toolpath(Toolpath.from_json(doc), json.loads(forged.read_text()), cell, SendSettings(host=host),
                      fold=job / "grid.fold")
    assert_no_connection(socks)


def test_a_forged_pass_for_a_failing_program_fails_the_check_run_again(job, tmp_path, listener, capsys):
    host, socks = listener
    failed = json.loads((job / "far_check.json").read_text())
    assert not failed["ok"] and any(p["kind"] == "holds" for p in failed["problems"])
    forged = tmp_path / "forged.json"
    forged.write_text(json.dumps({**failed, "ok": True, "problems": []}))
    rc, out, err = fabkit(capsys, "send", job / "far.json", "--check", forged, "--cell", job / "cell.toml", "--host",
                          host)
    assert rc == 2 and "the check run again before sending finds" in err and "holds" in err, err
    assert_no_connection(socks)


def test_a_failed_check_exits_1(job, listener, capsys):
    host, socks = listener
    rc, out, err = fabkit(capsys, "send", job / "far.json", "--check", job / "far_check.json", "--cell",
                          job / "cell.toml", "--host", host)
    assert rc == 1 and "refusing to send" in err and "is folded by nothing held" in err and err.count("\n") == 1
    assert_no_connection(socks)


@pytest.mark.parametrize("path, check", [("path.json", "check.json"), ("far.json", "far_check.json")])
def test_library_and_cli_check_reports_are_identical(job, path, check):
    from sim.check import check_toolpath

    cli = json.loads((job / check).read_text())
    lib = check_toolpath(str(job / path), load_cell(job / "cell.toml")).to_json()
    assert json.loads(json.dumps(lib)) == cli
    assert cli["format"] == "fabkit.check/2" and cli["fold"]["sha256"] == Toolpath.load(job / path).fold_sha256
    assert cli["cell_sha256"] == load_cell(job / "cell.toml").sha256


def test_check_fold_verifies_the_fold_hash_and_bad_coordinates_are_bad_input(job, tmp_path, capsys):
    (tmp_path / "other.fold").write_text((job / "grid.fold").read_text() + "\n")
    rc, out, err = fabkit(capsys, "check", job / "path.json", "--cell", job / "cell.toml", "-o", tmp_path / "c.json",
                          "--fold", tmp_path / "other.fold")
    assert rc == 2 and "the fold states changed since planning" in err and not (tmp_path / "c.json").exists()
    fold = json.loads((job / "grid.fold").read_text())
    fold["file_frames"][3]["vertices_coords"][7][1] = 1e300
    (tmp_path / "huge.fold").write_text(json.dumps(fold))
    rc, out, err = fabkit(capsys, "toolpath", tmp_path / "huge.fold", "--cell", job / "cell.toml", "-o",
                          tmp_path / "p.json")
    assert rc == 2 and "file_frames[3]" in err and "vertex 7" in err and not (tmp_path / "p.json").exists()
    # the same file handed to the check of a toolpath that names it (re-sealed to name it)
    doc = json.loads((job / "path.json").read_text())
    doc["source"]["file"] = "huge.fold"
    doc["source"]["sha256"] = __import__("hashlib").sha256((tmp_path / "huge.fold").read_bytes()).hexdigest()
    (tmp_path / "p2.json").write_text(json.dumps(_reseal(doc)))
    rc, out, err = fabkit(capsys, "check", tmp_path / "p2.json", "--cell", job / "cell.toml", "-o", tmp_path / "c.json")
    assert rc == 2 and "file_frames[3]" in err and "vertex 7" in err and not (tmp_path / "c.json").exists()


def test_a_user_script_sends_without_a_main_guard(job, tmp_path):
    """No `if __name__ == "__main__":` in the script: the ur_rtde worker is a plain subprocess."""
    nobody = free_loopback_hosts(random.Random(3))[0]
    script = tmp_path / "send_it.py"
    script.write_text(textwrap.dedent(f"""
        import json
        from robot.cell import load_cell
        from robot.sender import SendSettings, send_toolpath
        from robot.toolpath import Toolpath

        tp = Toolpath.load({str(job / "path.json")!r})
        check = json.load(open({str(job / "check.json")!r}))
        result = send_toolpath(tp, check, load_cell({str(job / "cell.toml")!r}),
                               SendSettings(host={nobody!r}, connect_retry_s=0.5), base_dir={str(job)!r})
        print("RESULT", result.ok, result.last_completed, result.reason)
    """))
    p = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr[-2000:]
    assert "RESULT False -1 ur_rtde error: RuntimeError: Timeout connecting to UR dashboard server." in p.stdout


def test_resume_from_outside_the_toolpath_is_refused(job, listener):
    host, socks = listener
    tp = Toolpath.load(job / "path.json")
    with pytest.raises(SendError, match=f"--resume-from {len(tp)}: the toolpath has waypoints 0-{len(tp) - 1}"):
        send_toolpath(tp, json.loads((job / "check.json").read_text()), load_cell(job / "cell.toml"),
                      SendSettings(host=host, resume_from=len(tp)), base_dir=job)
    assert_no_connection(socks)
