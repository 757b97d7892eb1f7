"""``wet-eha-thermal maps``: steady-state motor temperatures versus speed and current."""

import argparse
from pathlib import Path

from .arguments import add_config, add_out
from .console import print_validity, Progress
from ..config import load_config
from ..model.validity import ValidityLog

HELP = 'steady-state motor temperatures versus speed and current'
DESCRIPTION = ('Steady-state winding, frame, magnet and oil temperatures of the wet motor '
               'versus speed and versus current; prints two tables, writes a CSV and a PNG '
               'plot.')
#: Option -> the configuration key it overrides (None: the configuration's value).
OVERRIDES = {'oil_inlet_C': 'maps.oil_inlet_C', 'oil_flow_L_min': 'maps.oil_flow_L_min',
             'ambient_C': 'maps.ambient_C', 'slices': 'motor.slices', 'fluid': 'fluid.grade'}


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``maps``: overrides of the configuration's ``maps`` section."""
    add_config(p)
    add_out(p, 'maps')
    # ranges and choices are the configuration's: its validation names the key and the range
    p.add_argument('--oil-inlet-C', type=float, default=None,
                   help='oil inlet temperature, degC (default: from config)')
    p.add_argument('--oil-flow-L-min', type=float, default=None,
                   help='oil flow through the motor, L/min (default: from config)')
    p.add_argument('--ambient-C', type=float, default=None, help='ambient temperature, degC')
    p.add_argument('--slices', type=int, default=None, help='axial slices of the stack')
    p.add_argument('--fluid', default=None, help='oil grade (MIL-PRF-5606 or MIL-PRF-83282)')


def run(args: argparse.Namespace) -> int:
    """Compute and print the maps, write the CSV and the plot."""
    from ..offline import maps

    overrides = {key: getattr(args, option) for option, key in OVERRIDES.items()
                 if getattr(args, option) is not None}
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
    print_validity(log)
    print(f'\nwrote {csv_path} and {png_path}')
    return 0
