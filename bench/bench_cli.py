"""Command start-up: `fabkit --help`, every `fabkit SUB --help` and a no-op relax, as ratios to
`python -c pass` measured in the same run (so a slow or loaded machine moves both alike).

Targets: every `--help` within 0.3 s and a no-op relax (an input already within tolerance) within
0.5 s. Each command runs `repeat` times; the table gives the best wall time, the best CPU time
(user + system of the child process) and both as ratios to the interpreter's own start-up. On a
shared machine the wall time also counts the waits for a free core, which the CPU time does not:
`ok` compares the CPU time with the target, `ok_wall` the wall time. A last row says which heavy
packages a no-op relax imports (none of scipy, ezdxf, matplotlib, mujoco is needed for it); the
row `import numpy` is the floor of every command that reads a mesh (the no-op relax needs numpy).

Bytecode: the commands run as an installed fabkit runs, from compiled bytecode (a private
`PYTHONPYCACHEPREFIX` in a temporary folder, warmed by one run of each command; the environment's
`PYTHONDONTWRITEBYTECODE` is lifted for the children). The row "no bytecode cache" runs the no-op
relax with `PYTHONDONTWRITEBYTECODE=1` and no cache: fabkit's own modules are compiled from source
on every run (the installed packages keep their bytecode), as in an environment that forbids
writing bytecode next to a source checkout. The load average (1 min) before and after the run is
printed and stored: under a load above the core count the wall times mostly count waits.
"""
from __future__ import annotations

import os
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


def _child_env(cache: str | None) -> dict:
    """The environment of a timed command: bytecode written to and read from the folder `cache`;
    None: no bytecode written (`PYTHONDONTWRITEBYTECODE=1`), installed packages read from their own."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONDONTWRITEBYTECODE", "PYTHONPYCACHEPREFIX")}
    if cache is None:
        env["PYTHONDONTWRITEBYTECODE"] = "1"
    else:
        env["PYTHONPYCACHEPREFIX"] = cache
    return env


ENV: dict = {}  # set by main(): the children's environment


def _timed(args: list[str], repeat: int, env: dict | None = None) -> tuple[float, float]:
    """Best (wall, CPU) seconds of `repeat` runs of `args` (after one untimed run that warms the
    bytecode cache)."""
    env = ENV if env is None else env
    subprocess.run(args, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=120, env=env)
    wall = cpu = float("inf")
    for _ in range(repeat):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(args, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=60, env=env)
        wall = min(wall, time.perf_counter() - t0)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = min(cpu, after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    return wall, cpu


def _subcommands() -> list[str]:
    text = subprocess.run([sys.executable, "-m", "fabkit", "--help"], check=True, capture_output=True,
                          text=True, timeout=60, env=ENV or None).stdout
    block = text.split("positional arguments:", 1)[1].split("options:", 1)[0]
    return re.findall(r"^    (\w+)\s", block, flags=re.MULTILINE)


def _heavy_imports(args: list[str]) -> list[str]:
    """The top-level packages of `HEAVY` that `python -X importtime` shows for `args`."""
    err = subprocess.run([sys.executable, "-X", "importtime", *args], capture_output=True, text=True,
                         timeout=120, env=ENV or None).stderr
    names = {line.rsplit("|", 1)[-1].strip().split(".")[0] for line in err.splitlines() if "|" in line}
    return sorted(names & set(HEAVY))


def main() -> dict:
    with tempfile.TemporaryDirectory() as cache:
        ENV.clear()
        ENV.update(_child_env(cache))
        try:
            return _run(_child_env(None))
        finally:
            ENV.clear()


def _run(no_cache_env: dict) -> dict:
    load_before = os.getloadavg()[0]
    py = sys.executable
    fabkit = [py, "-m", "fabkit"]
    base_wall, base_cpu = _timed([py, "-c", "pass"], repeat=5)
    rows = [{"command": "python -c pass", "wall_s": base_wall, "cpu_s": base_cpu, "wall_ratio": 1.0,
             "cpu_ratio": 1.0, "target_s": "", "ok": "", "ok_wall": ""}]

    def row(label: str, args: list[str], target: float | None, env: dict | None = None) -> None:
        wall, cpu = _timed(args, repeat=3, env=env)
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
                       timeout=120, env=ENV)
        relax = ["-m", "fabkit", "relax", str(panel), "-o", str(Path(tmp) / "out.obj")]
        row("fabkit relax (no-op)", [py, *relax], NOOP_RELAX_TARGET_S)
        row("fabkit relax (no-op, no bytecode cache)", [py, *relax], None, env=no_cache_env)
        heavy = _heavy_imports(relax)
    load_after = os.getloadavg()[0]
    data = report("cli", rows, {"baseline_wall_s": base_wall, "baseline_cpu_s": base_cpu,
                                "noop_relax_heavy_imports": heavy, "load_average_1min": [load_before, load_after],
                                "cores": os.cpu_count()})
    print(f"a no-op relax imports {', '.join(heavy) or 'none of ' + ', '.join(HEAVY)}")
    print(f"load average (1 min): {load_before:.2f} before, {load_after:.2f} after, on {os.cpu_count()} cores")
    return data
