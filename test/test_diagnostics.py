"""The estimator node's diagnostic statuses, built without ROS from a session fed by hand."""

import pytest
from wet_eha_thermal import interface
from wet_eha_thermal.config import load_config
from wet_eha_thermal.estimator.intake import INPUTS
from wet_eha_thermal.estimator.session import EstimatorSession
from wet_eha_thermal.ros import diagnostics as dg

VALUES = {'current_A': 15.0, 'speed_rad_s': 800.0, 'p_a_Pa': 3e6, 'p_b_Pa': 1e6,
          'p_acc_Pa': 1e6, 'position_m': 0.0}


def counters(**kw):
    base = {'hardware_id': 'rig-7', 'published': 3, 'callback_errors': {}, 'waiting_for_clock': 0,
            'latency_ms': [], 'view': 'off'}
    return dg.NodeCounters(**{**base, **kw})


def feed(est, t0, seconds, skip=()):
    """Feed every input but ``skip`` at 1 kHz from ``t0``, advancing every 20 ms."""
    for k in range(1, int(seconds * 1000) + 1):
        for ch in INPUTS:
            if ch not in skip:
                est.push(ch, t0 + k / 1000, VALUES[ch])
        if k % 20 == 0:
            est.step()
    return t0 + seconds


def report(est, now_s, node=None, new_rejected=None, new_implausible=0):
    topic_of = {n: f'/eha/{n}' for n in est.inputs}
    topic_of.update({f'{interface.MEASURED_PREFIX}/{tc}': f'/eha/measured/{tc}'
                     for tc in interface.THERMOCOUPLES})
    rejected = {**dict.fromkeys(est.inputs, 0), **(new_rejected or {})}
    return {s.name: s for s in dg.statuses(est, node or counters(), now_s, topic_of, rejected,
                                           new_implausible)}


@pytest.fixture
def est():
    return EstimatorSession(load_config(overrides={'estimator.correction.enabled': False}))


def test_no_estimate_yet_is_stale_and_names_the_fallbacks(est):
    s = report(est, 0.0)
    assert s['estimate'].level == dg.STALE
    assert s['estimate'].message.startswith('no estimate yet')
    # no input has been silent for its timeout yet
    assert dict(s['estimate'].values)['inputs on fallback'] == 'none'
    assert [n for n in s if n.startswith('thermocouple')] == []     # correction off


def test_a_silent_input_is_stale_holding_its_last_value(est):
    t = feed(est, 0.0, 2.0)
    s = report(est, t)
    assert {x.level for x in s.values()} == {dg.OK}
    t = feed(est, t, 3.0, skip=('speed_rad_s',))
    s = report(est, t)
    speed = s['input speed_rad_s']
    assert speed.level == dg.STALE
    since = est.health['speed_rad_s'].stale_since_s
    assert speed.message == (f'stale: holding last value 800 since {since:.3f} s '
                             f'({t - since:.1f} s)')
    assert dict(speed.values)['topic'] == '/eha/speed_rad_s'
    assert s['estimate'].message.endswith('on fallback: speed_rad_s')
    assert s['input current_A'].level == dg.OK


def test_rejections_warn_and_a_failing_model_is_an_error(est, monkeypatch):
    t = feed(est, 0.0, 1.0)
    s = report(est, t, new_rejected={'current_A': 4})
    assert (s['input current_A'].level, s['input current_A'].message) == (
        dg.WARN, '4 samples rejected since the last report')

    def boom(*args, **kwargs):
        raise ValueError('boom')

    monkeypatch.setattr(est._est, 'advance', boom)      # the model's step fails, twice
    est.step(t)
    est.step(t)
    assert est.status().model_error == 'ValueError: boom'
    s = report(est, t)
    assert s['estimate'].level == dg.ERROR
    assert s['estimate'].message.endswith('ValueError: boom')
    assert dict(s['estimate'].values)['model errors'] == 2
    s = report(est, t, new_implausible=2)
    assert s['plausibility'].level == dg.WARN
    assert s['plausibility'].message.startswith('2 implausible steps')


def test_with_the_correction_every_thermocouple_has_a_status():
    est = EstimatorSession(load_config(overrides={'estimator.correction.enabled': True}))
    s = report(est, feed(est, 0.0, 1.0))
    names = list(s)
    assert names == (['estimate'] + [f'input {n}' for n in est.inputs] + ['plausibility']
                     + [f'thermocouple {tc}' for tc in interface.THERMOCOUPLES])
    # no reading yet: each says so, at OK, on its own topic
    frame = s['thermocouple frame']
    assert (frame.level, frame.message) == (dg.OK, 'no reading yet')
    assert dict(frame.values)['topic'] == '/eha/measured/frame'


def test_the_status_is_a_snapshot_of_the_session(est):
    before = est.status()
    assert not before.ready and before.t_model_s is None and before.last_sample_s is None
    t = feed(est, 0.0, 2.0)
    st = est.status()
    assert st.ready and st.t_model_s is not None and st.last_sample_s == pytest.approx(t)
    assert {n: c.accepted for n, c in st.inputs.items()} == dict.fromkeys(INPUTS, 2000)
    # a copy: later silences do not change a snapshot taken before them
    feed(est, t + 10.0, 1.0)
    assert est.status().gaps.count == 1 and st.gaps.count == 0 == before.gaps.count
