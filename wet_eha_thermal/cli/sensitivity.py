"""``wet-eha-thermal sensitivity``: which uncertain parameter moves the hot spot most."""

import argparse
from pathlib import Path

from .arguments import add_config, add_out, BadArgument
from .console import Progress
from ..config import load_config

HELP = 'which uncertain parameter moves the steady hot spot and magnet most, at the map points'
DESCRIPTION = ("Solve the motor maps' steady states with each uncertain parameter of the "
               'configuration (its uncertainty section) moved by its one sigma, and with each '
               'structural alternative; rank them by the largest move of the winding hot spot '
               'and of the magnets: what to measure first on the rig. Prints a table, writes a '
               'CSV and a tornado PNG.')


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options of ``sensitivity``: the configuration and the output folder."""
    add_config(p)
    add_out(p, 'sensitivity')


def run(args: argparse.Namespace) -> int:
    """Rank the uncertain parameters; print the table, write the CSV and the tornado."""
    from ..offline import sensitivity

    cfg = load_config(args.config)
    if cfg.uncertainty is None:
        raise BadArgument('the configuration has no uncertainty section: nothing to rank')
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    result = sensitivity.compute_sensitivity(cfg, Progress())
    print(f'\nLargest move over the map points ({cfg.maps.oil_inlet_C:g} degC oil in at '
          f'{cfg.maps.oil_flow_L_min:g} L/min), largest first:')
    print(sensitivity.format_table(result))
    if result.not_ranked:
        print('\nNot ranked (they move the oil inlet, which a motor map holds; their effect is '
              'in the uncertainty a coupled run propagates): ' + ', '.join(result.not_ranked))
    csv_path, png_path = out / 'sensitivity.csv', out / 'sensitivity.png'
    sensitivity.write_csv(result, csv_path)
    sensitivity.plot_tornado(result, png_path, 'Which unknown matters: steady moves at one '
                             'sigma, largest over the map points')
    print(f'\nwrote {csv_path} and {png_path}')
    return 0
