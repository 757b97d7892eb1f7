"""Tests of the heat-transfer and friction correlations (wet_eha_thermal.model.correlations)."""

import math
import warnings

import numpy as np
import pytest
from scipy.constants import Stefan_Boltzmann

from wet_eha_thermal.model import correlations as c
from wet_eha_thermal.model.validity import ValidityLog

# Reference-rig airgap (docs/model.md, The reference rig): rotor 18.0 mm, gap 0.5 mm, stack 55 mm.
R1 = 0.018
R2 = 0.0185
L = 0.055
# MIL-PRF-5606 near 40 degC.
RHO = 848.0
MU = 0.0114
K_OIL = 0.132
CP = 1957.0


# ------------------------------------------------------------------ friction


def test_couette_torque_against_numerical_shear_stress():
    """
    couette_torque equals the torque of the wall shear of u = A r + B / r.

    Independent evaluation: solve the no-slip conditions u(r1) = omega r1,
    u(r2) = 0 for A and B, differentiate u/r numerically (central
    difference, error O(h^2) ~ 1e-10 relative) and integrate
    tau = mu r d(u/r)/dr over the rotor: M = |tau| 2 pi r1 L r1.
    """
    mu, omega = 0.02, 300.0
    for r2 in (R2, 0.025, 0.04):
        mat = np.array([[R1, 1.0 / R1], [r2, 1.0 / r2]])
        a, b = np.linalg.solve(mat, [omega * R1, 0.0])

        def u_over_r(r):
            return (a * r + b / r) / r

        h = 1e-7 * R1
        dudr = (u_over_r(R1 + h) - u_over_r(R1 - h)) / (2.0 * h)
        torque = abs(mu * R1 * dudr) * 2.0 * math.pi * R1 * L * R1
        assert c.couette_torque(mu, omega, L, R1, r2) == pytest.approx(torque, rel=1e-6)


def test_couette_torque_narrow_gap_limit():
    """For delta << r1 the torque tends to the plane-Couette value (error ~ delta/r1)."""
    mu, omega, r2 = 0.01, 100.0, R1 * (1.0 + 1e-5)
    plane = mu * omega * R1 / (r2 - R1) * 2.0 * math.pi * R1 * L * R1
    assert c.couette_torque(mu, omega, L, R1, r2) == pytest.approx(plane, rel=2e-5)


def test_airgap_friction_low_re_is_exact_couette():
    """Re_d << 64: power is M omega of the exact Couette torque (rtol 1e-12), regime 0."""
    mu, rho, omega = 0.5, 900.0, 10.0
    re = rho * omega * R1 * (R2 - R1) / mu
    assert re < 1.0
    power, regime = c.airgap_friction(rho, mu, omega, R1, R2, L)
    expected = c.couette_torque(mu, omega, L, R1, R2) * omega
    assert power == pytest.approx(expected, rel=1e-12)
    assert regime == 0


# An airgap that is not the reference rig's: rotor 40 mm, gap 1.2 mm, 80 mm long (g = 0.03).
R1_T, R2_T, L_T = 0.040, 0.0412, 0.080


def omega_at_taylor(ta_m, r1=R1_T, r2=R2_T, rho=RHO, mu=MU):
    """Return the speed (rad/s) at a modified Taylor number (Becker-Kaye definition)."""
    delta, r_mean = r2 - r1, 0.5 * (r1 + r2)
    f_g = c.becker_kaye_geometric_factor(r1, r2)
    return math.sqrt(ta_m * f_g / (r_mean * delta ** 3)) * mu / rho


