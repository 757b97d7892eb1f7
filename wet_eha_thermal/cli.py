"""
Command-line entry point: ``wet-eha-thermal <command> ...``.

Every command reports bad input as one line on stderr (``error: ...``) and
exits with status 2, without a traceback; nothing runs after a bad config.
"""

import argparse
import contextlib
import math
from pathlib import Path
import shlex
import sys
import time
from typing import List, Optional, Tuple

from . import interface
from .config import ConfigError, load_config
from .model.kinetics import DutyError
from .model.validity import ValidityLog


class BadArgument(ValueError):
    """A command-line value that is out of range; the message names the option and value."""


class Progress:
    """Progress on stderr: one updating line on a terminal, a line per step otherwise."""

    def __init__(self, stream=None) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.tty = self.stream.isatty()
        self.t0 = time.monotonic()

    def __call__(self, done: int, total: int, label: str) -> None:
        """Report that ``done`` of ``total`` items are finished; ``label`` names the next."""
        pct = 100.0 * done / max(total, 1)
        bar = '#' * int(pct / 5)
        text = (f'[{bar:<20}] {done}/{total} {pct:3.0f}% {time.monotonic() - self.t0:5.1f}s '
                f'{label}')
        if self.tty:
            end = '\n' if done >= total else ''
            self.stream.write('\r' + text.ljust(100) + end)
        else:
            self.stream.write(text + '\n')
        self.stream.flush()


def _add_duty_arguments(p: argparse.ArgumentParser, required: bool) -> None:
    """Add the --stage | --duty choice (one of them; stage 6 when neither is required)."""
    which = p.add_mutually_exclusive_group(required=required)
    which.add_argument('--stage', type=int, default=None,
                       help='reference stage number (1-6)' + ('' if required else '; default 6'))
    which.add_argument('--duty', type=Path, metavar='FILE.csv',
                       help='duty table: time_s, flow_L_min, load_MPa (repeats periodically)')


def _add_dask_arguments(group, what: str) -> None:
    """Add --workers N | --scheduler ADDRESS: where ``what`` run on Dask."""
    group.add_argument('--workers', type=int, default=None, metavar='N',
                       help=f'run the {what} on a local Dask cluster of N processes (default '
                            'for a campaign: one per CPU)')
    group.add_argument('--scheduler', default=None, metavar='ADDRESS',
                       help=f'run the {what} on the Dask cluster of this scheduler, e.g. '
                            'tcp://host:8786 (its workers must see the same paths)')


def _add_maps_parser(sub) -> None:
    """Add the ``maps`` command: steady-state maps."""
    p = sub.add_parser('maps', help='steady-state motor temperatures versus speed and current',
                       description='Steady-state winding, frame, magnet and oil temperatures of '
                                   'the wet motor versus speed and versus current; prints two '
                                   'tables, writes a CSV and a PNG plot.')
    p.add_argument('--config', type=Path, default=None,
                   help='YAML configuration (default: the reference rig)')
    p.add_argument('--out', default='out/maps', help='output folder (default: %(default)s)')
    p.add_argument('--oil-inlet-C', type=float, default=None,
                   help='oil inlet temperature, degC (default: from config)')
    p.add_argument('--oil-flow-L-min', type=float, default=None,
                   help='oil flow through the motor, L/min (default: from config)')
    p.add_argument('--ambient-C', type=float, default=None, help='ambient temperature, degC')
    p.add_argument('--slices', type=int, default=None, help='axial slices of the stack')
    p.add_argument('--fluid', default=None, help='oil grade (MIL-PRF-5606 or MIL-PRF-83282)')
    p.set_defaults(func=_maps)


def _maps(args: argparse.Namespace) -> int:
    from .offline import maps

    overrides = {}
    for key, value in (('maps.oil_inlet_C', args.oil_inlet_C),
                       ('maps.oil_flow_L_min', args.oil_flow_L_min),
                       ('maps.ambient_C', args.ambient_C),
                       ('motor.slices', args.slices),
                       ('fluid.grade', args.fluid)):
        if value is not None:
            overrides[key] = value
    cfg = load_config(args.config, overrides)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    job = cfg.maps
    print(f'Motor maps: {cfg.fluid.grade} at {job.oil_inlet_C:g} degC inlet, '
          f'{job.oil_flow_L_min:g} L/min through the motor, ambient {job.ambient_C:g} degC, '
          f'{cfg.motor.slices} axial slices')
    log = ValidityLog()
    points = maps.compute_maps(cfg, Progress(), log)
    print(f'\nVersus speed at {job.sweep_current_A:g} A:')
    print(maps.format_table(points, 'speed'))
    print(f'\nVersus current at {job.sweep_speed_rpm:.0f} r/min:')
    print(maps.format_table(points, 'current'))
    csv_path, png_path = out / 'motor_maps.csv', out / 'motor_maps.png'
    maps.write_csv(points, csv_path)
    maps.plot_maps(points, png_path, f'Wet motor steady state: {cfg.fluid.grade}, oil in '
                   f'{job.oil_inlet_C:g} degC at {job.oil_flow_L_min:g} L/min, ambient '
                   f'{job.ambient_C:g} degC')
    if len(log):
        print('\nCorrelations used outside their validated range:')
        for flag in log:
            print(f'  - {flag}')
    print(f'\nwrote {csv_path} and {png_path}')
    return 0


