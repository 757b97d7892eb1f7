"""Tests of the pump's gap leakage: laminar gap law, orifice law, their blend, Re_gap."""

import dataclasses

import numpy as np
import pytest

from wet_eha_thermal.model.duty import stage_duty
from wet_eha_thermal.model.fluid_power import check_gap_leakage, GAP_LAMINAR_RE, gap_leakage
from wet_eha_thermal.model.kinetics import KineticModel, ThermalFeedback
from wet_eha_thermal.model.oil import get_oil
from wet_eha_thermal.model.validity import ValidityLog
from wet_eha_thermal.units import C_TO_K

C, H, L, CD = 9e-15, 1e-5, 2e-3, 0.61      # the reference pump's external path
RHO = 860.0


def orifice(dp, rho=RHO, coeff=C, h=H, length=L, cd=CD):
    """Return C_d A sqrt(2 dp / rho), A = b h with b = 12 C l / h^3 (the gap's section)."""
    width = 12.0 * coeff * length / h ** 3
    return cd * width * h * np.sqrt(2.0 * dp / rho)


def test_low_reynolds_is_the_laminar_law():
    """Re_gap of the reference rig at 40 degC (about 10): Q = C dp / mu to 1e-9."""
    dp = np.array([1e5, 1e6, 21e6, 35e6])
    mu = 0.0114
    q, re = gap_leakage(C, dp, mu, RHO, H, L, CD)
    assert q == pytest.approx(C * dp / mu, rel=1e-9)
    assert re.max() < 30.0
    q_neg, _ = gap_leakage(C, -dp, mu, RHO, H, L, CD)
    assert q_neg == pytest.approx(-q, rel=1e-15)


def test_high_reynolds_is_the_orifice_law():
    """With a thousandth of the viscosity (Re_L 1e7 and more) Q is C_d A sqrt(2 dp / rho)."""
    dp = np.array([1e6, 21e6])
    q, re = gap_leakage(C, dp, 1.14e-5, RHO, H, L, CD)
    assert q == pytest.approx(orifice(dp), rel=1e-6)
    assert re.min() > 10.0 * 48.0 * CD ** 2 * L / H


def test_reynolds_number_is_that_of_the_mean_velocity_on_twice_the_height():
    """Re_gap = rho u 2 h / mu, u = Q / (b h), from the returned flow (any regime)."""
    width = 12.0 * C * L / H ** 3
    for mu in (1e-2, 1e-3, 1e-4, 1e-5):
        dp = np.logspace(4, 7.6, 9)
        q, re = gap_leakage(C, dp, mu, RHO, H, L, CD)
        assert re == pytest.approx(RHO * q / (width * H) * 2.0 * H / mu, rel=1e-12)


def test_blend_is_continuous_monotonic_and_below_both_laws():
    """
    Across the crossing Re_x = 48 C_d^2 l / h the flow has no jump and never exceeds either law.

    On a fine grid of 4000 pressure differences over twelve decades of dp
    the flow increases strictly, each step in log Q is at most the step in
    log dp (the laminar law's slope, 1; the orifice law's is 1/2), and Q
    lies between 2^(-1/8) and 1 times the lesser of the two laws (the
    Churchill-Usagi form with n = 8 at the crossing).
    """
    mu = 2e-4
    dp = np.logspace(-2, 10, 4000)
    q, re = gap_leakage(C, dp, mu, RHO, H, L, CD)
    lesser = np.minimum(C * dp / mu, orifice(dp))
    assert np.all(np.diff(q) > 0.0)
    assert np.all(np.diff(np.log(q)) <= np.diff(np.log(dp)) * (1 + 1e-9))
    assert np.all(q <= lesser * (1 + 1e-12))
    assert np.all(q >= lesser * 2.0 ** (-1.0 / 8.0) * (1 - 1e-12))
    re_x = 48.0 * CD ** 2 * L / H
    assert re.min() < 1e-2 * re_x and re.max() > 50.0 * re_x


def test_gap_reynolds_flagged_beyond_the_laminar_range():
    """check_gap_leakage flags Re_gap above 2000 with the extreme seen; below it, nothing."""
    log = ValidityLog()
    check_gap_leakage(log, np.array([10.0, 1999.0]))
    assert len(log) == 0
    check_gap_leakage(log, np.array([10.0, 2500.0, 4000.0]))
    (flag,) = list(log)
    assert flag.quantity == 'Re_gap' and flag.high == GAP_LAMINAR_RE
    assert flag.count == 2 and flag.max_seen == 4000.0


def test_reference_rig_stays_laminar_over_its_temperature_range(cfg):
    """
    The reference pump's gaps stay laminar from -40 to 135 degC at 21 MPa.

    The largest gap Reynolds number is the external path's at 135 degC
    (thinnest oil): rho h^3 dp / (6 l mu^2) from the oil laws, far below
    2000, so the blend leaves the laminar coefficient at most 1e-6 below
    C dp / mu (the reference results do not move).
    """
    oil = get_oil(cfg.fluid.grade)
    pump = cfg.hydraulics.pump
    h, length, cd = pump.leak_gap_height_m, pump.leak_gap_length_m, pump.leak_discharge_coeff
    T = np.linspace(C_TO_K - 40.0, C_TO_K + 135.0, 36)
    p_mean = 0.5 * (21.6e6 + 0.6e6)
    rho = oil.density(T, p_mean)
    mu = oil.kinematic_viscosity(T, p_mean) * rho
    q, re = gap_leakage(pump.external_leak_coeff_m3, 21e6, mu, rho, h, length, cd)
    assert re.max() == pytest.approx(rho[-1] * h ** 3 * 21e6 / (6.0 * length * mu[-1] ** 2),
                                     rel=1e-6)
    assert re.max() < 0.25 * GAP_LAMINAR_RE
    assert q == pytest.approx(pump.external_leak_coeff_m3 * 21e6 / mu, rel=1e-6)


def test_kinetics_flags_a_turbulent_gap_and_loses_the_flow_the_orifice_law_allows(cfg):
    """
    A pump with a wide-open gap (40 um) leaks turbulently: flagged, and less than laminar.

    The kinetic model at stage 1 (16 MPa) with a 40 um equivalent gap of the
    same laminar coefficient reaches Re_gap beyond 2000 at 120 degC: the
    ValidityLog says so, and the leakage to the case is below C dp / mu.
    """
    pump = dataclasses.replace(cfg.hydraulics.pump, leak_gap_height_m=4e-5)
    wide = dataclasses.replace(cfg, hydraulics=dataclasses.replace(cfg.hydraulics, pump=pump))
    oil = get_oil(cfg.fluid.grade)
    fb = ThermalFeedback.uniform(C_TO_K + 120.0)
    t = np.linspace(0.0, 5.0, 501)
    log = ValidityLog()
    s = KineticModel(wide, oil, log).sample(stage_duty(wide, 1), t, fb)
    s_ref = KineticModel(cfg, oil).sample(stage_duty(cfg, 1), t, fb)
    flags = [f for f in log if f.quantity == 'Re_gap']
    assert flags and flags[0].max_seen > GAP_LAMINAR_RE
    peak = np.argmax(s_ref.q_external_m3_s)
    assert s.q_external_m3_s[peak] < 0.9 * s_ref.q_external_m3_s[peak]
