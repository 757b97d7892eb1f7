"""
Calibration on bench logs: a known truth recovered, identifiability, outputs, CLI, bad input.

The truth rig (docs/calibration.md, Measured on a known truth): the reference
rig with a 30 % larger frame-yoke contact gap (so 30 % more contact resistance)
and a 20 W seal loss into the pump case oil. The logs are made in memory by the
simulated rig with a 0.2 s truth step and 50 Hz samples (measured: the 10 s
means the fit compares, of every thermocouple's estimate, within 0.05 K of the
20 ms, 1 kHz rig after 300 s of stages 1 and 3, as with a 0.1 s step, for half
its CPU), thermocouples at 10 Hz with their 0.2 K noise and 1 s lag. Every log
is 600 s: long enough for the winding to rise 10-25 K and the contact gap to
show (winding minus frame), short enough that stage 1, which runs away within
the hour under the truth and costs three times the other stages per model run,
stays at about 65 degC; at 600 s the nominal model is already 2.3 K off the
held-out stage-4 winding.
"""

import math
import os
import signal
import time

from child_process import in_a_fresh_process
import numpy as np
import pytest
from wet_eha_thermal import calibration as cb
from wet_eha_thermal import processes
from wet_eha_thermal.bag.reader import iter_raw, open_bag
from wet_eha_thermal.bag.writer import BagWriter
from wet_eha_thermal.cli import main
from wet_eha_thermal.config import (config_from_yaml, ConfigError, default_config_path,
                                    load_config, with_values)
from wet_eha_thermal.estimator.session import EstimatorSession
from wet_eha_thermal.model.duty import stage_duty
from wet_eha_thermal.offline import replay as rp
from wet_eha_thermal.offline.simulated_rig import SimulatedRig
import yaml

pytestmark = pytest.mark.slow     # measured: see docs/development.md#tests-and-ci

GAP = 'motor.stator.frame_contact_gap_m'
SEAL = 'hydraulics.pump.extra_loss_W'
MAGNET_GLUE = 'motor.rotor.magnet_core_htc_W_m2K'     # no thermocouple sees the magnets
SECONDS = 600.0


def nominal_config():
    return load_config(overrides={'estimator.pressure_inputs': 'differential'})


def truth_values(cfg):
    return {GAP: 1.3 * cfg.motor.stator.frame_contact_gap_m, SEAL: 20.0}


def _rig_log(stage):
    cfg = nominal_config()
    truth = with_values(cfg, truth_values(cfg))
    rig = SimulatedRig(truth, stage_duty(truth, stage), rate_Hz=50.0, block_s=0.2, seed=stage)
    return cb.log_from_rig(rig, SECONDS, cfg.calibration, name=f'stage{stage}',
                           thermocouple_rate_Hz=10.0)


@pytest.fixture(scope='module')
def run():
    """Calibrate on stages 1-3, hold out 4-6; the magnets' glue is asked for too."""
    with processes.child_context().Pool(2) as pool:
        logs = pool.map(_rig_log, [1, 2, 3, 4, 5, 6], chunksize=1)
    return cb.calibrate(logs[:3], nominal_config(), [GAP, SEAL, MAGNET_GLUE],
                        validate_logs=logs[3:], jobs=2)


def test_recovers_the_truth_within_10_percent(run):
    truth = truth_values(nominal_config())
    fitted = {p.key: p for p in run.parameters}
    for key in (GAP, SEAL):
        p = fitted[key]
        print(f'{key}: nominal {p.nominal:.4g}, fitted {p.value:.4g}, truth {truth[key]:.4g}, '
              f'95 % interval {p.ci95[0]:.4g} .. {p.ci95[1]:.4g}, step shift '
              f'{p.step_shift:+.3g}')
        assert p.identifiable
        # the required tolerance; measured +2.3 % (gap) and -1.8 % (seal). What remains is
        # the fit step's own error (1 s is half of stage 2's period: up to 0.4 K on the oil)
        # and the sensor noise; without the fitted start offset the seal came out 5 % low
        assert abs(p.value - truth[key]) < 0.10 * truth[key]
        # the interval claims to hold the truth: it must (seeded data, so no 5 % lottery)
        assert p.ci95[0] < truth[key] < p.ci95[1]
        # and it is informative, not the bounds: less than a third of the value wide (the
        # gap's: 19 %, the seal's 8 %)
        assert p.ci95[1] - p.ci95[0] < 0.33 * truth[key]
    assert run.rms_after_K < 0.3 * run.rms_before_K