def _add_simulate_parser(sub) -> None:
    """Add the ``simulate`` command: a duty cycle run offline."""
    p = sub.add_parser('simulate', help='temperatures over a duty cycle (a stage or a duty file)',
                       description='Run the coupled thermal model over a duty cycle: a reference '
                                   'stage or a duty CSV (columns time_s, flow_L_min, load_MPa). '
                                   'Prints end and peak temperatures and when each limit is or '
                                   'would be reached; writes a CSV and a PNG plot.')
    _add_duty_arguments(p, required=True)
    p.add_argument('--duration', type=float, default=3600.0,
                   help='simulated time, s (default: %(default)g)')
    p.add_argument('--ambient-C', type=float, default=20.0,
                   help='ambient temperature, degC (default: %(default)g)')
    p.add_argument('--initial-C', type=float, default=None,
                   help='starting temperature of every node, degC (default: ambient)')
    p.add_argument('--dt', type=float, default=1.0,
                   help='thermal model step, s (default: %(default)g)')
    p.add_argument('--sample-rate-Hz', type=float, default=200.0,
                   help='sensor sample rate, Hz (default: %(default)g)')
    p.add_argument('--config', type=Path, default=None,
                   help='YAML configuration (default: the reference rig)')
    p.add_argument('--out', default='out/simulate', help='output folder (default: %(default)s)')
    p.add_argument('--fluid', default=None, help='oil grade (MIL-PRF-5606 or MIL-PRF-83282)')
    p.set_defaults(func=_simulate)


def _check_simulate_args(args: argparse.Namespace) -> None:
    """Raise :class:`BadArgument` for the first out-of-range option that needs no config."""
    from .model.kinetics import STAGES

    if args.stage is not None and args.stage not in STAGES:
        raise BadArgument(f'--stage {args.stage}: unknown stage; valid stages: '
                          f'{", ".join(str(k) for k in STAGES)}')
    if not (math.isfinite(args.duration) and args.duration > 0.0):
        raise BadArgument(f'--duration {args.duration:g}: must be a number of seconds > 0')
    if not (math.isfinite(args.dt) and 0.0 < args.dt <= args.duration):
        raise BadArgument(f'--dt {args.dt:g}: must be > 0 s and at most --duration '
                          f'({args.duration:g} s)')
    samples = args.sample_rate_Hz * args.dt
    if not (math.isfinite(args.sample_rate_Hz) and round(samples) >= 1):
        raise BadArgument(f'--sample-rate-Hz {args.sample_rate_Hz:g}: gives {samples:.3g} '
                          f'samples per {args.dt:g} s step; needs at least 1, i.e. >= '
                          f'{1.0 / args.dt:g} Hz')


