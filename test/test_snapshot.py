"""The outlook's model copies (model/snapshot.py): the same steps as a plain pickled copy."""

import operator
import pickle

import numpy as np
from wet_eha_thermal.config import load_config
from wet_eha_thermal.estimator.core import Estimator, INPUTS
from wet_eha_thermal.model import snapshot

#: a loaded duty: 15 A, 800 rad/s, 3 MPa on port A, the rod moving
DUTY = {'current_A': 15.0, 'speed_rad_s': 800.0, 'p_a_Pa': 3.0e6, 'p_b_Pa': 0.5e6,
        'p_acc_Pa': 0.5e6}


def _warm_estimator(samples: int) -> Estimator:
    """Return an estimator fed ``samples`` ms of DUTY at 1 kHz (coefficients refreshed)."""
    est = Estimator(load_config())
    for k in range(1, samples + 1):
        t = k * 1e-3
        for ch in INPUTS:
            est.push(ch, t, DUTY.get(ch, 0.01 * t))
        if k % 20 == 0:
            est.advance(t)
    return est


def test_a_snapshot_copy_steps_bit_for_bit_as_a_pickled_one_and_shares_only_the_fixed_parts():
    est = _warm_estimator(2000)              # 2 s at 1 kHz: coefficients refreshed, warm
    saved = snapshot.save(est.model)
    plain, shared = pickle.loads(pickle.dumps(est.model)), snapshot.copy(saved)
    other = snapshot.copy(saved)
    for path in snapshot.SHARED:
        get = operator.attrgetter(path)
        assert get(shared) is get(est.model) and get(other) is get(est.model), path
    # everything else is the copy's own: the state and the network's coefficients
    assert shared.state is not est.model.state
    assert shared.motor.net.conductance is not est.model.motor.net.conductance
    assert len(saved) < len(pickle.dumps(est.model))
    held = est._outlook.held_duty()
    for m in (plain, shared):
        m.defer_refresh = False
        for _ in range(5):                   # hotter: the coefficients move
            m.step(held.block(m.time_s + 1.0, 25.0), est.ambient_K)
    assert np.array_equal(plain.state, shared.state)
    assert plain.outputs() == shared.outputs()
    # the copies did not touch the original or each other
    assert np.array_equal(other.state, est.model.state)
    assert not np.array_equal(shared.state, est.model.state)


def test_a_second_copy_stepped_from_the_same_point_takes_the_firsts_matrices_to_the_bit():
    # the limits step two copies from one state (model/network.py's memo): the second
    # copy's coefficients are the first's, so it reuses their reduction and exponential
    est = _warm_estimator(1000)
    saved = snapshot.save(est.model)
    held = est._outlook.held_duty()
    first, second = snapshot.copy(saved), snapshot.copy(saved)
    plain = pickle.loads(pickle.dumps(est.model))     # its own structure: computes its own
    counts = []
    for m, amps in ((first, 0.0), (second, 25.0), (plain, 25.0)):
        m.defer_refresh = False
        before = m.motor.net.discretise_count
        m.step(held.block(m.time_s + 0.5, amps), est.ambient_K, max_substep_s=0.5,
               exact_coefficients=True)
        counts.append(m.motor.net.discretise_count - before)
    assert counts == [1, 0, 1]
    assert second.motor.net.last_disc is first.motor.net.last_disc
    assert np.array_equal(second.state, plain.state)
    assert second.outputs() == plain.outputs()
