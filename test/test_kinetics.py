"""Kinetic model: stages, duties, port mass and power balances, datasheet checks, duty CSV."""

import warnings

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid
from wet_eha_thermal.model.duty import (DutyError, load_duty_csv, SinusoidalDuty, Stage,
                                        stage_duty, STAGES, TableDuty)
from wet_eha_thermal.model.fluid_power import line_pressure_drop
from wet_eha_thermal.model.kinetics import KineticModel, T40_K, ThermalFeedback
from wet_eha_thermal.model.losses import copper_resistance
from wet_eha_thermal.model.oil import get_oil
from wet_eha_thermal.units import L_MIN, MPA, RPM


@pytest.fixture(scope='module')
def model(cfg):
    return KineticModel(cfg, get_oil(cfg.fluid.grade))


def constant(area, q_L_min, dp_MPa):
    """Return a duty holding one flow and load (a static operating point)."""
    return TableDuty([0.0, 1.0], [q_L_min * L_MIN] * 2, [dp_MPa * MPA] * 2, area,
                     name=f'constant {q_L_min} L/min {dp_MPa} MPa')


def gap_loss(speed):
    """Shaft friction that grows with speed (W), never zero, like a real rotor."""
    return 0.5 + 2e-7 * np.asarray(speed) ** 3


def em_loss(speed, current):
    """Return iron loss like Steinmetz's (W), linear and quadratic in speed, plus an I^2 loss."""
    s = np.asarray(speed)
    return 0.02 * s + 1e-5 * s ** 2 + 0.01 * np.asarray(current) ** 2


LOSSY = ThermalFeedback(drag_W=gap_loss, electromagnetic_loss_W=em_loss)

# the four quadrants (flow L/min, load MPa): motoring when flow and load have one sign
QUADRANTS = {'motoring +': (6.0, 12.0), 'regenerating +': (-6.0, 12.0),
             'motoring -': (-6.0, -12.0), 'regenerating -': (6.0, -12.0)}


# ---------------------------------------------------------------- stages, duties
@pytest.mark.slow
def test_six_stages_of_the_datasheet():
    table = {1: (16, 2, 0.2), 2: (12, 4, 0.5), 3: (8, 6, 1.0), 4: (6, 8, 2.0),
             5: (4, 10, 3.0), 6: (0, 12, 1.0)}
    assert sorted(STAGES) == sorted(table)
    for n, (dp, q, f) in table.items():
        s = STAGES[n]
        assert s.number == n and s.frequency_Hz == f
        assert s.load_dp_amplitude_Pa == pytest.approx(dp * 1e6, rel=1e-15)
        assert s.flow_amplitude_m3_s == pytest.approx(q / 60000.0, rel=1e-15)
        assert isinstance(s, Stage)


def test_sinusoidal_demand_is_the_stage_formula(cfg):
    area = cfg.hydraulics.actuator.area_m2
    d = SinusoidalDuty(STAGES[2], area)
    assert d.period_s == pytest.approx(2.0, rel=1e-15)
    t = np.array([0.0, 0.5, 1.0, 0.25, 1.7])
    q, dp, x = d.demand(t)
    w = 2 * np.pi * 0.5
    np.testing.assert_allclose(q, 4 / 60000 * np.cos(w * t), rtol=1e-14, atol=1e-20)
    np.testing.assert_allclose(dp, 12e6 * np.sin(w * t), rtol=1e-14, atol=1e-6)
    np.testing.assert_allclose(x, 4 / 60000 / (area * w) * np.sin(w * t), rtol=1e-14,
                               atol=1e-18)


@pytest.mark.parametrize('n', sorted(STAGES))
def test_stage_position_is_the_integral_of_flow(cfg, n):
    d = stage_duty(cfg, n)
    t = np.linspace(0.0, 2 * d.period_s, 200001)
    q, _, x = d.demand(t)
    x_num = x[0] + cumulative_trapezoid(q / d.area_m2, t, initial=0.0)
    # trapezoid error over the run: (2T) h^2 / 12 max|x'''| = T h^2 w^2 x_a / 6, x_a < 0.04 m
    h = t[1] - t[0]
    tol = d.period_s * h ** 2 * (2 * np.pi / d.period_s) ** 3 * 0.04 / 6 + 1e-12
    assert np.max(np.abs(x_num - x)) < tol
    assert abs(np.mean(x[:-1])) < 1e-9  # centred: mean over whole periods is zero


