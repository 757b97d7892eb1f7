"""The coupled wet-EHA model: energy, throttling, steady state, flow balance, step size, trends."""

import numpy as np
import pytest
from wet_eha_thermal.model.duty import SinusoidalDuty, Stage, stage_duty, TableDuty
from wet_eha_thermal.model.hydraulics import HydraulicCircuit, LINKS, OIL_NODES, StepFlows
from wet_eha_thermal.model.oil import get_oil, isenthalpic_throttle_temperature_rise
from wet_eha_thermal.offline.simulation import RUNAWAY_C, simulate, ThermalRunaway
from wet_eha_thermal.units import C_TO_K


def flows(by_link):
    """Make step flows from {link index: (mean flow m^3/s, pressure drop Pa)}."""
    n = len(LINKS)
    f, w = np.zeros(n), np.zeros(n)
    for k, (q, dp) in by_link.items():
        f[k], w[k] = q, q * dp
    p = np.full(len(OIL_NODES), 1e6)
    return StepFlows(f, w, p, p, np.zeros(len(OIL_NODES)), (5e-5, 5e-5), (0.0, 0.0),
                     4e-5, 0.0, 0.0, 300.0, 0.0)


def test_leak_is_heated_isenthalpically(cfg):
    # internal leakage port A -> port B across 20 MPa into an otherwise adiabatic
    # port B: at steady state it sits (1 - alpha_p T) dp / (rho c_p) above port A
    oil = get_oil(cfg.fluid.grade)
    ci = HydraulicCircuit(cfg.hydraulics, oil)
    ci.K_static *= 1e-9             # shells and ambient negligible: the stream alone
    ci.G_amb *= 1e-9
    T0, dp, q = 320.0, 20e6, 2e-6
    rho_cp = float(oil.density(T0) * oil.specific_heat(T0))
    leak = 2   # internal leakage A -> B (link 1 joins the same ports: the pump)
    assert LINKS[leak] == ('port_a', 'port_b')
    sf = flows({leak: (q, dp)})
    T = np.full(ci.n, T0)
    for _ in range(200):            # exact steps; port B's time constant is 2.3 s
        T = ci.step(T, 1.0, sf, 293.15, rho_cp)
    rise = T[ci.index('port_b')] - T[ci.index('port_a')]
    expected = isenthalpic_throttle_temperature_rise(dp, T0, oil)
    assert expected == pytest.approx(0.45 * 20, rel=0.1)     # about 0.45 K/MPa
    # the model takes alpha_p T at the circuit's filtered mean oil temperature, which
    # rises 1.1 K here as port B heats: (alpha_p 1.1 K) / (1 - alpha_p T) = 0.12 %
    assert rise == pytest.approx(expected, rel=2e-3)
    assert rise < expected     # and the error has that sign
    assert T[ci.index('port_a')] == pytest.approx(T0, abs=1e-12)   # nothing flows into A


@pytest.mark.slow
def test_steady_static_load_heat_in_equals_heat_out(cfg):
    # holding 2 MPa with the actuator still: the pump turns only for leakage. The
    # slowest time constant is about 2 h (accumulator and shells), so after 10 h the
    # heat still being stored is below 0.1 % of what is generated (measured 0.03 %).
    # Nothing changes within a step at a static hold, so 10 s steps are exact.
    hold = TableDuty([0.0, 1.0], [0.0, 0.0], [2e6, 2e6], cfg.hydraulics.actuator.area_m2)
    kw = {'dt_s': 10.0, 'sample_rate_Hz': 0.5, 'record_every_s': 3600.0}
    m = simulate(cfg, hold, 10 * 3600.0, **kw).model
    before = m.energy()
    after = simulate(cfg, hold, 3600.0, model=m, **kw).model.energy()
    heat_in = (after['sources'] - before['sources']) / 3600
    heat_out = (after['to_ambient'] - before['to_ambient']) / 3600
    assert heat_in > 5.0              # W: leakage and pump friction
    assert heat_out == pytest.approx(heat_in, rel=2e-3)


@pytest.mark.slow
def test_sustained_high_load_is_stopped_as_a_runaway(cfg):
    # holding 16 MPa dissipates ~340 W of leakage at 40 degC, more as the oil thins
    hold = TableDuty([0.0, 1.0], [0.0, 0.0], [16e6, 16e6], cfg.hydraulics.actuator.area_m2)
    with pytest.raises(ThermalRunaway, match='thermal runaway') as err:
        simulate(cfg, hold, 3 * 3600.0, sample_rate_Hz=4.0, record_every_s=60.0)
    res = err.value.result
    assert res.time_s[-1] < 3 * 3600.0
    assert max(v[-1] for v in res.temperatures_K.values()) - C_TO_K > RUNAWAY_C


