"""Controller hosts in the cell: `host` in `[robot]` and each `[[arms]]`, validated when the cell
is read, and the rule `fabkit send` and `fk.send` follow (`robot.send_options.controller_hosts`):
given --host addresses replace the cell's, else the cell's for every arm, else $FABKIT_UR_HOST for
one arm."""
from __future__ import annotations

import subprocess
import sys

import pytest

from fabkit.errors import InputError
from robot.cell import load_cell
from robot.send_options import controller_hosts
from tests._ursim import ROOT

DUAL = ROOT / "cells" / "dual_ur10e.toml"


def _dual(tmp_path, a: str | None, b: str | None):
    text = DUAL.read_text()
    if a is not None:
        text = text.replace('[robot]                                   # arm "a"\n',
                            f'[robot]                                   # arm "a"\nhost = "{a}"\n')
    if b is not None:
        text = text.replace('name = "b"\n', f'name = "b"\nhost = "{b}"\n')
    path = tmp_path / "dual.toml"
    path.write_text(text)
    return path


def test_the_cell_names_each_arms_controller(tmp_path):
    cell = load_cell(_dual(tmp_path, "192.168.1.10", "ur-b.cell.local"))
    assert {n: m.host for n, m in cell.arms} == {"a": "192.168.1.10", "b": "ur-b.cell.local"}
    assert controller_hosts(None, cell, ("a", "b")) == (("192.168.1.10", "ur-b.cell.local"), "cell")
    # given addresses replace the cell's, all of them
    assert controller_hosts(["10.0.0.1", "10.0.0.2"], cell, ("a", "b"), "10.9.9.9") == (("10.0.0.1", "10.0.0.2"),
                                                                                         "--host")
    # the cell comes before the environment
    assert controller_hosts([], cell, ("a", "b"), "10.9.9.9")[1] == "cell"
    assert load_cell(DUAL).robot.host is None


def test_some_arms_without_a_host_or_none_at_all(tmp_path):
    half = load_cell(_dual(tmp_path, "192.168.1.10", None))
    with pytest.raises(InputError, match="names the controller of arm a but not of arm b"):
        controller_hosts(None, half, ("a", "b"), "10.9.9.9")
    plain = load_cell(DUAL)
    with pytest.raises(InputError, match="no controller address"):
        controller_hosts(None, plain, ("a", "b"), "10.9.9.9")  # one variable cannot name two controllers
    assert controller_hosts(None, plain, ("a",), "10.9.9.9") == (("10.9.9.9",), "env")


@pytest.mark.parametrize("a, b, message", [
    ("not a host!", None, r"robot\.host: 'not a host!' is not an IP address or host name"),
    ("127.0.0.7", "127.0.0.7", r"arms\[0\]\.host: '127\.0\.0\.7' is arm a's controller too"),
    (None, "", None),  # an empty host is no host
])
def test_bad_hosts_are_refused_when_the_cell_is_read(tmp_path, a, b, message):
    path = _dual(tmp_path, a, b)
    if message is None:
        assert load_cell(path).extra_arms[0][1].host is None
        return
    with pytest.raises(InputError, match=message):
        load_cell(path)
    out = tmp_path / "cell.xml"
    r = subprocess.run([sys.executable, "-m", "fabkit", "cell", str(path), "--mjcf", str(out)], cwd=ROOT,
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and str(path) in r.stderr, r.stderr
    assert not out.exists()
