"""``wet-eha-thermal calibrate``: fit model parameters to the thermocouples of bench logs."""

import argparse
import contextlib
from pathlib import Path
import shlex
import sys
import time

from .arguments import add_dask_arguments, add_out, at_least, BadArgument, dask, existing

HELP = 'fit model parameters to the thermocouples of bench logs'
DESCRIPTION = ('Fit parameters of the thermal model (contact gaps, convection, loss and leakage '
               'coefficients, heat capacities: the keys with bounds in calibration.bounds) to '
               'the thermocouples of one or more MCAP logs, check the result on held-out logs, '
               'and write calibrated.yaml (loads as any configuration; records each value, its '
               '95 % interval and the logs) and report.md with plots. Parameters the logs '
               'cannot identify are held at their nominal values.')
#: Local worker processes by default (the fit's own default is one: no pool).
JOBS = 2


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``calibrate``."""
    p.add_argument('logs', type=existing, nargs='+', metavar='LOG',
                   help='logs to fit on: MCAP files or rosbag2 bag directories')
    p.add_argument('--validate', type=existing, nargs='+', default=[], metavar='LOG',
                   help='held-out logs (files or bag directories): errors before and after, '
                        'not fitted')
    p.add_argument('--fit', nargs='+', default=None, metavar='KEY',
                   help='dotted keys to fit, each with bounds in calibration.bounds (default: '
                        'calibration.fit)')
    p.add_argument('--config', type=Path, default=None,
                   help='YAML configuration (default: stored in the first log, else the '
                        'reference rig)')
    p.add_argument('--map', action='append', default=[], metavar='NAME=/TOPIC',
                   help='topic of an input, a thermocouple (measured/frame, ...) or ambient, as '
                        'for replay; repeatable')
    add_out(p, 'calibrate')
    where = p.add_mutually_exclusive_group()
    where.add_argument('--jobs', type=at_least(1, '', int), default=JOBS,
                       help='local worker processes evaluating the model (default: %(default)s)')
    add_dask_arguments(where, 'model runs')


def _read_logs(args: argparse.Namespace):
    """Return ``(config, keys, logs, read_s)``: every log planned (checked) before any is read."""
    from .. import calibration as cb
    from ..bag.reader import BagError, open_bag
    from ..offline.replay import choose_config, parse_mapping, ReplayError

    try:
        mapping = parse_mapping(args.map)
        config = choose_config(open_bag(args.logs[0]), args.config)
        keys = cb.fit_keys(config[0], args.fit)
        paths = list(args.logs) + list(args.validate)
        plans = [cb.plan_log(path, config, mapping) for path in paths]     # all checked first
        t0 = time.perf_counter()
        logs = []
        for k, (path, plan) in enumerate(zip(paths, plans)):
            print(f'reading {path} ({k + 1} of {len(paths)})', file=sys.stderr, flush=True)
            logs.append(cb.read_log(plan, config[0].calibration, path))
    except (BagError, ReplayError, cb.CalibrationError) as exc:
        raise BadArgument(str(exc)) from None
    return config, keys, logs, time.perf_counter() - t0


def run(args: argparse.Namespace) -> int:
    """Read the logs, fit, print the summary and write the outputs."""
    from .. import calibration as cb

    both = sorted({str(p) for p in args.logs} & {str(p) for p in args.validate})
    if both:
        raise BadArgument(f'{both[0]}: given both to fit on and to --validate: a held-out log '
                          'must not be fitted')
    config, keys, logs, read_s = _read_logs(args)
    cfg = config[0]
    print(f'configuration: {config[1]}; fitting {", ".join(keys)}')
    for k, log in enumerate(logs):
        role = 'fit' if k < len(args.logs) else 'held out'
        print(f'  {log.path} ({role}): {log.duration_s:.0f} s, thermocouples '
              f'{", ".join(log.thermocouples)}, start {log.start_C:.2f} degC')
        for w in log.warnings:
            print(f'warning: {w}', file=sys.stderr)
    t_fit = time.perf_counter()

    def say(text: str) -> None:
        print(f'[{time.perf_counter() - t_fit:6.1f} s] {text}', file=sys.stderr, flush=True)

    where = f'{args.jobs} jobs'
    try:
        with contextlib.ExitStack() as stack:
            client = None
            if args.workers is not None or args.scheduler is not None:
                from ..offline.campaign import describe
                client = stack.enter_context(dask(args))
                where = f'Dask, {describe(client)}'
                say(f'model runs on {where}')
            run = cb.calibrate(logs[:len(args.logs)], cfg, keys,
                               validate_logs=logs[len(args.logs):],
                               config_source=config[1], jobs=args.jobs, client=client,
                               on_progress=say)
    except cb.CalibrationError as exc:
        raise BadArgument(str(exc)) from None
    run.read_s = read_s
    command = 'wet-eha-thermal ' + ' '.join(shlex.quote(a) for a in args.argv)
    files = cb.write_outputs(run, args.out, command)
    print('\n' + cb.summary_text(run, cfg.calibration.residual_interval_s))
    for m in run.messages:
        print(f'warning: {m}', file=sys.stderr)
    print(cb.times_text(run, where))
    print('wrote ' + ', '.join(str(f) for f in files))
    return 0
