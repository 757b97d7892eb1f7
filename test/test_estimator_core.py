"""The estimator core without ROS: averaging, sensor health, fallbacks, alerts, forecast."""

import dataclasses
import math

import numpy as np
import pytest
from wet_eha_thermal.config import load_config, with_values
from wet_eha_thermal.estimator.core import Estimator, INPUTS
from wet_eha_thermal.model.duty import stage_duty
from wet_eha_thermal.model.eha import EHAModel
from wet_eha_thermal.model.kinetics import KineticModel, ThermalFeedback
from wet_eha_thermal.offline.simulation import feedback, simulate
from wet_eha_thermal.units import C_TO_K

STEADY = {'speed_rad_s': 800.0, 'p_a_Pa': 3e6, 'p_b_Pa': 1e6, 'p_acc_Pa': 1e6,
          'position_m': 0.0}


def feed(est, t0, seconds, rate_Hz=1000.0, current=lambda t: 15.0, skip=(), advance=True,
         values=None):
    """Feed every input at ``rate_Hz`` from ``t0`` (except those in ``skip``); return the end."""
    values = dict(STEADY, **(values or {}))
    n = int(round(seconds * rate_Hz))
    out = []
    for k in range(1, n + 1):
        t = t0 + k / rate_Hz
        for ch in INPUTS:
            if ch in skip:
                continue
            est.push(ch, t, current(t) if ch == 'current_A' else values[ch])
        if advance and k % 20 == 0:
            out += est.advance()
    return t0 + n / rate_Hz, out


@pytest.mark.slow
def test_current_is_averaged_as_mean_square(cfg):
    # a 100 Hz ripple on the RMS current, sampled at 1 kHz with stamps on the step
    # boundaries: the copper loss needs the mean of I^2 (15^2 + 10^2 / 2 = 275 A^2),
    # not the square of the mean (225 A^2)
    def winding(current):
        est = Estimator(cfg)
        feed(est, 0.0, 30.0, current=current)
        return est.latest.temperatures_C['winding_mean']

    got = winding(lambda t: 15.0 + 10.0 * math.sin(2 * math.pi * 100.0 * t))
    right = winding(lambda t: math.sqrt(275.0))
    wrong = winding(lambda t: 15.0)
    assert right - wrong > 0.2                     # the distinction matters
    # 20 samples per 20 ms step cover two whole periods: the sampled mean is exact for the
    # copper; the PWM ripple's losses, which do not grow as I^2 (the modulation index moves
    # with the current), follow the samples and differ by about 1e-3 K
    assert got == pytest.approx(right, abs=5e-3)


@pytest.mark.slow
def test_stale_input_falls_back_and_recovers(cfg):
    est = Estimator(cfg)
    t, _ = feed(est, 0.0, 2.0)
    assert est.latest.stale == []
    sigma0 = est.latest.uncertainty_K['winding_hotspot']
    # the speed topic goes silent for 5 s: estimates keep coming on the held value
    t2, out = feed(est, t, 5.0, skip=('speed_rad_s',))
    assert len(out) >= 240                         # 50 Hz all along
    assert 'speed_rad_s' in out[-1].stale
    assert est.health['speed_rad_s'].stale_events == 1
    assert out[-1].uncertainty_K['winding_hotspot'] > sigma0 + 0.2   # 0.05 K/s for ~5 s
    t3, out = feed(est, t2, 1.0)
    assert out[-1].stale == []
    assert out[-1].uncertainty_K['winding_hotspot'] == pytest.approx(sigma0)
    assert est.health['speed_rad_s'].stale_events == 1
    stamps = [e.stamp_s for e in out]
    assert all(b > a for a, b in zip(stamps, stamps[1:]))


def test_estimates_continue_when_every_input_is_silent(cfg):
    est = Estimator(cfg)
    t, _ = feed(est, 0.0, 1.0)
    out = []
    for k in range(1, 101):                        # 2 s of clock, no samples
        out += est.advance(now_s=t + 0.02 * k)
    assert len(out) >= 95
    assert set(out[-1].stale) == set(INPUTS)
    assert math.isfinite(out[-1].temperatures_C['winding_hotspot'])