@pytest.mark.parametrize('n', sorted(STAGES))
def test_each_stage_stays_inside_the_stroke(cfg, n):
    d = stage_duty(cfg, n)
    half = cfg.hydraulics.actuator.half_stroke_m
    s = STAGES[n]
    assert d.peak_position_m == pytest.approx(
        s.flow_amplitude_m3_s / (d.area_m2 * 2 * np.pi * s.frequency_Hz), rel=1e-14)
    _, _, x = d.demand(np.linspace(0, d.period_s, 10001))
    assert np.max(np.abs(x)) <= d.peak_position_m * (1 + 1e-12)
    assert d.peak_position_m < half


def test_stage_beyond_the_stroke_raises_naming_the_duty(cfg):
    area = cfg.hydraulics.actuator.area_m2
    slow = Stage(7, 1e6, 12 * L_MIN, 0.1)  # 0.34 m of travel
    with pytest.raises(DutyError, match=r'stage 7.*\+-33[0-9.]+ mm.*40\.00 mm'):
        SinusoidalDuty(slow, area, 0.040)


def random_table(area, seed=1):
    rng = np.random.default_rng(seed)
    t = np.concatenate(([0.0], np.cumsum(rng.uniform(0.05, 0.4, 30))))
    q = rng.uniform(-8, 8, t.size) * L_MIN
    dp = rng.uniform(-15, 15, t.size) * MPA
    return TableDuty(t, q, dp, area, name='random')


def test_table_position_is_the_exact_integral_of_the_flow(cfg):
    d = random_table(cfg.hydraulics.actuator.area_m2)
    t = np.linspace(0.0, d.period_s, 400001)[:-1]  # one period; at T the table wraps
    q, _, x = d.demand(t)
    x_num = x[0] + cumulative_trapezoid(q / d.area_m2, t, initial=0.0)
    # the flow is linear between nodes: the trapezoid is exact except in the grid cells
    # holding a node, error <= h^2 max|dQ/dt| / A per node
    h = t[1] - t[0]
    tol = 31 * h ** 2 * np.max(np.abs(d._q_slope)) / d.area_m2 + 1e-13
    assert np.max(np.abs(x_num - x)) < tol
    # centred: the mean over the period is zero (midpoint rule, error h^2 max|x''| / 24)
    n_mid = 100000
    x_mid = d.demand((np.arange(n_mid) + 0.5) * d.period_s / n_mid)[2]
    bound = (d.period_s / n_mid) ** 2 * np.max(np.abs(d._q_slope)) / d.area_m2 / 24
    assert abs(np.mean(x_mid)) < bound + 1e-15
    # peak: the exact extremum is at least the sampled one and not above it by more than
    # the grid's quadratic error
    assert np.max(np.abs(x)) <= d.peak_position_m + 1e-15
    assert d.peak_position_m - np.max(np.abs(x)) < h * np.max(np.abs(q)) / d.area_m2


def test_table_repeats_and_keeps_the_drift_of_a_net_flow(cfg):
    area = cfg.hydraulics.actuator.area_m2
    q_nodes, dp_nodes = [1 * L_MIN, 3 * L_MIN, 1 * L_MIN], [0.0, 5e6, 0.0]
    d = TableDuty([0.0, 1.0, 2.0], q_nodes, dp_nodes, area)
    net = 4 * L_MIN / area  # 70.7 mm per repeat
    assert d.net_displacement_m == pytest.approx(net, rel=1e-14)
    t = np.array([0.3, 1.6])
    q0, dp0, x0 = d.demand(t)
    q1, dp1, x1 = d.demand(t + 2 * d.period_s)
    np.testing.assert_allclose(q1, q0, rtol=1e-12)
    np.testing.assert_allclose(dp1, dp0, rtol=1e-12)
    np.testing.assert_allclose(x1 - x0, 2 * net, rtol=1e-9)
    # with the stroke known, the first period fits but the drift leaves the stroke
    d = TableDuty([0.0, 1.0, 2.0], q_nodes, dp_nodes, area, half_stroke_m=0.040, name='drift')
    d.demand(np.linspace(0.0, d.period_s, 11)[:-1])
    with pytest.raises(DutyError, match=r'drift: .*does not integrate to zero.*t = 2\.3 s'):
        d.demand(np.array([0.5, 2.3]))


