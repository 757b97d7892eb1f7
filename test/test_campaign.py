"""
Campaigns on Dask: many logs replayed at once give their single replays' numbers, bit for bit.

A real cluster: ``dask scheduler`` and two ``dask worker`` processes on
localhost, started and killed by the tests; and the default local cluster of
``replay --workers``. The logs are four short runs of the simulated rig, each
a bag directory in one folder (a folder of bags). The reference is each log
replayed alone, in this process, as ``replay BAG`` does. ``calibrate
--scheduler`` must fit what the local path fits, to the last bit.
"""

import contextlib
import csv
from dataclasses import replace
import os
from pathlib import Path
import shutil
import signal
import socket
import subprocess
import sys

from distributed import Client
import pytest
from wet_eha_thermal import calibration as cb
from wet_eha_thermal.bag.reader import BagError, open_bag
from wet_eha_thermal.cli import main
from wet_eha_thermal.config import load_config, with_values
from wet_eha_thermal.offline import campaign
from wet_eha_thermal.offline import replay as rp

pytestmark = pytest.mark.slow     # measured: see docs/development.md#tests-and-ci

SECONDS = 4.0
STAGES = (1, 3, 5, 6)
START_S = 60.0            # for processes to start and workers to join, on a busy machine
SEAL = 'hydraulics.pump.extra_loss_W'


@pytest.fixture(scope='module')
def logs(tmp_path_factory, record_rig_log):
    """Return a folder of four bag directories, each holding SECONDS of one stage."""
    folder = tmp_path_factory.mktemp('campaign')
    for k, stage in enumerate(STAGES):
        (folder / f'log{k}_stage{stage}').mkdir()
        record_rig_log(folder / f'log{k}_stage{stage}' / 'run.mcap', SECONDS, stage, seed=k)
    return folder


@pytest.fixture(scope='module')
def serial(logs, tmp_path_factory):
    """
    Return, per log, its single replay's summary figures and output files (bytes).

    The campaigns here are about distributing replays: the outlook (the limits, done inline
    and compared bit for bit in test_replay.py) is off throughout, for speed.
    """
    out = tmp_path_factory.mktemp('serial')
    ref = {}
    for bag in sorted(logs.iterdir()):
        # the calls of ``replay BAG --no-report --no-outlook`` (cli/replay.py), once: its
        # outputs and the figures of the same result
        result = rp.replay(rp.plan_replay(bag), output_rate_Hz=rp.ReplayOptions().output_rate_Hz,
                           outlook=False)
        rp.write_outputs(result, out / bag.name, False)
        ref[bag.name] = (campaign.summarise(result), {
            name: (out / bag.name / name).read_bytes()
            for name in ('estimates.csv', 'estimates.mcap')})
    return ref


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def dask_cluster(folder: Path, workers: int = 2):
    """
    Start ``dask scheduler`` and ``workers`` ``dask worker`` processes on localhost.

    Yields (scheduler address, {worker address: its process}) once every
    worker has joined; kills them all on the way out, whatever happened.
    """
    address = f'tcp://127.0.0.1:{_free_port()}'
    dask = [sys.executable, '-m', 'dask']
    # no nanny: the process started is the worker, so killing it kills the worker. Dask's
    # health checks as the local cluster sets them (campaign.LOCAL_CLUSTER_CONFIG): at its
    # defaults each process wakes every 20 ms, for the whole module
    env = dict(os.environ, OPENBLAS_NUM_THREADS='1', **{
        'DASK_' + key.upper().replace('.', '__').replace('-', '_'): value
        for key, value in campaign.LOCAL_CLUSTER_CONFIG.items()})
    procs = []
    try:
        with open(folder / 'scheduler.log', 'w') as log:
            procs.append(subprocess.Popen(dask + ['scheduler', '--host', '127.0.0.1', '--port',
                                                  address.rsplit(':', 1)[1], '--no-dashboard',
                                                  '--dashboard-address', ':0'],
                                          stdout=log, stderr=log, env=env))
        for k in range(workers):
            with open(folder / f'worker{k}.log', 'w') as log:
                procs.append(subprocess.Popen(dask + ['worker', address, '--nthreads', '1',
                                                      '--no-nanny', '--no-dashboard'],
                                              stdout=log, stderr=log, env=env))
        with Client(address, timeout=START_S) as client:
            client.wait_for_workers(workers, timeout=START_S)
            pids = client.run(os.getpid)
        by_pid = {p.pid: p for p in procs[1:]}
        yield address, {w: by_pid[pid] for w, pid in pids.items()}
    finally:
        for p in reversed(procs):
            p.kill()
            p.wait(timeout=START_S)


