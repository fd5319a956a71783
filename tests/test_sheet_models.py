"""Known answers of the sheet models against the worked examples of the sheet-metal reference."""
import math
from dataclasses import replace

import numpy as np
import pytest

from fabkit.errors import InputError
from fabkit.materials import get_material
from fabkit.sheet import (BendRadiusError, SpringbackError, VacuumCup, bend_allowance, check_bend_radius,
                          crease_correction, flat_length, fold_moment, k_factor, minimum_inside_radius, panel_mass,
                          panel_unfolding_moment, programmed_angle, released_angle, sheet_spec, springback_ratio)
from fabkit.sheet.springback import plate_stiffness

DEG = math.pi / 180
MM = 1e-3


def uncalibrated(name, **kw):
    return replace(get_material(name), calibration=1.0, **kw)


# reference §2.3: predicted springback [deg] on a 90 deg fold, flow stress (yield + UTS) / 2, any t
TABLE = [("1100-H14", 1, 0.7), ("3003-H14", 2, 1.5), ("5052-H32", 1, 1.2), ("5052-H32", 5, 4.4),
         ("5052-H32", 30, 24.4), ("6061-T6", 10, 12.0), ("6061-T6", 30, 34.2), ("mild-steel", 1, 0.6),
         ("mild-steel", 30, 11.8), ("304-stainless", 2, 1.3), ("304-stainless", 30, 15.3)]


@pytest.mark.parametrize("name,r_over_t,expected", TABLE)
def test_uncalibrated_springback_matches_the_reference_table(name, r_over_t, expected):
    for t in (1 * MM, 2 * MM):  # only r/t matters
        spec = sheet_spec(uncalibrated(name), t, inside_radius=r_over_t * t)
        got = 90 - released_angle(spec, 90 * DEG) / DEG
        assert got == pytest.approx(expected, abs=0.051)


def test_calibrated_5052_h32_straight_fold_springs_back_about_3_degrees():
    spec = sheet_spec(get_material("5052-H32"), 1.6 * MM, inside_radius=1.6 * MM)
    assert 90 - released_angle(spec, 90 * DEG) / DEG == pytest.approx(3.0, abs=0.1)
    # and the overbend undoes it exactly
    held = programmed_angle(spec, 90 * DEG)
    assert released_angle(spec, held) == pytest.approx(90 * DEG, abs=1e-12)
    assert held / DEG == pytest.approx(90 / springback_ratio(spec), rel=1e-12)


def test_worked_example_command_angles():
    # reference §2.2: 1 mm 5052-H32, R_i = 1 mm, sigma_y: K = 0.9877, command 91.1 deg; R_i = 10 mm -> 99.4
    s = sheet_spec(uncalibrated("5052-H32", flow_stress_rule="yield"), 1 * MM, inside_radius=1 * MM)
    assert springback_ratio(s) == pytest.approx(0.9877, abs=1e-4)
    assert programmed_angle(s, 90 * DEG) / DEG == pytest.approx(91.1, abs=0.05)
    s10 = sheet_spec(uncalibrated("5052-H32"), 1 * MM, inside_radius=10 * MM)
    assert programmed_angle(s10, 90 * DEG) / DEG == pytest.approx(99.4, abs=0.06)
    # mountain folds keep their sign
    assert programmed_angle(s10, -90 * DEG) == -programmed_angle(s10, 90 * DEG)


def test_elastic_limit_radius_springs_back_flat_and_is_refused():
    m = uncalibrated("5052-H32", flow_stress_rule="yield")
    # R_y = E t / (2 sigma_y) = 182 mm at 1 mm
    s = sheet_spec(m, 1 * MM, inside_radius=200 * MM)
    assert springback_ratio(s) == 0.0
    assert released_angle(s, 60 * DEG) == 0.0
    with pytest.raises(SpringbackError, match="springs back flat"):
        programmed_angle(s, 60 * DEG, crease="crease 3")