def test_airgap_friction_below_vortex_onset_is_exact_couette():
    """Below Ta_m = 1700 the power is M omega of the exact Couette torque (1e-9), regime 0."""
    for share in (1e-3, 0.5, 0.999):
        omega = omega_at_taylor(share * c.TAYLOR_ONSET)
        assert c.modified_taylor_number(omega, R1_T, R2_T, MU / RHO) == pytest.approx(
            share * c.TAYLOR_ONSET, rel=1e-12)
        power, regime = c.airgap_friction(RHO, MU, omega, R1_T, R2_T, L_T)
        assert regime == 0
        assert power == pytest.approx(c.couette_torque(MU, omega, L_T, R1_T, R2_T) * omega,
                                      rel=1e-9)
    # where Bilgen-Boulos alone would have read 40-50 % above it
    re = RHO * omega * R1_T * (R2_T - R1_T) / MU
    cm, _ = c.bilgen_boulos_torque_coefficient(re, (R2_T - R1_T) / R1_T)
    assert 0.5 * cm * math.pi * RHO * omega ** 3 * R1_T ** 4 * L_T > 1.3 * power


def test_airgap_friction_is_continuous_at_every_regime_boundary():
    """
    No jump at the onset, the end of the blend or a Bilgen-Boulos edge.

    At each boundary speed w_b, the powers at w_b (1 -+ 1e-9) agree within
    1e-7: the natural change over that bracket is below 2e-9 x the largest
    log-slope of the curve (about 5 at the end of the blend), a jump of a
    tenth of a per cent (the smallest published one is 0.02 %) would show.
    """
    re_per_omega = RHO * R1_T * (R2_T - R1_T) / MU
    onset = omega_at_taylor(c.TAYLOR_ONSET)
    blend_end = omega_at_taylor(c.TAYLOR_BLEND_END * c.TAYLOR_ONSET)
    edges = [re / re_per_omega for re in c.BILGEN_BOULOS_RE_EDGES]
    regimes = {}
    for name, omega in [('onset', onset), ('blend end', blend_end)] + [
            (f'Bilgen-Boulos edge {k + 2}', w) for k, w in enumerate(edges)]:
        p_lo, reg_lo = c.airgap_friction(RHO, MU, omega * (1 - 1e-9), R1_T, R2_T, L_T)
        p_hi, reg_hi = c.airgap_friction(RHO, MU, omega * (1 + 1e-9), R1_T, R2_T, L_T)
        assert p_hi == pytest.approx(p_lo, rel=1e-7), name
        regimes[name] = (int(reg_lo), int(reg_hi))
    # the boundaries were crossed: the regime flag changes at each one above the onset
    assert regimes['onset'] == (0, c.AIRGAP_ONSET_BLEND)
    assert regimes['blend end'] == (c.AIRGAP_ONSET_BLEND, 2)       # Re_d about 340
    assert regimes['Bilgen-Boulos edge 2'] == (0, 0)                # Re_d 56: below the onset
    assert regimes['Bilgen-Boulos edge 3'] == (2, 3)
    assert regimes['Bilgen-Boulos edge 4'] == (3, 4)
    # the blend is monotonic: the torque only grows through it
    w = np.linspace(onset, blend_end, 201)
    p = np.array([c.airgap_friction(RHO, MU, x, R1_T, R2_T, L_T)[0] for x in w])
    assert np.all(np.diff(p / w ** 2) > 0)


def test_bilgen_boulos_laws_meet_at_the_regime_edges():
    """Each edge is where the published laws of the two regimes meet (C_M continuous)."""
    g = (R2_T - R1_T) / R1_T
    for k, re in enumerate(c.BILGEN_BOULOS_RE_EDGES):
        below, reg_below = c.bilgen_boulos_torque_coefficient(re * (1 - 1e-12), g)
        above, reg_above = c.bilgen_boulos_torque_coefficient(re * (1 + 1e-12), g)
        assert (reg_below, reg_above) == (k + 1, k + 2)
        assert above == pytest.approx(below, rel=1e-9)


def test_airgap_friction_equals_bilgen_boulos_power_when_turbulent():
    """Above the switch, P = 0.5 C_M pi rho omega^3 r1^4 L with C_M from Bilgen-Boulos."""
    omega = 20000.0 * math.pi / 30.0
    power, regime = c.airgap_friction(RHO, MU, omega, R1, R2, L)
    re = RHO * omega * R1 * (R2 - R1) / MU
    cm, bb_regime = c.bilgen_boulos_torque_coefficient(re, (R2 - R1) / R1)
    assert regime == bb_regime == 3
    assert power == pytest.approx(0.5 * cm * math.pi * RHO * omega ** 3 * R1 ** 4 * L,
                                  rel=1e-12)
    assert power > c.couette_torque(MU, omega, L, R1, R2) * omega


