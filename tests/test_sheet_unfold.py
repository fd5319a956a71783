"""Neutral-surface development (fabkit.unfold.neutral) and `fabkit unfold --material --thickness`."""
import json
import math

import numpy as np
import pytest

from fabkit.cli import main as fabkit_main
from fabkit.cutfiles import crease_assignment
from fabkit.io.obj import save_obj
from fabkit.materials import get_material
from fabkit.mesh import PolyMesh
from fabkit.sheet import crease_correction, sheet_spec
from fabkit.unfold import develop
from fabkit.unfold.neutral import neutral_development

MM = 1e-3


def l_panel(up: bool, leg=0.1, width=0.05, n=4, seed=None):
    """A strip 2 x `leg` long (m), folded 90 deg along the straight crease x = leg: valley (`up`, the
    second leg rises toward the front side +z) or mountain. Vertex order shuffled with `seed`."""
    s = np.linspace(0, leg, n + 1)
    pts = [(x, y, 0.0) for x in s for y in (0.0, width)]
    pts += [(leg, y, (1 if up else -1) * z) for z in s[1:] for y in (0.0, width)]
    V = np.array(pts)
    faces = [[2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1] for i in range(2 * n)]
    perm = np.arange(len(V)) if seed is None else np.random.default_rng(seed).permutation(len(V))
    inv = np.argsort(perm)
    return PolyMesh(V[perm], [[int(inv[v]) for v in f] for f in faces]), int(inv[0]), int(inv[len(V) - 2])


@pytest.mark.parametrize("up", [True, False])
@pytest.mark.parametrize("seed", [None, 7])
def test_neutral_development_of_a_2mm_straight_fold_differs_by_the_k_factor_amount(up, seed):
    mesh, a, b = l_panel(up, seed=seed)
    crease = crease_assignment(mesh, math.radians(5))
    mask = np.isin(crease.edges_assignment, ["M", "V"])
    assert mask.sum() == 1
    angle = crease.edges_fold_angle[mask][0]
    assert angle == pytest.approx(math.pi / 2 if up else -math.pi / 2, abs=1e-12)
    spec = sheet_spec(get_material("5052-H32"), 2 * MM)  # R_i = 3 mm (1.5t), K = 0.369
    design = develop(mesh)
    neutral = neutral_development(mesh, design, spec, mask, "top")
    L_design = np.linalg.norm(design.uv[b] - design.uv[a])
    L_neutral = np.linalg.norm(neutral.uv[b] - neutral.uv[a])
    assert L_design == pytest.approx(0.2, abs=1e-12)
    expected = -0.128 * MM if up else -4.128 * MM  # reference §4: 199.87 (valley) and 195.87 mm (mountain)
    assert crease_correction(spec, angle) == pytest.approx(expected, abs=1e-6)
    assert L_neutral - L_design == pytest.approx(crease_correction(spec, angle), abs=1e-9)
    assert neutral.max_relative_deviation < 1e-9  # the neutral lengths are met exactly
    # the mid-surface as design surface: the same strip width for both senses
    mid = neutral_development(mesh, design, spec, mask, "mid")
    assert np.linalg.norm(mid.uv[b] - mid.uv[a]) - L_design == pytest.approx(-2.128 * MM, abs=1e-6)


def test_rigid_material_keeps_the_design_development():
    mesh, _, _ = l_panel(True)
    d = develop(mesh)
    assert neutral_development(mesh, d, sheet_spec(get_material("none"), None), np.ones(mesh.n_edges, bool)) is d


def test_unfold_command_with_thickness(tmp_path, capsys):
    mesh, a, b = l_panel(False)
    src = tmp_path / "l.obj"
    save_obj(mesh, src)
    out, rep = tmp_path / "flat.obj", tmp_path / "r.json"
    assert fabkit_main(["unfold", str(src), "-o", str(out), "--report", str(rep), "-q",
                        "--material", "5052-H32", "--thickness", "2mm"]) == 0
    doc = json.loads(rep.read_text())
    assert doc["sheet"]["surface"] == "neutral" and doc["sheet"]["design_surface"] == "top"
    assert doc["sheet"]["crease_strip_mm"] == pytest.approx([-4.128, -4.128], abs=1e-3)
    V = np.array([[float(x) for x in line.split()[1:4]] for line in out.read_text().splitlines()
                  if line.startswith("v ")])
    assert np.linalg.norm(V[b] - V[a]) == pytest.approx(0.2 - 4.128 * MM, abs=1e-6)
    assert fabkit_main(["unfold", str(src), "-o", str(out), "-q", "--material", "5052-H32", "--thickness",
                        "2mm", "--bend-radius", "1mm"]) == 2
    assert "minimum 3 mm" in capsys.readouterr().err
