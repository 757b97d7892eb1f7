"""
What-if from a state (:mod:`wet_eha_thermal.offline.whatif`) and its worker process.

Checked against what does not go through it: ``simulate()`` from cold and a
run split in two, the model stepped by hand, the live estimator stepped on
the same signals, the trajectory's own crossing of a limit.
"""

import json
import time

import numpy as np
import pytest
from wet_eha_thermal import interface
from wet_eha_thermal.config import load_config
from wet_eha_thermal.estimator.session import EstimatorSession
from wet_eha_thermal.interface import INPUTS
from wet_eha_thermal.model.duty import stage_duty, TableDuty
from wet_eha_thermal.model.eha import EHAModel, SampleBlock
from wet_eha_thermal.offline.simulation import SensorTable, simulate
from wet_eha_thermal.offline.whatif import (MAX_DURATION_S, model_outputs, parse_request,
                                            RequestError, what_if)
from wet_eha_thermal.offline.whatif_worker import run_request, WhatIfWorker
from wet_eha_thermal.units import C_TO_K, L_MIN, MPA

SIGNALS = {'current_A': 25.0, 'speed_rad_s': 800.0, 'p_a_Pa': 3.0e6, 'p_b_Pa': 1.0e6,
           'p_acc_Pa': 1.0e6, 'position_m': 0.001}


@pytest.fixture(scope='module')
def known(cfg):
    return model_outputs(cfg)


def _kelvin_to_C(res, name):
    return np.asarray(res.temperatures_K[name]) - C_TO_K


@pytest.mark.slow
def test_from_cold_it_is_the_simulation_from_cold_bit_for_bit(cfg, known):
    request = parse_request({'id': 'cold', 'stage': 3, 'duration_s': 120.0,
                             'record_every_s': 2.0}, cfg, known)
    got = what_if(cfg, request, ambient_C=25.0)
    sim = simulate(cfg, stage_duty(cfg, 3), 120.0, ambient_C=25.0, record_every_s=2.0)
    assert np.array_equal(got.time_s, np.concatenate([[0.0], sim.time_s]))
    for q in interface.ESTIMATES:
        assert got.temperatures_C[q][0] == 25.0          # cold: every node at the ambient
        assert np.array_equal(got.temperatures_C[q][1:], _kelvin_to_C(sim, q)), q
    i = int(np.argmax(got.temperatures_C['winding_hotspot']))
    assert got.peaks_C['winding_hotspot'] == got.temperatures_C['winding_hotspot'][i]
    assert got.peak_time_s['winding_hotspot'] == got.time_s[i]
    assert got.time_to_limit_s == {'winding_hotspot': None, 'magnet': None, 'oil': None}
    data = got.to_dict()
    assert json.loads(json.dumps(data, allow_nan=False)) == data
    assert data['id'] == 'cold' and data['ok'] and len(data['time_s']) == 61
    oil = data['temperatures_C']['oil'][-1]
    assert oil == pytest.approx(got.temperatures_C['oil'][-1], abs=1e-4)


@pytest.mark.slow
def test_a_table_of_flow_and_load_from_cold_is_its_simulation(cfg, known):
    table = {'time_s': [0.0, 0.5, 1.0], 'flow_L_min': [6.0, -6.0, 6.0],
             'load_MPa': [4.0, 8.0, 4.0]}
    got = what_if(cfg, parse_request({'table': table, 'duration_s': 60.0}, cfg, known))
    act = cfg.hydraulics.actuator
    duty = TableDuty(table['time_s'], np.array(table['flow_L_min']) * L_MIN,
                     np.array(table['load_MPa']) * MPA, act.area_m2, act.half_stroke_m)
    sim = simulate(cfg, duty, 60.0)
    assert np.array_equal(got.temperatures_C['oil'][1:], _kelvin_to_C(sim, 'oil'))
    assert got.duty == 'table of flow and load (period 1 s)'