def _simulate(args: argparse.Namespace) -> int:
    from .offline import report
    from .model import quantity_table
    from .model.kinetics import L_MIN, load_duty_csv, MPA, stage_duty
    from .model.oil import OIL_GRADES
    from .offline import simulation
    from .offline.simulation import simulate
    from .units import C_TO_K

    _check_simulate_args(args)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise BadArgument(f'--out {out}: exists and is not a folder')
    cfg = load_config(args.config, {'fluid.grade': args.fluid} if args.fluid else None)
    grade = OIL_GRADES[cfg.fluid.grade]
    low, high = grade.T_min_K - C_TO_K, grade.T_max_K - C_TO_K
    initial_C = args.ambient_C if args.initial_C is None else args.initial_C
    for option, value in (('--ambient-C', args.ambient_C), ('--initial-C', initial_C)):
        if not (math.isfinite(value) and low <= value <= high):
            raise BadArgument(f'{option} {value:g}: outside the {grade.name} range '
                              f'{low:g}..{high:g} degC')
    act = cfg.hydraulics.actuator
    if args.stage is not None:
        duty = stage_duty(cfg, args.stage)
        st = duty.stage
        what = (f'stage {st.number} (load {st.load_dp_amplitude_Pa / MPA:g} MPa, flow '
                f'{st.flow_amplitude_m3_s / L_MIN:g} L/min, {st.frequency_Hz:g} Hz)')
    else:
        duty = load_duty_csv(args.duty, act.area_m2, act.half_stroke_m)
        what = f'duty file {args.duty} (period {duty.period_s:g} s)'
    title = (f'Duty-cycle simulation: {what}, {args.duration:g} s at dt {args.dt:g} s '
             f'({args.sample_rate_Hz:g} Hz samples), ambient {args.ambient_C:g} degC, '
             f'start {initial_C:g} degC, {cfg.fluid.grade}')
    print(title, flush=True)
    stopped = None
    try:
        res = simulate(cfg, duty, args.duration, dt_s=args.dt,
                       sample_rate_Hz=args.sample_rate_Hz, ambient_C=args.ambient_C,
                       initial_C=initial_C, progress=Progress())
    except getattr(simulation, 'ThermalRunaway', ()) as exc:  # carries the run so far
        stopped, res = exc, exc.result
        if not res.time_s:
            raise
    print()
    if stopped is not None:
        print(f'Run stopped early: {stopped}\nResults up to t = {res.time_s[-1]:g} s:\n')
    print(report.format_table(res))
    oil_lim, oil_src = quantity_table.limits_C(cfg)['oil'], quantity_table.LIMIT_KEYS['oil']
    _, hottest = report.hottest_oil_C(res)
    print('\nLimits: first crossing in the run, else extrapolated by a first-order fit to the '
          'last third of the run')
    print(report.format_limits(report.check_limits(res, cfg)))
    print(f'(oil limit {oil_lim:g} degC from {oil_src}; hottest oil node at the end: '
          f'{hottest.replace("_", " ")})')
    print('\nWhere the heat is made and where it goes, mean over the last duty period:')
    print(report.format_heat(res, duty.period_s))
    print('\n' + report.format_energy(report.energy_check(res)))
    log = res.model.log if res.model is not None else []
    if len(log):
        print('\nCorrelations used outside their validated range:')
        for flag in log:
            print(f'  - {flag}')
    csv_path, png_path = out / 'simulation.csv', out / 'simulation.png'
    try:
        out.mkdir(parents=True, exist_ok=True)
        report.write_csv(res, csv_path)
        stop = f' (stopped at {res.time_s[-1]:.0f} s)' if stopped is not None else ''
        report.plot(res, cfg, png_path, title.replace(', ambient', f'{stop},\nambient', 1),
                    duty.period_s)
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise BadArgument(f'--out {out}: cannot write the results: {reason}') from None
    print(f'\nwrote {csv_path} and {png_path}')
    if stopped is not None:
        print(f'stopped at t = {res.time_s[-1]:g} s of {args.duration:g} s: {stopped}',
              file=sys.stderr)
        return 1
    return 0


