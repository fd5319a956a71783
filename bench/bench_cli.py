"""Command start-up: `fabkit --help`, every `fabkit SUB --help` and a no-op relax, as ratios to
`python -c pass` measured in the same run (so a slow or loaded machine moves both alike).

Targets: every `--help` within 0.3 s and a no-op relax (an input already within tolerance) within
0.5 s of wall time. The table gives the absolute times, the ratio to the interpreter's own start-up
and whether the target is met.
"""
from __future__ import annotations

import re
import subprocess
import sys
import tempfile
from pathlib import Path

from bench.common import best_time, report

HELP_TARGET_S = 0.3
NOOP_RELAX_TARGET_S = 0.5


def _run(args: list[str]) -> None:
    subprocess.run(args, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=60)


def _subcommands() -> list[str]:
    text = subprocess.run([sys.executable, "-m", "fabkit", "--help"], check=True, capture_output=True,
                          text=True, timeout=60).stdout
    block = text.split("positional arguments:", 1)[1].split("options:", 1)[0]
    return re.findall(r"^    (\w+)\s", block, flags=re.MULTILINE)


def main() -> dict:
    py = sys.executable
    fabkit = [py, "-m", "fabkit"]
    baseline = best_time(lambda: _run([py, "-c", "pass"]), repeat=5)
    rows = [{"command": "python -c pass", "seconds": baseline, "ratio": 1.0, "target_s": "", "ok": ""}]

    def row(label: str, args: list[str], target: float) -> None:
        t = best_time(lambda: _run(args), repeat=3)
        rows.append({"command": label, "seconds": t, "ratio": t / baseline, "target_s": target,
                     "ok": t <= target})

    row("fabkit --help", fabkit + ["--help"], HELP_TARGET_S)
    for sub in _subcommands():
        row(f"fabkit {sub} --help", fabkit + [sub, "--help"], HELP_TARGET_S)
    with tempfile.TemporaryDirectory() as tmp:
        panel = Path(tmp) / "reflect.obj"  # the reflect preset is exactly developable: relax leaves it
        _run(fabkit + ["generate", "reflect", "-o", str(panel)])
        row("fabkit relax (no-op)", fabkit + ["relax", str(panel), "-o", str(Path(tmp) / "out.obj")],
            NOOP_RELAX_TARGET_S)
    return report("cli", rows, {"baseline_s": baseline})
