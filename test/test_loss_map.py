"""
An FEA loss map in the configuration: read and checked at load, used where it is made, flagged.

The map here is made of simple laws (each loss linear in speed and in I^2) on
a coarse grid: the model's bilinear table must then give them exactly
between the map's points, the copper must follow R(T) from the map's
temperature, and beyond the map the use must be flagged.
"""

import csv

import pytest

from wet_eha_thermal.config import ConfigError, default_config_path, load_config
from wet_eha_thermal.model.duty import stage_duty
from wet_eha_thermal.model.motor import MotorInputs, WetMotor
from wet_eha_thermal.model.oil import get_oil
from wet_eha_thermal.model.validity import ValidityLog
from wet_eha_thermal.offline.simulation import simulate
from wet_eha_thermal.units import C_TO_K, RPM
SPEEDS = (0.0, 5000.0, 12000.0, 20000.0)
CURRENTS = (0.0, 10.0, 25.0, 45.0)


def laws(rpm, amps):
    """Return the map's losses (W): copper 3 x 0.06 ohm x I^2 x 1.2 (an AC share), and the rest."""
    return {'copper_W': 3 * 0.06 * 1.2 * amps ** 2, 'stator_iron_W': 2e-3 * rpm,
            'magnet_W': 1e-3 * rpm + 0.01 * amps ** 2, 'sleeve_W': 5e-4 * rpm,
            'rotor_core_W': 0.002 * amps ** 2}


def write_map(path, rows=None, header=None):
    rows = rows if rows is not None else [
        (s, i, *laws(s, i).values()) for s in SPEEDS for i in CURRENTS]
    with open(path, 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(header or ['speed_rpm', 'current_A', 'copper_W', 'stator_iron_W', 'magnet_W',
                              'sleeve_W', 'rotor_core_W'])
        w.writerows(rows)
    return path


def config_with_map(tmp_path, name='fea.csv'):
    """Write the reference rig's YAML next to a map, naming it by a relative path."""
    text = default_config_path().read_text().replace(
        '  loss_map: null', f'  loss_map: {{file: {name}, copper_temperature_C: 20.0}}')
    cfg_path = tmp_path / 'rig.yaml'
    cfg_path.write_text(text)
    return cfg_path


def test_the_map_is_where_the_losses_come_from(tmp_path):
    write_map(tmp_path / 'fea.csv')
    cfg = load_config(config_with_map(tmp_path))
    assert cfg.motor.loss_map.file == str(tmp_path / 'fea.csv')   # from the file's folder
    log = ValidityLog()
    m = WetMotor(cfg.motor, get_oil(cfg.fluid.grade), log)
    rpm, amps = 7300.0, 17.0                        # between the map's points
    u = MotorInputs(current_sq_mean_A2=amps ** 2, speed_rad_s=rpm * RPM, oil_inlet_K=313.15,
                    oil_flow_m3_s=1 / 60000, ambient_K=293.15, case_pressure_Pa=6e5)
    m.initialise(20.0 + C_TO_K)                     # the copper at the map's 20 degC
    m.power_W = m.losses(u)
    got, want = m.losses_W, laws(rpm, amps)
    # linear in speed and in I^2: the resampled, bilinear table is exact
    assert got['magnet'] == pytest.approx(want['magnet_W'], rel=1e-9)
    assert got['sleeve'] == pytest.approx(want['sleeve_W'], rel=1e-9)
    assert got['rotor_core'] == pytest.approx(want['rotor_core_W'], rel=1e-9)
    assert got['core_yoke'] + got['core_teeth'] == pytest.approx(want['stator_iron_W'],
                                                                 rel=1e-9)
    assert got['copper_slot'] + got['copper_end'] == pytest.approx(want['copper_W'], rel=1e-9)
    # 50 K hotter, the DC copper follows R(T), x (1 + 0.00393 * 50), and the map's AC excess
    # over it 1 / R(T) (eddy currents, resistance limited)
    m.initialise(70.0 + C_TO_K)
    m.power_W = m.losses(u)
    hot = m.losses_W['copper_slot'] + m.losses_W['copper_end']
    k, dc = 1 + 0.00393 * 50.0, cfg.motor.winding.phases * 0.060 * amps ** 2
    assert hot == pytest.approx(dc * k + (want['copper_W'] - dc) / k, rel=1e-9)
    assert len(log) == 0
    # past the map: extrapolated and flagged
    u.speed_rad_s = 24000.0 * RPM
    m.losses(u)
    assert [(f.correlation.startswith('map '), f.quantity) for f in log] == [(True, 'speed_rpm')]


def test_a_run_on_the_map_closes_its_energy(tmp_path):
    """The kinetic model pays for the map's losses as the thermal model makes them."""
    write_map(tmp_path / 'fea.csv')
    cfg = load_config(config_with_map(tmp_path))
    res = simulate(cfg, stage_duty(cfg, 3), 60.0, dt_s=1.0)
    e = res.model.energy()
    put_in = res.electrical_J - res.load_work_J
    assert abs(e['stored'] + e['to_ambient'] - put_in) < 1e-3 * put_in
    assert res.heat_W['loss_magnet'][-1] > 1.0


@pytest.mark.parametrize('edit, message', [
    (lambda rows, header: (rows, header[:-2] + ['rotor_core_W']), 'no column sleeve_W'),
    (lambda rows, header: (rows[:-1], header), 'not a full grid'),
    (lambda rows, header: (rows[:3] + [(rows[3][0], rows[3][1], 'x', *rows[3][3:])]
                           + rows[4:], header), "line 5, copper_W: 'x' is not a number"),
    (lambda rows, header: (rows[:2] + [(rows[2][0], rows[2][1], -1.0, *rows[2][3:])]
                           + rows[3:], header), 'line 4, copper_W = -1.0'),
    (lambda rows, header: (rows, header + ['torque_Nm']), 'unknown column torque_Nm'),
])
def test_a_bad_map_stops_the_load_naming_key_file_and_line(tmp_path, edit, message):
    rows = [(s, i, *laws(s, i).values()) for s in SPEEDS for i in CURRENTS]
    header = ['speed_rpm', 'current_A', 'copper_W', 'stator_iron_W', 'magnet_W', 'sleeve_W',
              'rotor_core_W']
    rows, header = edit(rows, header)
    if len(header) > 7:
        rows = [r + (0.0,) for r in rows]
    write_map(tmp_path / 'fea.csv', rows, header)
    with pytest.raises(ConfigError, match='motor.loss_map.file') as err:
        load_config(config_with_map(tmp_path))
    assert message in str(err.value) and 'fea.csv' in str(err.value)


def test_a_missing_map_is_one_error(tmp_path):
    with pytest.raises(ConfigError, match=r'motor.loss_map.file = .*nowhere.csv.*cannot read'):
        load_config(config_with_map(tmp_path, 'nowhere.csv'))