@pytest.mark.slow
def test_from_a_warm_state_it_continues_the_run(cfg, known):
    """A run split in two at a what-if's start: the same, up to the stage's phase arithmetic."""
    first = simulate(cfg, stage_duty(cfg, 2), 100.0, record_every_s=100.0).model
    state = first.state.copy()
    got = what_if(cfg, parse_request({'stage': 2, 'duration_s': 100.0, 'record_every_s': 1.0},
                                     cfg, known), model=first)
    assert np.array_equal(first.state, state), 'the model given was changed'
    whole = simulate(cfg, stage_duty(cfg, 2), 200.0, record_every_s=1.0)
    for q in ('winding_hotspot', 'magnet', 'oil', 'frame'):
        # the duty restarts its phase at the what-if's start: sin(w (t - 100)) and sin(w t)
        # differ in the last bits, nothing more (stage 2 has whole periods in 100 s)
        assert np.max(np.abs(got.temperatures_C[q] - _kelvin_to_C(whole, q)[99:])) < 1e-8, q


@pytest.mark.slow
def test_from_the_live_estimator_it_follows_what_the_estimator_then_does(cfg, known):
    """
    A what-if on the sensor signals the live estimator then gets, from its state, tracks it.

    At the estimator's step (20 ms, its 500 Hz grid) they agree within 1 mK
    over 20 s (what is left: when the coefficients are refreshed); at the
    default step of 1 s within 30 mK, the step's own error in the fast
    oil volumes. The what-if starts at the estimator's state.
    """
    est = EstimatorSession(cfg)

    def feed(k0, k1):
        for k in range(k0, k1):
            t = 0.02 * k + np.arange(1, 21) / 1000.0
            for name in est.inputs:
                est.add(name, t, np.full(t.size, SIGNALS[name]), now_s=float(t[-1]))
            est.step(float(t[-1]))

    feed(0, 750)
    start = {q: est.latest.temperatures_C[q] for q in interface.ESTIMATES}
    samples = {'time_s': [0.0, 1.0], **{n: [SIGNALS[n]] * 2 for n in INPUTS}}
    runs = {}
    for dt, rate, tol in ((0.02, 500.0, 1e-3), (1.0, 200.0, 3e-2)):
        got = what_if(cfg, parse_request({'samples': samples, 'duration_s': 20.0, 'dt_s': dt,
                                          'sample_rate_Hz': rate, 'record_every_s': 1.0},
                                         cfg, known),
                      model=est.model, source='live', start_stamp_s=est.t_model)
        assert {q: got.temperatures_C[q][0] for q in start} == start
        runs[tol] = got
    feed(750, 1750)
    for tol, got in runs.items():
        for q in ('winding_hotspot', 'magnet', 'oil', 'frame', 'pump_case'):
            assert got.temperatures_C[q][-1] == pytest.approx(est.latest.temperatures_C[q],
                                                              abs=tol), (q, tol)


def test_a_sensor_table_drives_the_model_as_its_samples_would(cfg, known):
    """Constant signals from a table step the model as the same blocks stepped by hand."""
    samples = {'time_s': [0.0, 3.0], **{n: [SIGNALS[n]] * 2 for n in INPUTS}}
    got = what_if(cfg, parse_request({'samples': samples, 'duration_s': 30.0,
                                      'sample_rate_Hz': 50.0, 'ambient_C': 30.0}, cfg, known))
    model = EHAModel(cfg)
    T_K = 30.0 + C_TO_K
    model.T_hyd = np.full(model.circuit.n, T_K)      # as simulate() starts it, then initialise
    model.initialise(T_K, SampleBlock(np.zeros(1), *(np.full(1, SIGNALS[n]) for n in INPUTS)))
    for k in range(30):
        t = k + np.arange(1, 51) / 50.0
        model.step(SampleBlock(t, *(np.full(t.size, SIGNALS[n]) for n in INPUTS)), T_K)
    assert got.temperatures_C['winding_hotspot'][-1] == \
        model.outputs()['winding_hotspot'] - C_TO_K
    # linear between the rows, repeating, the table's time 0 at its start
    table = SensorTable([0.0, 1.0, 2.0], {**{n: [0.0, 0.0, 0.0] for n in INPUTS},
                                          'current_A': [0.0, 10.0, 0.0]}, start_s=100.0)
    block = table.sample(np.array([100.5, 101.0, 102.25, 103.5]))
    assert block.current_A.tolist() == [5.0, 10.0, 2.5, 5.0]


