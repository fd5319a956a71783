"""`fabkit demo --material/--thickness`: the sheet thickness the check's panel pieces get, and the
refusals before the first stage (exit 2, one line naming the option)."""
from __future__ import annotations

import argparse
import subprocess
import sys

import pytest

from fabkit.commands.demo import sheet_thickness
from fabkit.errors import InputError


def _demo(tmp_path, *extra):
    return subprocess.run([sys.executable, "-m", "fabkit", "demo", "--out", str(tmp_path / "out"), "--small",
                           "--no-render", "--no-dry-run", "-q", *extra], capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("extra, option", [(("--thickness", "1mm"), "--material"),
                                           (("--material", "5052-H32"), "--thickness"),
                                           (("--material", "5052-H32", "--thickness", "1.6"), "--thickness"),
                                           (("--material", "unobtainium", "--thickness", "1mm"), "--material")])
def test_bad_sheet_options_are_refused_before_any_stage(tmp_path, extra, option):
    proc = _demo(tmp_path, *extra)
    assert proc.returncode == 2, proc.stderr
    assert option in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "out" / "trifold.obj").exists()


def test_the_material_gives_the_check_its_thickness():
    ns = argparse.Namespace(material="5052-H32", thickness="1.6 mm")
    assert sheet_thickness(ns) == pytest.approx(0.0016)
    assert sheet_thickness(argparse.Namespace(material="none", thickness=None)) is None
    with pytest.raises(InputError, match="needs a --material"):
        sheet_thickness(argparse.Namespace(material="none", thickness="1mm"))
