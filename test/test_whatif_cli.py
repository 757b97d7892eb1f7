"""``wet-eha-thermal whatif`` from a bag and cold (from a running estimator: its node test)."""


import numpy as np
import pytest
from wet_eha_thermal import cli, interface
from wet_eha_thermal.estimator.session import EstimatorSession
from wet_eha_thermal.offline import replay as rp

pytestmark = pytest.mark.slow     # measured: see docs/development.md#tests-and-ci


def _csv(path):
    data = np.genfromtxt(path, delimiter=',', names=True)
    return {name: data[name] for name in data.dtype.names}


def test_from_the_last_state_of_a_bag(record_rig_log, tmp_path, capsys):
    bag = record_rig_log(tmp_path / 'rig.mcap', 4.0)
    out = tmp_path / 'out'
    assert cli.main(['whatif', '--bag', str(bag), '--stage', '6', '--duration', '120',
                     '--out', str(out)]) == 0
    text = capsys.readouterr().out
    assert f'What-if from the last state of {bag} (its state at sample time ' in text
    assert 'winding hot-spot' in text and 'not within the run' in text
    table = _csv(out / 'whatif.csv')
    assert table['time_s'][0] == 0.0 and table['time_s'][-1] == 120.0
    # the first row is the state the replay ends in
    est = EstimatorSession(rp.ReplayOptions().plan(bag).cfg)
    rp.replay(rp.ReplayOptions().plan(bag), session=est)
    for q in interface.ESTIMATES:
        assert table[f'{q}_C'][0] == pytest.approx(est.latest.temperatures_C[q], abs=1e-4), q
    assert (out / 'whatif.png').stat().st_size > 10000


def test_cold_with_a_sensor_table_and_its_errors(tmp_path, capsys):
    samples = tmp_path / 'samples.csv'
    samples.write_text('# a steady load\ntime_s,current_A,speed_rad_s,p_a_Pa,p_b_Pa,p_acc_Pa\n'
                       '0,20,800,2e6,1e6,1e6\n10,20,800,2e6,1e6,1e6\n')
    out = tmp_path / 'out'
    assert cli.main(['whatif', '--cold', '--samples', str(samples), '--duration', '60',
                     '--ambient-C', '30', '--out', str(out)]) == 0
    assert 'What-if from cold: table of sensor signals (period 10 s), 60 s at ambient 30' \
        in capsys.readouterr().out
    assert _csv(out / 'whatif.csv')['oil_C'][0] == 30.0
    # a bad request is one line and status 2; nothing is written
    assert cli.main(['whatif', '--cold', '--stage', '6', '--duration', '1e6',
                     '--out', str(tmp_path / 'none')]) == 2
    assert 'duration_s = 1000000.0: expected a number in (0, 86400]' in capsys.readouterr().out
    assert not (tmp_path / 'none').exists()
    samples.write_text('time_s,current_A\n0,1\n1,1\n')
    assert cli.main(['whatif', '--cold', '--samples', str(samples), '--out', str(out)]) == 2
    assert "missing column 'speed_rad_s'" in capsys.readouterr().err