def test_curved_crease_unfolding_moment_and_reopening_of_a_deep_score():
    m = uncalibrated("5052-H32", flow_stress_rule="yield")
    s = sheet_spec(m, 1 * MM, inside_radius=1 * MM)
    assert plate_stiffness(s) == pytest.approx(6.575, rel=1e-3)  # D = 6575 N mm
    mu = panel_unfolding_moment(s, 90 * DEG, 1 / 0.5, 0.2)
    assert mu == pytest.approx(10.5, rel=0.01)  # N mm / mm
    # plain crease holds (m_p = 48 N mm/mm > m_u): a little extra springback, the overbend covers it
    straight = programmed_angle(s, 90 * DEG)
    curved = programmed_angle(s, 90 * DEG, kappa_g=2.0, panel_width=0.2)
    assert curved > straight
    assert released_angle(s, curved, 2.0, 0.2) == pytest.approx(90 * DEG, abs=1e-9)
    # scored to 0.4 mm: m_p = 7.7 < m_u, the crease re-opens to about 81 deg whatever the overbend
    g = sheet_spec(m, 1 * MM, "grooved", ligament=0.4 * MM)
    assert released_angle(g, 90 * DEG, 2.0, 0.2) / DEG == pytest.approx(81, abs=0.5)
    assert released_angle(g, 170 * DEG, 2.0, 0.2) / DEG == pytest.approx(81, abs=0.5)
    with pytest.raises(SpringbackError, match="crease 2.*80.8 deg"):
        programmed_angle(g, 90 * DEG, kappa_g=2.0, panel_width=0.2, crease="crease 2")


def test_rigid_material_changes_nothing():
    s = sheet_spec(get_material("none"), None)
    for a in (0.3, -1.2, 0.0):
        assert programmed_angle(s, a) == a and released_angle(s, a, 2.0, 0.2) == a
    assert fold_moment(s, 0.6).high == 0.0 and crease_correction(s, 1.0) == 0.0


def test_k_factor_development_of_a_straight_90_degree_fold():
    # reference §4: 2 mm 5052-H32, R_i = 3 mm, K = 0.369, BA = 5.872 mm, legs 100 + 100 mm
    s = sheet_spec(get_material("5052-H32"), 2 * MM)
    assert s.inside_radius == pytest.approx(3 * MM)  # table minimum 1.5t at 2 mm
    assert k_factor(s) == pytest.approx(0.369, abs=5e-4)
    assert bend_allowance(s, 90 * DEG) / MM == pytest.approx(5.872, abs=1e-3)
    legs = (100 * MM, 100 * MM)
    assert flat_length(s, *legs, 90 * DEG, "top") / MM == pytest.approx(199.87, abs=0.005)   # valley
    assert flat_length(s, *legs, -90 * DEG, "top") / MM == pytest.approx(195.87, abs=0.005)  # mountain
    assert flat_length(s, *legs, 90 * DEG, "mid") / MM == pytest.approx(197.87, abs=0.005)
    assert flat_length(s, *legs, -90 * DEG, "bottom") / MM == pytest.approx(199.87, abs=0.005)
    # the two faces differ by 2 t tan(45 deg) = 4 mm per crease
    assert (crease_correction(s, 90 * DEG) - crease_correction(s, -90 * DEG)) / MM == pytest.approx(4.0, abs=1e-9)


def test_sharp_crease_corrections():
    s = sheet_spec(replace(get_material("1100-H14"), k_factor=0.33), 1 * MM, inside_radius=0.0)
    assert crease_correction(s, 90 * DEG) / MM == pytest.approx(0.52, abs=0.005)
    assert crease_correction(s, 90 * DEG, "mid") / MM == pytest.approx(-0.48, abs=0.005)
    assert crease_correction(s, -120 * DEG) / MM == pytest.approx(-2.77, abs=0.005)


@pytest.mark.parametrize("name,t_mm,lo,hi", [("5052-H32", 1, 29.0, 36.5), ("3003-H14", 1, 21.8, 25.7),
                                              ("6061-T6", 1, 41.4, 50.8), ("mild-steel", 1, 37.5, 51.0),
                                              ("5052-H32", 2, 116, 146)])
def test_fold_moment_of_a_600_mm_crease(name, t_mm, lo, hi):
    m = fold_moment(sheet_spec(get_material(name), t_mm * MM), 0.6, "crease 0")
    assert m.low == pytest.approx(lo, rel=0.01) and m.high == pytest.approx(hi, rel=0.01)
    assert m.crease == "crease 0"


