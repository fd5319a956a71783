"""JSON files: reading an input with the one-line refusals every command gives; writing reports
(numpy values and dataclasses made plain JSON, written atomically)."""
from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from fabkit.errors import InputError
from fabkit.io.atomic import atomic_write


def load_json(path: str | os.PathLike, what: str = "JSON file", *, missing: str | None = None) -> Any:
    """Parse `path`; InputError naming the file: "<missing>" if absent, "not a <what>: ..." if unreadable."""
    source = str(path)
    try:
        with open(path, encoding="utf-8") as fh:
            return json.load(fh)
    except FileNotFoundError:
        raise InputError(missing or f"{what} not found", source=source) from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"not a {what}: {exc}", source=source) from None


def to_jsonable(obj: Any) -> Any:
    """Convert numpy scalars/arrays and dataclasses to plain JSON values (NaN/Inf -> None)."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        f = float(obj)
        return f if math.isfinite(f) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, Path):
        return str(obj)
    if hasattr(obj, "__dataclass_fields__"):
        import dataclasses

        return to_jsonable(dataclasses.asdict(obj))
    return obj


def write_json(path: str | Path, data: Any) -> None:
    """Write JSON atomically (temporary file + rename)."""
    with atomic_write(path) as fh:
        json.dump(to_jsonable(data), fh, indent=1, allow_nan=False)
        fh.write("\n")
