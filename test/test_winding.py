"""
One description of the winding (model/winding.py): what it implies, and what it refuses.

The reference rig's layout by hand from its datasheet figures; a winding that contradicts its
phase resistance, its torque constant or its slot stops the configuration with one message
naming the keys and the numbers; the retired keys say what replaces them.
"""

import math

import pytest
from wet_eha_thermal.config import default_config_path, load_config, with_values
from wet_eha_thermal.config_spec import ConfigError
from wet_eha_thermal.model.rotor_losses import implied_turns_per_phase
from wet_eha_thermal.model.winding import winding_layout


@pytest.fixture(scope='module')
def cfg():
    return load_config()


def test_reference_layout_by_hand(cfg):
    """Slot 150 mm^2, 27 wires per coil side in 14 rows of 2, fill 0.18, 36 turns, 0.065 ohm."""
    lay = winding_layout(cfg.motor)
    # sector between r 20 mm (bore 18.5 + tips 1.5) and 38 mm, 55 % of a 30 degree pitch
    area = 0.55 * math.pi * (0.038 ** 2 - 0.020 ** 2) / 12
    assert lay.slot_area_m2 == pytest.approx(area, rel=1e-12)
    # 9 turns x 3 strands; 17.5 mm of depth holds 20 rows of 0.86 mm: 2 columns, 14 rows
    assert (lay.conductors_per_side, lay.columns, lay.rows) == (27, 2, 14)
    assert lay.copper_fill == pytest.approx(2 * 27 * math.pi * 0.0008 ** 2 / 4 / area, rel=1e-12)
    assert 0.17 < lay.copper_fill < 0.19
    # 12 coils, 4 per phase in series: 36 turns; turn 2 (55 + 24) mm
    assert lay.series_turns == 36.0
    r20 = 1.7241e-8 * 0.158 * 36 / (3 * math.pi * 0.0008 ** 2 / 4)
    assert lay.resistance_20C_ohm == pytest.approx(r20, rel=1e-12)
    assert lay.resistance_20C_ohm == pytest.approx(0.060, rel=0.10)
    # both coil sides' 2 wires across the 8.35 mm mean breadth
    assert lay.porosity == pytest.approx(4 * 0.0008 / (0.55 * math.pi * 0.058 / 12), rel=1e-12)
    assert lay.series_turns == pytest.approx(implied_turns_per_phase(cfg.motor), rel=0.15)


@pytest.mark.parametrize('values, words', [
    ({'motor.winding.phase_resistance_20C_ohm': 0.040},
     ['phase_resistance_20C_ohm = 0.04', 'contradicts the wire', '0.06503 ohm', 'strands_in_hand',
      'end_turn_length_m', 'within 10%']),
    ({'motor.winding.turns_per_coil': 6, 'motor.winding.strands_in_hand': 2},
     ['24 series turns', 'torque_constant_Nm_A = 0.12', 'implies 36.5', 'within 15%']),
    ({'motor.winding.turns_per_coil': 40},
     ['do not fit the slot', 'turns_per_coil 40', 'insulated_diameter_m']),
    ({'motor.winding.insulated_diameter_m': 0.0007},
     ['insulated_diameter_m = 0.0007', 'conductor_diameter_m = 0.0008']),
    ({'motor.winding.parallel_paths': 3},
     ['12 coils do not share out', 'parallel_paths 3']),
])
def test_contradictions_stop_with_one_message(cfg, values, words):
    with pytest.raises(ConfigError) as err:
        with_values(cfg, values)
    text = str(err.value)
    assert '\n' not in text
    for w in words:
        assert w in text, (w, text)


@pytest.mark.parametrize('key', ['copper_fill', 'layers_per_slot_side'])
def test_retired_keys_say_what_replaces_them(tmp_path, key):
    text = default_config_path().read_text()
    bad = text.replace('    k_radial_W_mK: 0.9', f'    {key}: 2\n    k_radial_W_mK: 0.9', 1)
    path = tmp_path / 'old.yaml'
    path.write_text(bad)
    with pytest.raises(ConfigError, match=rf'motor\.winding\.{key}: no longer a key; .*give'):
        load_config(path)
