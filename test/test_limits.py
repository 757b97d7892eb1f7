"""The current limits for the drive: against the model itself, determinism, fallbacks."""

import copy
import dataclasses
import math
import pickle

import numpy as np
import pytest
from wet_eha_thermal.config import load_config
from wet_eha_thermal.estimator import limits as limits_module, uncertainty
from wet_eha_thermal.estimator.core import Estimator, INPUTS
from wet_eha_thermal.estimator.limits import (ceiling_K, limit_steps, LimitProblem, linearise,
                                              probing, RATING, TOL_A2)
from wet_eha_thermal.estimator.outlook import MARGIN_DELAY_S
from wet_eha_thermal.estimator.session import EstimatorSession
from wet_eha_thermal.estimator.uncertainty import HEATING_WAIT_PER_STEP_S
from wet_eha_thermal.interface import LimitStatus
from wet_eha_thermal.model import snapshot
from wet_eha_thermal.model.network import NetworkError
from wet_eha_thermal.units import C_TO_K

pytestmark = pytest.mark.slow     # measured: see docs/development.md#tests-and-ci

#: a loaded pump (8 MPa) at 15 A: the winding warms by about 10 K in a minute
DUTY = {'current_A': 15.0, 'speed_rad_s': 800.0, 'p_a_Pa': 3e6, 'p_b_Pa': 1e6,
        'p_acc_Pa': 1e6, 'position_m': 0.0}
#: limits low enough that the winding binds, the others far: at 40 degC over 10 s (44 over 60 s),
#: at 80 degC over 600 s (the pump's heat alone takes it past 52 degC in 10 minutes)
LOW_LIMITS = {'motor.winding.insulation_limit_C': 40.0, 'motor.rotor.magnet_limit_C': 120.0,
              'fluid.oil_limit_C': 120.0}
#: the cold start's heating on DUTY takes 8 steps (its unperturbed copy's rise with 4 is 1.8 %
#: off that with 8: benchmarks/heated_relative.py), so its figures are taken this long after
#: the first tick (s of sample time; checked in test_a_cold_motor_is_limited_by_its_rating...)
HEATING_WAIT_S = 8 * HEATING_WAIT_PER_STEP_S
#: the figures of a cold start's heated copies are in by then (s): the first tick at 0.5 s,
#: then HEATING_WAIT_S
HEATED_S = 1.0 + HEATING_WAIT_S
#: a run past the first margin (the continuous limit), MARGIN_DELAY_S after the figures (s)
RUN_S = int(HEATED_S + MARGIN_DELAY_S) + 1


def feed(est, t0, seconds, skip=(), rate_Hz=1000.0):
    """Feed the steady duty from ``t0`` (except the inputs in ``skip``); return the end."""
    n = int(round(seconds * rate_Hz))
    for k in range(1, n + 1):
        t = t0 + k / rate_Hz
        for ch in INPUTS:
            if ch not in skip:
                est.push(ch, t, DUTY[ch])
        if k % 20 == 0:
            est.advance(t)
    return t0 + n / rate_Hz


def run(gen):
    """Run a generator to its end; return its value."""
    while True:
        try:
            next(gen)
        except StopIteration as done:
            return done.value


@pytest.fixture(scope='module')
def warm():
    """
    Return an estimator after 60 s of the duty, with the constant 4 K sigma.

    Without the uncertainty section: the limits below are set for a ceiling 8 K under
    them (the propagated sigma is a few tenths of a kelvin after a minute).
    """
    est = Estimator(dataclasses.replace(load_config(), uncertainty=None))
    feed(est, 0.0, 60.0)
    return est


def peak_excess(est, limits_C, current_A, horizon_s, k_sigma):
    """
    Step a copy of the model on the held duty at ``current_A`` for ``horizon_s``.

    Return the largest excess over (0, horizon] of a quantity of ``limits_C``
    plus k sigma over its limit (K): the nonlinear model, step by step,
    where the limits solved its linearisation.
    """
    held = est._outlook.held_duty()
    m = copy.deepcopy(est.model)
    m.defer_refresh = False
    dt = est.cfg.estimator.limits.period_s
    worst = -math.inf
    for _ in range(int(round(horizon_s / dt))):
        m.step(held.block(m.time_s + dt, current_A), est.ambient_K, max_substep_s=dt)
        out = m.outputs()
        worst = max(worst, max(out[q] - C_TO_K + k_sigma * est.latest.uncertainty_K[q] - lim
                               for q, lim in limits_C.items()))
    return worst


