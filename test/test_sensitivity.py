"""Which unknown matters: the sensitivity of the steady hot spot and magnet, and its command."""

import csv

import numpy as np
import pytest
from wet_eha_thermal import cli
from wet_eha_thermal.config import default_config_path, load_config
from wet_eha_thermal.offline import maps
from wet_eha_thermal.offline.sensitivity import compute_sensitivity, LEAKAGE_KEY

#: two map points: the maps' sweep speed at 15 and 35 A
SMALL = {'maps.speeds_rpm': [10000.0], 'maps.currents_A': [35.0]}


@pytest.fixture(scope='module')
def small():
    """Return the reference rig with two map points, and its sensitivity."""
    cfg = load_config(overrides=SMALL)
    return cfg, compute_sensitivity(cfg)


def test_each_move_is_the_difference_of_two_maps(small):
    # an independent path: the maps job on the perturbed configuration, minus the nominal
    cfg, result = small
    base = maps.compute_maps(cfg)
    assert [(p.sweep, p.speed_rpm, p.current_A) for p in base] == result.points
    for q in ('winding_hotspot', 'magnet'):
        assert result.base_C[q] == pytest.approx([p.temperatures_C[q] for p in base], abs=1e-6)
    slices = maps.compute_maps(load_config(overrides={**SMALL, 'motor.slices': 10}))
    move = result.moves_K['motor.slices=10']['winding_hotspot']
    assert move == pytest.approx([a.temperatures_C['winding_hotspot']
                                  - b.temperatures_C['winding_hotspot']
                                  for a, b in zip(slices, base)], abs=1e-6)


def test_less_cooling_flow_and_worse_end_spaces_make_the_winding_hotter(small):
    _, result = small
    # one sigma down of the case leakage (the motor's oil flow) and of the end-space h
    assert np.all(result.moves_K[LEAKAGE_KEY]['winding_hotspot'] > 0.5)
    assert np.all(result.moves_K['motor.end_spaces.htc_multiplier']['winding_hotspot'] > 0.0)
    # more rotor loss makes the magnets hotter: a lower loss factor cools them
    assert np.all(result.moves_K['motor.electromagnetic.loss_factor']['magnet'] < 0.0)
    # the pump's friction moves the oil inlet, which a map holds: listed, not ranked
    assert 'hydraulics.pump.viscous_friction_coeff' in result.not_ranked
    # the review's large unknowns lead: the cooling flow and the end spaces' h (their order
    # turns on the model: 4.6 and 4.8 K at 35 A with the end spaces' torque balance)
    ranked = [name for name, _, _ in result.largest('winding_hotspot')]
    assert {LEAKAGE_KEY, 'motor.end_spaces.htc_multiplier'} <= set(ranked[:3]), ranked
    moves = [abs(m) for _, m, _ in result.largest('winding_hotspot')]
    assert moves == sorted(moves, reverse=True)


def test_the_command_prints_the_ranking_and_writes_the_table_and_the_tornado(tmp_path, capsys):
    path = tmp_path / 'small.yaml'
    text = (default_config_path().read_text()
            .replace('speeds_rpm: [2000, 4000, 6000, 8000, 10000, 12000, 14000, 16000, 18000, '
                     '20000]', 'speeds_rpm: [10000]')
            .replace('currents_A: [5, 10, 15, 20, 25, 30, 35]', 'currents_A: [35]'))
    assert 'speeds_rpm: [10000]' in text and 'currents_A: [35]' in text
    path.write_text(text)
    assert cli.main(['sensitivity', '--config', str(path), '--out', str(tmp_path)]) == 0
    out = capsys.readouterr().out
    keys = ('motor.', 'hydraulics.')
    table = [line.split()[0] for line in out.splitlines() if line.startswith(keys)]
    assert {LEAKAGE_KEY, 'motor.end_spaces.htc_multiplier'} <= set(table[:3]), out
    assert 'Not ranked' in out and 'hydraulics.pump.extra_loss_W' in out
    rows = list(csv.DictReader((tmp_path / 'sensitivity.csv').open()))
    assert {r['perturbation'] for r in rows} >= {LEAKAGE_KEY, 'motor.slices=10'}
    assert len(rows) == 2 * len({r['perturbation'] for r in rows})
    assert (tmp_path / 'sensitivity.png').stat().st_size > 10000