# -------------------------------------------------------------- balances
@pytest.mark.parametrize('quadrant', sorted(QUADRANTS))
def test_port_mass_balance_closes_in_every_quadrant(cfg, model, quadrant):
    q_L, dp_M = QUADRANTS[quadrant]
    s = model.sample(constant(cfg.hydraulics.actuator.area_m2, q_L, dp_M),
                     np.array([0.2, 0.5]), LOSSY)
    d_w = model.d_rad * s.speed_rad_s
    q, q_int, q_ext = s.flow_m3_s, s.q_internal_m3_s, s.q_external_m3_s
    assert np.all(q_ext > 0)
    # the high port (by port pressure) leaks to the case; the low port takes the make-up
    a_high = s.port_a_Pa > s.port_b_Pa
    assert np.all(a_high == (dp_M > 0))
    e_a, e_b = np.where(a_high, q_ext, 0), np.where(a_high, 0, q_ext)
    m_a, m_b = np.where(a_high, 0, q_ext), np.where(a_high, q_ext, 0)
    scale = np.max(np.abs(q)) * 1e-12
    np.testing.assert_allclose(d_w + m_a, q + q_int + e_a, rtol=0, atol=scale)   # port A
    np.testing.assert_allclose(q + q_int + m_b, d_w + e_b, rtol=0, atol=scale)   # port B
    np.testing.assert_allclose(m_a + m_b, e_a + e_b, rtol=0, atol=1e-22)  # accumulator
    # speed follows the flow; regenerating quadrants return power to the supply
    assert np.all(np.sign(s.speed_rad_s) == np.sign(q_L))
    assert np.all(np.sign(s.load_power_W) == np.sign(q_L * dp_M))
    if quadrant.startswith('regenerating'):
        assert np.all((s.load_power_W < s.electrical_power_W) & (s.electrical_power_W < 0))
    else:
        assert np.all(s.electrical_power_W > s.load_power_W)


def power_residuals(model, s):
    """Return the two power-balance residuals (W) and the power scale they are measured on."""
    dpp = s.port_a_Pa - s.port_b_Pa
    w = s.speed_rad_s
    shaft = s.torque_Nm * w - (model.d_rad * w * dpp + s.pump_friction_W + s.drag_W)
    p_high = np.maximum(s.port_a_Pa, s.port_b_Pa)
    p_low = np.minimum(s.port_a_Pa, s.port_b_Pa)
    dpl = s.port_a_Pa - s.p_a_Pa
    assert np.allclose(s.p_b_Pa - s.port_b_Pa, dpl, rtol=0, atol=1e-6)  # same drop both lines
    losses = (s.copper_W + s.electromagnetic_W + s.pump_friction_W + s.drag_W
              + s.q_internal_m3_s * dpp
              + s.q_external_m3_s * (p_high - s.p_acc_Pa)   # leak into the case
              + s.q_external_m3_s * (s.p_acc_Pa - p_low)    # make-up into the low port
              + 2 * s.flow_m3_s * dpl)                      # both lines
    total = s.electrical_power_W - s.load_power_W - losses
    scale = np.max(np.abs(s.electrical_power_W)) + np.max(np.abs(s.load_power_W))
    return shaft, total, scale