def test_fold_moment_of_grooved_and_perforated_creases():
    m = get_material("5052-H32")
    for lig, low in ((0.6, 10.4), (0.5, 7.2), (0.4, 4.6), (0.3, 2.6)):
        g = fold_moment(sheet_spec(m, 1 * MM, "grooved", ligament=lig * MM), 0.6)
        assert g.low == pytest.approx(low, abs=0.06)
    p = fold_moment(sheet_spec(m, 1 * MM, "perforated", uncut_fraction=0.5), 0.6)
    assert p.low == pytest.approx(29.0 / 2, rel=0.01)


def test_vacuum_cup_holding_force_and_tilt():
    # reference §7 at 60 kPa: D = 50 mm -> 118 N, 59 N at S = 2, tilt 1.5 N m; D = 80 mm -> 302 N, 6.0 N m
    c = VacuumCup(0.05, vacuum=60e3, safety=2)
    assert c.holding_force == pytest.approx(118, abs=0.5) and c.usable_force == pytest.approx(59, abs=0.5)
    assert c.lateral_force == pytest.approx(29, abs=0.6) and c.tilt_capacity == pytest.approx(1.5, abs=0.03)
    c80 = VacuumCup(0.08, safety=2)
    assert c80.holding_force == pytest.approx(302, abs=0.5) and c80.tilt_capacity == pytest.approx(6.0, abs=0.05)


def test_panel_mass_and_centre_of_gravity():
    # 600 x 200 mm of 1 mm 5052: 0.32 kg, centre in the middle, whatever the triangulation
    V = np.array([[0, 0, 0], [0.6, 0, 0], [0.6, 0.2, 0], [0, 0.2, 0], [0.3, 0.1, 0]])
    T = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    pm = panel_mass(sheet_spec(get_material("5052-H32"), 1 * MM), V, T)
    assert pm.mass == pytest.approx(0.3216, rel=1e-9) and pm.area == pytest.approx(0.12)
    np.testing.assert_allclose(pm.cog, [0.3, 0.1, 0], atol=1e-12)
    assert panel_mass(sheet_spec(get_material("none"), None), V, T).mass == 0.0


def test_minimum_radius_by_thickness_column_and_preparation():
    m = get_material("5052-H32")
    assert minimum_inside_radius(m, 1.6 * MM) == pytest.approx(1.6 * MM)   # 1t
    assert minimum_inside_radius(m, 2.0 * MM) == pytest.approx(3.0 * MM)   # next thicker column: 1.5t
    assert minimum_inside_radius(get_material("6061-T6"), 2 * MM) == pytest.approx(5 * MM)  # 2.5t
    assert minimum_inside_radius(get_material("3003-H14"), 3 * MM) == pytest.approx(3 * MM)
    assert minimum_inside_radius(get_material("mild-steel"), 1 * MM) == pytest.approx(0.8 * MM)
    g = sheet_spec(m, 2 * MM, "grooved")
    assert minimum_inside_radius(m, 2 * MM, g.prep) == 0.0
    tight = sheet_spec(m, 2 * MM, inside_radius=2 * MM)
    with pytest.raises(BendRadiusError, match=r"crease 4: inside radius 2 mm is tighter than 5052-H32's minimum 3 mm"):
        check_bend_radius(tight, "crease 4")
    check_bend_radius(sheet_spec(m, 2 * MM), "crease 4")
    with pytest.raises(InputError, match="does not allow grooved"):
        sheet_spec(get_material("6061-T6"), 1 * MM, "grooved")
    with pytest.raises(InputError, match="not thinner"):
        sheet_spec(m, 1 * MM, "grooved", ligament=1 * MM)


@pytest.mark.parametrize("prep,kw", [("plain", {}), ("grooved", {"ligament": 0.6 * MM}),
                                     ("perforated", {"uncut_fraction": 0.5})])
def test_programmed_angle_inverts_the_release_model(prep, kw):
    spec = sheet_spec(get_material("5052-H32"), 1 * MM, prep, **kw)
    rng = np.random.default_rng(11)
    for _ in range(40):
        design = rng.uniform(5, 120) * DEG * rng.choice([-1, 1])
        kappa, b = rng.uniform(0, 3.0), rng.uniform(0.05, 0.3)
        try:
            held = programmed_angle(spec, design, kappa, b)
        except SpringbackError:
            # then no held angle reaches the design: the most folded hold falls short
            assert abs(released_angle(spec, 179 * DEG, kappa, b)) < abs(design)
            continue
        assert abs(held) > abs(design)
        assert released_angle(spec, held, kappa, b) == pytest.approx(design, abs=1e-10)
