"""A production run on a real dask.distributed cluster on loopback: scheduler + 2 workers as processes.

The same outputs as the serial run (file hashes), and a worker killed mid-run loses no finished
panel: the scheduler re-runs the killed worker's tasks on the other one and the run completes.
"""
from __future__ import annotations

import json
import os
import random
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from fabkit.generate.pleated import pleated_vault
from fabkit.panels.layout import layout_panels
from fabkit.panels.production import run_production
from fabkit.panels.surface import GridSurface, grid_from_topology

ROOT = Path(__file__).resolve().parents[1]
CELL = ROOT / "cells" / "ur5e_bench.toml"


def _free_address() -> tuple[str, int]:
    rng = random.Random()
    for _ in range(50):
        host = f"127.0.0.{rng.randint(100, 250)}"
        with socket.socket() as s:
            try:
                s.bind((host, 0))
            except OSError:
                continue
            return host, s.getsockname()[1]
    raise RuntimeError("no free loopback address")


class Cluster:
    """`dask scheduler` and `dask worker` processes (the programs behind those commands, run with this
    interpreter so they import this checkout); every process is killed by `stop()`."""

    def __init__(self, n_workers: int, tmp: Path):
        host, port = _free_address()
        self.address = f"tcp://{host}:{port}"
        env = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
        common = dict(cwd=ROOT, env=env, start_new_session=True)
        self.log = open(tmp / "cluster.log", "w")
        self.scheduler = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", host,
                                           "--port", str(port), "--dashboard-address", ":0", "--no-show"],
                                          stdout=self.log, stderr=subprocess.STDOUT, **common)
        self.workers = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", self.address,
                                          "--nthreads", "1", "--no-nanny", "--host", host, "--no-dashboard",
                                          "--death-timeout", "60", "--local-directory", str(tmp / f"w{i}")],
                                         stdout=self.log, stderr=subprocess.STDOUT, **common)
                        for i in range(n_workers)]
        from distributed import Client

        deadline = time.monotonic() + 90
        while True:
            try:
                with Client(self.address, timeout=5) as c:
                    c.wait_for_workers(n_workers, timeout=max(1.0, deadline - time.monotonic()))
                break
            except (OSError, TimeoutError):
                if time.monotonic() > deadline:
                    self.stop()
                    raise

    def kill_worker(self, i: int) -> None:
        os.killpg(self.workers[i].pid, signal.SIGKILL)
        self.workers[i].wait(timeout=30)

    def stop(self) -> None:
        for p in [*self.workers, self.scheduler]:
            if p.poll() is None:
                try:
                    os.killpg(p.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                p.wait(timeout=30)
        self.log.close()


def _layout():
    mesh = pleated_vault(rows=2, length=0.5, radius=0.6, arc=np.radians(60.0), fold=np.radians(40.0), columns=12,
                         rows_per_band=8)
    index, _ = grid_from_topology(mesh)
    S = GridSurface(points=mesh.vertices[index], mesh=mesh, index=index)
    return layout_panels(S, cols=3, columns_per_panel=4)


def _files(out: Path) -> dict:
    m = json.loads((out / "manifest.json").read_text())["panels"]
    return {name: (e["stage"], e["reason"], {k: v["sha256"] for k, v in e["files"].items()}) for name, e in m.items()}


@pytest.mark.slow
def test_dask_cluster_matches_serial_and_survives_a_killed_worker(tmp_path):
    from sim.production import program_panel

    layout = _layout()
    # 4 of the 6 panels refolded, programmed and checked (the others end "not selected" in every run)
    kw = dict(cell_toml=CELL.read_text(), cell_name=CELL.name, program=program_panel, timeout=600,
              select={p.name for p in layout.panels[:4]})
    serial = run_production(layout, tmp_path / "serial", **kw)
    assert len(serial.panels) == 6 and sum(p.reason.startswith("not selected") for p in serial.panels) == 2
    cluster = Cluster(2, tmp_path)
    try:
        # a run on the cluster from scratch; kill one worker as soon as the first panel is finished:
        # the run completes with every file as the serial run wrote it
        out = tmp_path / "killed"
        result = {}
        t = threading.Thread(target=lambda: result.update(run=run_production(layout, out, scheduler=cluster.address,
                                                                             **kw)), daemon=True)
        t.start()
        finished_before = {}
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and t.is_alive():
            if (out / "manifest.json").is_file():
                finished_before = _files(out)
                if finished_before:
                    break
            time.sleep(0.05)
        assert finished_before, "no panel finished before the deadline"
        cluster.kill_worker(0)
        t.join(timeout=600)
        assert not t.is_alive() and "run" in result
        after = _files(out)
        assert after == _files(tmp_path / "serial")  # every panel, the same bytes
        assert [p.stage for p in result["run"].panels] == [p.stage for p in serial.panels]
        assert len(finished_before) < len(after)  # the kill came mid-run
        for name, rec in finished_before.items():  # nothing finished before the kill was lost or redone
            assert after[name] == rec
    finally:
        cluster.stop()