def test_bad_samples_are_rejected_and_counted(cfg):
    est = Estimator(cfg)
    feed(est, 0.0, 0.5)
    h = est.health['current_A']
    assert not est.add_many('current_A', [0.6], [float('nan')])
    assert not est.add_many('current_A', [0.6], [float('inf')])
    assert not est.add_many('current_A', [0.6], [-3.0])        # below the plausible range
    assert not est.add_many('current_A', [0.4], [10.0])        # stamp going backwards
    assert est.add_many('current_A', [0.6], [10.0])
    assert (h.non_finite, h.out_of_range, h.backwards) == (2, 1, 1)
    assert not est.add_many('speed_rad_s', [0.1], [500.0])      # behind the model: counted
    assert est.health['speed_rad_s'].rejected == 1
    with pytest.raises(KeyError):
        est.add_many('torque', [0.7], [1.0])


def test_implausible_combinations_are_counted(cfg):
    est = Estimator(cfg)
    feed(est, 0.0, 1.0, current=lambda t: 0.0)                # 800 rad/s with no current
    assert est.implausible_counts['speed_without_current'] >= 45
    assert 'speed_without_current' in est.latest.implausible
    est2 = Estimator(cfg)
    feed(est2, 0.0, 1.0, values={'speed_rad_s': 0.0, 'position_m': 0.0})
    for k in range(1, 501):                                  # 20 mm/s of piston with no pump
        t = 1.0 + k / 1000
        sample = dict(STEADY, current_A=5.0, speed_rad_s=0.0, position_m=0.02 * (t - 1.0))
        for ch in INPUTS:
            est2.push(ch, t, sample[ch])
        if k % 20 == 0:
            est2.advance()
    assert est2.implausible_counts['flow_without_speed'] >= 20


@pytest.mark.slow
def test_alerts_follow_the_estimate_and_acknowledge(cfg, tmp_path):
    low = load_config(overrides={'estimator.alerts.winding_hotspot.warn_C': 21.0,
                                 'estimator.alerts.winding_hotspot.critical_C': 400.0})
    est = Estimator(low)
    _, out = feed(est, 0.0, 20.0, current=lambda t: 30.0)
    raised = [e for x in out for e in x.alert_events if e.kind == 'raised']
    assert raised and raised[0].quantity == 'winding_hotspot'
    assert est.latest.alert_level == 1
    acks = est.acknowledge('winding_hotspot')
    assert acks and acks[0].kind == 'acknowledged'


@pytest.mark.slow
def test_forecast_matches_a_simulated_run_to_the_limit(cfg):
    # stage 2 heats the oil past 135 degC within the hour: run it in full, then let
    # the estimator see its first minute and forecast from the repeated duty
    full = simulate(cfg, stage_duty(cfg, 2), 4000.0, record_every_s=1.0)
    t = np.array(full.time_s)
    oil = np.max([np.array(full.temperatures_K[k]) for k in
                  ('airgap_oil_outlet', 'motor_oil_outlet', 'pump_case', 'chamber_a',
                   'chamber_b', 'accumulator')], axis=0) - C_TO_K
    magnet = np.array(full.temperatures_K['magnet']) - C_TO_K
    truth = {'oil': t[np.argmax(oil >= cfg.fluid.oil_limit_C)],
             'magnet': t[np.argmax(magnet >= cfg.motor.rotor.magnet_limit_C)]}
    # the limits' ticks once a minute, on the forecast's: the forecast does not depend on the
    # limits (the same answers as with a tick every 0.5 s), which took half the estimator's CPU
    est = Estimator(with_values(cfg, {'estimator.limits.period_s': 60.0,
                                      'estimator.limits.horizons_s': (60.0,)}), outlook='inline')
    kin = KineticModel(cfg, est.model.oil)
    duty = stage_duty(cfg, 2)
    for k in range(301):                # 60.2 s at 200 Hz, fed back like the rig
        ts = k * 0.2 + np.arange(1, 41) / 200.0
        fb = feedback(est.model) if est.t_model is not None else ThermalFeedback.uniform(
            cfg.estimator.ambient_C + C_TO_K)
        s = kin.sample(duty, ts, fb)
        for i in range(ts.size):
            for ch in INPUTS:
                est.push(ch, ts[i], float(getattr(s, ch)[i]))
        est.advance_all()
    start = est._outlook.stamp_s       # the forecast tick at 60 s, done at once (inline)
    assert start == pytest.approx(60.0, abs=0.1)
    for q in ('oil', 'magnet'):
        predicted = start + est._outlook.result[q]
        # the forecast repeats the first minute's sensor duty, while in the run the oil
        # thins, the leakage grows and the speed (and its friction) with it: the forecast
        # crosses late, by 3-4 % whatever its step (2 s: 4.0 %, 10 s: 3.1 %)
        assert truth[q] < predicted < 1.045 * truth[q], q
    assert est._outlook.failures == 0


