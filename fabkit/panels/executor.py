"""Where per-panel work runs: in-process, a process pool, or a dask.distributed cluster.

All three take the same picklable task function and arguments and return results in input
order, so a run gives the same numbers wherever it ran: every task runs with single-threaded
BLAS (threadpoolctl), in-process or in a worker, so no reduction order depends on the number of
threads.
Pool workers die with the parent process (`fabkit.lifeline`), even on `kill -9`.
"""
from __future__ import annotations

import contextlib
import os
import socket
from concurrent.futures import Executor, ProcessPoolExecutor
from typing import Callable, Iterable, Iterator, Sequence

from fabkit.errors import InputError
from fabkit.lifeline import die_with_parent

__all__ = ["panel_executor", "map_ordered", "single_threaded", "check_scheduler"]

_SINGLE_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def single_threaded(fn: Callable, item):
    """Run `fn(item)` with BLAS/OpenMP limited to one thread (same arithmetic everywhere)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        return fn(item)


class _Serial(Executor):
    """An executor that runs each task when submitted (no pickling, no processes)."""

    def submit(self, fn, /, *args, **kwargs):
        from concurrent.futures import Future

        f = Future()
        try:
            f.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # delivered through the future like a real executor
            f.set_exception(exc)
        return f


def check_scheduler(address: str, timeout: float = 5.0) -> None:
    """`InputError` unless `address` is tcp://HOST:PORT (or tls://) and a connection opens within `timeout` s."""
    from urllib.parse import urlsplit

    try:
        parts = urlsplit(address if "://" in address else f"tcp://{address}")
        host, port = parts.hostname, parts.port
    except ValueError:
        host = port = None
    if parts.scheme not in ("tcp", "tls") or not host or port is None:
        raise InputError("expected a dask scheduler address tcp://HOST:PORT", source=address)
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as exc:
        raise InputError(f"cannot reach the dask scheduler ({exc.strerror or exc})", source=address) from None


@contextlib.contextmanager
def panel_executor(jobs: int = 1, scheduler: str | None = None) -> Iterator[Executor]:
    """`jobs` = 1: in-process; > 1: spawn-based process pool; `scheduler`: a dask.distributed address."""
    if scheduler:
        from distributed import Client

        try:
            client = Client(scheduler, timeout=30, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise InputError(f"cannot reach the dask scheduler ({exc})", source=scheduler) from None
        try:
            yield client.get_executor()
        finally:
            client.close(timeout=10)
        return
    if jobs <= 1:
        yield _Serial()
        return
    import multiprocessing as mp

    saved = {k: os.environ.get(k) for k in _SINGLE_THREAD}
    os.environ.update(_SINGLE_THREAD)  # inherited by the spawned workers before they import numpy
    try:
        pool = ProcessPoolExecutor(max_workers=jobs, mp_context=mp.get_context("spawn"),
                                   initializer=die_with_parent, initargs=(os.getpid(),))
        try:
            yield pool
        except BaseException:  # an error, Ctrl-C or SIGTERM: drop the queued panels, do not wait for them
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown(wait=True)
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def map_ordered(executor: Executor, fn: Callable, items: Sequence, progress: Callable | None = None,
                timeout: float | None = None) -> list:
    """Submit `fn(item)` for every item and return the results in input order."""
    futures = [executor.submit(single_threaded, fn, item) for item in items]
    out = []
    for f in futures:
        out.append(f.result(timeout=timeout))
        if progress:
            progress()
    return out