@pytest.mark.slow
def test_time_to_limit_is_where_the_trajectory_crosses(known):
    hot = load_config(overrides={'motor.winding.insulation_limit_C': 26.0})
    got = what_if(hot, parse_request({'stage': 1, 'duration_s': 300.0, 'record_every_s': 5.0},
                                     hot, known))
    t, T = got.time_s, got.temperatures_C['winding_hotspot']
    ttl = got.time_to_limit_s['winding_hotspot']
    assert ttl is not None and got.limits_C['winding_hotspot'] == 26.0
    i = int(np.searchsorted(t, ttl))
    assert T[i - 1] < 26.0 <= T[i]
    assert np.interp(ttl, t[i - 1:i + 1], T[i - 1:i + 1]) == pytest.approx(26.0)
    assert got.time_to_limit_s['magnet'] is None      # far below its limit
    # not asked for, the limited quantities are still checked
    only = what_if(hot, parse_request({'stage': 1, 'duration_s': 300.0, 'record_every_s': 5.0,
                                       'quantities': ['frame']}, hot, known))
    assert set(only.temperatures_C) == {'frame'} and only.time_to_limit_s == got.time_to_limit_s


@pytest.mark.parametrize('request_, message', [
    ('{"stage": 6', 'not JSON'),
    ('[1]', 'expected a JSON object'),
    ({'stage': 6}, 'duration_s: missing'),
    ({'stage': 6, 'duration_s': 0}, 'duration_s = 0: expected a number in (0, 86400]'),
    ({'stage': 6, 'duration_s': MAX_DURATION_S + 1}, 'in (0, 86400]'),
    ({'stage': 6, 'duration_s': 'long'}, "duration_s = 'long'"),
    ({'stage': 7, 'duration_s': 10}, 'stage = 7: expected one of 1, 2, 3, 4, 5, 6'),
    ({'stage': True, 'duration_s': 10}, 'stage = True'),
    ({'duration_s': 10}, 'exactly one duty: stage, table or samples (got none)'),
    ({'stage': 6, 'table': {}, 'duration_s': 10}, '(got stage, table)'),
    ({'stage': 6, 'duration_s': 10, 'durration_s': 5}, 'durration_s: unknown field'),
    ({'stage': 6, 'duration_s': 100, 'dt_s': 0.001}, 'dt_s = 0.001: expected a number in [0.01'),
    ({'stage': 6, 'duration_s': 10, 'dt_s': 20}, 'dt_s = 20: expected a number in [0.01, 10]'),
    ({'stage': 6, 'duration_s': 86400, 'sample_rate_Hz': 1000},
     'more than 2e+07; shorten it or lower the rate'),
    ({'stage': 6, 'duration_s': 100, 'record_every_s': 0.5}, 'record_every_s = 0.5'),
    ({'stage': 6, 'duration_s': 100, 'ambient_C': 500}, 'ambient_C = 500: expected a number'),
    ({'stage': 6, 'duration_s': 100, 'quantities': ['oil', 'coffee']},
     "quantities: 'coffee' is not a list of known names"),
    ({'stage': 6, 'duration_s': 100, 'quantities': []}, 'quantities: []'),
    ({'stage': 6, 'duration_s': 100, 'id': 5}, 'id = 5: expected a string'),
    ({'table': {'time_s': [0, 1], 'flow_L_min': [1, 2]}, 'duration_s': 10},
     'table.load_MPa: missing column'),
    ({'table': {'time_s': [0, 1], 'flow_L_min': [1, 2], 'load_MPa': [1]}, 'duration_s': 10},
     'table.load_MPa: expected a list of 2..'),
    ({'table': {'time_s': [0, 1, 2], 'flow_L_min': [1, 2], 'load_MPa': [1, 2]},
      'duration_s': 10}, 'table: the columns differ in length'),
    ({'samples': {'time_s': [0, 1], 'current_A': [1, 1], 'speed_rad_s': [0, 0],
                  'p_a_Pa': [1e6, 1e6], 'p_b_Pa': [1e6, 1e6], 'p_acc_Pa': [1e6, 1e6],
                  'torque': [0, 0]}, 'duration_s': 10}, 'samples.torque: unknown column'),
    ({'samples': {'time_s': [0, 1], 'current_A': [1, 99], 'speed_rad_s': [0, 0],
                  'p_a_Pa': [1e6, 1e6], 'p_b_Pa': [1e6, 1e6], 'p_acc_Pa': [1e6, 1e6]},
      'duration_s': 10}, 'samples.current_A = 99.0: outside the plausible range [0, 60]'),
])
def test_bad_requests_name_the_field_the_value_and_the_range(cfg, known, request_, message):
    with pytest.raises(RequestError) as info:
        parse_request(request_, cfg, known)
    assert message in str(info.value)


