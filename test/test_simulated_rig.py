"""The simulated rig's thermocouples: at the named output's mean, or at a point of the truth."""

import numpy as np
import pytest
from wet_eha_thermal.config import load_config
from wet_eha_thermal.model.duty import stage_duty
from wet_eha_thermal.offline.simulated_rig import SimulatedRig
from wet_eha_thermal.units import C_TO_K


@pytest.mark.parametrize('points', [False, True])
def test_thermocouples_read_the_mean_or_the_mid_stack_point(points):
    # two slices: the mid-stack point is their common face, halfway between their centres;
    # the end spaces at the bottom of their calibration range keep the end windings apart
    # from the slots (at the correlations' value they sit within 0.01 K of them after 2 min)
    cfg = load_config(overrides={'motor.slices': 2, 'motor.end_spaces.htc_multiplier': 0.3})
    rig = SimulatedRig(cfg, stage_duty(cfg, 3), rate_Hz=200.0, noise=False,
                       thermocouple_lag_s=0.0, block_s=0.5, point_thermocouples=points)
    for _ in range(240):                      # 2 min: the axial profile has formed
        rig.next_block()
    tc = {k: v + C_TO_K for k, v in rig.thermocouples_C().items()}
    motor, out = rig.truth.motor, rig.truth.outputs()
    slot = motor.winding_slices_K()
    frame = motor.T[motor.idx_frame]
    # the two readings can tell mean from point: they differ by a million times the 1e-9 K
    # the comparisons below allow (about 5 mK; the oil warms along the stack)
    assert abs(slot[1] - slot[0]) > 1e-3
    if points:
        assert tc['winding'] == pytest.approx(np.mean(slot), abs=1e-9)
        assert tc['frame'] == pytest.approx(np.mean(frame), abs=1e-9)
        # the conductor mean also holds the end windings: the point reads something else
        assert abs(tc['winding'] - out['winding_mean']) > 0.01
    else:
        assert tc['winding'] == pytest.approx(out['winding_mean'], abs=1e-9)
        assert tc['frame'] == pytest.approx(out['frame'], abs=1e-9)
    assert tc['pump_case'] == pytest.approx(out['pump_case'], abs=1e-9)


def test_a_rig_honouring_a_limit_clamps_counts_and_heats_less():
    cfg = load_config()
    rigs = {limit: SimulatedRig(cfg, stage_duty(cfg, 1), rate_Hz=200.0, noise=False,
                                block_s=0.1) for limit in (None, 20.0)}
    rigs[20.0].current_limit_A = 20.0
    currents = {limit: np.concatenate([rig.next_block()['current_A'] for _ in range(100)])
                for limit, rig in rigs.items()}
    free, held = rigs[None], rigs[20.0]
    # stage 1 asks for 33 A at its peaks: the open rig carries it and counts nothing
    assert np.max(currents[None]) > 32.0 and free.clamped_samples == 0
    assert free.largest_cut_A == 0.0 and np.isnan(free.first_clamp_s)
    # the limited one carries at most the limit, clamped over the demand's excess only
    assert np.max(currents[20.0]) <= 20.0
    demanded_over = currents[None] > 20.0
    assert held.clamped_samples == pytest.approx(np.sum(demanded_over), rel=0.02)
    assert held.first_clamp_s == pytest.approx(
        (np.argmax(demanded_over) + 1) * held.period_s, abs=0.05)
    assert held.largest_cut_A == pytest.approx(np.max(currents[None]) - 20.0, abs=0.5)
    # the truth heats with what the drive carried
    rise = {k: rig.peak_hotspot_K - (rig.ambient_C + C_TO_K) for k, rig in rigs.items()}
    assert rise[20.0] < 0.8 * rise[None]
    assert held.peak_hotspot_K >= held.truth.outputs()['winding_hotspot']
