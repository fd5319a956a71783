"""The production manifest: per panel the hash of its inputs and the SHA-256 of every file written.

`manifest.json` is rewritten (atomically) after every finished panel, so a killed run keeps what
it finished; a rerun trusts an entry only when its files are still there with the same hashes.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from fabkit.io.jsonfile import to_jsonable

__all__ = ["MANIFEST", "load_manifest", "write_manifest", "write_text", "files_intact", "store_panel_files",
           "sha256_text"]

MANIFEST = "manifest.json"


def sha256_text(text: str | bytes) -> str:
    return hashlib.sha256(text.encode() if isinstance(text, str) else text).hexdigest()


def load_manifest(out: Path) -> dict:
    path = out / MANIFEST
    if not path.is_file():
        return {"format": "fabkit.production/1", "panels": {}}
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return {"format": "fabkit.production/1", "panels": {}}
    return data if isinstance(data.get("panels"), dict) else {"format": "fabkit.production/1", "panels": {}}


def write_manifest(out: Path, manifest: dict) -> None:
    tmp = out / f".{MANIFEST}.{os.getpid()}.tmp"
    tmp.write_text(json.dumps(to_jsonable(manifest), indent=1, allow_nan=False) + "\n")
    os.replace(tmp, out / MANIFEST)


def write_text(path: Path, text: str) -> str:
    """Write `text` atomically (temporary file, renamed); returns its SHA-256."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)
    return sha256_text(text)


def files_intact(out: Path, entry: dict) -> bool:
    for rec in entry.get("files", {}).values():
        p = out / rec["path"]
        if not p.is_file() or sha256_text(p.read_bytes()) != rec["sha256"]:
            return False
    return True


def store_panel_files(out: Path, r: dict) -> dict:
    """Write one panel's refold/program/check files; returns kind -> {"path", "sha256"}."""
    files = {}
    pdir = out / "panels"
    for kind, suffix, value in (("refold", "_refold.fold", r.get("fold")),
                                ("program", "_path.json", r.get("toolpath")),
                                ("check", "_check.json", r.get("check"))):
        if value is None:
            continue
        text = value if isinstance(value, str) else json.dumps(to_jsonable(value), indent=1, allow_nan=False) + "\n"
        rel = f"panels/{r['name']}{suffix}"
        files[kind] = {"path": rel, "sha256": write_text(pdir / f"{r['name']}{suffix}", text)}
    return files