@pytest.mark.parametrize('request_, message', [
    ({'table': {'time_s': [0, 1, 1], 'flow_L_min': [1, 2, 1], 'load_MPa': [1, 2, 1]},
      'duration_s': 10}, 'duty table: time must increase strictly'),
    ({'table': {'time_s': [0, 10], 'flow_L_min': [100, 100], 'load_MPa': [1, 1]},
      'duration_s': 10}, 'beyond the half stroke'),
    ({'samples': {'time_s': [1, 2], **{n: [0, 0] for n in INPUTS}}, 'duration_s': 10},
     'samples: time_s must start at 0'),
])
def test_a_duty_that_cannot_be_built_is_a_request_error(cfg, known, request_, message):
    with pytest.raises(RequestError, match=message):
        what_if(cfg, parse_request(request_, cfg, known))


def test_an_answer_is_strict_json_and_an_error_is_an_answer(cfg, known):
    model = simulate(cfg, stage_duty(cfg, 6), 5.0).model
    good = json.loads(run_request('{"id": "a", "stage": 6, "duration_s": 20}', cfg, known,
                                  __import__('pickle').dumps(model), 20.0, 'test', 5.0))
    assert good['id'] == 'a' and good['ok'] and good['error'] is None
    assert good['start_stamp_s'] == 5.0 and good['source'] == 'test'
    assert set(good['time_to_limit_s']) == {'winding_hotspot', 'magnet', 'oil'}
    bad = json.loads(run_request('{"id": "b", "stage": 6, "duration_s": -1}', cfg, known,
                                 None, 20.0, 'cold', None))
    assert bad == {'id': 'b', 'ok': False,
                   'error': 'duration_s = -1: expected a number in (0, 86400]'}
    assert json.loads(run_request('nonsense', cfg, known, None, 20.0, 'cold', None))['id'] == ''


def _wait_answer(worker, timeout=60.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        answer = worker.poll()
        if answer is not None:
            return json.loads(answer)
        time.sleep(0.02)
    pytest.fail('no answer from the worker')


@pytest.mark.slow
def test_the_worker_runs_one_at_a_time_and_refuses_the_rest(cfg, known):
    model = simulate(cfg, stage_duty(cfg, 6), 5.0).model
    worker = WhatIfWorker(cfg, known)
    try:
        worker.start()
        refused = json.loads(worker.submit('{"id": "early", "stage": 6, "duration_s": 10}',
                                           None, 20.0, 'live', None))
        assert refused['id'] == 'early' and 'no state yet' in refused['error']
        t = time.perf_counter()
        assert worker.submit('{"id": "one", "stage": 6, "duration_s": 30}', model, 20.0, 'live',
                             5.0) is None
        assert time.perf_counter() - t < 0.1        # a snapshot and a hand-off, no more
        busy = json.loads(worker.submit('{"id": "two", "stage": 6, "duration_s": 30}', model,
                                        20.0, 'live', 5.0))
        assert busy['id'] == 'two' and not busy['ok'] and "busy: what-if 'one'" in busy['error']
        answer = _wait_answer(worker)
        assert answer['id'] == 'one' and answer['ok'] and answer['time_s'][-1] == 30.0
        assert worker.poll() is None and not worker.busy
        # free again: a bad one is answered by the worker
        worker.submit('{"id": "three", "stage": 6}', model, 20.0, 'live', 5.0)
        assert _wait_answer(worker)['error'].startswith('duration_s: missing')
        assert (worker.requests, worker.refused, worker.runs) == (4, 2, 2)
        # a day of stage 6 takes minutes: closing stops it at once
        worker.submit('{"id": "long", "stage": 6, "duration_s": 86400}', model, 20.0, 'live', 5.0)
        t = time.perf_counter()
    finally:
        worker.close()
    assert time.perf_counter() - t < 5.0