@pytest.fixture(scope='module')
def cluster(tmp_path_factory):
    """Return the address of a scheduler with two workers, for the module."""
    with dask_cluster(tmp_path_factory.mktemp('cluster')) as (address, _):
        yield address


def read_rows(path: Path) -> list:
    with open(path, newline='') as f:
        return list(csv.DictReader(f))


def assert_as_serial(row: dict, out: Path, serial: dict) -> None:
    """Assert a campaign's row and outputs of one log equal its single replay's, bit for bit."""
    figures, files = serial[row['name']]
    assert row['status'] == 'ok', row
    for key, value in figures.items():
        # campaign.csv holds the repr of every float: it reads back exactly
        got = row[key] if not isinstance(row[key], str) or isinstance(value, str) \
            else type(value)(row[key])
        assert got == value, (row['name'], key)
    for name, data in files.items():
        assert (out / row['name'] / name).read_bytes() == data, (row['name'], name)


def test_a_folder_of_bags_expands_to_its_bag_directories(logs, tmp_path):
    bags = campaign.expand([logs])
    assert [b.name for b in bags] == sorted(b.name for b in logs.iterdir())
    # a bag directory (here one of its .mcap files makes it one) and a file stay as given
    assert campaign.expand([bags[0], tmp_path / 'x.mcap']) == [bags[0], tmp_path / 'x.mcap']
    # a folder of single-file logs is those logs; a folder of one split series is one bag
    loose = tmp_path / 'loose'
    loose.mkdir()
    for name in ('b.mcap', 'a.mcap', 'c_0.mcap'):
        shutil.copy(bags[0] / 'run.mcap', loose / name)
    assert campaign.expand([loose]) == [loose / 'a.mcap', loose / 'b.mcap', loose / 'c_0.mcap']
    with pytest.raises(BagError, match='3 separate logs'):
        open_bag(loose)
    series = tmp_path / 'series'
    series.mkdir()
    for k in (0, 1, 10):
        shutil.copy(bags[0] / 'run.mcap', series / f'run_{k}.mcap')
    assert campaign.expand([series]) == [series]
    assert campaign.output_names([Path('a/run.mcap'), Path('b/run'), Path('c/run_2.mcap'),
                                  Path('run.mcap')]) == ['run', 'run_2', 'run_2_2', 'run_3']


def test_a_campaign_on_a_scheduler_equals_the_single_replays(cluster, logs, serial, tmp_path,
                                                             capsys):
    out = tmp_path / 'out'
    assert main(['replay', str(logs), '--out', str(out), '--no-report', '--no-outlook',
                 '--scheduler', cluster]) == 0
    captured = capsys.readouterr()
    assert f'replaying 4 logs on 2 worker(s) at {cluster}' in captured.out
    assert '4/4' in captured.err
    rows = read_rows(out / 'campaign.csv')
    assert [r['name'] for r in rows] == sorted(serial)
    for row in rows:
        assert_as_serial(row, out, serial)
    assert (out / 'campaign.md').read_text().count('| ok |') == 4
    assert (out / 'campaign.png').stat().st_size > 0
    assert not list(out.rglob('*.partial*'))