@pytest.mark.slow
@pytest.mark.filterwarnings('error')
def test_airgap_friction_zero_and_negative_speed():
    """Zero speed gives 0 W without warnings; the sign of omega does not matter."""
    power, regime = c.airgap_friction(RHO, MU, 0.0, R1, R2, L)
    assert power == 0.0 and regime == 0
    omega = np.array([-1500.0, -10.0, 0.0, 10.0, 1500.0])
    p, _ = c.airgap_friction(RHO, MU, omega, R1, R2, L)
    assert p[0] == p[4] and p[1] == p[3] and p[2] == 0.0


def test_airgap_friction_validity_flags():
    """Re_d above 1e5 is flagged when Bilgen-Boulos sets the torque; the rig is not."""
    log = ValidityLog()
    c.airgap_friction(RHO, MU, 12000.0 * math.pi / 30.0, R1, R2, L, log=log)
    assert len(log) == 0
    c.airgap_friction(RHO, MU / 200.0, 12000.0 * math.pi / 30.0, R1, R2, L, log=log)
    assert [flag.quantity for flag in log] == ['Re_d']
    c.airgap_friction(RHO, MU, 100.0, R1, 0.0205, L, log=log)
    assert 'delta/r1' in {flag.quantity for flag in log}


# ------------------------------------------------------------ Taylor-Couette


def test_becker_kaye_factor_narrow_gap_limit():
    """F_g -> pi^4 / (1697 * 0.05766) = 0.99551 as delta -> 0 (within 1e-3 at 1e-4)."""
    limit = math.pi ** 4 / (1697.0 * (0.0571 + 0.00056))
    assert limit == pytest.approx(0.99551, abs=1e-5)
    assert c.becker_kaye_geometric_factor(1.0, 1.0 + 1e-4) == pytest.approx(limit, abs=1e-3)
    assert c.becker_kaye_geometric_factor(1.0, 1.0 + 1e-7) == pytest.approx(limit, abs=1e-6)


def test_becker_kaye_nusselt_conduction_limit_and_continuity():
    """Nu = 2 (conduction) below the vortex onset; continuous at 1700 and 1e4 within 2 %."""
    assert c.taylor_couette_nusselt(100.0) == 2.0
    for join in (1700.0, 1.0e4):
        below = c.taylor_couette_nusselt(join * (1 - 1e-12))
        above = c.taylor_couette_nusselt(join)
        assert above == pytest.approx(below, rel=0.02)
    ta = np.logspace(0, 7, 400)
    assert np.all(np.diff(c.taylor_couette_nusselt(ta)) >= 0.0)


def test_becker_kaye_flags_above_1e7():
    """Ta_m above 1e7 is flagged, 1e6 is not."""
    log = ValidityLog()
    c.taylor_couette_nusselt(1e6, log=log)
    assert len(log) == 0
    c.taylor_couette_nusselt(3e7, log=log)
    assert len(log) == 1


# ----------------------------------------------------------- duct convection


def test_gnielinski_against_dittus_boelter():
    """Gnielinski at Re = 1e4, Pr = 0.7 within 10 % of Dittus-Boelter 0.023 Re^0.8 Pr^0.4."""
    dittus_boelter = 0.023 * 1e4 ** 0.8 * 0.7 ** 0.4
    assert c.pipe_internal_nusselt(1e4, 0.7) == pytest.approx(dittus_boelter, rel=0.10)
    assert c.annulus_axial_nusselt(1e4, 0.7) == pytest.approx(dittus_boelter, rel=0.10)


