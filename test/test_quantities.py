"""The map of named quantities: one name per state, each output defined once and read by all."""

import dataclasses

import numpy as np
import pytest
from wet_eha_thermal import interface
from wet_eha_thermal.config import load_config, Thermocouples
from wet_eha_thermal.estimator.correction import ThermalCorrection
from wet_eha_thermal.estimator.kalman import output_variances
from wet_eha_thermal.model.duty import stage_duty
from wet_eha_thermal.model.hydraulics import NODES
from wet_eha_thermal.model.quantities import MAX, MEAN, PEAK, PORT, Quantity, QuantityMap, STATE
from wet_eha_thermal.offline.simulation import simulate


@pytest.fixture(scope='module')
def cfg():
    return load_config(overrides={'estimator.correction.enabled': True})


@pytest.fixture(scope='module')
def model(cfg):
    """Return the coupled model after 30 s of a loaded stage: no two states alike."""
    return simulate(cfg, stage_duty(cfg, 3), 30.0, record_every_s=30.0).model


def test_one_name_per_element_of_the_state(model):
    q = model.quantities
    assert len(q.state_names) == model.state.size
    assert len(set(q.state_names)) == len(q.state_names)
    m = model.motor.state_count
    assert q.state_names[m:] == NODES
    # each name is the element it names: the motor's by its node temperature
    for i, name in enumerate(q.state_names[:m]):
        assert model.state[i] == model.motor.temperature(name), name


def test_winding_mean_weights_are_the_copper_length_shares(cfg, model):
    q = model.quantities
    w = q.weights('winding_mean')
    assert w.sum() == pytest.approx(1.0, abs=1e-12)
    # each slot slice carries its length of the stack, each end winding half the end turn,
    # of the conductor length of half a turn; each radial layer (equal depths, slot bottom
    # first) its share of the section's area
    mo = cfg.motor
    turn = mo.stack_length_m + mo.winding.end_turn_length_m
    lengths = [mo.stack_length_m / mo.slices / turn] * mo.slices \
        + [mo.winding.end_turn_length_m / 2.0 / turn] * 2
    r_out, r_in = mo.stator.yoke_inner_radius_m, mo.stator.bore_radius_m \
        + mo.stator.tooth_tip_depth_m
    r = r_out - (r_out - r_in) * np.arange(mo.winding_layers + 1) / mo.winding_layers
    areas = (r[:-1] ** 2 - r[1:] ** 2) / (r_out ** 2 - r_in ** 2)
    np.testing.assert_allclose(w, np.kron(lengths, areas), rtol=1e-12)


def test_every_estimate_and_thermocouple_resolves(model):
    outputs = model.outputs()
    assert list(outputs) == list(model.quantities.outputs)
    assert set(interface.ESTIMATES) <= set(outputs)
    # every thermocouple measures a published estimate, and the configuration trusts each
    assert set(interface.THERMOCOUPLES.values()) <= set(interface.ESTIMATES)
    assert [f.name for f in dataclasses.fields(Thermocouples)] == list(interface.THERMOCOUPLES)


def test_the_kalman_row_of_each_output_is_its_definition(cfg, model):
    corr = ThermalCorrection(cfg, model)
    q = model.quantities
    # the circuit reports its step means; on the end state the outputs and the rows meet
    model.circuit.T_report = None
    state = np.concatenate([model.state, np.zeros(corr.nd)])
    outputs, taken = model.outputs_and_states()
    assert outputs == model.outputs()
    # and the variance of each output is its row's quadratic form in a covariance
    a = np.random.default_rng(3).normal(size=(corr.n, corr.n))
    P = a @ a.T
    variances = dict(zip(q.names, output_variances(P, taken, corr._H_mean,
                                                   corr._mean_of_output)))
    kinds = set()
    for name, quantity in q.outputs.items():
        kinds.add(quantity.kind)
        row = corr._row(name, taken)
        if quantity.kind == PEAK:
            # a peak's row is its hottest block's mean: the peak is at or above it
            assert outputs[name] >= row @ state - 1e-9, name
        else:
            assert row @ state == pytest.approx(outputs[name], abs=1e-9), name
        assert variances[name] == pytest.approx(row @ P @ row, rel=1e-12), name
        if quantity.kind in (MEAN, STATE):
            expected = np.zeros(corr.n)
            expected[q.state_indices(name)] = q.weights(name)
            np.testing.assert_array_equal(row, expected, err_msg=name)
        else:
            # one state: the hottest of the set, or the port the pressure chose
            assert np.count_nonzero(row) == 1 and row.max() == 1.0, name
    assert kinds == {MEAN, MAX, STATE, PORT, PEAK}


def test_the_oil_is_the_hottest_oil_volume(model):
    out = model.outputs()
    oil_volumes = ('airgap_oil_outlet', 'motor_oil_outlet', 'pump_case', 'chamber_a',
                   'chamber_b', 'accumulator')
    assert out['oil'] == max(out[n] for n in oil_volumes)
    taken = model.outputs_and_states()[1]
    i = taken[model.quantities.names.index('oil')]
    assert model.quantities.state_names[i] in {
        s for n in oil_volumes for s in model.quantities.outputs[n].states}


def test_an_output_over_a_name_that_is_no_state_is_refused():
    with pytest.raises(ValueError, match='no state named surface'):
        QuantityMap(['core'], {'t': Quantity(STATE, ('surface',))}, lambda name: 0)
    with pytest.raises(ValueError, match='share a name'):
        QuantityMap(['core', 'core'], {}, lambda name: 0)