def test_held_out_winding_error_drops_below_1_5_K(run):
    before = {lf.log.name: lf.before['winding']['max_abs_K'] for lf in run.logs[3:]}
    after = {lf.log.name: lf.after['winding']['max_abs_K'] for lf in run.logs[3:]}
    for lf in run.logs[3:]:
        print('\n'.join([f'{lf.log.name}:'] + cb.error_table(lf)))
    assert [lf.role for lf in run.logs] == ['fit'] * 3 + ['validate'] * 3
    # the required accuracy: 1.5 degC max on the held-out stages (10 s means; measured 0.1-0.2 K,
    # and below 0.9 K against every single reading, whose noise is 0.2 K)
    assert max(after.values()) < 1.5
    assert max(lf.after['winding']['max_abs_raw_K'] for lf in run.logs[3:]) < 1.5
    # the nominal model misses stage 4 by 2.3 K: the test can fail
    assert before['stage4'] > 1.5
    # stage 6 (no load) barely involves the two parameters in the winding; its case oil
    # does (8.8 K before)
    assert run.logs[5].before['pump_case']['max_abs_K'] > 5.0
    assert run.logs[5].after['pump_case']['max_abs_K'] < 1.0


def test_an_unidentifiable_parameter_is_reported_and_held_at_nominal(run):
    p = {p.key: p for p in run.parameters}[MAGNET_GLUE]
    assert not p.identifiable and p.value == p.nominal == 3000.0 and p.ci95 is None
    assert 'changes no thermocouple' in p.note
    # it moves no reading by more than a few tenths of a kelvin across 300..30000 W/m2K
    assert p.effect_K < run.base_cfg.calibration.min_effect_K
    assert run.calibrated_cfg.motor.rotor.magnet_core_htc_W_m2K == 3000.0
    record = {r.key: r for r in run.calibrated_cfg.calibration.result.parameters}
    assert not record[MAGNET_GLUE].identifiable and record[MAGNET_GLUE].ci95_low is None