def test_pipe_laminar_values_and_blend():
    """Laminar 3.66 / 4.36; linear blend from 2300 to Gnielinski at 4000; continuous."""
    assert c.pipe_internal_nusselt(1000.0, 5.0) == 3.66
    assert c.pipe_internal_nusselt(1000.0, 5.0, thermal_bc='q') == 4.36
    pr = 5.0
    mid = c.pipe_internal_nusselt(3150.0, pr)
    assert mid == pytest.approx(0.5 * (3.66 + c.pipe_internal_nusselt(4000.0, pr)), rel=1e-12)
    for join in (2300.0, 4000.0):
        lo = c.pipe_internal_nusselt(join * (1 - 1e-12), pr)
        hi = c.pipe_internal_nusselt(join * (1 + 1e-12), pr)
        assert hi == pytest.approx(lo, rel=1e-9)
    with pytest.raises(ValueError):
        c.pipe_internal_nusselt(1000.0, 5.0, thermal_bc='x')


def test_annulus_laminar_value():
    """Laminar plates: Nu = 7.54 for Re <= 2300."""
    assert c.annulus_axial_nusselt(np.array([0.0, 20.0, 2300.0]), 170.0).tolist() == [7.54] * 3


def test_wall_to_bulk_limits():
    """Nu_wb = 4 for a still, stagnant gap; 7.54 with laminar flow and no rotation."""
    delta = R2 - R1
    still = c.airgap_wall_to_bulk_htc(0.0, R1, R2, 0.0, RHO, MU, K_OIL, CP)
    assert still.Nu == pytest.approx(4.0, rel=1e-14)
    assert still.h == pytest.approx(4.0 * K_OIL / (2.0 * delta), rel=1e-14)
    assert still.Ta_m == 0.0 and still.Re_axial == 0.0
    flow = c.airgap_wall_to_bulk_htc(0.0, R1, R2, 1.0 / 60000.0, RHO, MU, K_OIL, CP)
    assert flow.Nu == pytest.approx(7.54, rel=1e-14)
    assert flow.h == pytest.approx(7.54 * K_OIL / (2.0 * delta), rel=1e-14)
    # Re = rho u 2 delta / mu with u = Q / (pi (r2^2 - r1^2)).
    u = (1.0 / 60000.0) / (math.pi * (R2 ** 2 - R1 ** 2))
    assert flow.Re_axial == pytest.approx(RHO * u * 2.0 * delta / MU, rel=1e-13)


def test_wall_to_bulk_rotation_only():
    """With rotation and no flow, Nu_wb = 2 Nu_TC(Ta_m)."""
    omega = 10000.0 * math.pi / 30.0
    res = c.airgap_wall_to_bulk_htc(omega, R1, R2, 0.0, RHO, MU, K_OIL, CP)
    ta_m = c.modified_taylor_number(omega, R1, R2, MU / RHO)
    assert res.Ta_m == pytest.approx(ta_m, rel=1e-14)
    assert res.Nu == pytest.approx(2.0 * c.taylor_couette_nusselt(ta_m), rel=1e-14)
    assert res.Nu > 4.0


def test_wall_to_bulk_flags_laminar_leakage_flow():
    """An axial Re of 20 is flagged against 380-4220; an in-range case is not."""
    delta = R2 - R1
    area = math.pi * (R2 ** 2 - R1 ** 2)

    def flow_for(re):
        return re * MU * area / (RHO * 2.0 * delta)

    log = ValidityLog()
    res = c.airgap_wall_to_bulk_htc(1000.0, R1, R2, flow_for(1000.0), RHO, MU, K_OIL, CP,
                                    log=log)
    assert res.Re_axial == pytest.approx(1000.0)
    assert len(log) == 0
    res = c.airgap_wall_to_bulk_htc(1000.0, R1, R2, flow_for(20.0), RHO, MU, K_OIL, CP,
                                    log=log)
    assert res.Re_axial == pytest.approx(20.0)
    flags = list(log)
    assert len(flags) == 1 and flags[0].quantity == 'Re_axial'
    assert 'laminar' in flags[0].note
    assert flags[0].min_seen == pytest.approx(20.0)


