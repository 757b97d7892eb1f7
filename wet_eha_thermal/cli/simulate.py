"""``wet-eha-thermal simulate``: temperatures over a duty cycle, offline."""

import argparse
import math
import sys

from .arguments import add_config, add_duty_arguments, add_out, BadArgument, default, positive
from .console import print_validity, Progress
from ..config import load_config

HELP = 'temperatures over a duty cycle (a stage or a duty file)'
DESCRIPTION = ('Run the coupled thermal model over a duty cycle: a reference stage or a duty '
               'CSV (columns time_s, flow_L_min, load_MPa). Prints end and peak temperatures '
               'and when each limit is or would be reached; writes a CSV and a PNG plot.')
#: Simulated time by default (s): an hour, where most stages settle.
DURATION_S = 3600.0


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``simulate``; the defaults are those of :func:`.simulation.simulate`."""
    from ..offline.simulation import simulate

    add_duty_arguments(p, required=True)
    p.add_argument('--duration', type=positive('seconds'), default=DURATION_S,
                   help='simulated time, s (default: %(default)g)')
    p.add_argument('--ambient-C', type=float, default=default(simulate, 'ambient_C'),
                   help='ambient temperature, degC (default: %(default)g)')
    p.add_argument('--initial-C', type=float, default=None,
                   help='starting temperature of every node, degC (default: ambient)')
    p.add_argument('--dt', type=positive('seconds'), default=default(simulate, 'dt_s'),
                   help='thermal model step, s (default: %(default)g)')
    p.add_argument('--sample-rate-Hz', type=positive('Hz'),
                   default=default(simulate, 'sample_rate_Hz'),
                   help='sensor sample rate, Hz (default: %(default)g)')
    add_config(p)
    add_out(p, 'simulate')
    p.add_argument('--fluid', default=None, help='oil grade (MIL-PRF-5606 or MIL-PRF-83282)')


def _check(args: argparse.Namespace) -> None:
    """Raise :class:`BadArgument` for options out of range together."""
    if args.dt > args.duration:
        raise BadArgument(f'--dt {args.dt:g}: must be > 0 s and at most --duration '
                          f'({args.duration:g} s)')
    samples = args.sample_rate_Hz * args.dt
    if round(samples) < 1:
        raise BadArgument(f'--sample-rate-Hz {args.sample_rate_Hz:g}: gives {samples:.3g} '
                          f'samples per {args.dt:g} s step; needs at least 1, i.e. >= '
                          f'{1.0 / args.dt:g} Hz')


def _check_temperatures(cfg, ambient_C: float, initial_C: float) -> None:
    """Raise :class:`BadArgument` for an ambient or start outside the oil grade's range."""
    from ..model.oil import OIL_GRADES
    from ..units import C_TO_K

    grade = OIL_GRADES[cfg.fluid.grade]
    low, high = grade.T_min_K - C_TO_K, grade.T_max_K - C_TO_K
    for option, value in (('--ambient-C', ambient_C), ('--initial-C', initial_C)):
        if not (math.isfinite(value) and low <= value <= high):
            raise BadArgument(f'{option} {value:g}: outside the {grade.name} range '
                              f'{low:g}..{high:g} degC')


def run(args: argparse.Namespace) -> int:
    """Simulate, print the report, write the CSV and the plot; 1 if the run stopped early."""
    from ..model.duty import load_duty_csv, stage_duty
    from ..offline import report, simulation

    _check(args)
    out = args.out
    cfg = load_config(args.config, {'fluid.grade': args.fluid} if args.fluid else None)
    initial_C = args.ambient_C if args.initial_C is None else args.initial_C
    _check_temperatures(cfg, args.ambient_C, initial_C)
    act = cfg.hydraulics.actuator
    if args.stage is not None:
        duty = stage_duty(cfg, args.stage)
        what = duty.stage.describe()
    else:
        duty = load_duty_csv(args.duty, act.area_m2, act.half_stroke_m)
        what = f'duty file {args.duty} (period {duty.period_s:g} s)'
    title = (f'Duty-cycle simulation: {what}, {args.duration:g} s at dt {args.dt:g} s '
             f'({args.sample_rate_Hz:g} Hz samples), ambient {args.ambient_C:g} degC, '
             f'start {initial_C:g} degC, {cfg.fluid.grade}')
    print(title, flush=True)
    stopped = None
    try:
        res = simulation.simulate(cfg, duty, args.duration, dt_s=args.dt,
                                  sample_rate_Hz=args.sample_rate_Hz,
                                  ambient_C=args.ambient_C, initial_C=initial_C,
                                  progress=Progress())
    except simulation.ThermalRunaway as exc:  # carries the run so far
        stopped, res = exc, exc.result
        if not res.time_s:
            raise
    print()
    if stopped is not None:
        print(f'Run stopped early: {stopped}\nResults up to t = {res.time_s[-1]:g} s:\n')
    print(report.format_summary(res, cfg, duty.period_s))
    print_validity(res.model.log if res.model is not None else [])
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