def _add_live_parser(sub) -> None:
    """Add the ``live`` command: the live twin."""
    p = sub.add_parser('live', help='the live digital twin: estimator on the simulated rig',
                       description='Run the live digital twin: the simulated rig (ROS 2 node '
                                   'eha_sim_rig) publishes the sensor topics of a stage or a duty '
                                   'file, the estimator (eha_thermal_estimator) follows them, and '
                                   'a status line shows the estimated temperatures, margin, time '
                                   'to limit, alerts and stale inputs. Ends after --duration or '
                                   'on Ctrl-C with a summary. The recorder (eha_recorder) writes '
                                   'the run to a rosbag2 bag of MCAP files. The nodes run on a '
                                   'private ROS domain (from the process id, or '
                                   '$WET_EHA_LIVE_DOMAIN_ID).')
    _add_duty_arguments(p, required=False)
    p.add_argument('--duration', type=float, default=60.0,
                   help='how long to run, s (default: %(default)g)')
    p.add_argument('--rate-Hz', type=float, default=1000.0,
                   help='sensor sample rate of the rig, Hz (default: %(default)g)')
    p.add_argument('--config', type=Path, default=None,
                   help='YAML configuration of rig and estimator (default: the reference rig)')
    p.add_argument('--no-noise', action='store_true', help='publish noise-free sensor values')
    p.add_argument('--executor', choices=('events', 'single'), default='events',
                   help='rclpy executor of both nodes (default: %(default)s)')
    p.add_argument('--record', type=Path, default=None, metavar='PATH',
                   help='recording of the run: a rosbag2 bag directory, as ros2 bag record -o '
                        'makes, or one MCAP file when PATH ends in .mcap; never overwritten '
                        '(default: runs/live_<UTC time>)')
    p.add_argument('--no-record', action='store_true', help='do not record the run')
    p.add_argument('--max-bag-size', type=int, default=interface.LIVE_SPLIT_BYTES,
                   metavar='BYTES',
                   help='start a new file of the recording after this many bytes, as ros2 bag '
                        'record -b; 0: no size split (default: %(default)d, 1 GiB)')
    p.add_argument('--max-bag-duration', type=float,
                   default=interface.LIVE_SPLIT_DURATION_S, metavar='SECONDS',
                   help='start a new file of the recording after this much time, as ros2 bag '
                        'record -d; 0: no time split (default: %(default)g s). Each closed '
                        'file is complete: a crash or a full disk cannot take the run whole')
    p.add_argument('--foxglove', default='127.0.0.1:8765', metavar='HOST:PORT',
                   help='where the estimator serves the Foxglove view (estimates with their '
                        'bands, margins, alerts, inputs, thermocouples; open it with '
                        'layouts/live.json); live prints the address to open; one taken is '
                        'one warning and the run goes on without it (default: %(default)s)')
    p.add_argument('--no-foxglove', action='store_true', help='no Foxglove view')
    p.add_argument('--closed-loop', action='store_true',
                   help="the rig's simulated drive honours the current limit the estimator "
                        'publishes (the load yields where the duty asks for more); the status '
                        'line and the summary show when it binds')
    p.set_defaults(func=_live)


def _check_live_args(args: argparse.Namespace) -> None:
    """Raise :class:`BadArgument` for the first out-of-range option of ``live``."""
    from .model.kinetics import STAGES

    if args.stage is not None and args.stage not in STAGES:
        raise BadArgument(f'--stage {args.stage}: unknown stage; valid stages: '
                          f'{", ".join(str(k) for k in STAGES)}')
    if not (math.isfinite(args.duration) and args.duration > 0.0):
        raise BadArgument(f'--duration {args.duration:g}: must be a number of seconds > 0')
    if not (math.isfinite(args.rate_Hz) and 50.0 <= args.rate_Hz <= 10000.0):
        raise BadArgument(f'--rate-Hz {args.rate_Hz:g}: must be 50..10000 Hz')
    if args.max_bag_size < 0:
        raise BadArgument(f'--max-bag-size {args.max_bag_size}: must be a number of bytes >= 0 '
                          '(0: no size split)')
    if not (math.isfinite(args.max_bag_duration) and args.max_bag_duration >= 0.0):
        raise BadArgument(f'--max-bag-duration {args.max_bag_duration:g}: must be a number of '
                          'seconds >= 0 (0: no time split)')


def _foxglove_address(text: str) -> Tuple[str, int]:
    """Return ``(host, port)`` of ``--foxglove``; :class:`BadArgument` if it is not one."""
    from .live_view import parse_address

    try:
        host, port = parse_address(text)
    except ValueError as exc:
        raise BadArgument(f'--foxglove {exc}') from None
    if port == 0:       # live prints the address to open: it must know it
        raise BadArgument(f'--foxglove {text}: give a port, 1..65535')
    return host, port


def _live(args: argparse.Namespace) -> int:
    from .model.kinetics import load_duty_csv, stage_duty

    _check_live_args(args)
    foxglove = None if args.no_foxglove else _foxglove_address(args.foxglove)
    # check the configuration and the duty here, so that a mistake is one line, not two
    # children failing
    cfg = load_config(args.config)
    act = cfg.hydraulics.actuator
    if args.duty is not None:
        load_duty_csv(args.duty, act.area_m2, act.half_stroke_m)
    stage = None if args.duty is not None else (args.stage or 6)
    if stage is not None:
        stage_duty(cfg, stage)
    from .ros import live, live_monitor

    try:
        domain = live_monitor.domain_from_env()
    except ValueError as exc:
        raise BadArgument(str(exc)) from None
    opts = live.LiveOptions(stage=stage, duty=args.duty, duration_s=args.duration,
                            rate_Hz=args.rate_Hz, config=args.config, noise=not args.no_noise,
                            executor=args.executor, record=not args.no_record,
                            record_path=args.record, max_bag_size_B=args.max_bag_size,
                            max_bag_duration_s=args.max_bag_duration, foxglove=foxglove,
                            closed_loop=args.closed_loop)
    return live.run(opts, domain=domain)