@pytest.mark.slow
def test_margin_current_brings_the_hotspot_to_its_limit_less_k_sigma(cfg):
    # with the constant sigma (no uncertainty section): a known k sigma below the limit
    cfg = dataclasses.replace(cfg, uncertainty=None)
    est = Estimator(cfg, outlook='inline')
    feed(est, 0.0, 2.0, rate_Hz=200.0)
    amps = est._outlook._margins[1][0]    # the first tick's continuous limit
    assert 10.0 < amps < 200.0
    # independent check: the motor alone in steady state at that current
    mot = est._outlook._margin_motor
    lim = cfg.estimator.limits
    assert mot.outputs()['winding_hotspot'] - C_TO_K == pytest.approx(
        cfg.motor.winding.insulation_limit_C - lim.k_sigma * cfg.estimator.model_uncertainty_K,
        abs=0.1)


@pytest.mark.slow
def test_differential_pressure_matches_ports_with_the_low_side_at_the_accumulator(cfg):
    # a load reversing every 2 s: the high side swaps ports, the low side sits at the
    # accumulator pressure, which is what the differential mode assumes: same model inputs
    p_acc = cfg.hydraulics.accumulator.pressure_Pa
    diff_cfg = load_config(overrides={'estimator.pressure_inputs': 'differential'})
    ports, diff = Estimator(cfg), Estimator(diff_cfg)
    assert diff.inputs == ('current_A', 'speed_rad_s', 'dp_Pa', 'position_m')
    for k in range(1, 20001):
        t = k / 1000.0
        dp = 8e6 * math.sin(2 * math.pi * t / 4.0)
        x = 0.01 * math.sin(2 * math.pi * t / 4.0)
        common = {'current_A': 20.0, 'speed_rad_s': 900.0, 'position_m': x}
        for ch, v in dict(common, p_a_Pa=p_acc + max(dp, 0.0), p_b_Pa=p_acc + max(-dp, 0.0),
                          p_acc_Pa=p_acc).items():
            ports.push(ch, t, v)
        for ch, v in dict(common, dp_Pa=dp).items():
            diff.push(ch, t, v)
        ports.advance()
        diff.advance()
    assert ports.steps == diff.steps > 900
    assert diff.latest.stale == []
    for name, value in ports.latest.temperatures_C.items():
        assert diff.latest.temperatures_C[name] == pytest.approx(value, abs=1e-9), name
    # and the pressure does matter: without it port A misses its compression and
    # throttling heat (0.86 K after 20 s here)
    flat = Estimator(diff_cfg)
    for k in range(1, 20001):
        t = k / 1000.0
        for ch, v in {'current_A': 20.0, 'speed_rad_s': 900.0, 'dp_Pa': 0.0,
                      'position_m': 0.01 * math.sin(2 * math.pi * t / 4.0)}.items():
            flat.push(ch, t, v)
        flat.advance()
    assert diff.latest.temperatures_C['pump_port_a'] \
        - flat.latest.temperatures_C['pump_port_a'] > 0.3


@pytest.mark.slow
def test_deferred_rediscretisation_is_deterministic_and_lags_harmlessly(cfg):
    # the live estimator re-discretises the motor after publishing (prepare), so its
    # coefficients lag one 20 ms step; whether prepare is called must not change a bit
    kin = KineticModel(cfg, Estimator(cfg).model.oil)
    t = np.arange(1, 60001) / 1000.0
    s = kin.sample(stage_duty(cfg, 3), t, ThermalFeedback.uniform())
    cols = [(ch, getattr(s, ch)) for ch in INPUTS]

    def run(est, prepare):
        prepared = 0
        for i in range(t.size):
            for ch, v in cols:
                est.push(ch, t[i], float(v[i]))
            if i % 20 == 19:
                est.advance()
                if prepare:
                    prepared += est.prepare()
        return est.latest.temperatures_C, prepared

    with_prepare, prepared = run(Estimator(cfg), True)
    without, _ = run(Estimator(cfg), False)
    immediate, _ = run(Estimator(cfg, EHAModel(
        cfg, coefficient_filter_s=cfg.estimator.coefficient_filter_s)), False)
    assert prepared > 20                       # refreshes did happen, and were deferred
    assert with_prepare == without             # bit for bit: replay equals live
    # a 20 ms lag of coefficients filtered over 4 s: 7e-5 K after 2 min measured
    for name, value in immediate.items():
        assert with_prepare[name] == pytest.approx(value, abs=1e-3), name


