"""
A golden replay: a fixed bag and what replay makes of it, to show a refactor changed nothing.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/golden_replay.py record DIR [--seconds 120]
     OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/golden_replay.py check DIR

``record`` writes ``DIR/rig.mcap``: ``--seconds`` of the simulated rig on
reference stage 6 (seed 1, the reference configuration with a differential
pressure input, as the tests' rig logs), then replays it through
``wet-eha-thermal replay`` twice, with the thermocouples correcting the model
(``DIR/closed``) and open loop (``DIR/open``), and stores the SHA-256 of the
bag and of each ``estimates.csv``, ``estimates.mcap`` and ``limits.csv`` (the
current limits for the drive, computed by default) in ``DIR/golden.txt``.
An MCAP's digest is that of its messages in order (topic, schema, log and
publish time, the serialised bytes, each length-prefixed), not of the file:
the bag writer closes a chunk after ``flush_interval_s`` of wall time too, so
where chunks end depends on the machine's speed, not on the data.

``check`` writes the bag again into a fresh folder, replays the stored bag
again both ways and compares every digest with the record. A
difference prints the first differing CSV line (and the largest difference
of each column) and exits 1. The bag and the estimates are written by the
package's public entry points, so the record made before a refactor checks
the code after it.
"""

import argparse
import csv
import hashlib
import os
from pathlib import Path
import subprocess
import sys
import tempfile

from mcap.reader import make_reader
from wet_eha_thermal import interface
from wet_eha_thermal.config import default_config_path, load_config
from wet_eha_thermal.model.duty import stage_duty
from wet_eha_thermal.offline.simulated_rig import SimulatedRig, write_rig_bag
import yaml

MODES = {'closed': [], 'open': ['--open-loop']}
OUTPUTS = ('estimates.csv', 'estimates.mcap', 'limits.csv')


def write_bag(path: Path, seconds: float) -> None:
    """Write the rig's log as the tests' ``record_rig_log`` fixture does (stage 6, seed 1)."""
    data = yaml.safe_load(default_config_path().read_text())
    data['estimator']['pressure_inputs'] = 'differential'
    meta = {interface.CONFIG_METADATA: {interface.CONFIG_METADATA_KEY: yaml.safe_dump(data)}}
    cfg = load_config(overrides={'estimator.pressure_inputs': 'differential'})
    write_rig_bag(path, SimulatedRig(cfg, stage_duty(cfg, 6), seed=1), seconds, metadata=meta)


def replay(bag: Path, out: Path, extra) -> None:
    """Run ``wet-eha-thermal replay`` as a user does, without the report."""
    subprocess.run([sys.executable, '-m', 'wet_eha_thermal.cli', 'replay', str(bag),
                    '--out', str(out), '--no-report', *extra], check=True)


def digest(path: Path) -> str:
    """Return the SHA-256 of a CSV's bytes, or of an MCAP's messages in order."""
    if path.suffix != '.mcap':
        return hashlib.sha256(path.read_bytes()).hexdigest()
    h = hashlib.sha256()
    with open(path, 'rb') as f:
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            for part in (channel.topic.encode(), schema.name.encode(), message.data):
                h.update(len(part).to_bytes(8, 'little'))
                h.update(part)
            h.update(message.log_time.to_bytes(8, 'little'))
            h.update(message.publish_time.to_bytes(8, 'little'))
    return h.hexdigest()


def first_difference(a: Path, b: Path) -> str:
    """Describe where two estimates CSVs part: the first line and each column's largest gap."""
    with open(a, newline='') as fa, open(b, newline='') as fb:
        ra, rb = list(csv.reader(fa)), list(csv.reader(fb))
    if ra[0] != rb[0]:
        return f'columns differ: {ra[0]} != {rb[0]}'
    if len(ra) != len(rb):
        return f'{len(ra)} rows in the record, {len(rb)} now'
    worst = {}
    first = None
    for i, (x, y) in enumerate(zip(ra[1:], rb[1:]), start=2):
        if x != y and first is None:
            first = i
        for name, u, v in zip(ra[0], x, y):
            try:
                gap = abs(float(u) - float(v))
            except ValueError:
                gap = 0.0 if u == v else float('inf')
            worst[name] = max(worst.get(name, 0.0), gap)
    lines = [f'first differing line: {first}']
    lines += [f'  {name}: largest difference {gap:.3g}'
              for name, gap in worst.items() if gap > 0]
    return '\n'.join(lines)


def record(folder: Path, seconds: float) -> int:
    """Write the bag and both replays, and their digests."""
    folder.mkdir(parents=True, exist_ok=True)
    bag = folder / 'rig.mcap'
    write_bag(bag, seconds)
    rows = [f'rig.mcap {digest(bag)}', f'seconds {seconds}']
    for mode, extra in MODES.items():
        replay(bag, folder / mode, extra)
        rows += [f'{mode}/{name} {digest(folder / mode / name)}' for name in OUTPUTS]
    (folder / 'golden.txt').write_text('\n'.join(rows) + '\n')
    print('\n'.join(rows))
    return 0


def check(folder: Path) -> int:
    """Make everything again and compare it with the record, byte for byte."""
    golden = dict(line.split(' ', 1) for line in (folder / 'golden.txt').read_text().splitlines())
    failed = 0
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        write_bag(tmp / 'rig.mcap', float(golden['seconds']))
        same = digest(tmp / 'rig.mcap') == golden['rig.mcap']
        print(f'rig.mcap: {"same" if same else "DIFFERENT"}')
        failed += not same
        for mode, extra in MODES.items():
            replay(folder / 'rig.mcap', tmp / mode, extra)
            for name in OUTPUTS:
                same = digest(tmp / mode / name) == golden[f'{mode}/{name}']
                print(f'{mode}/{name}: {"same" if same else "DIFFERENT"}')
                if not same:
                    failed += 1
                    if name.endswith('.csv'):
                        print(first_difference(folder / mode / name, tmp / mode / name))
    print('bit for bit the same' if not failed else f'{failed} file(s) differ')
    return 1 if failed else 0


def main(argv=None) -> int:
    """Parse the command line and record or check."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('action', choices=('record', 'check'))
    parser.add_argument('folder', type=Path)
    parser.add_argument('--seconds', type=float, default=120.0,
                        help='length of the rig log to record (default 120 s)')
    args = parser.parse_args(argv)
    os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
    if args.action == 'record':
        return record(args.folder, args.seconds)
    return check(args.folder)


if __name__ == '__main__':
    sys.exit(main())
