"""``wet-eha-thermal replay``: the estimator over recorded bags, offline; many are a campaign."""

import argparse
from pathlib import Path
import sys
from typing import List

from .arguments import (add_config, add_dask_arguments, add_out, BadArgument, dask, default,
                        positive)
from .console import Progress
from ..config import load_config

HELP = 'run the estimator over recorded bags, offline'
DESCRIPTION = ('Replay a rosbag2-style MCAP (ours, or ros2 bag record -s mcap with the same '
               'message types) through the estimator in sample time, as fast as it goes. Writes '
               'estimates.csv and estimates.mcap, the current limits for the drive as the live '
               'estimator computes them (limits.csv, and in the MCAP), and a report (report.md, '
               'PNG plots of inputs, temperatures, errors against the thermocouples, alerts and '
               'limits). The configuration is --config, else the one stored in the bag, else '
               'the reference rig. Several bags, or a folder of them, are a campaign: replayed '
               'in parallel on Dask, each into its own subfolder of --out, with a summary of all '
               '(campaign.csv, campaign.md, campaign.png).')


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``replay``; the defaults are :class:`ReplayOptions`'."""
    from ..offline.replay import ReplayOptions

    # not checked here: a campaign reports a missing log with the others' results
    p.add_argument('bag', type=Path, nargs='+',
                   help='an MCAP file, a rosbag2 bag directory (its files as one run), or a '
                        'folder of them')
    add_out(p, 'replay')
    add_config(p, 'stored in the bag, else the reference rig')
    p.add_argument('--inputs', type=Path, default=None, metavar='INPUTS_FILE',
                   help="the estimator's inputs file (topics, types, joints, units: "
                        'wet_eha_thermal/inputs.py), as the node took it (default: the one the '
                        'recorder stored in the bag, else the /eha topics)')
    p.add_argument('--map', action='append', default=[], metavar='NAME=/TOPIC',
                   help='topic of an input (current_A, speed_rad_s, p_a_Pa, p_b_Pa, p_acc_Pa, '
                        'dp_Pa, position_m), a thermocouple (measured/frame, ...) or ambient; '
                        'repeatable')
    p.add_argument('--output-rate-Hz', type=positive('Hz'),
                   default=default(ReplayOptions, 'output_rate_Hz'),
                   help='rate of the estimates written (default: %(default)g; the model steps '
                        'at 50 Hz)')
    p.add_argument('--prefix', default=None, metavar='/NAMESPACE',
                   help="topic prefix of estimates.mcap, as a live node's under it (default: "
                        'the one the bag was recorded under, else /eha)')
    p.add_argument('--no-report', action='store_true', help='skip the plots and report.md')
    p.add_argument('--open-loop', action='store_true',
                   help='do not let the thermocouples correct the model (estimator.correction '
                        'off): the errors against them then validate the model itself')
    p.add_argument('--no-outlook', action='store_true',
                   help='skip the current limits for the drive, the forecast and the margin '
                        '(limits.csv, the limit topics and columns): faster')
    add_dask_arguments(p.add_mutually_exclusive_group(), 'replays of a campaign')


def run(args: argparse.Namespace) -> int:
    """Replay one bag with the details on the console, or many as a campaign."""
    from ..offline import campaign
    from ..offline import replay as rp

    try:
        options = rp.ReplayOptions(config_path=args.config, mapping=rp.parse_mapping(args.map),
                                   inputs_path=args.inputs,
                                   output_rate_Hz=args.output_rate_Hz, report=not args.no_report,
                                   open_loop=args.open_loop, outlook=not args.no_outlook,
                                   prefix=args.prefix)
    except rp.ReplayError as exc:
        raise BadArgument(str(exc)) from None
    bags = campaign.expand(args.bag)
    if len(args.bag) == 1 and bags == args.bag:
        return _replay_one(args.bag[0], options, args.out)
    return _replay_campaign(bags, options, args)


