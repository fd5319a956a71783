"""Headless Debian chromium for page tests (installed by scripts/system-deps.sh when possible)."""
from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np


def chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


def screenshot(page: Path, png: Path, width: int = 1200, height: int = 2000) -> np.ndarray:
    """Render `page` headless (no network, fresh profile) and return the screenshot as RGB floats."""
    import matplotlib.image as mpimg

    with tempfile.TemporaryDirectory() as profile:
        subprocess.run([chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                        "--disable-background-networking", "--disable-component-update", "--disable-sync",
                        f"--user-data-dir={profile}", f"--window-size={width},{height}", f"--screenshot={png}",
                        page.as_uri()], check=True, timeout=90, capture_output=True)
    return mpimg.imread(png)[:, :, :3]


def count_colour(img: np.ndarray, hex_rgb: str, tol: float = 0.06) -> int:
    """Pixels within `tol` of a colour like '#1f77b4'."""
    rgb = np.array([int(hex_rgb[i:i + 2], 16) for i in (1, 3, 5)]) / 255
    return int(np.all(np.abs(img - rgb) < tol, axis=2).sum())