def test_calibrated_yaml_loads_and_runs_in_the_estimator(run, tmp_path):
    files = cb.write_outputs(run, tmp_path)
    assert [f.name for f in files[-2:]] == ['report.md', cb.CALIBRATED_YAML]
    assert not list(tmp_path.glob('*.partial*'))
    cfg = load_config(tmp_path / cb.CALIBRATED_YAML)
    assert cfg == run.calibrated_cfg
    fitted = {p.key: p for p in run.parameters}
    assert cfg.motor.stator.frame_contact_gap_m == fitted[GAP].value
    assert cfg.hydraulics.pump.extra_loss_W == fitted[SEAL].value
    assert cfg.estimator.step_s == 0.02            # the live twin's step, not the fit's
    rec = cfg.calibration.result
    assert [log.role for log in rec.logs] == ['fit'] * 3 + ['validate'] * 3
    assert rec.logs[0].path == 'stage1' and rec.logs[0].sha256 == ''    # made in memory
    seal = {r.key: r for r in rec.parameters}[SEAL]
    assert seal.ci95_low < seal.value < seal.ci95_high and seal.identifiable
    # the estimator runs on it as on any configuration
    est = EstimatorSession(cfg)
    log = run.logs[3].log
    # the fit itself runs open-loop, whatever the configuration says about the live correction
    correction = cb.run_config(with_values(cfg, {'estimator.correction.enabled': True}),
                               log).estimator.correction
    assert correction.enabled is False
    for name in est.inputs:
        t, v = log.inputs[name]
        est.add(name, t[:500], v[:500])
    estimates = est.step(all_steps=True)
    assert len(estimates) > 400 and math.isfinite(estimates[-1].temperatures_C['winding_mean'])
    report = (tmp_path / 'report.md').read_text()
    assert f'| {MAGNET_GLUE} |' in report and '**no**' in report
    assert '## Held-out logs' in report and '![stage4](stage4.png)' in report
    assert (tmp_path / 'stage4.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def short_log(cfg):
    """Return 30 s of stage 2 on the nominal rig."""
    rig = SimulatedRig(cfg, stage_duty(cfg, 2), rate_Hz=50.0, block_s=0.2, seed=2)
    return cb.log_from_rig(rig, 30.0, cfg.calibration, name='short', thermocouple_rate_Hz=10.0)


def assert_workers_give_the_inline_numbers():
    """Run two parameter sets on a short log inline and in two workers: the same numbers."""
    cfg = nominal_config()
    log = short_log(cfg)
    values = [cfg.motor.stator.frame_contact_gap_m, 10.0]
    sets = [values, [1.3 * values[0], 20.0]]
    runs = []
    for jobs in (1, 2):
        evaluator = cb.Evaluator([log], [cb.run_config(cfg, log)], [GAP, SEAL], jobs=jobs)
        try:
            runs.append(evaluator.run(sets, [[0], [0]]))
        finally:
            evaluator.close()
    inline, workers = runs
    for a, b in zip(inline, workers):
        assert np.array_equal(a[0][0], b[0][0]) and np.array_equal(a[0][1], b[0][1])
    # the two sets differ: the comparison can fail
    assert not np.array_equal(inline[0][0][1], inline[1][0][1])


def test_workers_from_the_fork_server_give_the_inline_numbers(monkeypatch):
    # what a caller that runs threads (a notebook, a ROS node, this test process) gets
    monkeypatch.setattr(processes, 'can_fork', lambda: False)
    assert_workers_give_the_inline_numbers()


def test_forked_workers_give_the_inline_numbers():
    in_a_fresh_process('test_calibration', 'assert_workers_give_the_inline_numbers')


def test_a_set_the_model_fails_on_or_a_worker_that_dies_fails_the_run_and_says_so():
    # killed by the kernel's out-of-memory killer or by hand: the run must stop with a message,
    # not wait for ever for the task the worker held (as a multiprocessing Pool did). The one
    # test of the evaluator's failures, so first a set the model fails on
    cfg = nominal_config()
    log = short_log(cfg)
    values = [cfg.motor.stator.frame_contact_gap_m, 10.0]
    evaluator = cb.Evaluator([log], [cb.run_config(cfg, log)], [GAP, SEAL], jobs=2)
    try:
        # a set the model fails on is named, and the workers live on
        with pytest.raises(cb.CalibrationError, match=f'short: the model failed with {GAP} = -1'):
            evaluator.run([values, [-1.0, 10.0]], [[0], [0]])
        evaluator.run([values], [[0]])
        # (the executor's private mapping is the one place that names its workers)
        worker = next(iter(evaluator.pool._processes.values()))
        os.kill(worker.pid, signal.SIGKILL)
        worker.join()
        end = time.monotonic() + 60.0                   # (a deadline, not a wait)
        while not evaluator.pool._broken and time.monotonic() < end:
            time.sleep(0.01)                            # its manager thread has seen it
        with pytest.raises(cb.CalibrationError, match='worker process died'):
            evaluator.run([values] * 4, [[0]] * 4)
    finally:
        evaluator.close()
    assert not worker.is_alive()


def test_screen_holds_weak_and_collinear_parameters():
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=200), rng.normal(size=200)
    # columns: a; b; 2a (the same effect as the first, as a gap and its gap conductivity);
    # a + b + tiny; weak
    jac = np.column_stack([a, b, 2 * a, a + b + 1e-3 * rng.normal(size=200), 0.01 * b])
    effect = np.array([1.0, 0.8, 2.0, 1.5, 0.01])
    kept, held, index = cb.screen(jac, effect, min_effect_K=0.5, max_collinearity=20.0)
    # largest effect first: 2a is kept, a then held as its copy; a + b is kept before b,
    # which is then nearly its combination with 2a
    assert kept == [2, 3]
    assert 'collinearity' in held[0] and 'collinearity' in held[1]
    assert 4 in held and 'changes no thermocouple' in held[4]
    assert index[0] > 1e6
    # independent columns are all kept
    kept, held, _ = cb.screen(np.column_stack([a, b]), np.array([1.0, 1.0]), 0.5, 20.0)
    assert kept == [0, 1] and not held


def test_effective_samples_counts_autocorrelated_residuals_as_fewer():
    rng = np.random.default_rng(5)
    white = rng.normal(size=1000)
    assert 700 < cb.effective_samples([white]) <= 1000
    walk = np.cumsum(rng.normal(size=1000))          # what a model error looks like
    assert cb.effective_samples([walk]) < 100


