"""Command start-up: `fabkit --help`, every `fabkit SUB --help` and a no-op relax, as ratios to
`python -c pass` measured in the same run (so a slow or loaded machine moves both alike).

Targets: every `--help` within 0.3 s and a no-op relax (an input already within tolerance) within
0.5 s. Each command runs `repeat` times; the table gives the best wall time, the best CPU time
(user + system of the child process) and both as ratios to the interpreter's own start-up. On a
shared machine the wall time also counts the waits for a free core, which the CPU time does not:
`ok` compares the CPU time with the target, `ok_wall` the wall time. A last row says which heavy
packages a no-op relax imports (none of scipy, ezdxf, matplotlib, mujoco is needed for it); the
row `import numpy` is the floor of every command that reads a mesh (the no-op relax needs numpy).
"""
from __future__ import annotations

import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench.common import report

HELP_TARGET_S = 0.3
NOOP_RELAX_TARGET_S = 0.5
HEAVY = ("scipy", "ezdxf", "matplotlib", "mujoco", "trimesh", "shapely", "rich", "robot", "sim")


def _timed(args: list[str], repeat: int) -> tuple[float, float]:
    """Best (wall, CPU) seconds of `repeat` runs of `args`."""
    wall = cpu = float("inf")
    for _ in range(repeat):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(args, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=60)
        wall = min(wall, time.perf_counter() - t0)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = min(cpu, after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    return wall, cpu


def _subcommands() -> list[str]:
    text = subprocess.run([sys.executable, "-m", "fabkit", "--help"], check=True, capture_output=True,
                          text=True, timeout=60).stdout
    block = text.split("positional arguments:", 1)[1].split("options:", 1)[0]
    return re.findall(r"^    (\w+)\s", block, flags=re.MULTILINE)


def _heavy_imports(args: list[str]) -> list[str]:
    """The top-level packages of `HEAVY` that `python -X importtime` shows for `args`."""
    err = subprocess.run([sys.executable, "-X", "importtime", *args], capture_output=True, text=True,
                         timeout=120).stderr
    names = {line.rsplit("|", 1)[-1].strip().split(".")[0] for line in err.splitlines() if "|" in line}
    return sorted(names & set(HEAVY))


def main() -> dict:
    py = sys.executable
    fabkit = [py, "-m", "fabkit"]
    base_wall, base_cpu = _timed([py, "-c", "pass"], repeat=5)
    rows = [{"command": "python -c pass", "wall_s": base_wall, "cpu_s": base_cpu, "wall_ratio": 1.0,
             "cpu_ratio": 1.0, "target_s": "", "ok": "", "ok_wall": ""}]

    def row(label: str, args: list[str], target: float | None) -> None:
        wall, cpu = _timed(args, repeat=3)
        rows.append({"command": label, "wall_s": wall, "cpu_s": cpu, "wall_ratio": wall / base_wall,
                     "cpu_ratio": cpu / base_cpu if base_cpu > 0 else float("nan"), "target_s": target or "",
                     "ok": "" if target is None else cpu <= target, "ok_wall": "" if target is None else wall <= target})

    row("python -c 'import numpy'", [py, "-c", "import numpy"], None)  # the floor of any command that reads a mesh
    row("fabkit --help", fabkit + ["--help"], HELP_TARGET_S)
    for sub in _subcommands():
        row(f"fabkit {sub} --help", fabkit + [sub, "--help"], HELP_TARGET_S)
    with tempfile.TemporaryDirectory() as tmp:
        panel = Path(tmp) / "reflect.obj"  # the reflect preset is exactly developable: relax leaves it
        subprocess.run(fabkit + ["generate", "reflect", "-o", str(panel)], check=True, capture_output=True,
                       timeout=120)
        relax = ["-m", "fabkit", "relax", str(panel), "-o", str(Path(tmp) / "out.obj")]
        row("fabkit relax (no-op)", [py, *relax], NOOP_RELAX_TARGET_S)
        heavy = _heavy_imports(relax)
    data = report("cli", rows, {"baseline_wall_s": base_wall, "baseline_cpu_s": base_cpu,
                                "noop_relax_heavy_imports": heavy})
    print(f"a no-op relax imports {', '.join(heavy) or 'none of ' + ', '.join(HEAVY)}")
    return data