def _add_replay_parser(sub) -> None:
    """Add the ``replay`` command: replay of recorded bags."""
    p = sub.add_parser('replay', help='run the estimator over recorded bags, offline',
                       description='Replay a rosbag2-style MCAP (ours, or ros2 bag record -s mcap '
                                   'with the same message types) through the estimator in sample '
                                   'time, as fast as it goes. Writes estimates.csv and '
                                   'estimates.mcap, the current limits for the drive as the live '
                                   'estimator computes them (limits.csv, and in the MCAP), and a '
                                   'report (report.md, PNG plots of inputs, temperatures, errors '
                                   'against the thermocouples, alerts and limits). '
                                   'The configuration is --config, else the one stored in the '
                                   'bag, else the reference rig. Several bags, or a folder of '
                                   'them, are a campaign: replayed in parallel on Dask, each into '
                                   'its own subfolder of --out, with a summary of all '
                                   '(campaign.csv, campaign.md, campaign.png).')
    p.add_argument('bag', type=Path, nargs='+',
                   help='an MCAP file, a rosbag2 bag directory (its files as one run), or a '
                        'folder of them')
    p.add_argument('--out', default='out/replay', help='output folder (default: %(default)s)')
    p.add_argument('--config', type=Path, default=None,
                   help='YAML configuration (default: stored in the bag, else the reference rig)')
    p.add_argument('--map', action='append', default=[], metavar='NAME=/TOPIC',
                   help='topic of an input (current_A, speed_rad_s, p_a_Pa, p_b_Pa, p_acc_Pa, '
                        'dp_Pa, position_m), a thermocouple (measured/frame, ...) or ambient; '
                        'repeatable')
    p.add_argument('--output-rate-Hz', type=float, default=10.0,
                   help='rate of the estimates written (default: %(default)g; the model steps '
                        'at 50 Hz)')
    p.add_argument('--no-report', action='store_true', help='skip the plots and report.md')
    p.add_argument('--open-loop', action='store_true',
                   help='do not let the thermocouples correct the model (estimator.correction '
                        'off): the errors against them then validate the model itself')
    p.add_argument('--no-outlook', action='store_true',
                   help='skip the current limits for the drive, the forecast and the margin '
                        '(limits.csv, the limit topics and columns): faster')
    _add_dask_arguments(p.add_mutually_exclusive_group(), 'replays of a campaign')
    p.set_defaults(func=_replay)


def _replay(args: argparse.Namespace) -> int:
    from .offline import campaign
    from .offline import replay as rp

    if not args.output_rate_Hz > 0.0:
        raise BadArgument(f'--output-rate-Hz {args.output_rate_Hz}: must be > 0')
    _check_dask_args(args)
    try:
        options = rp.ReplayOptions(config_path=args.config, mapping=rp.parse_mapping(args.map),
                                   output_rate_Hz=args.output_rate_Hz, report=not args.no_report,
                                   open_loop=args.open_loop, outlook=not args.no_outlook)
    except rp.ReplayError as exc:
        raise BadArgument(str(exc)) from None
    bags = campaign.expand(args.bag)
    if len(args.bag) == 1 and bags == args.bag:
        return _replay_one(args.bag[0], options, Path(args.out))
    return _replay_campaign(bags, options, args)


def _replay_one(bag: Path, options, out: Path) -> int:
    """Replay one bag with progress and the details on the console (the original command)."""
    from .offline import replay as rp

    try:
        plan = options.plan(bag)
    except rp.ReplayError as exc:
        raise BadArgument(str(exc)) from None
    info = plan.info
    print(f'{info.path}: {info.message_count} messages, '
          f'{(info.end_time_ns - info.start_time_ns) * 1e-9:.1f} s; configuration: '
          f'{plan.config_source}')
    print('inputs: ' + ', '.join(f'{n} <- {t}' for n, t in plan.inputs.items())
          + (f'; no topic, on fallback: {", ".join(plan.missing)}' if plan.missing else '')
          + f'; thermocouples: {", ".join(plan.thermocouples) or "none"}')
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
    print(f'replayed {result.messages} messages: {result.steps} steps, '
          f'{result.sample_time_s:.1f} s of sample time in {result.wall_s:.1f} s '
          f'({result.speed_x:.0f}x real time)')
    for tc, e in rp.thermocouple_errors(result).items():
        print(f'  {e["estimate"]:<17} - {tc:<17} max |e| {e["max_abs_K"]:5.2f} K, RMS '
              f'{e["rms_K"]:5.2f} K, bias {e["bias_K"]:+5.2f} K')
    if result.truncated:
        print(f'warning: the bag ended early ({result.problem}): the outputs cover the '
              f'{result.messages} messages recovered', file=sys.stderr)
    print('wrote ' + ', '.join(str(f) for f in files))
    return 0


