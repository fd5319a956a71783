"""Content-addressed results of per-panel tasks, so a rerun computes only what changed.

A task's key is the SHA-256 of everything it reads: every value of its input dict (arrays by dtype,
shape and bytes; other values by their JSON text) plus a code salt that changes when the stage's
meaning changes. A result is stored as one `.npz` per key (arrays, with scalars and strings as
0-d arrays; no pickles), written atomically, so a run killed half way keeps every finished result.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

__all__ = ["task_key", "ResultCache"]


def _feed(h, value) -> None:
    if isinstance(value, np.ndarray):
        a = np.ascontiguousarray(value)
        h.update(f"a{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    elif isinstance(value, dict):
        h.update(b"{")
        for k in sorted(value):
            h.update(str(k).encode() + b"=")
            _feed(h, value[k])
        h.update(b"}")
    elif isinstance(value, (list, tuple)):
        h.update(b"[")
        for v in value:
            _feed(h, v)
        h.update(b"]")
    elif callable(value):
        h.update(f"f{value.__module__}.{value.__qualname__}".encode())
    else:
        h.update(json.dumps(value, sort_keys=True, default=str).encode())


def task_key(task: dict, salt: str) -> str:
    """SHA-256 (hex) of a task's inputs and the stage's code salt."""
    h = hashlib.sha256(salt.encode())
    _feed(h, task)
    return h.hexdigest()


class ResultCache:
    """Results of one stage under `folder/<key>.npz`; `computed` / `reused` count what a run did."""

    def __init__(self, folder: str | os.PathLike, salt: str):
        self.folder = Path(folder)
        self.salt = salt
        self.computed: list = []
        self.reused: list = []

    def key(self, task: dict) -> str:
        return task_key(task, self.salt)

    def get(self, key: str) -> dict | None:
        path = self.folder / f"{key}.npz"
        if not path.is_file():
            return None
        try:
            with np.load(path, allow_pickle=False) as z:
                return {k: (z[k].item() if z[k].ndim == 0 else np.array(z[k])) for k in z.files}
        except (OSError, ValueError):  # a damaged entry is recomputed
            return None

    def put(self, key: str, result: dict) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        arrays = {k: np.asarray(v) for k, v in result.items() if v is not None}
        tmp = self.folder / f".{key}.{os.getpid()}.tmp.npz"
        np.savez(tmp, **arrays)
        os.replace(tmp, self.folder / f"{key}.npz")
