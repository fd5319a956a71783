"""README examples run as written: the pipeline walk-through, from generate to the dry-run send."""
from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path

from sim.ursim.launch import free_loopback_address

ROOT = Path(__file__).resolve().parents[1]


def _walkthrough() -> str:
    blocks = re.findall(r"```sh\n(.*?)```", (ROOT / "README.md").read_text(), re.S)
    walk = [b for b in blocks if "mkdir -p walk" in b]
    assert len(walk) == 1, "README lost its pipeline walk-through"
    return walk[0]


def test_readme_walkthrough_runs_as_written(tmp_path):
    script = _walkthrough()
    host = free_loopback_address(first=100)
    script = script.replace("127.0.0.9", host)  # a free address: tests run in parallel
    shutil.copytree(ROOT / "cells", tmp_path / "cells")
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    # its own session: whatever happens (a failed step under `bash -e` skips the `kill $URSIM`), the
    # stand-in started in the background is killed with the group
    proc = subprocess.Popen(["bash", "-e", "-c", script], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=300)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    walk = tmp_path / "walk"
    assert proc.returncode == 0, out[-3000:] + err[-3000:] + _tails(walk, "ursim.log", "send.log")
    relax = json.loads((walk / "relax.json").read_text())
    assert relax["converged"] and relax["final"]["max_abs_angle_defect_rad"] <= 1e-8
    check = json.loads((walk / "check.json").read_text())
    assert check["ok"] and check["toolpath_sha256"] == json.loads((walk / "path.json").read_text())["sha256"]
    send = json.loads((walk / "send.json").read_text())
    assert send["ok"] and send["last_completed"] == send["total"] - 1
    for f in ("flat.dxf", "flat.svg", "flat.png", "fold.fold", "fold_angles.png", "fold.script", "check.png"):
        assert (walk / f).is_file(), f


def _tails(walk: Path, *names: str) -> str:
    """The ends of the walk's logs, for a failure message (the stand-in says why a program stopped)."""
    parts = []
    for name in names:
        f = walk / name
        if f.is_file():
            parts.append(f"\n--- {name} ---\n" + "\n".join(f.read_text(errors="replace").splitlines()[-25:]))
    return "".join(parts)


def test_readme_links_and_images_exist():
    text = (ROOT / "README.md").read_text()
    targets = re.findall(r"\]\(((?:docs|cells)/[^)]+)\)", text)
    assert len(targets) >= 10
    missing = [t for t in targets if not (ROOT / t).exists()]
    assert not missing, missing
