"""Configuration: the shipped file loads; each bad value gives one clear error and stops."""

import csv

import pytest
from wet_eha_thermal.cli import main
from wet_eha_thermal.config import (config_value, ConfigError, default_config_path, load_config,
                                    with_values)
import yaml


def test_reference_config_loads_with_datasheet_values():
    cfg = load_config()
    assert cfg.motor.slices == 5
    assert cfg.motor.winding.phase_resistance_20C_ohm == 0.060
    assert cfg.motor.rotor.outer_radius_m == 0.018
    assert cfg.fluid.grade == 'MIL-PRF-5606'


def write_bad(tmp_path, edit):
    data = yaml.safe_load(default_config_path().read_text())
    edit(data)
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump(data))
    return path


def _del(d, *keys):
    for k in keys[:-1]:
        d = d[k]
    del d[keys[-1]]


def _set(d, value, *keys):
    for k in keys[:-1]:
        d = d[k]
    d[keys[-1]] = value


CASES = [
    ('missing key', lambda d: _del(d, 'motor', 'stator', 'bore_radius_m'),
     ['motor.stator.bore_radius_m', 'missing']),
    ('negative length', lambda d: _set(d, -0.11, 'motor', 'frame', 'length_m'),
     ['motor.frame.length_m', '-0.11', '(0, inf)']),
    ('inner radius not below outer', lambda d: _set(d, 0.06, 'motor', 'frame', 'inner_radius_m'),
     ['motor.frame.inner_radius_m', '0.06', 'motor.frame.outer_radius_m', '0.052']),
    ('unknown fluid', lambda d: _set(d, 'SAE-30', 'fluid', 'grade'),
     ['fluid.grade', 'SAE-30', 'MIL-PRF-5606', 'MIL-PRF-83282']),
    ('unknown key', lambda d: _set(d, 1.0, 'motor', 'frame', 'lenght_m'),
     ['motor.frame.lenght_m', 'unknown', 'length_m']),
    ('wrong type', lambda d: _set(d, 'five', 'motor', 'slices'),
     ['motor.slices', 'five', 'whole number']),
    ('magnets past the shaft', lambda d: _set(d, 0.02, 'motor', 'rotor', 'magnet_thickness_m'),
     ['motor.rotor.core_inner_radius_m', '0.007']),
]


@pytest.mark.parametrize('name, edit, words', CASES, ids=[c[0] for c in CASES])
def test_bad_config_gives_one_clear_error_and_nothing_runs(tmp_path, capsys, name, edit, words):
    path = write_bad(tmp_path, edit)
    with pytest.raises(ConfigError):
        load_config(path)
    out_dir = tmp_path / 'out'
    rc = main(['maps', '--config', str(path), '--out', str(out_dir)])
    captured = capsys.readouterr()
    assert rc == 2
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('error: '), captured.err
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert captured.out == ''          # nothing else ran
    assert not out_dir.exists()


def test_exponent_without_sign_is_read_as_a_number(tmp_path):
    path = write_bad(tmp_path, lambda d: _set(d, '2.0e4', 'hydraulics', 'pump',
                                              'viscous_friction_coeff'))
    assert load_config(path).hydraulics.pump.viscous_friction_coeff == 2.0e4


def test_command_line_override_is_validated_like_the_file(tmp_path, capsys):
    rc = main(['maps', '--oil-flow-L-min', '-1', '--out', str(tmp_path / 'o')])
    err = capsys.readouterr().err
    assert rc == 2 and 'maps.oil_flow_L_min = -1.0' in err


def test_unreadable_config_is_reported(tmp_path, capsys):
    rc = main(['maps', '--config', str(tmp_path / 'nope.yaml')])
    assert rc == 2 and 'cannot read config file' in capsys.readouterr().err


@pytest.mark.slow
def test_maps_command_writes_table_csv_and_plot(tmp_path, capsys):
    rc = main(['maps', '--out', str(tmp_path)])
    out = capsys.readouterr().out
    assert rc == 0
    assert 'Versus speed at 15 A' in out and 'Versus current at 10000 r/min' in out
    assert 'Re_axial' in out        # the laminar airgap flow is reported, not hidden
    with open(tmp_path / 'motor_maps.csv') as f:
        rows = list(csv.DictReader(f))
    cfg = load_config()
    assert len(rows) == len(cfg.maps.speeds_rpm) + len(cfg.maps.currents_A)
    assert {'winding_mean_C', 'winding_hotspot_C', 'frame_C', 'gap_friction_W',
            'bore_W'} <= set(rows[0])
    png = (tmp_path / 'motor_maps.png').read_bytes()
    assert png[:8] == b'\x89PNG\r\n\x1a\n' and len(png) > 20000


def test_with_values_sets_dotted_keys_and_validates_them():
    cfg = load_config()
    gap = cfg.motor.stator.frame_contact_gap_m
    truth = with_values(cfg, {'motor.stator.frame_contact_gap_m': 1.3 * gap,
                              'hydraulics.pump.extra_loss_W': 20.0})
    assert config_value(truth, 'motor.stator.frame_contact_gap_m') == pytest.approx(1.3 * gap)
    assert truth.hydraulics.pump.extra_loss_W == 20.0
    assert cfg.hydraulics.pump.extra_loss_W == 0.0        # the original is untouched
    with pytest.raises(ConfigError, match=r'hydraulics\.pump\.extra_loss_W = -1\.0: out of range'):
        with_values(cfg, {'hydraulics.pump.extra_loss_W': -1.0})
    with pytest.raises(ConfigError, match=r'motor\.stator\.no_such_key: no such key'):
        with_values(cfg, {'motor.stator.no_such_key': 1.0})
