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


_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
          "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def dump_dom(page: Path) -> str:
    """The page's DOM after its scripts ran, as chromium serialises it (`--dump-dom`)."""
    with tempfile.TemporaryDirectory() as profile:
        r = subprocess.run([chromium(), *_FLAGS, f"--user-data-dir={profile}", "--dump-dom", page.as_uri()],
                           check=True, timeout=90, capture_output=True, text=True)
    return r.stdout


def table_rows(dom: str, after_heading: str) -> list[list[str]]:
    """Cell texts of each row of the first <table> after the <h2> whose text is `after_heading`."""
    import html.parser

    class Rows(html.parser.HTMLParser):
        def __init__(self):
            super().__init__()
            self.state, self.heading, self.rows, self.cell = "seek", "", [], None

        def handle_starttag(self, tag, attrs):
            if self.state == "seek" and tag == "h2":
                self.state, self.heading = "heading", ""
            elif self.state == "found" and tag == "table":
                self.state = "table"
            elif self.state == "table" and tag == "tr":
                self.rows.append([])
            elif self.state == "table" and tag in ("td", "th"):
                self.cell = ""

        def handle_endtag(self, tag):
            if self.state == "heading" and tag == "h2":
                self.state = "found" if self.heading.strip() == after_heading else "seek"
            elif self.state == "table" and tag in ("td", "th") and self.cell is not None:
                self.rows[-1].append(self.cell.strip())
                self.cell = None
            elif self.state == "table" and tag == "table":
                self.state = "done"

        def handle_data(self, data):
            if self.state == "heading":
                self.heading += data
            elif self.cell is not None:
                self.cell += data

    parser = Rows()
    parser.feed(dom)
    return parser.rows
