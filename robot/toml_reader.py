"""Typed, validating access to a TOML table (a cell file's): every error is one `InputError`
line naming the file and the key (`tool.shapes[1].radius: ...`), and keys nobody read are
refused as unknown (`done`), so a typo is never silently ignored."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from fabkit.errors import InputError

__all__ = ["TableReader", "checked_number"]


class TableReader:
    """Typed access to a TOML table that names the key in every error."""

    def __init__(self, table: dict, where: str, source: str):
        self.table, self.where, self.source = table, where, source
        self.used: set[str] = set()

    def key(self, name: str) -> str:
        return f"{self.where}.{name}" if self.where else name

    def fail(self, name: str, message: str):
        raise InputError(f"{self.key(name)}: {message}", source=self.source)

    def has(self, name: str) -> bool:
        return name in self.table

    def raw(self, name: str, required: bool = True, default: Any = None) -> Any:
        self.used.add(name)
        if name not in self.table:
            if required:
                raise InputError(f"{self.key(name)}: missing (required)", source=self.source)
            return default
        return self.table[name]

    def string(self, name: str, required: bool = True, default: str = "", choices=None) -> str:
        v = self.raw(name, required, default)
        if not isinstance(v, str):
            self.fail(name, f"expected a string, got {type(v).__name__} {v!r}")
        if choices is not None and v not in choices:
            self.fail(name, f"{v!r} is not one of {', '.join(map(repr, choices))}")
        return v

    def number(self, name: str, required: bool = True, default: float | None = None, lo: float | None = None,
               hi: float | None = None, lo_open: bool = False, unit: str = "") -> float:
        v = self.raw(name, required, default)
        return checked_number(v, self.key(name), self.source, lo, hi, lo_open, unit)

    def integer(self, name: str, required: bool = True, default: int = 0, lo: int | None = None,
                hi: int | None = None) -> int:
        v = self.raw(name, required, default)
        if isinstance(v, bool) or not isinstance(v, int):
            self.fail(name, f"expected an integer, got {type(v).__name__} {v!r}")
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            self.fail(name, f"{v} is outside {lo}..{hi}")
        return int(v)

    def vector(self, name: str, n: int, required: bool = True, default=None, lo=None, hi=None, lo_open=False,
               unit: str = "") -> np.ndarray:
        v = self.raw(name, required, default)
        if not isinstance(v, (list, tuple)):
            self.fail(name, f"expected a list of {n} numbers, got {type(v).__name__} {v!r}")
        if len(v) != n:
            self.fail(name, f"expected {n} numbers, got {len(v)}")
        return np.array([checked_number(x, f"{self.key(name)}[{i}]", self.source, lo, hi, lo_open, unit)
                         for i, x in enumerate(v)])

    def pose(self, name: str, required: bool = True) -> np.ndarray:
        p = self.vector(name, 6, required, default=[0.0] * 6)
        if np.linalg.norm(p[:3]) > 100.0:
            self.fail(name, f"position {p[:3].tolist()} m is more than 100 m from the origin (millimetres?)")
        from robot.cell import pose_to_matrix  # the cell module reads its files with this one

        return pose_to_matrix(p)

    def table_(self, name: str, required: bool = True) -> "TableReader":
        v = self.raw(name, required, {})
        if not isinstance(v, dict):
            self.fail(name, f"expected a table, got {type(v).__name__}")
        return TableReader(v, self.key(name), self.source)

    def tables(self, name: str) -> list["TableReader"]:
        v = self.raw(name, False, [])
        if not isinstance(v, list) or not all(isinstance(t, dict) for t in v):
            self.fail(name, "expected an array of tables ([[...]])")
        return [TableReader(t, f"{self.key(name)}[{i}]", self.source) for i, t in enumerate(v)]

    def done(self) -> None:
        """Reject keys nobody read (typos would otherwise be silently ignored)."""
        extra = [k for k in self.table if k not in self.used]
        if extra:
            raise InputError(f"{self.key(extra[0])}: unknown key", source=self.source)


def checked_number(v, key: str, source: str, lo=None, hi=None, lo_open=False, unit="") -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InputError(f"{key}: expected a number, got {type(v).__name__} {v!r}", source=source)
    v = float(v)
    u = f" {unit}" if unit else ""
    if not math.isfinite(v):
        raise InputError(f"{key}: {v} is not finite", source=source)
    if lo is not None and (v <= lo if lo_open else v < lo):
        raise InputError(f"{key}: {v:.12g}{u} must be {'>' if lo_open else '>='} {lo:.12g}{u}", source=source)
    if hi is not None and v > hi:
        raise InputError(f"{key}: {v:.12g}{u} must be <= {hi:.12g}{u}", source=source)
    return v