# (over a minute at no current the held speed's friction and iron loss take the slot's peak
# 2.6 K up from 31.1 degC: with 2 sigma of 8 K a 40 degC limit is already lost there)
@pytest.mark.parametrize('winding_C, horizon_s, tol_K', [(40.0, 10.0, 0.5), (44.0, 60.0, 0.5),
                                                         (80.0, 600.0, 3.0)])
def test_a_limit_takes_the_model_to_its_limit_and_no_further(warm, winding_C, horizon_s, tol_K):
    est = warm
    lim = est.cfg.estimator.limits
    limits_C = {'winding_hotspot': winding_C, 'magnet': 120.0, 'oil': 120.0}
    got = run(limit_steps(pickle.dumps(est.model), est.model.state,
                          probing(est.model, list(limits_C)), est._outlook.held_duty(),
                          est.ambient_K, est.latest.uncertainty_K, limits_C, lim.k_sigma,
                          (horizon_s,), lim.period_s, est.cfg.motor.peak_current_A))
    amps, binds = got[0]
    assert binds == 'winding_hotspot' and 5.0 < amps < est.cfg.motor.peak_current_A
    # the model itself, stepped at the limit: the winding ends at its limit less k sigma,
    # within the linearisation's error: 0.5 K over a minute (the coefficients barely
    # move); over 10 minutes the oil thins, its friction falls and the pump's leakage heat
    # grows, which a linearisation half-way along follows only in part: 1.2 K here,
    # 2.6 K after 10 minutes of stage 2 (8 MPa) with the limit at 60 degC
    assert abs(peak_excess(est, limits_C, amps, horizon_s, lim.k_sigma)) < tol_K
    # and it is the largest: 1 A more crosses the limit
    if tol_K <= 0.5:
        assert peak_excess(est, limits_C, amps + 1.0, horizon_s, lim.k_sigma) > 0.0


def bisected_root(f, top):
    """Return the largest I^2 in [0, ``top``] with ``f`` <= 0, by bisection to 1e-6 A^2."""
    if f(0.0) > 0.0:
        return 0.0
    if f(top) <= 0.0:
        return top
    lo, hi = 0.0, top
    while hi - lo > 1e-6:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(mid) <= 0.0 else (lo, mid)
    return lo


def test_the_search_finds_the_root_within_its_tolerance_whatever_its_guess(warm):
    # the search of each tick starts at the last tick's answer: against a brute-force
    # bisection of the same linearised problem, within TOL_A2 (A^2), the same answer from
    # any start, and two evaluations when the guess is right
    est = warm
    lim, top = est.cfg.estimator.limits, est.cfg.motor.peak_current_A
    setup = probing(est.model, ['winding_hotspot', 'magnet', 'oil'])
    terms = linearise(snapshot.save(est.model), None, est._outlook.held_duty(), lim.period_s,
                      est.ambient_K, top, setup.layout, setup.alpha_copper, setup.peaks)
    for winding_C, horizon_s in ((40.0, 10.0), (44.0, 60.0), (80.0, 600.0), (200.0, 10.0),
                                 (20.0, 10.0)):
        limits_C = {'winding_hotspot': winding_C, 'magnet': 120.0, 'oil': 120.0}
        ceiling = {q: ceiling_K(c, est.latest.uncertainty_K[q], lim.k_sigma, None,
                                est.ambient_K) for q, c in limits_C.items()}
        problem = LimitProblem(*terms, est.model.state, setup.rows, ceiling)
        steps = int(round(horizon_s / lim.period_s))
        calls = []

        def excess(i_sq, n=steps, p=problem):
            calls.append(i_sq)
            return p.horizon_excess(i_sq, n)

        root = bisected_root(lambda s: excess(s)[0], top ** 2)
        answers = set()
        for guess in (None, 0.0, 5.0, math.sqrt(root) - 0.5, math.sqrt(root) + 0.5, top):
            answers.add(problem.solve(excess, top, guess))
        assert len(answers) == 1, answers
        ((amps, binds),) = answers
        assert abs(amps ** 2 - root) <= TOL_A2, (winding_C, horizon_s)
        assert binds == (RATING if root == top ** 2 else 'winding_hotspot')
        calls.clear()
        assert problem.solve(excess, top, amps) == (amps, binds)
        assert len(calls) <= 2, calls