def test_inputs_are_averaged_onto_the_grid():
    calib = nominal_config().calibration          # 50 Hz: bins (k/50, (k+1)/50]
    t = np.arange(1, 101) * 1e-3                  # 1 kHz for 0.1 s; 20 ms on a bin end
    current = cb.InputAverager('current_A', calib.average_rate_Hz)
    current.add(t[:37], np.where(t[:37] < 0.02 + 1e-9, 3.0, 4.0))
    current.add(t[37:], np.where(t[37:] < 0.02 + 1e-9, 3.0, 4.0))   # a bin across two chunks
    stamps, values = current.result()
    assert np.allclose(stamps, [0.02, 0.04, 0.06, 0.08, 0.10])
    assert np.allclose(values, [3.0, 4.0, 4.0, 4.0, 4.0])
    mixed = cb.InputAverager('current_A', 50.0)
    mixed.add(np.array([0.001, 0.002]), np.array([3.0, 4.0]))
    assert mixed.result()[1][0] == pytest.approx(math.sqrt(12.5))   # RMS, not the mean
    speed = cb.InputAverager('speed_rad_s', 50.0)
    speed.add(t, t * 1000.0)
    assert np.allclose(speed.result()[1], [10.5, 30.5, 50.5, 70.5, 90.5])
    position = cb.InputAverager('position_m', 50.0)
    position.add(t, t)
    assert np.allclose(position.result()[1], [0.02, 0.04, 0.06, 0.08, 0.10])   # sampled


# ------------------------------------------------------------------ configuration
def _reference(edit):
    data = yaml.safe_load(default_config_path().read_text())
    edit(data['calibration'])
    return yaml.safe_dump(data)


BAD_CALIBRATION = [
    (lambda c: c['bounds'].update({GAP: [4e-5, 1e-4]}),
     [f'calibration.bounds.{GAP} = [4e-05, 0.0001]', 'does not hold', '3e-05']),
    (lambda c: c['bounds'].update({'motor.stator.no_such_gap_m': [0.0, 1.0]}),
     ['calibration.bounds.motor.stator.no_such_gap_m', 'no such key']),
    (lambda c: c['bounds'].update({'motor.slices': [1, 10]}),
     ['calibration.bounds.motor.slices', 'not a number that can be fitted']),
    (lambda c: c['bounds'].update({'estimator.step_s': [0.01, 1.0]}),
     ['calibration.bounds.estimator.step_s', 'not a parameter of the thermal model']),
    (lambda c: c['bounds'].update({GAP: [1e-4, 1e-5]}),
     [f'calibration.bounds.{GAP} = [0.0001, 1e-05]', 'low < high']),
    (lambda c: c['bounds'].update({GAP: [1e-5, 2e-3]}),
     [f'calibration.bounds.{GAP} = 0.002', 'out of range', '(0, 0.001]']),
    (lambda c: c.update({'fit': [GAP, 'hydraulics.pump.coulomb_torque_Nm']}),
     ["calibration.fit[1] = 'hydraulics.pump.coulomb_torque_Nm'", 'has no bounds']),
    (lambda c: c.update({'step_s': 0.35}),
     ['calibration.average_rate_Hz = 50.0', 'whole number', 'step_s = 0.35']),
    (lambda c: c.update({'check_step_s': 1.0}),
     ['calibration.check_step_s = 1.0', 'below']),
]


@pytest.mark.parametrize('edit, words', BAD_CALIBRATION)
def test_a_bad_calibration_entry_is_one_clear_error(edit, words):
    with pytest.raises(ConfigError) as info:
        config_from_yaml(_reference(edit))
    for w in words:
        assert w in str(info.value), (w, str(info.value))


def test_configs_without_a_calibration_section_still_load():
    data = yaml.safe_load(default_config_path().read_text())
    del data['calibration']
    cfg = config_from_yaml(yaml.safe_dump(data))
    assert cfg.calibration.step_s == 1.0 and cfg.calibration.bounds == {}
    assert with_values(cfg, {SEAL: 5.0}).hydraulics.pump.extra_loss_W == 5.0
    with pytest.raises(cb.CalibrationError, match=f'--fit {SEAL}: has no bounds'):
        cb.fit_keys(cfg, [SEAL])


# ----------------------------------------------------------------------- command
CLI_SECONDS = 120.0


@pytest.fixture(scope='module')
def bags(tmp_path_factory, record_rig_log):
    """Small logs as the recorder writes them, the nominal configuration stored."""
    cfg = nominal_config()
    truth = with_values(cfg, truth_values(cfg))
    folder = tmp_path_factory.mktemp('logs')
    return {stage: record_rig_log(folder / f'stage{stage}.mcap', CLI_SECONDS, stage, seed=stage,
                                  rig_cfg=truth, rate_Hz=50.0, block_s=0.2)
            for stage in (3, 4, 6)}


