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


#: Test files that take longest (seconds of `--durations` on the 2-core machine: the real-time
#: dry runs on the stand-in, the demo, the production runs). `make test` hands whole files to its
#: two workers in collection order (`--dist loadfile`); starting with these keeps one worker from
#: running a long file alone at the end.
LONGEST_FIRST = ("test_phased_program.py", "test_two_arm_send.py", "test_structure_pipeline.py", "test_readme.py",
                 "test_demo_e2e.py", "test_api_pipeline.py",
                 "test_sheet_send.py", "test_two_arm_sheet.py", "test_production.py", "test_panels.py", "test_send_stop.py",
                 "test_production_dask.py", "test_production_repeats.py", "test_ursim_interfaces.py",
                 "test_send.py")
#: Run last, when the other worker is on short files: their assertions measure the stand-in's 500 Hz
#: stream, and beside a regrip dry run on the other worker it delivered 79-98.7 % of the periods.
LAST = ("test_ursim_fuzz.py",)


def pytest_collection_modifyitems(session, config, items):
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    rank.update({name: len(LONGEST_FIRST) + 1 + i for i, name in enumerate(LAST)})
    items.sort(key=lambda item: rank.get(item.path.name, len(LONGEST_FIRST)))  # stable: file order kept within
