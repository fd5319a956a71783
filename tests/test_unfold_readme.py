"""The console examples in docs/unfold.md run as written (exit codes and summary lines)."""
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "docs" / "unfold.md"


def console_blocks(text: str) -> list[list[tuple[str, list[str]]]]:
    """Each ```console block as [(command, expected output lines)], continuation lines joined."""
    blocks = []
    for body in re.findall(r"```console\n(.*?)```", text, flags=re.S):
        steps: list[tuple[str, list[str]]] = []
        pending = None
        for line in body.splitlines():
            if pending is not None:
                pending += " " + line.strip()
                if not line.endswith("\\"):
                    steps.append((pending.replace("\\ ", ""), []))
                    pending = None
                continue
            if line.startswith("$ "):
                cmd = line[2:]
                if cmd.endswith("\\"):
                    pending = cmd
                else:
                    steps.append((cmd, []))
            elif steps:
                steps[-1][1].append(line)
        blocks.append(steps)
    return blocks


def test_readme_examples_run(tmp_path):
    text = README.read_text(encoding="utf-8")
    blocks = console_blocks(text)
    assert len(blocks) == 2 and sum(len(b) for b in blocks) == 5
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    for steps in blocks:
        for cmd, expected in steps:
            cmd = cmd.split("  # ")[0].strip()
            shell = cmd.replace("python -c", f"{sys.executable} -c", 1) if cmd.startswith("python ") else cmd
            proc = subprocess.run(shell, shell=True, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
            wants_failure = any("(exit 1)" in e for e in expected)
            assert proc.returncode == (1 if wants_failure else 0), (cmd, proc.stdout, proc.stderr)
            for e in expected:
                if e.startswith("unfold "):  # the summary line: same file and vertex count, same kind of result
                    head = e.split(": relative length deviation")[0]
                    assert head in proc.stdout, (cmd, head, proc.stdout)
                    mean = float(re.search(r"mean ([0-9.e+-]+)", e).group(1))
                    got = float(re.search(r"mean ([0-9.e+-]+)", proc.stdout.split(head)[1]).group(1))
                    if mean < 1e-9:  # exact or relaxed: stays at round-off / relax-tolerance level
                        assert got < 1e-7, (cmd, got)
                    else:  # a real error: the same to a factor of 2
                        assert mean / 2 < got < 2 * mean, (cmd, got, mean)
                elif e.startswith("fabkit unfold: FAILED"):
                    assert "FAILED: max relative length deviation" in proc.stderr
    assert (tmp_path / "flat.dxf").exists() and (tmp_path / "unfold.json").exists()


@pytest.mark.parametrize("needle", ["$INSUNITS", "--max-error", "--norm", "CUT", "MOUNTAIN", "VALLEY", "LABEL"])
def test_readme_mentions(needle):
    assert needle in README.read_text(encoding="utf-8")