# --------------------------------------------------- free convection, radiation


def test_churchill_chu_limits_and_published_correlations():
    """
    Ra -> 0 limits 0.36 and 0.825^2; agreement with other published laws within 10 %.

    Horizontal cylinder: Morgan, Nu = 0.480 Ra^0.25 for Ra 1e4-1e7
    (Incropera table 9.1). Vertical plate: Churchill-Chu's laminar form
    Nu = 0.68 + 0.670 Ra^0.25 / [1 + (0.492/Pr)^(9/16)]^(4/9) for Ra 1e4-1e7
    (Incropera eq. 9.27; the full-range form is known to sit 5-7 % below it
    there) and McAdams' Nu = 0.59 Ra^0.25 at Ra 1e7-1e8. Air, Pr = 0.7.
    """
    assert c.churchill_chu_horizontal_cylinder(0.0, 0.7) == pytest.approx(0.36, rel=1e-14)
    assert c.churchill_chu_vertical_plate(0.0, 0.7) == pytest.approx(0.825 ** 2, rel=1e-14)
    for ra in (1e4, 1e5, 1e6, 1e7):
        assert c.churchill_chu_horizontal_cylinder(ra, 0.7) == pytest.approx(
            0.480 * ra ** 0.25, rel=0.10)
        laminar_form = 0.68 + 0.670 * ra ** 0.25 / (1 + (0.492 / 0.7) ** (9 / 16)) ** (4 / 9)
        assert c.churchill_chu_vertical_plate(ra, 0.7) == pytest.approx(laminar_form, rel=0.10)
    for ra in (1e7, 1e8):
        assert c.churchill_chu_vertical_plate(ra, 0.7) == pytest.approx(
            0.59 * ra ** 0.25, rel=0.10)


def test_morgan_and_mcadams_joins_and_distance_to_churchill_chu():
    """
    The truth rig's other free-convection laws: joins, distance to Churchill-Chu, flags.

    Morgan's five pieces (Incropera table 9.1) meet within 0.8 %. The
    docstrings' distances to Churchill-Chu (air, Pr 0.71) are checked to the
    percent; their hand values are their docstrings' examples.
    """
    for edge in (1.0e-2, 1.0e2, 1.0e4, 1.0e7):
        below = c.morgan_horizontal_cylinder(edge * (1 - 1e-9))
        assert c.morgan_horizontal_cylinder(edge) == pytest.approx(below, rel=8e-3)
    for ra, ratio in ((1.0e2, 1.21), (1.0e4, 1.10), (1.0e6, 1.04)):
        got = c.morgan_horizontal_cylinder(ra) / c.churchill_chu_horizontal_cylinder(ra, 0.71)
        assert got == pytest.approx(ratio, abs=0.01)
    for ra, ratio in ((1.0e4, 1.09), (1.0e8, 0.97), (1.0e10, 0.85)):
        got = c.mcadams_vertical_plate(ra) / c.churchill_chu_vertical_plate(ra, 0.71)
        assert got == pytest.approx(ratio, abs=0.01)
    log = ValidityLog()
    c.mcadams_vertical_plate(1.0e3, log=log)
    c.morgan_horizontal_cylinder(1.0e13, log=log)
    assert len(log) == 2


def test_natural_convection_law_is_chosen_by_name():
    """'morgan_mcadams' gives the power laws with the same air properties; the default is CC."""
    ts, ta, d = 333.15, 293.15, 0.104
    ra, air = c._rayleigh_air(ts, ta, d, None)
    assert c.natural_convection_htc_horizontal_cylinder(ts, ta, d, law='morgan_mcadams') == \
        pytest.approx(c.morgan_horizontal_cylinder(ra) * air.k / d, rel=1e-14)
    assert c.natural_convection_htc_vertical_plate(ts, ta, d, law='morgan_mcadams') == \
        pytest.approx(c.mcadams_vertical_plate(ra) * air.k / d, rel=1e-14)
    assert c.natural_convection_htc_horizontal_cylinder(ts, ta, d) == pytest.approx(
        c.churchill_chu_horizontal_cylinder(ra, air.Pr) * air.k / d, rel=1e-14)