@pytest.mark.slow
def test_stamps_since_the_epoch_give_the_same_estimates_as_small_stamps(cfg):
    # ROS stamps are ~1.8e9 s: a float64 resolves them to ~0.2 us, so the model must
    # not take step lengths from their differences (each step would then differ and
    # re-discretise); it runs on time since the start
    epoch = 1.79e9
    small, big = Estimator(cfg), Estimator(cfg)
    for est, t0 in ((small, 0.0), (big, epoch)):
        feed(est, t0, 20.0, current=lambda t, t0=t0: 15.0 + 5.0 * math.sin(t - t0))
    assert big.latest.stamp_s - epoch == pytest.approx(small.latest.stamp_s, abs=1e-6)
    assert small.model.time_s < 21.0
    expm = [e.model.motor.net.discretise_count for e in (small, big)]
    assert expm[0] == expm[1] < small.steps / 5
    assert big.model.time_s == pytest.approx(small.model.time_s, abs=1e-9)
    for name, value in small.latest.temperatures_C.items():
        assert big.latest.temperatures_C[name] == pytest.approx(value, abs=1e-6), name


def test_add_many_counts_and_keeps_the_same_in_blocks_as_one_by_one(cfg):
    # a replay feeds arrays: the same samples must be accepted and rejected for the
    # same reasons as one by one (NaN, out of range, backwards, duplicate, late)
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.0005, 0.0015, 3000))
    v = rng.uniform(5.0, 30.0, t.size)
    v[rng.choice(t.size, 30, replace=False)] = np.nan
    v[rng.choice(t.size, 30, replace=False)] = 500.0          # above the 60 A range
    t[rng.choice(np.arange(1, t.size), 30, replace=False)] -= 0.01   # backwards
    t[rng.choice(t.size, 5, replace=False)] = np.inf
    one, many = Estimator(cfg), Estimator(cfg)
    for est in (one, many):
        for ch in INPUTS:
            est.add_many(ch, [0.0], [STEADY.get(ch, 10.0)])
        est.advance()                   # starts the model at t = 0
    for a, b in ((0, 1000), (1000, 1001), (1001, t.size)):
        for k in range(a, b):
            one.add_many('current_A', t[k:k + 1], v[k:k + 1])
        many.add_many('current_A', t[a:b], v[a:b])
    h1, h2 = one.health['current_A'], many.health['current_A']
    assert vars(h1) == vars(h2)
    assert h1.non_finite >= 30 and h1.out_of_range >= 25 and h1.backwards >= 20
    kept = [(b.stamps().tolist(), b.v[b.lo:b.hi].tolist())
            for b in (one._intake.buffers['current_A'], many._intake.buffers['current_A'])]
    assert kept[0] == kept[1]
    late = Estimator(cfg)
    late.t_model = 1.0
    assert late.add_many('current_A', np.array([0.5, 1.0, 1.5]), np.array([1.0, 1.0, 1.0])) == 1
    assert late.health['current_A'].late == 2


@pytest.mark.slow
def test_a_burst_of_bunched_position_stamps_is_rate_limited(cfg):
    # a receiver that stalls 0.4 s stamps the LVDT samples of the stall on arrival, all
    # within a millisecond: differentiated, the position would jump at 100 m/s and the
    # model would book the throttling heat of that flow
    def run(burst, limit=True):
        est = Estimator(cfg)
        if not limit:
            est.max_stroke_speed_m_s = math.inf
        held = []
        for k in range(1, 10001):
            t = k / 1000.0
            x = 0.02 * math.sin(2 * math.pi * t / 2.0)       # 63 mm/s peak
            for ch in INPUTS[:-1]:
                est.push(ch, t, 15.0 if ch == 'current_A' else STEADY[ch])
            if burst and 4000 < k <= 4400:
                held.append(x)                                 # stalled receiver
            elif held:
                for j, xj in enumerate(held):                  # stamped on arrival
                    est.push('position_m', t - 0.001 + (j + 1) * 1e-6, xj)
                held = []
                est.push('position_m', t, x)
            else:
                est.push('position_m', t, x)
            est.advance()
        return est

    smooth, limited, raw = run(False), run(True), run(True, limit=False)
    assert smooth.implausible_counts['position_faster_than_pump'] == 0
    assert limited.implausible_counts['position_faster_than_pump'] >= 1
    for name in ('chamber_a', 'chamber_b', 'pump_case'):
        ok = abs(limited.latest.temperatures_C[name] - smooth.latest.temperatures_C[name])
        bad = abs(raw.latest.temperatures_C[name] - smooth.latest.temperatures_C[name])
        assert ok < 0.2 * bad, (name, ok, bad)