def test_command_end_to_end(bags, tmp_path, capsys):
    out = tmp_path / 'calibrated'
    rc = main(['calibrate', str(bags[3]), str(bags[4]), '--validate', str(bags[6]),
               '--fit', GAP, SEAL, '--out', str(out), '--jobs', '2'])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    assert 'configuration: stored in stage3.mcap' in captured.out
    assert 'stage6.mcap (held out)' in captured.out and 'wall time: reading' in captured.out
    assert 'iteration 1: cost' in captured.err and 'reading ' in captured.err
    for name in ('calibrated.yaml', 'report.md', 'stage3.png', 'stage4.png', 'stage6.png'):
        assert (out / name).stat().st_size > 0, name
    assert not list(out.glob('*.partial*'))
    cfg = load_config(out / 'calibrated.yaml')
    rec = cfg.calibration.result
    assert [log.path for log in rec.logs] == [str(bags[3]), str(bags[4]), str(bags[6])]
    assert all(len(log.sha256) == 64 for log in rec.logs)
    assert rec.logs[0].size_bytes == bags[3].stat().st_size
    assert {p.key for p in rec.parameters} == {GAP, SEAL}
    # two minutes hold less information than ten, but the seal loss shows in the case oil
    seal = cfg.hydraulics.pump.extra_loss_W
    assert 10.0 < seal < 30.0
    text = (out / 'calibrated.yaml').read_text()
    assert text.startswith('# Calibrated by wet-eha-thermal calibrate')
    report = (out / 'report.md').read_text()
    assert f'Command: `wet-eha-thermal calibrate {bags[3]}' in report
    assert '### stage6.mcap' in report
    # the replay takes the calibrated file as any configuration
    plan = rp.plan_replay(bags[6], config_path=out / 'calibrated.yaml')
    assert plan.cfg.hydraulics.pump.extra_loss_W == seal


def test_a_topic_mapped_to_two_thermocouples_feeds_both(bags):
    config = rp.choose_config(open_bag(bags[3]), None)
    topic = '/eha/measured/chamber_a'
    log = cb.load_log(bags[3], config, config[0].calibration, {'measured/chamber_b': topic})
    assert log.thermocouples['chamber_a'][0].size > 0
    for a, b in zip(log.thermocouples['chamber_a'], log.thermocouples['chamber_b']):
        assert np.array_equal(a, b)


def _without_thermocouples(bag, path):
    info = open_bag(bag)
    keep = [t for t in info.topics if not t.startswith('/eha/measured/')]
    with BagWriter(path) as w:
        for topic in keep:
            w.add_topic(topic, info.topics[topic].type_name, None)
        for m in iter_raw(bag, keep):
            w.write(m.topic, m.data, m.log_time_ns)
    return path


def test_bad_input_is_one_error_line_and_nothing_written(bags, tmp_path, capsys):
    out = tmp_path / 'out'
    text_file = tmp_path / 'notes.mcap'
    text_file.write_text('not a bag\n')
    no_tc = _without_thermocouples(bags[3], tmp_path / 'no_tc.mcap')
    log = str(bags[3])
    cases = [
        ([str(text_file)], 'not an MCAP file'),
        ([log, '--validate', str(no_tc)], 'no thermocouple topics'),
        ([log, '--fit', 'motor.stator.no_such_gap_m'], 'no such key'),
        ([log, '--fit', 'hydraulics.pump.coulomb_torque_Nm'], 'has no bounds'),
        ([log, '--fit', 'fluid.grade'], 'not a parameter of the thermal model'),
        ([log] + [f'--map={n}=/rig/{n}' for n in ('current_A', 'speed_rad_s', 'dp_Pa',
                                                  'position_m')],
         'no topic of the mapping is in the bag'),
        ([log, '--map', 'measured/frame=/rig/frame_tc'], 'no such topic'),
        ([log, '--validate', log], 'given both to fit on and to --validate'),
        ([log, '--jobs', '0'], '--jobs 0'),
        ([log, '--workers', '0'], '--workers 0'),
    ]
    for argv, expected in cases:
        assert main(['calibrate'] + argv + ['--out', str(out)]) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith('error:') and expected in err[0], (argv, err)
    assert not out.exists()