@pytest.mark.filterwarnings('error')
def test_natural_convection_equal_temperatures():
    """T_s == T_inf returns the Ra -> 0 limit, without warnings or NaN."""
    air = c.air_properties(300.0)
    assert c.natural_convection_htc_horizontal_cylinder(300.0, 300.0, 0.1) == pytest.approx(
        0.36 * air.k / 0.1, rel=1e-14)
    assert c.natural_convection_htc_vertical_plate(300.0, 300.0, 0.2) == pytest.approx(
        0.825 ** 2 * air.k / 0.2, rel=1e-14)
    log = ValidityLog()
    c.natural_convection_htc_horizontal_cylinder(300.0, 300.0, 0.1, log=log)
    assert len(log) == 0


def test_natural_convection_of_the_rig_frame_is_usual_and_symmetric():
    """
    The rig frame (D 104 mm, 60 degC in 20 degC air) gets an h in the usual band.

    Free convection in air gives 3-10 W/(m^2 K); a surface 40 K below the air
    gets the h of one 40 K above it (same film temperature and |dT|).
    """
    ts, ta, d = 333.15, 293.15, 0.104
    h = c.natural_convection_htc_horizontal_cylinder(ts, ta, d)
    assert 3.0 < h < 10.0
    assert c.natural_convection_htc_horizontal_cylinder(ta, ts, d) == pytest.approx(h, rel=1e-14)


def test_radiation_htc():
    """h_r at 300 K / 300 K with eps = 1 is 4 sigma T^3; h_r dT = eps sigma (Ts^4 - Ta^4)."""
    assert c.radiation_htc(300.0, 300.0, 1.0) == pytest.approx(
        4.0 * Stefan_Boltzmann * 300.0 ** 3, rel=1e-14)
    ts, ta, eps = 380.0, 293.15, 0.8
    flux = eps * Stefan_Boltzmann * (ts ** 4 - ta ** 4)
    assert c.radiation_htc(ts, ta, eps) * (ts - ta) == pytest.approx(flux, rel=1e-12)


def test_air_properties_against_incropera_table():
    """mu, k, cp, Pr within 1.5 % of Incropera table A.4; rho is the ideal gas."""
    table = {300.0: (184.6e-7, 26.3e-3, 1007.0, 0.707),
             400.0: (230.1e-7, 33.8e-3, 1014.0, 0.690),
             500.0: (270.1e-7, 40.7e-3, 1030.0, 0.684)}
    for t_k, (mu, k, cp, pr) in table.items():
        air = c.air_properties(t_k)
        assert air.mu == pytest.approx(mu, rel=0.015)
        assert air.k == pytest.approx(k, rel=0.015)
        assert air.cp == pytest.approx(cp, rel=0.015)
        assert air.Pr == pytest.approx(pr, rel=0.015)
        assert air.rho == pytest.approx(101325.0 / (287.05 * t_k), rel=1e-14)
        assert air.beta == pytest.approx(1.0 / t_k, rel=1e-14)
    log = ValidityLog()
    c.air_properties(300.0, log=log)
    assert len(log) == 0
    c.air_properties(700.0, log=log)
    assert len(log) == 1


# ---------------------------------------------------------- arrays vs scalars