@pytest.mark.parametrize('n', sorted(STAGES))
def test_power_balance_of_every_stage(cfg, model, n):
    d = stage_duty(cfg, n)
    s = model.sample(d, np.linspace(0, d.period_s, 997), LOSSY)
    shaft, total, scale = power_residuals(model, s)
    # round-off: pressures of 1e7 Pa times flows, summed over ~10 terms
    assert np.max(np.abs(shaft)) < 1e-11 * scale
    assert np.max(np.abs(total)) < 1e-11 * scale
    assert np.all(s.pump_friction_W >= 0) and np.all(s.drag_W >= 0)
    assert np.all(s.copper_W >= 0) and np.all(s.electromagnetic_W >= 0)
    # the losses are real: the balance would fail without any one of the big ones
    for part in (s.copper_W, s.pump_friction_W, s.drag_W):
        assert np.max(part) > 1e3 * np.max(np.abs(total))
    # the make-up term (accumulator to the low port, across one line drop) is small but
    # not round-off: tens of mW against hundreds of W
    p_low = np.minimum(s.port_a_Pa, s.port_b_Pa)
    makeup = s.q_external_m3_s * (s.p_acc_Pa - p_low)
    dpl = np.abs(s.port_a_Pa - s.p_a_Pa)
    assert np.all(np.abs(makeup) <= s.q_external_m3_s * dpl * (1 + 1e-9))
    assert np.max(np.abs(makeup)) < 2e-4 * scale


@pytest.mark.parametrize('quadrant', sorted(QUADRANTS))
def test_power_balance_in_every_quadrant(cfg, model, quadrant):
    q_L, dp_M = QUADRANTS[quadrant]
    s = model.sample(constant(cfg.hydraulics.actuator.area_m2, q_L, dp_M),
                     np.array([0.0, 0.5]), LOSSY)
    shaft, total, scale = power_residuals(model, s)
    assert np.max(np.abs(shaft)) < 1e-11 * scale
    assert np.max(np.abs(total)) < 1e-11 * scale


def test_current_copper_and_electromagnetic_losses(cfg, model):
    d = stage_duty(cfg, 3)
    t = np.linspace(0.0, 1.0, 41)
    hot = ThermalFeedback(winding_K=T40_K + 100.0, electromagnetic_loss_W=em_loss)
    s = model.sample(d, t, hot)
    k_t = cfg.motor.torque_constant_Nm_A
    np.testing.assert_allclose(s.current_A, np.abs(s.torque_Nm) / k_t, rtol=1e-14)
    w = cfg.motor.winding
    r = copper_resistance(w.phase_resistance_20C_ohm, w.copper_tempco_1_K, T40_K + 100.0)
    np.testing.assert_allclose(s.copper_W, 3 * s.current_A ** 2 * r, rtol=1e-13)
    np.testing.assert_allclose(s.electromagnetic_W, em_loss(np.abs(s.speed_rad_s), s.current_A),
                               rtol=1e-14)
    # the winding temperature changes copper loss only, not the kinetics
    cold = model.sample(d, t, ThermalFeedback(electromagnetic_loss_W=em_loss))
    np.testing.assert_array_equal(cold.torque_Nm, s.torque_Nm)
    assert np.all(s.copper_W[s.current_A > 1] > 1.3 * cold.copper_W[s.current_A > 1])


