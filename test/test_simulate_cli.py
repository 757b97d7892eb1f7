"""The ``simulate`` command: outputs, bad arguments, and the time-to-limit estimate."""

import contextlib
import csv
import functools
import io
import math

import numpy as np
import pytest
from wet_eha_thermal.cli import main
from wet_eha_thermal.offline import simulation
from wet_eha_thermal.offline.report import check_limit, fit_first_order, TABLE

PNG_MAGIC = b'\x89PNG\r\n\x1a\n'


def run(argv):
    """Run the command line in this process; return (status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(argv)
        except SystemExit as exc:  # argparse usage errors
            rc = exc.code
    return rc, out.getvalue(), err.getvalue()


@pytest.fixture(scope='module')
def stage_run(tmp_path_factory):
    out = tmp_path_factory.mktemp('sim') / 'out'
    rc, stdout, stderr = run(['simulate', '--stage', '6', '--duration', '20', '--dt', '0.1',
                              '--out', str(out)])
    return rc, stdout, stderr, out


@pytest.mark.slow
def test_stage_run_writes_csv_and_png(stage_run):
    rc, stdout, stderr, out = stage_run
    assert rc == 0, stderr
    with open(out / 'simulation.csv', newline='') as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 20
    assert [float(r['time_s']) for r in rows] == pytest.approx(np.arange(1.0, 21.0))
    columns = set(rows[0])
    for name in TABLE:
        assert f'{name}_C' in columns
    for name in ('current_A_rms', 'speed_rpm', 'p_a_MPa', 'p_b_MPa', 'motor_losses_W'):
        assert name in columns
    for r in rows:
        assert all(math.isfinite(float(v)) for v in r.values())
    assert float(rows[-1]['winding_hotspot_C']) > 20.0
    assert (out / 'simulation.png').read_bytes()[:8] == PNG_MAGIC


def test_stage_run_prints_table_limits_energy(stage_run):
    rc, stdout, stderr, out = stage_run
    assert stdout.startswith('Duty-cycle simulation: stage 6')
    for text in ('winding hot-spot', 'magnet (hottest)', 'pump case', 'accumulator', 'Limits',
                 'oil (hottest node)', 'Energy: electrical in', 'residual',
                 f'wrote {out / "simulation.csv"} and {out / "simulation.png"}'):
        assert text in stdout
    assert '/200 ' in stderr and '200/200 100%' in stderr   # progress on stderr
    assert 'error' not in stderr


@pytest.mark.slow
def test_duty_file_runs(tmp_path):
    duty = tmp_path / 'duty.csv'
    duty.write_text('# a small square-ish cycle\ntime_s,flow_L_min,load_MPa\n'
                    '0,3,4\n1,-3,4\n2,3,4\n')
    out = tmp_path / 'out'
    rc, stdout, stderr = run(['simulate', '--duty', str(duty), '--duration', '5',
                              '--ambient-C', '30', '--initial-C', '40', '--out', str(out)])
    assert rc == 0, stderr
    assert f'duty file {duty}' in stdout and 'ambient 30 degC, start 40 degC' in stdout
    with open(out / 'simulation.csv', newline='') as f:
        assert len(list(csv.DictReader(f))) == 5
    assert (out / 'simulation.png').is_file()


@pytest.mark.slow
def test_run_stopped_early_reports_and_writes(tmp_path, monkeypatch):
    runaway = getattr(simulation, 'ThermalRunaway', None)
    if runaway is None:
        pytest.skip('this simulation module does not stop runs early')
    real = simulation.simulate

    @functools.wraps(real)      # the command reads its options' defaults from simulate's
    def stops(cfg, duty, duration_s, **kw):
        res = real(cfg, duty, 5.0, **kw)
        res.append(5.5, res.model.outputs(), {}, dict(res.model.heat_W))
        raise runaway('thermal runaway: test', res)

    monkeypatch.setattr(simulation, 'simulate', stops)
    out = tmp_path / 'out'
    rc, stdout, stderr = run(['simulate', '--stage', '2', '--duration', '20', '--out', str(out)])
    assert rc == 1
    assert 'Run stopped early: thermal runaway: test' in stdout and 'Limits' in stdout
    assert stderr.splitlines()[-1].startswith('stopped at t = 5.5 s of 20 s')
    with open(out / 'simulation.csv', newline='') as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 6 and rows[-1]['current_A_rms'] == '' and rows[-1]['magnet_C'] != ''
    assert (out / 'simulation.png').is_file()


@pytest.mark.parametrize('args, expected', [
    (['--stage', '7'], ['--stage 7', 'valid stages: 1, 2, 3, 4, 5, 6']),
    (['--stage', '6', '--duration', '-10'], ['--duration -10', '> 0']),
    (['--stage', '6', '--duration', 'nan'], ['--duration nan']),
    (['--stage', '6', '--duration', '20', '--dt', '0'], ['--dt 0']),
    (['--stage', '6', '--duration', '20', '--dt', '30'], ['--dt 30', '--duration (20 s)']),
    (['--stage', '6', '--duration', '20', '--dt', '0.1', '--sample-rate-Hz', '4'],
     ['--sample-rate-Hz 4']),
    (['--stage', '6', '--duration', '20', '--initial-C', '200'],
     ['--initial-C 200', '-54..135 degC']),
    (['--stage', '6', '--duration', '20', '--ambient-C', '-80'], ['--ambient-C -80']),
    (['--stage', '6', '--duration', '20', '--fluid', 'water'], ['fluid.grade', 'water']),
    (['--duty', 'MISSING', '--duration', '20'], ['missing.csv', 'not found']),
    (['--duty', 'BAD', '--duration', '20'], ['line 4', "'abc' is not a number"]),
])
def test_bad_argument_gives_one_error_line(tmp_path, args, expected):
    bad = tmp_path / 'bad.csv'
    bad.write_text('time_s,flow_L_min,load_MPa\n0,1,2\n1,2,3\n2,abc,3\n')
    args = [str(tmp_path / 'missing.csv') if a == 'MISSING' else str(bad) if a == 'BAD' else a
            for a in args]
    out = tmp_path / 'out'
    rc, stdout, stderr = run(['simulate', *args, '--out', str(out)])
    assert rc == 2
    lines = stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith('error: '), stderr
    for text in expected:
        assert text in lines[0]
    assert 'Traceback' not in stderr and stdout == ''
    assert not out.exists()


@pytest.mark.parametrize('args', [[], ['--stage', '1', '--duty', 'x.csv'], ['--stage', 'two']])
def test_usage_errors_exit_2(tmp_path, args):
    out = tmp_path / 'out'
    rc, stdout, stderr = run(['simulate', *args, '--out', str(out)])
    assert rc == 2 and 'error:' in stderr
    assert not out.exists()


# ------------------------------------------------------------ time to limit
def first_order(t, T0, T_inf, tau):
    return T_inf - (T_inf - T0) * np.exp(-t / tau)


def test_extrapolation_recovers_known_exponential():
    t = np.arange(1.0, 1501.0)
    c = check_limit('w', t, first_order(t, 20.0, 220.0, 1000.0), 180.0)
    assert c.method == 'extrapolated'
    assert c.tau_s == pytest.approx(1000.0, rel=0.02)
    assert c.settles_C == pytest.approx(220.0, rel=0.02)
    assert c.time_to_limit_s == pytest.approx(1000.0 * math.log(200.0 / 40.0), rel=0.02)
    assert '(extrapolated)' in c.describe()


def test_extrapolation_tolerates_duty_ripple():
    t = np.arange(1.0, 1501.0)
    ripple = 0.3 * np.sin(2 * np.pi * t / 5.0) + np.random.default_rng(0).normal(0, 0.05, t.size)
    c = check_limit('w', t, first_order(t, 20.0, 220.0, 1000.0) + ripple, 180.0)
    assert c.tau_s == pytest.approx(1000.0, rel=0.02)
    assert c.time_to_limit_s == pytest.approx(1000.0 * math.log(5.0), rel=0.02)


def test_crossing_inside_the_run():
    t = np.arange(0.0, 601.0)
    T = first_order(t, 20.0, 220.0, 100.0)
    c = check_limit('w', t, T, 150.0)
    assert c.method == 'in run'
    assert c.time_to_limit_s == pytest.approx(100.0 * math.log(200.0 / 70.0), abs=0.5)
    assert c.peak_C == pytest.approx(T.max()) and c.peak_time_s == 600.0
    assert 'in the run' in c.describe()


def test_settling_below_the_limit_is_not_reached():
    t = np.arange(1.0, 1201.0)
    c = check_limit('w', t, first_order(t, 20.0, 120.0, 300.0), 135.0)
    assert c.time_to_limit_s is None
    assert c.settles_C == pytest.approx(120.0, rel=0.01)
    assert 'not reached (settles at 120.0 degC' in c.describe()


def test_flat_and_decreasing_histories():
    t = np.arange(1.0, 301.0)
    flat = check_limit('w', t, np.full(t.size, 50.0), 135.0)
    assert flat.time_to_limit_s is None and flat.settles_C == pytest.approx(50.0)
    falling = check_limit('w', t, first_order(t, 100.0, 40.0, 60.0), 135.0)
    assert falling.time_to_limit_s is None and falling.settles_C == pytest.approx(40.0, abs=0.5)
    assert falling.peak_time_s == 1.0 and falling.end_C < falling.peak_C


def test_straight_rise_extrapolates_linearly():
    t = np.arange(1.0, 301.0)
    c = check_limit('w', t, 20.0 + 0.1 * t, 135.0)
    assert c.method == 'extrapolated, linear'
    assert c.time_to_limit_s == pytest.approx(1150.0, rel=0.01)


def test_fit_needs_three_points():
    assert fit_first_order([0.0, 1.0], [20.0, 21.0]) is None
    assert check_limit('w', [1.0, 2.0], [20.0, 21.0], 135.0).method == 'unknown'
