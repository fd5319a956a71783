"""The CLI contract for every subcommand under every output mistake: exit 2, one line naming the path,
no file changed or left behind, no temporary file left (the output plan in fabkit/commands/_outputs.py).

Cases: a read-only output folder, a full disk (a file-size limit in a subprocess), a name over 255
bytes, an output that is an input, two outputs naming one file, and a later output that cannot be
written while the first could. Inputs are a real pipeline run (`fabkit demo --small`) made once.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from cli_inputs import make_inputs, run, snapshot, temp_files


ROOT = Path(__file__).resolve().parents[1]
LONG = "x" * 300 + ".json"
PANELS_SMALL = ["--rows", "2", "--cols", "2", "--jobs", "1", "--no-plots", "--levels", "2",
                "--columns-per-panel", "2", "--max-rounds", "1"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    return make_inputs(tmp_path_factory.mktemp("inputs"))


@pytest.fixture(scope="module")
def readonly(tmp_path_factory):
    """A folder nobody can write in (a read-only tmpfs when running as root, who ignores modes)."""
    d = tmp_path_factory.mktemp("ro")
    if os.geteuid() != 0:
        d.chmod(0o555)
        yield d
        d.chmod(0o755)
        return
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=64k", "tmpfs", str(d)], capture_output=True,
                       timeout=20)
    if r.returncode != 0:
        pytest.skip("root without a read-only mount: no way to make a folder read-only")
    yield d
    subprocess.run(["umount", str(d)], capture_output=True, timeout=20)


def run_subprocess(argv: list[str], timeout: float = 120) -> tuple[int, str]:
    r = subprocess.run([sys.executable, "-m", "fabkit", *argv], capture_output=True, text=True, timeout=timeout,
                       cwd=ROOT)
    return r.returncode, r.stderr


# command -> (argv with OUT as the output under test, the input that OUT may be set to)
COMMANDS = {
    "generate": (lambda f, o: ["generate", "grid", "--nx", "4", "--ny", "4", "-o", o], None),
    "info": (lambda f, o: ["info", f("trifold.obj"), "--report", o], "trifold.obj"),
    "relax": (lambda f, o: ["relax", f("relaxed.obj"), "-o", o], "relaxed.obj"),
    "unfold": (lambda f, o: ["unfold", f("relaxed.obj"), "-o", o], "relaxed.obj"),
    "panels": (lambda f, o: ["panels", f("canopy.obj"), "-o", o, *PANELS_SMALL], "canopy.obj"),
    "refold": (lambda f, o: ["refold", f("flat.obj"), f("relaxed.obj"), "-o", o, "--frames", "3"], "flat.obj"),
    "toolpath": (lambda f, o: ["toolpath", f("fold.fold"), "--cell", f("cell.toml"), "-o", o], "fold.fold"),
    "check": (lambda f, o: ["check", f("path.json"), "--cell", f("cell.toml"), "-o", o], "path.json"),
    "send": (lambda f, o: ["send", f("path.json"), "--check", f("check.json"), "--cell", f("cell.toml"),
                           "--host", "127.0.0.9", "--log", o], "check.json"),
    "demo": (lambda f, o: ["demo", "--out", o, "--cell", f("cell.toml"), "--small", "--no-render",
                           "--no-dry-run"], "cell.toml"),
    "ursim": (lambda f, o: ["ursim", "--host", "127.0.0.9", "--cell", f("cell.toml"), "--log", o], "cell.toml"),
}
#: the file name each command's output under test gets
OUT_NAME = {"generate": "out.obj", "relax": "out.obj", "unfold": "out.obj", "refold": "out.fold", "panels": "out",
            "demo": "out"}
#: commands whose only output is --report (no second output to clash with)
ONE_OUTPUT = {"info"}
#: a full disk shows while writing: these write only after their work (send: after the arm moved, a
#: stand-in and a whole demo are too slow for this table), so the file-size case covers the rest
FULL_DISK = ["generate", "info", "relax", "unfold", "panels", "refold", "toolpath", "check"]


def assert_refused(code: int, err: str, names: str, before: dict, *dirs: Path) -> None:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, err
    assert len(lines) == 1, err
    assert "Traceback" not in err and "internal error" not in err
    assert names in lines[0], lines[0]
    assert snapshot(*dirs) == before
    assert temp_files(*dirs) == []


def case_argv(case: str, command: str, files: Path, work: Path, readonly: Path) -> tuple[list[str], str]:
    """(argv, the path the one-line error must name)."""
    build, input_name = COMMANDS[command]
    f = lambda name: str(files / name)  # noqa: E731
    good = str(work / OUT_NAME.get(command, "out.json"))
    if case == "readonly":
        target = str(readonly / "out.json")
        return build(f, target), target
    if case == "long name":
        target = str(work / LONG)
        return build(f, target), LONG
    if case == "output is input":
        return build(f, f(input_name)), input_name
    if case == "two outputs the same":
        return build(f, good) + ["--report", good], good
    if case == "later output unwritable":
        target = str(readonly / "r.json")
        return build(f, good) + ["--report", target], target
    raise AssertionError(case)


CASES = ["readonly", "long name", "output is input", "two outputs the same", "later output unwritable"]
TABLE = [(case, command) for command in COMMANDS for case in CASES
         if not (case == "output is input" and COMMANDS[command][1] is None)
         and not (case in ("two outputs the same", "later output unwritable") and command in ONE_OUTPUT)]


@pytest.mark.parametrize("case,command", TABLE, ids=[f"{c}-{k}" for k, c in TABLE])
def test_output_mistake_is_refused_before_any_work(case, command, files, readonly, tmp_path):
    argv, names = case_argv(case, command, files, tmp_path, readonly)
    before = snapshot(files, tmp_path, readonly)
    if command == "ursim":  # a stand-in that was not refused would serve until killed
        code, err = run_subprocess(argv, timeout=60)
    else:
        code, err = run(argv)
    assert_refused(code, err, names, before, files, tmp_path, readonly)


@pytest.mark.parametrize("command", FULL_DISK)
def test_full_disk_is_exit_2_and_leaves_nothing(command, files, tmp_path):
    build, _ = COMMANDS[command]
    out = tmp_path / OUT_NAME.get(command, "out.json")
    argv = build(lambda name: str(files / name), str(out))
    before = snapshot(files, tmp_path)
    code, err = run(argv, fsize=200)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, err
    assert len(lines) == 1 and "cannot write" in lines[0], err
    assert snapshot(files, tmp_path) == before
    assert temp_files(files, tmp_path) == []


def test_a_stale_temporary_file_of_a_dead_process_is_removed_and_a_live_ones_kept(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True, timeout=30).stdout.strip()
    stale = tmp_path / f".g.obj.fabkit-{dead}-0a1b2c3d.tmp.obj"
    stale.write_bytes(b"x" * 1000)
    live = tmp_path / f".g.obj.fabkit-{os.getpid()}-0a1b2c3d.tmp.obj"
    live.write_bytes(b"y")
    code, err = run(["generate", "grid", "-o", str(tmp_path / "g.obj"), "-q"])
    assert code == 0, err
    assert not stale.exists() and live.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["g.obj", live.name])


def test_unwritten_output_keeps_the_old_file_and_later_failure_commits_nothing(files, tmp_path):
    """check --waypoint 999 fails after the check ran: the check report it produced is not committed."""
    out = tmp_path / "c.json"
    out.write_text("old")
    code, err = run(["check", str(files / "path.json"), "--cell", str(files / "cell.toml"), "-o", str(out),
                     "--render", str(tmp_path / "w.png"), "--waypoint", "999"])
    if "no offscreen OpenGL" in err:
        pytest.skip("no offscreen OpenGL backend")
    assert code == 2, err
    assert out.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.json"]


@pytest.mark.parametrize("argv,words", [
    (["refold", "{flat}", "{target}", "-o", "{tmp}/s.fold", "--frames", "100000000"], "--frames"),
    (["panels", "{canopy}", "-o", "{tmp}/p", "--levels", "30"], "--levels"),
    (["panels", "{canopy}", "-o", "{tmp}/p", "--scheduler", "tcp://127.0.0.63:1"], "cannot reach"),
    (["panels", "{canopy}", "-o", "{flat}"], "is not a folder"),
    (["relax", "{target}", "-o", "{tmp}/r.obj", "--max-seconds", "-5"], "max_seconds"),
    (["send", "{path}", "--check", "{check}", "--cell", "{cell}", "--host", "127.0.0.9", "--stall", "inf"], "--stall"),
    (["send", "{path}", "--check", "{check}", "--cell", "{cell}", "--host", "not a host;rm -rf"], "--host"),
    (["send", "{path}", "--check", "{check}", "--cell", "{cell}", "--host", "127.0.0.9", "--log", "{path}"], "overwrite the input"),
    (["demo", "--out", "{tmp}/d", "--small", "--frames", "0"], "--frames"),
    (["demo", "--out", "{flat}"], "is not a folder"),
    (["demo", "--out", "{tmp}/d", "--cell", "{tmp}/broken.toml"], "not valid TOML"),
    (["info", "/dev/zero"], "not a regular file"),
    (["info", "{tmp}/fifo.obj"], "not a regular file"),
    (["relax", "{tmp}", "-o", "{tmp}/r.obj"], "is a directory"),
    (["info", "{tmp}/huge.obj"], "beyond"),
    (["toolpath", "{fold}", "--cell", "{cell}", "-o", "{tmp}/p.json", "--script", "{tmp}/nodir/p.script"],
     "output directory does not exist"),
    (["check", "{path}", "--cell", "{cell}", "-o", "{tmp}/c.json", "--report", "{tmp}/c.json"], "same file"),
    (["toolpath", "{fold}", "--cell", "{cell}", "-o", "{cell}"], "overwrite the input"),
    (["generate", "grid", "-o", "{tmp}/o.obj", "--png", "{tmp}/O.obj", "--report", "{tmp}/o.obj"], "same file"),
])
def test_options_and_inputs_refused_up_front(argv, words, files, tmp_path):
    (tmp_path / "broken.toml").write_text("[robot\nmodel =")
    os.mkfifo(tmp_path / "fifo.obj")
    (tmp_path / "huge.obj").write_text("v 0 0 0\nv 1 0 0\nv 1e300 1 0\nv 0 1 0\nf 1 2 3 4\n")
    names = {"flat": files / "flat.obj", "target": files / "relaxed.obj", "canopy": files / "canopy.obj",
             "path": files / "path.json", "check": files / "check.json", "fold": files / "fold.fold",
             "cell": files / "cell.toml", "tmp": tmp_path}
    argv = [a.format(**{k: str(v) for k, v in names.items()}) for a in argv]
    before = snapshot(files, tmp_path)
    code, err = run(argv)
    assert code == 2, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and words in lines[0], err
    assert snapshot(files, tmp_path) == before
    assert temp_files(files, tmp_path) == []


def test_hard_link_and_symlink_of_the_input_are_the_input(files, tmp_path):
    link = tmp_path / "link.obj"
    os.symlink(files / "relaxed.obj", link)
    hard = tmp_path / "hard.obj"
    os.link(files / "relaxed.obj", hard)
    before = snapshot(files, tmp_path)
    for out in (link, hard):
        code, err = run(["relax", str(files / "relaxed.obj"), "-o", str(out)])
        assert code == 2 and "overwrite the input" in err, err
    assert snapshot(files, tmp_path) == before


def _children(pid: int) -> list[int]:
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except OSError:
        return []
    return [int(t) for t in text.split()]


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux")
@pytest.mark.parametrize("sig", ["SIGKILL", "SIGTERM", "SIGINT"])
def test_panels_workers_die_with_the_parent(sig, files, tmp_path):
    import signal
    import time

    out = tmp_path / "p"
    proc = subprocess.Popen([sys.executable, "-m", "fabkit", "panels", str(files / "canopy.obj"), "-o", str(out),
                             "--jobs", "2", "-q", "--no-plots"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            cwd=ROOT)
    kids: list[int] = []
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and len(kids) < 2 and proc.poll() is None:
        kids = _children(proc.pid)
        time.sleep(0.2)
    assert len(kids) >= 2, "the pool workers did not start"
    time.sleep(1.0)
    proc.send_signal(getattr(signal, sig))
    proc.wait(timeout=60)
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline and any(Path(f"/proc/{k}").exists() for k in kids):
        time.sleep(0.2)
    alive = [k for k in kids if Path(f"/proc/{k}").exists()
             and Path(f"/proc/{k}/stat").read_text().split()[2] != "Z"]
    assert alive == []
    if sig != "SIGKILL":  # unwound: the exit code says why, nothing half-written is left
        assert proc.returncode == (128 + signal.SIGTERM if sig == "SIGTERM" else 130)
        assert not out.exists() and temp_files(tmp_path) == []
    # a SIGKILL leaves the staging folder; the next run in that folder removes it
    code, err = run(["generate", "grid", "-o", str(tmp_path / "g.obj"), "-q"])
    assert code == 0, err
    assert temp_files(tmp_path) == []
