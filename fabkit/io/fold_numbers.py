"""Exact number conversion at the FOLD boundary: file units <-> metres, degrees <-> radians.

Hand-written: no library converts JSON number text between units without a second rounding.
Coordinates are written as the exact decimal of `repr(x)` shifted three places (metres -> mm) and
read back by shifting the file's digits, so every double survives a round trip bitwise. Angles are
written as the shortest degree string that reads back (through pi/180 to 40 digits) to the same
double. `Num` is the float the reader parses JSON numbers into: it keeps the file's text.
"""
from __future__ import annotations

import decimal
import math

import numpy as np

__all__ = ["Num", "UNIT_TO_METRES", "to_si", "metres_to_mm_text", "degrees_to_radians",
           "radians_to_degrees_text", "number_text", "decimal_json"]

_CTX = decimal.Context(prec=40, Emax=decimal.MAX_EMAX, Emin=decimal.MIN_EMIN)


def _pi(digits: int = 50) -> decimal.Decimal:
    """pi to `digits` digits (the series from the Python `decimal` documentation)."""
    ctx = decimal.Context(prec=digits + 5)
    three = decimal.Decimal(3)
    lasts, t, s, n, na, d, da = 0, three, three, 1, 0, 0, 24
    while s != lasts:
        lasts = s
        n, na = n + na, na + 8
        d, da = d + da, da + 32
        t = ctx.divide(ctx.multiply(t, n), d)
        s = ctx.add(s, t)
    return +s


_RAD_PER_DEG = _CTX.divide(_pi(), decimal.Decimal(180))
_DEG_PER_RAD = _CTX.divide(decimal.Decimal(180), _pi())

#: FOLD `frame_unit` -> metres per file unit (exact decimals; pt = 1/72 in to 40 digits).
UNIT_TO_METRES: dict[str, decimal.Decimal] = {
    "m": decimal.Decimal(1), "cm": decimal.Decimal("0.01"), "mm": decimal.Decimal("0.001"),
    "um": decimal.Decimal("1e-6"), "nm": decimal.Decimal("1e-9"), "in": decimal.Decimal("0.0254"),
    "pt": _CTX.divide(decimal.Decimal("0.0254"), decimal.Decimal(72)), "unit": decimal.Decimal(1),
}
#: units that are a power of ten of a metre: metres = value * 10**-k, done by appending "e-k" to the text
_POW10 = {"m": 0, "unit": 0, "cm": 2, "mm": 3, "um": 6, "nm": 9}

class Num(float):
    """A JSON number that remembers its text (so unit conversion can start from the exact decimal)."""

    def __new__(cls, text: str) -> "Num":
        obj = super().__new__(cls, text)
        obj.text = text
        return obj


def number_text(x: float | int) -> str:
    return x.text if isinstance(x, Num) else repr(x) if isinstance(x, float) else str(int(x))


def decimal_json(d: decimal.Decimal) -> str:
    """A Decimal as a JSON number: plain digits for everyday magnitudes, exponent form otherwise."""
    if d.is_zero():
        return "0"
    if -7 <= d.adjusted() <= 15:
        t = format(d, "f")
        if "." in t:
            t = t.rstrip("0").rstrip(".")
        return t
    return str(d).replace("E", "e")


def to_si(x: float | int, unit: str) -> float:
    """A number from the file in `unit` -> metres, rounded once (exactly the decimal the file wrote)."""
    k = _POW10.get(unit)
    if k == 0:
        return float(x)
    t = number_text(x)
    if k is not None and "e" not in t and "E" not in t:
        return float(f"{t}e-{k}")  # Python's float() rounds the exact decimal once
    return float(_CTX.multiply(decimal.Decimal(t), UNIT_TO_METRES[unit]))


def metres_to_mm_text(x: float) -> str:
    """`repr(x)` metres with the decimal point moved three places: exact, reads back to exactly x."""
    r = repr(float(x))
    if "e" in r or "n" in r:  # exponent form, inf, nan: let decimal do it
        return decimal_json(decimal.Decimal(r).scaleb(3))
    sign = "-" if r[0] == "-" else ""
    whole, frac = r.lstrip("-").split(".")
    frac = frac.ljust(3, "0")
    new_whole = (whole + frac[:3]).lstrip("0") or "0"
    new_frac = frac[3:].rstrip("0")
    return sign + new_whole + ("." + new_frac if new_frac else "")


_RADIANS_OF: dict[str, float] = {}


def degrees_to_radians(x: float | int) -> float:
    """Degrees (file text) -> radians through pi/180 to 40 digits, rounded once (memoised by text)."""
    t = number_text(x)
    a = _RADIANS_OF.get(t)
    if a is None:
        a = float(_CTX.multiply(decimal.Decimal(t), _RAD_PER_DEG))
        if len(_RADIANS_OF) < 100_000:
            _RADIANS_OF[t] = a
    return a


def radians_to_degrees_text(a: float) -> str | None:
    """Shortest degree string that `degrees_to_radians` maps back to exactly `a` (None for NaN)."""
    a = float(a)
    if math.isnan(a):
        return None
    if a == 0.0:
        return "0"
    t = repr(float(np.degrees(a)))
    if degrees_to_radians(Num(t)) == a:
        return t
    exact = _CTX.multiply(decimal.Decimal(a), _DEG_PER_RAD)
    for digits in range(15, 30):
        t = decimal_json(decimal.Context(prec=digits).plus(exact))
        if degrees_to_radians(Num(t)) == a:
            return t
    return repr(float(np.degrees(a)))  # pragma: no cover - 30 digits always suffice


