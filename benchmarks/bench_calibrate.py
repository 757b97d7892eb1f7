"""
Calibration on three one-hour bench logs: wall time, and the parameters recovered vs the truth.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_calibrate.py
     [--dir DIR] [--minutes 60] [--stages 3 4 6] [--validate N ...] [--fit KEY ...]
     [--step S] [--jobs 2]

The logs come from the simulated rig running the known truth of docs/calibration.md: the reference
rig with a 30 % larger frame-yoke contact gap (30 % more contact resistance)
and a 20 W seal loss into the pump case oil. Each is what the recorder writes
(:func:`~wet_eha_thermal.offline.simulated_rig.write_rig_bag`): current, speed, one
differential pressure and position at 1 kHz from 20 ms truth steps,
thermocouples at 10 Hz, ambient at 1 Hz, and the nominal configuration stored
as the estimator's. They are written once (about 5 minutes per hour of log,
two at a time) and kept in ``--dir`` (default: a folder in the system's temp
directory) for later runs.

Stages 3, 4 and 6 by default: none runs away within the hour under the truth
(winding at most 76 degC, oil 74 degC; stage 1 passes 300 degC after 37
minutes and stage 2 reaches 164 degC), they load the rig differently (8, 6
and 0 MPa), and the fit's 1 s step is a whole number of their duty periods
(1, 0.5 and 1 s), where it is most accurate.

The calibration runs as the command does (``wet-eha-thermal calibrate``, in
this process); printed: its wall time in total and split into reading (with
pre-averaging and the files' sha256) and fitting, and the recovered
parameters against the truth.
"""

import argparse
from multiprocessing import get_context
from pathlib import Path
import sys
import tempfile
import time

GAP = 'motor.stator.frame_contact_gap_m'
SEAL = 'hydraulics.pump.extra_loss_W'


def truth_values(cfg) -> dict:
    """Return the truth rig's values: 30 % more contact gap, a 20 W seal loss."""
    return {GAP: 1.3 * cfg.motor.stator.frame_contact_gap_m, SEAL: 20.0}


def write_log(job: tuple) -> str:
    """Write one stage's log (in a worker process); return its path."""
    import yaml
    from wet_eha_thermal import interface
    from wet_eha_thermal.config import default_config_path, load_config, with_values
    from wet_eha_thermal.model.duty import stage_duty
    from wet_eha_thermal.offline.simulated_rig import SimulatedRig, write_rig_bag

    path, stage, minutes = job
    data = yaml.safe_load(default_config_path().read_text())
    data['estimator']['pressure_inputs'] = 'differential'
    meta = {interface.CONFIG_METADATA: {interface.CONFIG_METADATA_KEY: yaml.safe_dump(data)}}
    cfg = load_config(overrides={'estimator.pressure_inputs': 'differential'})
    truth = with_values(cfg, truth_values(cfg))
    t = time.perf_counter()
    partial = Path(path).with_suffix('.partial')
    partial.unlink(missing_ok=True)
    write_rig_bag(partial, SimulatedRig(truth, stage_duty(truth, stage), seed=stage),
                  minutes * 60.0, metadata=meta)
    partial.replace(path)
    print(f'wrote {path} in {time.perf_counter() - t:.0f} s', flush=True)
    return path


def main() -> None:
    """Write the logs if needed, calibrate, print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--dir', type=Path,
                        default=Path(tempfile.gettempdir()) / 'wet_eha_bench_calibrate')
    parser.add_argument('--minutes', type=float, default=60.0)
    parser.add_argument('--stages', type=int, nargs='+', default=[3, 4, 6])
    parser.add_argument('--validate', type=int, nargs='*', default=[],
                        help='held-out stages (not in the timing target)')
    parser.add_argument('--fit', nargs='+', default=None,
                        help='keys (default: calibration.fit of the configuration)')
    parser.add_argument('--step', type=float, default=None, help='calibration.step_s')
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args()
    print('command: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_calibrate.py '
          + ' '.join(sys.argv[1:]), flush=True)
    args.dir.mkdir(parents=True, exist_ok=True)
    paths = {s: args.dir / f'truth_stage{s}_{args.minutes:g}min.mcap'
             for s in args.stages + args.validate}
    todo = [(str(p), s, args.minutes) for s, p in paths.items() if not p.exists()]
    if todo:
        print(f'writing {len(todo)} log(s) of {args.minutes:g} min (about 5 min of CPU per '
              'hour of log, two at a time)', flush=True)
        with get_context('fork').Pool(min(2, len(todo))) as pool:
            pool.map(write_log, todo, chunksize=1)

    from wet_eha_thermal.cli import main as cli
    from wet_eha_thermal.config import load_config

    out = args.out or args.dir / 'out'
    argv = ['calibrate'] + [str(paths[s]) for s in args.stages]
    if args.validate:
        argv += ['--validate'] + [str(paths[s]) for s in args.validate]
    if args.fit:
        argv += ['--fit'] + args.fit
    argv += ['--out', str(out), '--jobs', str(args.jobs)]
    if args.step is not None:
        import yaml
        from wet_eha_thermal import interface
        from wet_eha_thermal.bag.reader import open_bag

        stored = open_bag(paths[args.stages[0]]).metadata[interface.CONFIG_METADATA]
        data = yaml.safe_load(stored[interface.CONFIG_METADATA_KEY])
        data['calibration']['step_s'] = args.step
        config = args.dir / f'config_step{args.step:g}.yaml'
        config.write_text(yaml.safe_dump(data))
        argv += ['--config', str(config)]
    print('wet-eha-thermal ' + ' '.join(argv), flush=True)
    t = time.perf_counter()
    rc = cli(argv)
    wall = time.perf_counter() - t
    if rc != 0:
        sys.exit(rc)
    cfg = load_config(out / 'calibrated.yaml')
    nominal = load_config()
    truth = truth_values(nominal)
    print(f'\ncalibration wall time: {wall:.1f} s in total (target: under 300 s)')
    print('recovered against the truth:')
    for p in cfg.calibration.result.parameters:
        want = truth.get(p.key, p.nominal)
        err = f'{100 * (p.value - want) / want:+.1f} %' if want else '-'
        ci = f'[{p.ci95_low:.4g}, {p.ci95_high:.4g}]' if p.ci95_low is not None else \
            'held: not identifiable'
        print(f'  {p.key:<42} nominal {p.nominal:<9.4g} fitted {p.value:<9.4g} truth '
              f'{want:<9.4g} error {err:>8}  95 % {ci}')


if __name__ == '__main__':
    main()