def test_a_cold_motor_is_limited_by_its_rating_over_short_horizons():
    est = Estimator(load_config(), outlook='inline')
    # past the first forecast's margin: the first tick, its figures' HEATING_WAIT_S, then
    # MARGIN_DELAY_S
    feed(est, 0.0, 0.5 + HEATING_WAIT_S + MARGIN_DELAY_S + 0.5)
    limits = est._outlook.limits
    assert limits.status == 'ok' and est.propagation.heated_after_s == HEATING_WAIT_S
    assert limits.limits_A[limits.names.index('10s')] == est.cfg.motor.peak_current_A
    assert limits.binds[limits.names.index('10s')] == RATING
    assert limits.binding_A == est.cfg.motor.peak_current_A
    # the continuous limit, the steady margin, is below the rating
    i = limits.names.index('continuous')
    assert 0.0 < limits.limits_A[i] < est.cfg.motor.peak_current_A
    assert limits.binds[i] == 'winding_hotspot'
    # the first HEATING_WAIT_S the fallback, while the copies are heated; then MARGIN_DELAY_S
    # without a continuous limit: the fallback current, pending
    ticks = est._outlook.take_limits()
    fallback = est.cfg.estimator.limits.fallback_current_A
    heating = [t for t in ticks if t.stamp_s < 0.5 + HEATING_WAIT_S]
    assert heating and all(t.code == LimitStatus.UNCERTAIN and 'heated' in t.detail
                           and max(t.limits_A) == fallback for t in heating)
    first = ticks[len(heating)]
    assert first.status == 'ok'
    assert (first.limits_A[i], first.binds[i]) == (fallback, 'pending')


def collect(mode, seconds):
    """Return every tick's limits of ``seconds`` of the duty, worked ``mode``."""
    est = Estimator(load_config(overrides=LOW_LIMITS), outlook=mode)
    out = []
    t = 0.0
    while t < seconds:
        t = feed(est, t, 1.0)
        while est._outlook.busy:
            est.background(1.0)
        out += est._outlook.take_limits()
    return out


@pytest.fixture(scope='module')
def inline():
    """Return the limits of RUN_S of the duty worked out at once (past the first margin)."""
    return collect('inline', RUN_S)


def test_limits_are_bit_for_bit_the_same_at_once_and_in_background_slices(inline):
    # past the first margin, so the continuous limit (the margin job's) is compared too
    background = collect('background', RUN_S)
    assert len(inline) == 2 * RUN_S - 1    # a tick each 0.5 s from the start at 1 ms
    assert inline[-1].binds[0] == 'winding_hotspot'   # (at 40 degC)
    assert inline == background            # every field, floats compared exactly
    assert all((lim.status == 'ok') == (lim.stamp_s >= 0.5 + HEATING_WAIT_S) for lim in inline)
    stamps = [lim.stamp_s for lim in inline]
    assert stamps == sorted(stamps)


def warm_ticks(seconds, warm_s=40.0):
    """Return the limits of ``seconds`` of the duty at once, after ``warm_s`` without them."""
    est = Estimator(load_config(overrides=LOW_LIMITS), outlook='inline')
    est.outlook_mode = 'off'          # (the warm-up's ticks cost time and test nothing)
    t = feed(est, 0.0, warm_s)
    est.outlook_mode = 'inline'
    out = []
    while t < warm_s + seconds:
        t = feed(est, t, 1.0)
        out += est._outlook.take_limits()
    return out


def test_ticks_near_a_linearised_one_take_its_linearisations_within_a_cell_of_the_grid(
        monkeypatch):
    made = []

    def counted(*args, **kwargs):
        made.append(args[1] is None)        # at the tick's state, or half-way
        return linearise(*args, **kwargs)

    monkeypatch.setattr(limits_module, 'linearise', counted)
    reused = warm_ticks(12.0)
    kept = made.count(True)
    made.clear()
    # the reference: every tick linearised at its own state
    monkeypatch.setattr(limits_module, 'REUSE_TOL_K', -1.0)
    fresh = warm_ticks(12.0)
    # the winding warms slowly: about every other tick takes the last one's
    assert made.count(True) == len(fresh) and 0 < kept < 0.75 * len(fresh)
    assert all(max(lim.limits_A) < 45.0 for lim in fresh)       # every horizon binds
    for a, b in zip(reused, fresh):
        # each answer is the middle of its cell of I^2 (2 TOL_A2 wide) around its root: a
        # reused linearisation moves the root by less than a cell
        assert a.binds == b.binds and a.stamp_s == b.stamp_s
        assert max(abs(x * x - y * y) for x, y in zip(a.limits_A, b.limits_A)) \
            <= 2 * TOL_A2 + 1e-9