def _replay_campaign(bags: List[Path], options, args: argparse.Namespace) -> int:
    """Replay many bags on Dask, each into its own folder, and summarise them."""
    from .offline import campaign

    if args.config is not None:
        load_config(args.config)         # a bad file is one error, not one per log
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise BadArgument(f'--out {out}: exists and is not a folder')
    progress = Progress()

    def on_done(done: int, total: int, row: dict) -> None:
        what = 'failed' if row['status'] == 'failed' else f'{row["status"]} in ' \
            f'{row["wall_s"]:.1f} s'
        progress(done, total, f'{row["name"]}: {what}')

    with _dask(args) as client:
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


def _check_dask_args(args: argparse.Namespace) -> None:
    """Raise :class:`BadArgument` for a --workers below 1."""
    if args.workers is not None and args.workers < 1:
        raise BadArgument(f'--workers {args.workers}: must be at least 1')


@contextlib.contextmanager
def _dask(args: argparse.Namespace):
    """Yield the Dask client of --scheduler, else of a local cluster of --workers processes."""
    from .offline.campaign import ClusterError, dask_client

    try:
        with dask_client(args.scheduler, args.workers) as client:
            yield client
    except ClusterError as exc:
        raise BadArgument(str(exc)) from None


def _add_calibrate_parser(sub) -> None:
    """Add the ``calibrate`` command: calibration on bench logs."""
    p = sub.add_parser('calibrate', help='fit model parameters to the thermocouples of bench logs',
                       description='Fit parameters of the thermal model (contact gaps, '
                                   'convection, loss and leakage coefficients, heat capacities: '
                                   'the keys with bounds in calibration.bounds) to the '
                                   'thermocouples of one or more MCAP logs, check the result on '
                                   'held-out logs, and write calibrated.yaml (loads as any '
                                   'configuration; records each value, its 95 % interval and '
                                   'the logs) and report.md with plots. Parameters the logs '
                                   'cannot identify are held at their nominal values.')
    p.add_argument('logs', type=Path, nargs='+', metavar='LOG',
                   help='logs to fit on: MCAP files or rosbag2 bag directories')
    p.add_argument('--validate', type=Path, nargs='+', default=[], metavar='LOG',
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
    p.add_argument('--out', default='out/calibrate', help='output folder (default: %(default)s)')
    where = p.add_mutually_exclusive_group()
    where.add_argument('--jobs', type=int, default=2,
                       help='local worker processes evaluating the model (default: %(default)s)')
    _add_dask_arguments(where, 'model runs')
    p.set_defaults(func=_calibrate)


def _calibrate(args: argparse.Namespace) -> int:
    from . import calibration as cb
    from .bag.reader import BagError, open_bag
    from .offline.replay import choose_config, parse_mapping, ReplayError

    if args.jobs < 1:
        raise BadArgument(f'--jobs {args.jobs}: must be at least 1')
    _check_dask_args(args)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise BadArgument(f'--out {out}: exists and is not a folder')
    both = sorted({str(p) for p in args.logs} & {str(p) for p in args.validate})
    if both:
        raise BadArgument(f'{both[0]}: given both to fit on and to --validate: a held-out log '
                          'must not be fitted')
    try:
        mapping = parse_mapping(args.map)
        config = choose_config(open_bag(args.logs[0]), args.config)
        cfg = config[0]
        keys = cb.fit_keys(cfg, args.fit)
        paths = list(args.logs) + list(args.validate)
        plans = [cb.plan_log(path, config, mapping) for path in paths]     # all checked first
        t0 = time.perf_counter()
        logs = []
        for k, (path, plan) in enumerate(zip(paths, plans)):
            print(f'reading {path} ({k + 1} of {len(paths)})', file=sys.stderr, flush=True)
            logs.append(cb.read_log(plan, cfg.calibration, path))
    except (BagError, ReplayError, cb.CalibrationError) as exc:
        raise BadArgument(str(exc)) from None
    read_s = time.perf_counter() - t0
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
                from .offline.campaign import describe
                client = stack.enter_context(_dask(args))
                where = f'Dask, {describe(client)}'
                say(f'model runs on {where}')
            run = cb.calibrate(logs[:len(args.logs)], cfg, keys,
                               validate_logs=logs[len(args.logs):], config_source=config[1],
                               jobs=args.jobs, client=client, on_progress=say)
    except cb.CalibrationError as exc:
        raise BadArgument(str(exc)) from None
    run.read_s = read_s
    command = 'wet-eha-thermal ' + ' '.join(shlex.quote(a) for a in args.argv)
    files = cb.write_outputs(run, out, command)
    print('\nparameters: nominal -> calibrated [95 % interval]')
    for p in run.parameters:
        if p.identifiable:
            print(f'  {p.key:<42} {p.nominal:<10.4g} -> {p.value:<10.4g} '
                  f'[{p.ci95[0]:.4g}, {p.ci95[1]:.4g}]{"  " + p.note if p.note else ""}')
        else:
            print(f'  {p.key:<42} {p.nominal:<10.4g} held: not identifiable ({p.note})')
    for lf in run.logs:
        role = 'fit' if lf.role == 'fit' else 'held out'
        print(f'{lf.log.name} ({role}): model - thermocouple, max abs over '
              f'{cfg.calibration.residual_interval_s:g} s means, nominal -> calibrated (K)')
        print('  ' + ', '.join(f'{c} {lf.before[c]["max_abs_K"]:.2f} -> '
                               f'{lf.after[c]["max_abs_K"]:.2f}' for c in lf.windows.channels))
    for m in run.messages:
        print(f'warning: {m}', file=sys.stderr)
    print(f'wall time: reading {run.read_s:.1f} s, fit {run.fit_s:.1f} s ({run.evaluations} '
          f'model runs of whole logs, {run.iterations} iterations, {where})')
    print('wrote ' + ', '.join(str(f) for f in files))
    return 0


def _add_whatif_parser(sub) -> None:
    """Add the ``whatif`` command: what a duty does from the live state, a bag's, or cold."""
    p = sub.add_parser('whatif', help='what a duty does from where the actuator is now',
                       description='Run a duty from the state of a running estimator (asked '
                                   'over ROS, on this ROS_DOMAIN_ID), from the last state of a '
                                   'recorded bag (--bag, replayed first) or cold (--cold); print '
                                   'the peaks and when each limit is reached; write whatif.csv '
                                   'and whatif.png.')
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument('--stage', type=int, default=None, help='reference stage number (1-6)')
    which.add_argument('--duty', type=Path, metavar='FILE.csv',
                       help='duty table: time_s, flow_L_min, load_MPa (repeats periodically)')
    which.add_argument('--samples', type=Path, metavar='FILE.csv',
                       help='sensor table: time_s, current_A, speed_rad_s, p_a_Pa, p_b_Pa, '
                            'p_acc_Pa[, position_m], SI units (repeats periodically)')
    start = p.add_mutually_exclusive_group()
    start.add_argument('--bag', type=Path, default=None, metavar='PATH',
                       help='start from the last state of this bag (an MCAP file or a bag '
                            'directory), replayed through the estimator')
    start.add_argument('--cold', action='store_true',
                       help='start cold: every temperature at the ambient')
    p.add_argument('--duration', type=float, default=3600.0,
                   help='time to run the duty, s (default: %(default)g)')
    p.add_argument('--ambient-C', type=float, default=None,
                   help="ambient temperature, degC (default: the estimator's; cold: 20)")
    p.add_argument('--dt', type=float, default=None, help='thermal model step, s (default: 1)')
    p.add_argument('--config', type=Path, default=None,
                   help='YAML configuration for --bag and --cold (default: stored in the bag, '
                        'else the reference rig)')
    p.add_argument('--topic-prefix', default=interface.PREFIX,
                   help="the estimator's topic_prefix (default: %(default)s)")
    p.add_argument('--timeout', type=float, default=300.0,
                   help="how long to wait for the estimator's answer, s (default: %(default)g)")
    p.add_argument('--out', default='out/whatif', help='output folder (default: %(default)s)')
    p.set_defaults(func=_whatif)


def _whatif_request(args: argparse.Namespace, cfg) -> dict:
    """Return the request of the command line (the duty's files read and checked)."""
    from .model.kinetics import L_MIN, load_duty_csv, MPA
    from .offline.simulation import SENSORS

    request = {'id': f'cli-{time.time_ns()}', 'duration_s': args.duration}
    if args.ambient_C is not None:
        request['ambient_C'] = args.ambient_C
    if args.dt is not None:
        request['dt_s'] = args.dt
    if args.stage is not None:
        request['stage'] = args.stage
    elif args.duty is not None:
        act = cfg.hydraulics.actuator
        t, q, dp = load_duty_csv(args.duty, act.area_m2, act.half_stroke_m).rows()
        request['table'] = {'time_s': t.tolist(), 'flow_L_min': (q / L_MIN).tolist(),
                            'load_MPa': (dp / MPA).tolist()}
    else:
        request['samples'] = _read_samples(args.samples, ('time_s',) + SENSORS)
    return request


def _read_samples(path: Path, columns: Tuple[str, ...]) -> dict:
    """Return the named columns of a CSV of numbers (``position_m`` may be left out)."""
    import numpy as np

    try:
        # comment lines dropped first: genfromtxt would take one before the header for it
        lines = [ln for ln in path.read_text().splitlines()
                 if ln.strip() and not ln.lstrip().startswith('#')]
        data = np.genfromtxt(lines, delimiter=',', names=True, ndmin=1)
    except (OSError, ValueError) as exc:
        raise BadArgument(f'--samples {path}: cannot read it: {exc}') from None
    names = data.dtype.names or ()
    table = {}
    for name in columns:
        if name not in names:
            if name == 'position_m':
                continue
            raise BadArgument(f'--samples {path}: missing column {name!r}; the header has '
                              f'{", ".join(names)}')
        values = np.atleast_1d(data[name])
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise BadArgument(f'--samples {path}: column {name!r}, data row {bad[0] + 1}: not '
                              'a finite number')
        table[name] = values.tolist()
    return table


def _whatif(args: argparse.Namespace) -> int:
    import json
    import pickle

    from .offline.whatif import format_answer, model_outputs, write_answer
    from .offline.whatif_worker import run_request

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise BadArgument(f'--out {out}: exists and is not a folder')
    if args.bag is None and not args.cold:
        cfg = load_config(args.config)
        request = _whatif_request(args, cfg)
        from .ros.whatif_client import ask, NoAnswer
        print(f'asking the estimator on {args.topic_prefix}/whatif/request ...', flush=True)
        try:
            text = ask(json.dumps(request), request['id'], args.topic_prefix, args.timeout)
        except NoAnswer as exc:
            raise BadArgument(str(exc)) from None
    elif args.cold:
        cfg = load_config(args.config)
        text = run_request(json.dumps(_whatif_request(args, cfg)), cfg, model_outputs(cfg),
                           None, 20.0, 'cold', None)
    else:
        from .estimator.session import EstimatorSession
        from .offline import replay as rp

        try:
            plan = rp.ReplayOptions(config_path=args.config).plan(args.bag)
            session = EstimatorSession(plan.cfg)
            print(f'replaying {args.bag} for its last state ...', flush=True)
            rp.replay(plan, session=session)
        except (rp.ReplayError, rp.BagError) as exc:
            raise BadArgument(str(exc)) from None
        text = run_request(json.dumps(_whatif_request(args, plan.cfg)), plan.cfg,
                           session.model.quantities.names, pickle.dumps(session.model),
                           session.ambient_C, f'the last state of {args.bag}', session.t_model)
    answer = json.loads(text)
    print(format_answer(answer))
    if not answer['ok']:
        return 2
    try:
        files = write_answer(answer, out)
    except OSError as exc:
        raise BadArgument(f'--out {out}: cannot write the results: {exc.strerror or exc}') \
            from None
    print('wrote ' + ', '.join(str(f) for f in files))
    return 0


def _add_play_parser(sub) -> None:
    """Add the ``play`` command: the bag player."""
    # parsed by the player itself (main() hands it everything after 'play')
    sub.add_parser('play', add_help=False,
                   help='publish a bag on the ROS graph with /clock (wet-eha-thermal play BAG '
                        '[--rate R] [--loop] ...; play --help for all options)')


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of all commands."""
    parser = argparse.ArgumentParser(
        prog='wet-eha-thermal',
        description='Thermal digital twin of a wet electro-hydrostatic actuator.')
    sub = parser.add_subparsers(dest='command', required=True)
    for add in (_add_maps_parser, _add_simulate_parser, _add_live_parser, _add_replay_parser,
                _add_calibrate_parser, _add_whatif_parser, _add_play_parser):
        add(sub)
    return parser


def main(argv: Optional[List[str]] = None) -> int:
    """Run the command line; return the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ['play']:
        from .ros import player
        return player.main(argv[1:])
    args = build_parser().parse_args(argv)
    args.argv = argv
    try:
        return args.func(args)
    except (BadArgument, ConfigError, DutyError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print('interrupted', file=sys.stderr)
        return 130


if __name__ == '__main__':
    sys.exit(main())