def _plan_text(plan) -> str:
    """Return the two lines that say what a replay reads: the bag, its inputs, thermocouples."""
    info = plan.info
    return (f'{info.path}: {info.message_count} messages, '
            f'{(info.end_time_ns - info.start_time_ns) * 1e-9:.1f} s; configuration: '
            f'{plan.config_source}; inputs file: {plan.inputs_source}; outputs under '
            f'{plan.prefix}\n'
            'inputs: ' + ', '.join(f'{n} <- {t}' for n, t in plan.inputs.items())
            + (f'; no topic, on fallback: {", ".join(plan.missing)}' if plan.missing else '')
            + f'; thermocouples: {", ".join(plan.thermocouples) or "none"}')


def _result_text(result, errors) -> str:
    """Return what a replay did and its errors against the thermocouples."""
    lines = [f'replayed {result.messages} messages: {result.steps} steps, '
             f'{result.sample_time_s:.1f} s of sample time in {result.wall_s:.1f} s '
             f'({result.speed_x:.0f}x real time)']
    lines += [f'  {e["estimate"]:<17} - {tc:<17} max |e| {e["max_abs_K"]:5.2f} K, RMS '
              f'{e["rms_K"]:5.2f} K, bias {e["bias_K"]:+5.2f} K' for tc, e in errors.items()]
    return '\n'.join(lines)


def _replay_one(bag: Path, options, out: Path) -> int:
    """Replay one bag with progress and the details on the console (the original command)."""
    from ..offline import replay as rp

    try:
        plan = options.plan(bag)
    except rp.ReplayError as exc:
        raise BadArgument(str(exc)) from None
    info = plan.info
    print(_plan_text(plan))
    if info.truncated:
        print(f'warning: {info.path} is truncated ({info.problem}); replaying the '
              f'{info.message_count} messages that could be read', file=sys.stderr)
    out.mkdir(parents=True, exist_ok=True)
    progress = Progress()

    def on_progress(fraction: float, sample_s: float, wall_s: float) -> None:
        speed = sample_s / wall_s if wall_s > 0 else 0.0
        progress(int(round(1000 * fraction)), 1000,
                 f'{sample_s:.0f} s of log, {speed:.0f}x real time')

    try:
        result = rp.replay(plan, output_rate_Hz=options.output_rate_Hz, on_progress=on_progress,
                           outlook=options.outlook)
    except (rp.ReplayError, rp.BagError) as exc:
        raise BadArgument(str(exc)) from None
    progress(1000, 1000, 'done')
    files = rp.write_outputs(result, out, options.report)
    print(_result_text(result, rp.thermocouple_errors(result)))
    if result.truncated:
        print(f'warning: the bag ended early ({result.problem}): the outputs cover the '
              f'{result.messages} messages recovered', file=sys.stderr)
    print('wrote ' + ', '.join(str(f) for f in files))
    return 0


def _replay_campaign(bags: List[Path], options, args: argparse.Namespace) -> int:
    """Replay many bags on Dask, each into its own folder, and summarise them."""
    from ..offline import campaign

    if args.config is not None:
        load_config(args.config)         # a bad file is one error, not one per log
    out = args.out
    progress = Progress()

    def on_done(done: int, total: int, row: dict) -> None:
        what = 'failed' if row['status'] == 'failed' else f'{row["status"]} in ' \
            f'{row["wall_s"]:.1f} s'
        progress(done, total, f'{row["name"]}: {what}')

    with dask(args) as client:
        print(f'replaying {len(bags)} logs on {campaign.describe(client)} into {out}',
              flush=True)
        rows = campaign.run(client, bags, out, options, on_done)
    files = campaign.write_summary(rows, out)
    failed = [r for r in rows if r['status'] == 'failed']
    for r in rows:
        if r['reason']:
            print(f'{r["status"]}: {r["name"]} ({r["path"]}): {r["reason"]}', file=sys.stderr)
    print('wrote ' + ', '.join(str(f) for f in files))
    if failed:
        print(f'{len(failed)} of {len(rows)} logs failed', file=sys.stderr)
        return 1
    return 0