def test_limits_taken_sample_by_sample_with_a_small_budget_are_the_same_as_at_once(inline):
    # as the live node's session works: take() per sample, 4 ms of background after each estimate,
    # the limits given up when older than max_age_s; what it computes is what a replay does
    at_once = {lim.stamp_s: lim for lim in inline}
    live = []
    session = EstimatorSession(load_config(overrides=LOW_LIMITS), outlook='background',
                               publish=lambda out: live.extend(out.limits), budget_s=0.004)
    for k in range(1, int(RUN_S * 1000) + 1):
        t = k / 1000.0
        for ch in INPUTS:
            session.take(ch, t, DUTY[ch], now_s=t)
    computed = [lim for lim in live if lim.status == 'ok']
    assert len(computed) >= len(at_once) // 2, [lim.reason for lim in live]
    assert all(lim == at_once[lim.stamp_s] for lim in computed)
    assert all(lim.reason.startswith('behind') or lim.code == LimitStatus.UNCERTAIN
               and lim.stamp_s < 0.5 + HEATING_WAIT_S for lim in live if lim.status != 'ok')
    # one channel: the estimate (the view, /diagnostics) carries the limits the drive got,
    # with their status
    assert session.limits is live[-1] and session.latest.current_limits is live[-1]


def test_a_stale_input_drops_the_limits_to_the_fallback_and_says_why():
    cfg = load_config()
    est = Estimator(cfg, outlook='inline')
    t = feed(est, 0.0, HEATED_S)
    feed(est, t, 2.0, skip=('current_A',))
    limits = est._outlook.take_limits()
    assert 'ok' in [lim.status for lim in limits]     # after the heating, before the stale
    last = limits[-1]
    assert last.status == 'fallback' and 'current_A' in last.reason
    assert set(last.limits_A) == {cfg.estimator.limits.fallback_current_A}


def test_fallbacks_wait_behind_the_ticks_still_worked_on_so_stamps_never_go_back():
    est = Estimator(load_config(), outlook='background')
    t = feed(est, 0.0, HEATED_S + 0.6)     # two ticks waiting for background work
    feed(est, t, 1.0, skip=('current_A',))  # then stale ticks, decided at once
    while est._outlook.busy:
        est.background(1.0)
    limits = est._outlook.take_limits()
    stamps = [lim.stamp_s for lim in limits]
    assert stamps == sorted(stamps) and len(stamps) == len(set(stamps))
    worked = [lim for lim in limits if lim.stamp_s > HEATED_S]
    assert worked[0].status == 'ok' and 'current_A' in limits[-1].reason


def test_too_uncertain_an_estimate_drops_the_limits_to_the_fallback():
    # the constant sigma of a configuration without the uncertainty section, 4 K > 1 K
    cfg = dataclasses.replace(load_config(overrides={'estimator.limits.max_sigma_K': 1.0,
                                                     'estimator.correction.enabled': False}),
                              uncertainty=None)
    est = Estimator(cfg, outlook='inline')
    feed(est, 0.0, 1.0)
    last = est._outlook.limits
    assert last.status == 'fallback' and last.reason.startswith('uncertain')


def test_a_tick_not_worked_on_in_time_is_published_as_the_fallback():
    cfg = load_config()
    est = Estimator(cfg, outlook='background')
    feed(est, 0.0, HEATED_S + 2.0)         # no background work at all: every tick waits
    limits = est._outlook.take_limits(est.t_model)
    behind = [lim for lim in limits if lim.code == LimitStatus.BEHIND]
    assert behind and all(lim in behind or lim.code == LimitStatus.UNCERTAIN
                          and lim.stamp_s < 0.5 + HEATING_WAIT_S for lim in limits)
    assert est._outlook.limits_behind == len(behind)
    assert [lim.stamp_s for lim in limits] == sorted(lim.stamp_s for lim in limits)


def test_stopping_gives_up_the_waiting_ticks_then_says_stopped():
    # a managed node deactivated: what waits goes out as behind, then one STOPPED, nothing after
    cfg = load_config(overrides=LOW_LIMITS)
    live = []
    session = EstimatorSession(cfg, outlook='background',
                               publish=lambda out: live.extend(out.limits), budget_s=0.0)
    # no budget: every tick after the heating's waits for the CPU
    for k in range(1, int(HEATED_S * 1000) + 1):
        t = k / 1000.0
        for ch in INPUTS:
            session.take(ch, t, DUTY[ch], now_s=t)
    n = len(live)
    session.stop_limits('the estimator was deactivated')
    last = live[-1]
    assert last.frame_id == 'fallback: stopped: the estimator was deactivated'
    assert last.code == LimitStatus.STOPPED and last.stamp_s == session.t_model > HEATED_S - 0.1
    assert max(last.limits_A) == cfg.estimator.limits.fallback_current_A
    given_up = live[n:-1]
    assert given_up and all(lim.code == LimitStatus.BEHIND for lim in given_up)
    stamps = [lim.stamp_s for lim in live]
    assert stamps == sorted(stamps)
    st = session.status()
    assert st.limits is last and st.limits_published == len(live)
    assert st.limits_fallback == sum(lim.code != LimitStatus.OK for lim in live)