def test_arrays_and_scalars_agree():
    """Vectorised evaluation equals element-by-element scalar evaluation."""
    omega = np.array([-2000.0, 0.0, 5.0, 300.0, 1047.0, 2094.0])
    flow = np.array([0.0, 1e-6, 1.7e-5, 1e-4, 1e-3, 3e-3])
    cases = [
        (lambda w, q: c.airgap_friction(RHO, MU, w, R1, R2, L)[0], omega, flow),
        (lambda w, q: c.airgap_friction(RHO, MU, w, R1, R2, L)[1], omega, flow),
        (lambda w, q: c.airgap_wall_to_bulk_htc(w, R1, R2, q, RHO, MU, K_OIL, CP).h,
         omega, flow),
        (lambda w, q: c.airgap_wall_to_bulk_htc(w, R1, R2, q, RHO, MU, K_OIL, CP).Nu,
         omega, flow),
        (lambda re, pr: c.pipe_internal_nusselt(re, pr), np.array([0, 1e3, 2300, 3e3, 4e3, 1e5]),
         np.array([0.7, 5.0, 50.0, 170.0, 0.7, 3.0])),
        (lambda ta, _: c.taylor_couette_nusselt(ta), np.array([0, 1e3, 1700, 5e3, 1e4, 1e8]),
         flow),
        (lambda ts, d: c.natural_convection_htc_horizontal_cylinder(ts, 293.15, d),
         np.array([293.15, 300.0, 330.0, 350.0, 400.0, 450.0]),
         np.array([0.01, 0.05, 0.1, 0.104, 0.2, 0.5])),
        (lambda ts, h: c.natural_convection_htc_vertical_plate(ts, 293.15, h),
         np.array([293.15, 300.0, 330.0, 350.0, 400.0, 450.0]),
         np.array([0.01, 0.05, 0.1, 0.104, 0.2, 0.5])),
        (lambda ts, e: c.radiation_htc(ts, 293.15, e),
         np.array([293.15, 300.0, 330.0, 350.0, 400.0, 450.0]),
         np.array([0.1, 0.5, 0.8, 0.9, 1.0, 0.3])),
        (lambda t, _: c.air_properties(t).Pr, np.array([250.0, 300.0, 400.0, 500.0, 600.0, 650.0]),
         flow),
    ]
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        for func, x, y in cases:
            vec = func(x, y)
            assert np.shape(vec) == x.shape
            for i in range(x.size):
                scalar = func(float(x[i]), float(y[i]))
                assert np.ndim(scalar) == 0
                assert scalar == vec[i]


def test_airgap_nusselt_registry():
    """The configuration offers the registry's names; the default law is Becker-Kaye's."""
    import dataclasses
    from wet_eha_thermal.config_model import Frame, Motor
    from wet_eha_thermal.config_spec import choices_of
    meta = {f.name: f.metadata for f in dataclasses.fields(Motor)}['airgap_nusselt']
    assert choices_of(meta) == tuple(c.AIRGAP_NUSSELT)
    meta = {f.name: f.metadata for f in dataclasses.fields(Frame)}['natural_convection']
    assert choices_of(meta) == tuple(c.NATURAL_CONVECTION)
    assert c.AIRGAP_NUSSELT['becker_kaye'].function is c.taylor_couette_nusselt
    default = c.airgap_wall_to_bulk_htc(2000.0, R1, R2, 1e-5, RHO, MU, K_OIL, CP)
    named = c.airgap_wall_to_bulk_htc(2000.0, R1, R2, 1e-5, RHO, MU, K_OIL, CP,
                                      nusselt='becker_kaye')
    assert default == named


def test_tachibana_fukui_by_hand():
    """Nu = 0.21 (Ta^2 Pr)^(1/4) (delta/r1)^(1/4), Ta^2 = omega^2 r1 delta^3 / nu^2."""
    omega, r1, r2, nu, pr = 3000.0, 0.018, 0.0185, 1.0e-5, 150.0
    delta = r2 - r1
    ta2 = omega ** 2 * r1 * delta ** 3 / nu ** 2        # 2.025e5 (the paper's Ta^2)
    expected = 0.21 * (ta2 * pr) ** 0.25 * (delta / r1) ** 0.25
    ta_m = c.modified_taylor_number(omega, r1, r2, nu)
    assert c.tachibana_fukui_nusselt(ta_m, pr, delta / r1) == pytest.approx(expected, rel=1e-12)
    assert expected == pytest.approx(6.365, abs=1e-3)  # 0.21 * 3.04e7^0.25 * 0.4082
