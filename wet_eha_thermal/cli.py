"""
Command-line entry point: ``wet-eha-thermal <command> ...``.

Every command reports bad input as one line on stderr (``error: ...``) and
exits with status 2, without a traceback; nothing runs after a bad config.
"""

import argparse
from pathlib import Path
import sys
import time
from typing import List, Optional

from .config import ConfigError, load_config
from .model.validity import ValidityLog


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


def _maps(args: argparse.Namespace) -> int:
    from . import maps

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


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of all commands."""
    parser = argparse.ArgumentParser(
        prog='wet-eha-thermal',
        description='Thermal digital twin of a wet electro-hydrostatic actuator.')
    sub = parser.add_subparsers(dest='command', required=True)
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
    return parser


def main(argv: Optional[List[str]] = None) -> int:
    """Run the command line; return the exit status."""
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ConfigError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print('interrupted', file=sys.stderr)
        return 130


if __name__ == '__main__':
    sys.exit(main())