def test_the_default_local_cluster_reports_failed_logs_and_completes_the_others(
        logs, serial, tmp_path, capsys):
    out = tmp_path / 'out'
    empty = tmp_path / 'empty.mcap'
    empty.write_bytes(b'')
    bags = sorted(logs.iterdir())
    argv = [str(b) for b in (bags[0], empty, tmp_path / 'missing.mcap', bags[1])]
    assert main(['replay', *argv, '--out', str(out), '--workers', '2', '--no-outlook']) == 1
    captured = capsys.readouterr()
    assert 'replaying 4 logs on 2 worker(s)' in captured.out
    assert '2 of 4 logs failed' in captured.err.splitlines()[-1]
    rows = read_rows(out / 'campaign.csv')
    assert [r['status'] for r in rows] == ['ok', 'failed', 'failed', 'ok']
    assert 'empty file (0 bytes)' in rows[1]['reason']
    assert 'No such file' in rows[2]['reason'] and rows[2]['peak_oil_C'] == ''
    for row in (rows[0], rows[3]):
        assert_as_serial(row, out, serial)
        assert (out / row['name'] / 'report.md').stat().st_size > 0
    report = (out / 'campaign.md').read_text()
    assert f'- missing (failed, {tmp_path / "missing.mcap"}): cannot open' in report


def test_the_local_cluster_runs_with_slower_health_checks():
    # what keeps Dask's own wake-ups from taking the GIL from the replays: the settings reach
    # the worker processes, not only the client
    import dask
    with campaign.dask_client(workers=1) as client:
        for key, value in campaign.LOCAL_CLUSTER_CONFIG.items():
            assert set(client.run(dask.config.get, key).values()) == {value}, key
            assert client.run_on_scheduler(dask.config.get, key) == value, key


def test_a_worker_killed_mid_run_costs_nothing(logs, serial, tmp_path):
    bags = campaign.expand([logs])
    killed = []
    with dask_cluster(tmp_path) as (address, workers), Client(address) as client:

        def on_done(done, total, row):
            # at the first result the other logs are still running or queued: kill a
            # worker that is busy with one; the scheduler gives its log to the other
            if not killed:
                busy = [w for w, keys in client.processing().items() if keys]
                assert busy
                workers[busy[0]].send_signal(signal.SIGKILL)
                killed.append(busy[0])

        rows = campaign.run(client, bags, tmp_path / 'out',
                            rp.ReplayOptions(report=False, outlook=False), on_done)
        assert workers[killed[0]].wait(timeout=START_S) == -signal.SIGKILL
    for row in rows:
        assert_as_serial(row, tmp_path / 'out', serial)


def test_calibration_on_dask_equals_the_local_path(cluster, record_rig_log, tmp_path):
    # a seal loss of 20 W, fitted from 10 W on a minute of stage 6 (the case oil shows it)
    nominal = load_config(overrides={'estimator.pressure_inputs': 'differential'})
    bag = record_rig_log(tmp_path / 'stage6.mcap', 60.0, 6, seed=6,
                         rig_cfg=with_values(nominal, {SEAL: 20.0}), rate_Hz=50.0, block_s=0.1)
    base = tmp_path / 'base.yaml'
    base.write_text(cb.config_yaml(with_values(nominal, {SEAL: 10.0})))
    config = rp.choose_config(open_bag(bag), base)
    local = cb.calibrate([cb.load_log(bag, config, config[0].calibration)], config[0], [SEAL],
                         jobs=1)
    seal = local.calibrated_cfg.hydraulics.pump.extra_loss_W
    assert 18.0 < seal < 22.0
    out = tmp_path / 'out'
    assert main(['calibrate', str(bag), '--config', str(base), '--fit', SEAL, '--out', str(out),
                 '--scheduler', cluster]) == 0
    fitted = load_config(out / cb.CALIBRATED_YAML)
    assert fitted.hydraulics.pump.extra_loss_W == seal
    # the interval and the errors before and after too: all but the time and the source
    same = {'created_utc': '', 'base_config': ''}
    assert replace(fitted.calibration.result, **same) == \
        replace(local.calibrated_cfg.calibration.result, **same)