def horizon_excess(est, horizon_s, current_A, steps):
    """
    Step every uncertainty copy on the held duty at ``current_A`` over ``horizon_s``.

    Return each limited quantity's estimate plus k sigma at the horizon less its
    limit (K), and its sigma per K of rise there, the sigma formed from the copies
    as the estimator forms it (the GUM sum over the copies, with the structural
    part): what the limit promised, found without the limits' linearisation and
    without a figure per K of rise carried from elsewhere.
    """
    prop, lim = est.propagation, est.cfg.estimator.limits
    held = est._outlook.held_duty()
    y = []
    for m in prop.models:
        c = snapshot.copy(snapshot.save(m))
        c.hold_from(held.block(c.time_s, current_A))
        for _ in range(steps):
            dt = horizon_s / steps
            c.step(held.block(c.time_s + dt, current_A), est.ambient_K, max_substep_s=dt)
        out = c.outputs()
        y.append([out[n] for n in prop.names])
    y = np.array(y)
    d = y[1:] - y[0]
    rise = y[0] - est.ambient_K
    sigma = np.sqrt(np.sum(d * d, axis=0) + (est.cfg.uncertainty.structural.rise_fraction
                                             * rise) ** 2)
    limited = [(i, q) for i, q in enumerate(prop.names) if q in est.limits_C]
    return ({q: float(y[0][i] - C_TO_K + lim.k_sigma * sigma[i] - est.limits_C[q])
             for i, q in limited}, {q: float(sigma[i] / rise[i]) for i, q in limited})


def test_a_cold_start_limit_holds_with_the_sigma_its_horizon_will_have():
    """
    A cold start's 600 s limit, held for 600 s: the estimate plus k sigma stays at the limit.

    In the first tens of seconds the copies all sit near ambient and know no sigma
    per K of rise, while ten minutes at the limit raise the sigma to about 8 K. The
    copies are stepped to the horizon at the limit (60 s steps): no limited quantity
    may end more than the 600 s linearisation's tolerance (3 K, as above) past its
    limit, and the sigma per K of rise the limits took from the heated copies must
    be that of the horizon within 10 % (the heating's 1 % at this duty, at the
    continuous rating rather than the limit's current). Measured at 7a4e4d1's
    figures (none at a cold start), at 3 s: 37.5 A, the oil 2.5 K past, inside the
    tolerance only because the linearisation of the cold, viscous oil errs 16 K on
    the safe side; with the heated copies (8 steps), at 4.5 s: 32.7 A, the oil
    15.9 K under, and the figures 0.078, 0.096, 0.089 against 0.080, 0.091, 0.092
    at the horizon.
    """
    est = Estimator(load_config(), outlook='inline')
    feed(est, 0.0, HEATED_S)
    limits = est._outlook.take_limits()[-1]       # one of the first with the heated figures
    assert limits.status == 'ok' and est.propagation.periods == 0
    h = limits.names.index('600s')
    amps, binds = limits.limits_A[h], limits.binds[h]
    assert binds in est.limits_C and amps > est.cfg.motor.max_continuous_current_A
    excess, per_K = horizon_excess(est, 600.0, amps, 10)
    assert max(excess.values()) < 3.0, (binds, amps, excess)
    taken = est.propagation.relative(est._outlook.held_duty(), est.ambient_K, est.t_model,
                                     est.limits_C)
    assert set(per_K) <= set(taken), taken
    assert all(abs(taken[q] / per_K[q] - 1.0) < 0.1 for q in per_K), (taken, per_K)


def test_a_failed_heating_leaves_the_limits_on_the_fallback_and_the_estimates_going(monkeypatch):
    # a held duty that takes a copy's oil past the model's range within the horizon (the
    # reference rig at 2000 rad/s and 25 MPa in 120 steps): a copy's step fails on the thread
    def fail(*args, **kwargs):
        raise NetworkError('advective capacity rate must be >= 0')

    monkeypatch.setattr(uncertainty, '_heated', fail)
    est = Estimator(load_config(), outlook='inline')
    feed(est, 0.0, HEATED_S + 1.0)
    limits = est._outlook.take_limits()
    assert limits and all(lim.code == LimitStatus.UNCERTAIN for lim in limits)
    assert est.propagation.heating_error.startswith('NetworkError: advective')
    assert est.latest.stamp_s > HEATED_S + 0.9        # the estimates went on