@pytest.mark.slow
def test_every_oil_volume_balances_its_flows(cfg):
    r = simulate(cfg, stage_duty(cfg, 1), 30.0, dt_s=0.1, record_every_s=30.0)
    m = r.model
    sf = m.flows
    d_in = np.zeros(len(OIL_NODES))
    for k, (u, d) in enumerate(LINKS):
        d_in[OIL_NODES.index(d)] += sf.flow_m3_s[k]
        d_in[OIL_NODES.index(u)] -= sf.flow_m3_s[k]
    d_in[OIL_NODES.index('case')] -= sf.motor_flow_m3_s
    d_in[OIL_NODES.index('accumulator')] += sf.motor_flow_m3_s
    dt = 0.1
    expected = np.zeros(len(OIL_NODES))
    expected[OIL_NODES.index('chamber_a')] = sf.chamber_dV_m3[0] / dt
    expected[OIL_NODES.index('chamber_b')] = sf.chamber_dV_m3[1] / dt
    expected[OIL_NODES.index('case')] = sf.case_dV_m3 / dt
    expected[OIL_NODES.index('accumulator')] = -sf.case_dV_m3 / dt
    scale = np.abs(sf.flow_m3_s).max()
    assert scale > 1e-5
    assert np.allclose(d_in, expected, atol=1e-9 * scale)


def cycle_means(res, window_s=10.0):
    t = np.array(res.time_s)
    sel = t > t[-1] - window_s
    return {k: float(np.mean(np.array(v)[sel])) for k, v in res.temperatures_K.items()
            if k != 'pump_outlet'}


@pytest.mark.slow
def test_default_step_agrees_with_a_fine_step(cfg):
    # stage 6, the no-load rig test: the default 1 s step against 10 ms steps; compare
    # the means over the last cycles (a 1 s step cannot show the swing inside a cycle)
    duty = stage_duty(cfg, 6)
    fine = simulate(cfg, duty, 120.0, dt_s=0.01, sample_rate_Hz=200.0, record_every_s=0.01)
    coarse = simulate(cfg, duty, 120.0, record_every_s=1.0)
    ref, got = cycle_means(fine), cycle_means(coarse)
    assert max(ref[k] - C_TO_K for k in ref) > 25.0        # it did heat up
    for k in ref:
        assert got[k] == pytest.approx(ref[k], abs=0.2), k


def rise_after(cfg, stage: Stage, seconds=600.0):
    duty = SinusoidalDuty(stage, cfg.hydraulics.actuator.area_m2)
    r = simulate(cfg, duty, seconds, record_every_s=seconds)
    return {k: v[-1] - (20.0 + C_TO_K) for k, v in r.temperatures_K.items()}


@pytest.mark.slow
def test_more_load_gives_more_temperature_rise(cfg):
    rises = [rise_after(cfg, Stage(3, dp, 6.0 / 60000, 1.0)) for dp in (4e6, 8e6, 12e6)]
    for key in ('winding_mean', 'pump_case', 'chamber_a', 'accumulator'):
        r = [x[key] for x in rises]
        assert r[0] < r[1] < r[2], (key, r)


@pytest.mark.slow
def test_more_flow_and_frequency_give_more_temperature_rise(cfg):
    # faster duty at the same load: more speed, more friction and core loss
    rises = [rise_after(cfg, Stage(3, 8e6, q / 60000, f))
             for q, f in ((3.0, 0.5), (6.0, 1.0), (9.0, 2.0))]
    for key in ('winding_mean', 'magnet', 'motor_oil_outlet', 'pump_case'):
        r = [x[key] for x in rises]
        assert r[0] < r[1] < r[2], (key, r)


@pytest.mark.slow
def test_extra_loss_is_booked_as_a_source_and_heats_the_case(cfg):
    # a constant extra loss (a shaft seal the friction law lacks) is heat into the case
    # oil alone, and the coupled model's books still close with it
    from wet_eha_thermal.config import with_values
    hot = with_values(cfg, {'hydraulics.pump.extra_loss_W': 20.0})
    still = flows({})
    base = HydraulicCircuit(cfg.hydraulics, get_oil(cfg.fluid.grade))
    circ = HydraulicCircuit(hot.hydraulics, get_oil(hot.fluid.grade))
    T0 = np.full(circ.n, 300.0)
    extra = circ.sources(T0, 1.0, still) - base.sources(T0, 1.0, still)
    assert extra[circ.index('case')] == pytest.approx(20.0, abs=1e-12)
    assert np.delete(extra, circ.index('case')) == pytest.approx(0.0, abs=1e-12)
    a = simulate(cfg, stage_duty(cfg, 6), 300.0, record_every_s=300.0)
    b = simulate(hot, stage_duty(hot, 6), 300.0, record_every_s=300.0)
    eb = b.model.energy()
    assert eb['stored'] + eb['to_ambient'] == pytest.approx(eb['sources'], rel=1e-3)
    assert b.temperatures_K['pump_case'][-1] - a.temperatures_K['pump_case'][-1] > 1.0
