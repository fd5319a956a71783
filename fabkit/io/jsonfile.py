"""Reading a JSON input file with the one-line refusals every command gives."""
from __future__ import annotations

import json
import os
from typing import Any

from fabkit.errors import InputError


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
