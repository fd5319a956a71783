"""Shared fixtures. Tests point at the source tree; strict invariant checks are on."""
import os

import numpy as np
import pytest

os.environ.setdefault("FABKIT_STRICT", "1")

# One BLAS thread per process: the suite runs two workers, their stand-ins and subprocesses on two
# cores, where OpenBLAS's threads wait on each other (a 777 x 324 SVD of the holds check: 2.2 s with
# two threads at load 8, 0.14 s with one). The variables reach the subprocesses; numpy is already
# loaded here, so threadpoolctl limits this process.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")
from threadpoolctl import threadpool_limits  # noqa: E402

threadpool_limits(limits=1)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


#: Test files that run the controller stand-in and a sender in real time for longest (dry runs and
#: sends; seconds of `--durations` on the loaded 2-core machine: 692 of the suite's 1,435), and the
#: stand-in stream's own test. `make test` (`--dist loadfile --no-loadscope-reorder`) gives them to
#: one worker as one unit, one file after another, first: each stand-in emulates a controller with
#: a CPU of its own, and two dry runs side by side on the two cores starved each other (a README
#: walk-through was stopped by the RTDE watchdog). The other worker takes the other files whole,
#: in the order of the collection: the longest compute files first, so that no worker runs a long
#: file alone at the end (xdist's default reorder, by number of tests, started the 70 s README
#: walk-through last). (xdist's own `--dist loadgroup` marks do nothing under pytest 9: it renames
#: `item._nodeid`, which pytest 9 no longer reads; hence the scheduler below.)
REALTIME = ("test_two_arm_send.py", "test_phased_program.py", "test_structure_pipeline.py",  # 117, 100, 95 s
            "test_api_pipeline.py", "test_readme.py", "test_demo_e2e.py", "test_sheet_send.py",  # 72-45 s
            "test_send_stop.py", "test_zigzag_fold.py", "test_send_faults.py", "test_send.py",  # 40-30 s
            "test_ursim_fuzz.py")  # last: it measures the stand-in's 500 Hz stream
COMPUTE_LONGEST = ("test_production.py", "test_nest.py", "test_bad_files.py", "test_grip_cup_footprint.py",  # 51-27
                   "test_toolpath_refold.py", "test_panels.py", "test_production_dask.py")                     # 26-20


def pytest_collection_modifyitems(session, config, items):
    rank = {name: i for i, name in enumerate(REALTIME + COMPUTE_LONGEST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: file order kept within


@pytest.hookimpl(optionalhook=True)  # an xdist hook: unknown under `-p no:xdist`
def pytest_xdist_make_scheduler(config, log):
    """`--dist loadfile`, with the `REALTIME` files one unit of work (one worker, in order)."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class RealtimeTogether(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = nodeid.split("::", 1)[0]
            return "realtime" if path.rsplit("/", 1)[-1] in REALTIME else path

    return RealtimeTogether(config, log)