def test_standstill_gives_no_friction_torque_and_no_warning(cfg, model):
    d = constant(cfg.hydraulics.actuator.area_m2, 0.0, 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        with np.errstate(all='raise'):
            s = model.sample(d, np.array([0.0, 0.5]), LOSSY)
    assert np.all(s.speed_rad_s == 0) and np.all(s.torque_Nm == 0)
    assert np.all(s.drag_W == 0) and np.all(s.pump_friction_W == 0)
    assert np.all(s.electrical_power_W == s.electromagnetic_W + s.copper_W)


def test_sample_is_vectorised_and_keeps_the_times(cfg, model):
    d = stage_duty(cfg, 4)
    t = np.linspace(0.1, 0.2, 20)
    s = model.sample(d, t, LOSSY)
    one = [model.sample(d, t[i:i + 1], LOSSY) for i in range(t.size)]
    np.testing.assert_array_equal(s.t_s, t)
    for name in ('current_A', 'speed_rad_s', 'p_a_Pa', 'p_b_Pa', 'position_m',
                 'electrical_power_W', 'q_external_m3_s'):
        np.testing.assert_allclose(getattr(s, name),
                                   np.concatenate([getattr(o, name) for o in one]),
                                   rtol=1e-14, atol=1e-20)
    assert np.all(s.p_acc_Pa == cfg.hydraulics.accumulator.pressure_Pa)


# ------------------------------------------------------------- datasheet values
def test_external_leakage_at_21_MPa_and_40_C_is_about_1_L_min(cfg, model):
    oil = get_oil(cfg.fluid.grade)
    s = model.sample(constant(cfg.hydraulics.actuator.area_m2, 0.0, 21.0), np.array([0.5]),
                     ThermalFeedback())
    p_acc = cfg.hydraulics.accumulator.pressure_Pa
    c_ext = cfg.hydraulics.pump.external_leak_coeff_m3
    assert s.port_a_Pa[0] == pytest.approx(p_acc + 21e6, rel=1e-15)
    # the model: Q = C dp / mu, mu at 40 degC and the gap's mean pressure
    mu = oil.dynamic_viscosity(T40_K, p_acc + 10.5e6)
    assert s.q_external_m3_s[0] == pytest.approx(c_ext * 21e6 / mu, rel=1e-12)
    # the datasheet's 1 L/min holds at the atmospheric viscosity (how C was fitted) ...
    q_datasheet = c_ext * 21e6 / oil.dynamic_viscosity(T40_K, 0.0)
    assert q_datasheet / L_MIN == pytest.approx(1.0, abs=0.03)
    # ... and the Barus factor exp(1.5e-8 * 11.5e6) = 1.19 takes about 16 % off it
    assert 0.78 < s.q_external_m3_s[0] / L_MIN < 0.88
    # at standstill the pump holds the load against leakage: speed makes up Q_int + Q_ext
    assert s.speed_rad_s[0] * model.d_rad == pytest.approx(
        s.q_internal_m3_s[0] + s.q_external_m3_s[0], rel=1e-12)


def test_stage_6_peak_speed_is_about_8000_rpm(cfg, model):
    d = stage_duty(cfg, 6)
    s = model.sample(d, np.linspace(0, 1, 4001), ThermalFeedback())
    peak = np.max(np.abs(s.speed_rad_s)) / RPM
    # 12 L/min over 1.5 mL/rev is 8000 r/min; leakage at the line drops adds a little
    assert 8000.0 < peak < 8000.0 * 1.005
    # no load: the ports differ by the two line drops only
    dpl = line_pressure_drop(12 * L_MIN, 0.30, 0.006, model.line_properties(T40_K)[0],
                             model.line_properties(T40_K)[1])
    assert np.max(s.port_a_Pa - s.port_b_Pa) == pytest.approx(2 * dpl, rel=1e-6)


def test_feedback_defaults_are_40_C():
    fb = ThermalFeedback()
    assert fb.pump_oil_K == fb.line_oil_K == fb.winding_K == pytest.approx(313.15)
    assert np.all(fb.drag_W(np.array([0.0, 1e3])) == 0)
    assert np.all(fb.electromagnetic_loss_W(np.array([0.0, 1e3]), np.array([5.0, 5.0])) == 0)
    hot = ThermalFeedback.uniform(373.15)
    assert hot.pump_oil_K == hot.line_oil_K == hot.winding_K == 373.15


def test_hot_oil_leaks_more(cfg, model):
    d = constant(cfg.hydraulics.actuator.area_m2, 2.0, 16.0)
    cold = model.sample(d, np.array([0.5]), ThermalFeedback())
    hot = model.sample(d, np.array([0.5]), ThermalFeedback(pump_oil_K=T40_K + 60.0))
    oil = get_oil(cfg.fluid.grade)
    p_gap = 0.5 * (cold.port_a_Pa[0] + cold.p_acc_Pa[0])  # same pressures: same flow demand
    assert hot.port_a_Pa[0] == cold.port_a_Pa[0]
    ratio = oil.dynamic_viscosity(T40_K, p_gap) / oil.dynamic_viscosity(T40_K + 60.0, p_gap)
    assert ratio > 2.5  # 13.5 cSt at 40 degC, 5.1 cSt at 100 degC
    # laminar: the blend into the orifice law takes off 1e-8 at 100 degC (Re_gap 60)
    assert hot.q_external_m3_s[0] / cold.q_external_m3_s[0] == pytest.approx(ratio, rel=1e-7)
    assert hot.speed_rad_s[0] > cold.speed_rad_s[0]


# ------------------------------------------------------------------- duty CSV
GOOD = ('# recorded duty, flows in L/min\n'
        'flow_L_min, time_s, note, load_MPa\n'
        '2.0, 0.0, start, 0\n'
        '\n'
        '# a comment inside\n'
        '-4.0, 0.5, x, 10\n'
        '1.0, 2.0, , -5.5\n')


def test_valid_csv_round_trips_through_demand(cfg, tmp_path):
    path = tmp_path / 'duty.csv'
    path.write_text(GOOD)
    area = cfg.hydraulics.actuator.area_m2
    d = load_duty_csv(path, area, cfg.hydraulics.actuator.half_stroke_m)
    assert d.period_s == 2.0 and d.name == str(path)
    t_nodes = np.array([0.0, 0.5])
    q, dp, _ = d.demand(t_nodes)
    np.testing.assert_allclose(q, np.array([2.0, -4.0]) * L_MIN, rtol=1e-15)
    np.testing.assert_allclose(dp, np.array([0.0, 10e6]), rtol=1e-15)
    # linear in between
    q, dp, _ = d.demand(np.array([0.125, 1.25, 1.75]))
    np.testing.assert_allclose(q, np.array([0.5, -1.5, -4 + 5 * 1.25 / 1.5]) * L_MIN,
                               rtol=1e-13)
    np.testing.assert_allclose(dp, np.array([2.5e6, 2.25e6, 10e6 - 15.5e6 * 1.25 / 1.5]),
                               rtol=1e-13)
    # the end node is reached from the left, then the table repeats
    q, dp, _ = d.demand(np.array([2.0 - 1e-12, 2.0, 2.5]))
    np.testing.assert_allclose(q, np.array([1.0, 2.0, -4.0]) * L_MIN, rtol=1e-9)
    np.testing.assert_allclose(dp, np.array([-5.5e6, 0.0, 10e6]), rtol=1e-9, atol=1e-3)


BAD_CSVS = {
    'missing column': ('time_s,flow_L_min,load\n0,1,2\n1,1,2\n', 1, 'load_MPa'),
    'not a number': ('time_s,flow_L_min,load_MPa\n0,1,2\n# c\n1,abc,2\n', 4, 'flow_L_min'),
    'nan': ('time_s,flow_L_min,load_MPa\n0,1,2\n1,1,nan\n', 3, 'load_MPa'),
    'inf': ('time_s,flow_L_min,load_MPa\n0,1,2\n1,-inf,2\n', 3, 'flow_L_min'),
    'empty value': ('time_s,flow_L_min,load_MPa\n0,1,2\n1,,2\n', 3, 'flow_L_min'),
    'short row': ('time_s,flow_L_min,load_MPa\n0,1,2\n1,1\n', 3, 'load_MPa'),
    'time not increasing': ('time_s,flow_L_min,load_MPa\n0,1,2\n1,1,2\n1,1,2\n', 4,
                            'time_s'),
    'time going back': ('time_s,flow_L_min,load_MPa\n0,1,2\n2,1,2\n1.5,1,2\n', 4, 'time_s'),
    'first time not 0': ('# start late\ntime_s,flow_L_min,load_MPa\n0.5,1,2\n1,1,2\n', 3,
                         'time_s'),
    'one row': ('time_s,flow_L_min,load_MPa\n0,1,2\n', 2, 'at least 2'),
    'no rows': ('time_s,flow_L_min,load_MPa\n', 1, 'at least 2'),
    'empty file': ('# nothing\n', 1, 'no header'),
    'beyond the stroke': ('time_s,flow_L_min,load_MPa\n0,12,0\n30,12,0\n60,-12,0\n', None,
                          'half stroke'),
}


@pytest.mark.parametrize('case', sorted(BAD_CSVS))
def test_malformed_csv_gives_one_error_naming_file_and_line(cfg, tmp_path, case):
    text, line, words = BAD_CSVS[case]
    path = tmp_path / 'bad_duty.csv'
    path.write_text(text)
    with pytest.raises(DutyError) as info:
        load_duty_csv(path, cfg.hydraulics.actuator.area_m2,
                      cfg.hydraulics.actuator.half_stroke_m)
    msg = str(info.value)
    assert str(path) in msg
    if line is not None:
        assert f'line {line}' in msg and f'line {line + 1}' not in msg
    assert words in msg


def test_missing_csv_file_names_the_file(cfg, tmp_path):
    path = tmp_path / 'nowhere.csv'
    with pytest.raises(DutyError, match='not found') as info:
        load_duty_csv(path, cfg.hydraulics.actuator.area_m2, 0.04)
    assert str(path) in str(info.value)


def test_missing_column_lists_the_columns_found(cfg, tmp_path):
    path = tmp_path / 'cols.csv'
    path.write_text('time_s, flow, load_MPa, extra\n0,1,2,3\n1,1,2,3\n')
    with pytest.raises(DutyError) as info:
        load_duty_csv(path, cfg.hydraulics.actuator.area_m2, 0.04)
    for name in ('time_s', 'flow', 'load_MPa', 'extra', 'flow_L_min'):
        assert repr(name) in str(info.value)


# ------------------------------------------------------------- a limited drive
#: shaft friction that vanishes at standstill, as the motor's does (the load scale can take
#: the speed through zero, where a friction power of LOSSY's would be an infinite torque)
STILL = ThermalFeedback(drag_W=lambda speed: 2e-7 * np.asarray(speed) ** 3,
                        electromagnetic_loss_W=em_loss)


def test_a_limited_drive_clamps_only_where_and_as_much_as_needed(cfg, model):
    # stage 1 (16 MPa): 33 A at its peak; a 20 A limit binds over about half of the period
    d = stage_duty(cfg, 1)
    t = np.linspace(0.0, d.period_s, 2001)
    free = model.sample(d, t, STILL)
    s, demanded = model.sample_limited(d, t, STILL, 20.0)
    np.testing.assert_array_equal(demanded, free.current_A)
    over = demanded > 20.0
    assert 0.3 < over.mean() < 0.7
    # within the limit the samples are the duty's, every one of their fields
    for name in ('current_A', 'p_a_Pa', 'p_b_Pa', 'speed_rad_s', 'copper_W', 'torque_Nm'):
        np.testing.assert_array_equal(getattr(s, name)[~over], getattr(free, name)[~over])
    # over it the current is the limit, up to the friction's jump where the speed crosses 0
    assert np.max(s.current_A) <= 20.0
    cut_more = 20.0 - s.current_A[over]
    assert np.mean(cut_more < 1e-3) > 0.95 and np.max(cut_more) < 2.0
    # the load gave way, the flow and the piston followed the duty
    held = np.abs(s.p_a_Pa - s.p_b_Pa)[over]
    assert np.all(held < np.abs(free.p_a_Pa - free.p_b_Pa)[over])
    np.testing.assert_array_equal(s.flow_m3_s, free.flow_m3_s)
    np.testing.assert_array_equal(s.position_m, free.position_m)
    # one physics: the clamped samples balance their power as the duty's do
    shaft, total, scale = power_residuals(model, s)
    assert np.max(np.abs(shaft)) < 1e-11 * scale and np.max(np.abs(total)) < 1e-11 * scale


def test_a_limit_below_the_unloaded_current_unloads_the_pump(cfg, model):
    d = stage_duty(cfg, 1)
    t = np.linspace(0.0, d.period_s, 101)
    s, demanded = model.sample_limited(d, t, STILL, 0.01)
    unloaded = model.sample(d, t, STILL, load_scale=0.0)
    # friction alone takes more than 10 mA: the load goes (or, regenerating, the little
    # that cancels the friction stays), the current never rises above the unloaded one
    assert np.all(s.current_A <= np.maximum(unloaded.current_A, 0.01) * (1 + 1e-12))
    at_zero = s.current_A > 0.01
    assert at_zero.mean() > 0.5
    np.testing.assert_array_equal(s.p_a_Pa[at_zero], s.p_b_Pa[at_zero])
