"""
Motor loss maps exported by an electromagnetic FEA: read and check the CSV grid.

Motor-CAD, JMAG or Maxwell export the losses of a machine over its operating
range; ``motor.loss_map`` in the configuration names such a table, and the
model then takes its copper, stator iron, magnet and sleeve losses from it
instead of the analytical laws (docs/model.md, Motor losses). The file is a
CSV with a header row and one row per point of a full speed x current grid,
in any order:

=============== ================================================
column          meaning
=============== ================================================
speed_rpm       shaft speed (r/min, >= 0)
current_A       RMS phase current (A, >= 0)
copper_W        copper loss of the whole winding (W), at the map's
                ``copper_temperature_C``
stator_iron_W   stator iron loss (W)
magnet_W        magnet eddy-current loss (W)
sleeve_W        retaining-sleeve eddy-current loss (W)
rotor_core_W    optional: rotor iron loss (W), 0 when absent
=============== ================================================

No ROS and no model import: the configuration checks a map with this module
when it loads, and the model reads the same grid.
"""

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Dict

import numpy as np

#: the columns every map has, then the optional one
COLUMNS = ('speed_rpm', 'current_A', 'copper_W', 'stator_iron_W', 'magnet_W', 'sleeve_W')
OPTIONAL = ('rotor_core_W',)
#: the loss columns, in the order of :attr:`LossGrid.losses_W`
LOSSES = ('copper_W', 'stator_iron_W', 'magnet_W', 'sleeve_W', 'rotor_core_W')


class LossMapError(ValueError):
    """A loss map that cannot be read or is not a full grid of finite, non-negative losses."""


@dataclass(frozen=True)
class LossGrid:
    """
    A loss map on its grid.

    :ivar speeds_rpm: the grid's speeds (r/min), increasing.
    :ivar currents_A: the grid's RMS currents (A), increasing.
    :ivar losses_W: each loss of ``LOSSES`` (W), ``(speeds, currents)``.
    """

    speeds_rpm: np.ndarray
    currents_A: np.ndarray
    losses_W: Dict[str, np.ndarray]


def read_loss_map(path) -> LossGrid:
    """
    Read the CSV loss map at ``path``; raise LossMapError with what is wrong and where.

    Every speed must come with every current (a full grid, at least two of
    each), each pair once; values finite, speeds, currents and losses >= 0.
    """
    p = Path(path)
    try:
        with open(p, newline='') as f:
            rows = list(csv.reader(f))
    except OSError as exc:
        raise LossMapError(f'cannot read it: {exc.strerror}') from exc
    if not rows:
        raise LossMapError('empty file')
    header = [h.strip() for h in rows[0]]
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise LossMapError(f'no column {", ".join(missing)}; the header has '
                           f'{", ".join(header)}')
    unknown = [c for c in header if c not in COLUMNS + OPTIONAL]
    if unknown:
        raise LossMapError(f'unknown column {unknown[0]}; allowed: '
                           f'{", ".join(COLUMNS + OPTIONAL)}')
    table = _numbers(rows[1:], header)
    speeds, currents = np.unique(table['speed_rpm']), np.unique(table['current_A'])
    if speeds.size < 2 or currents.size < 2:
        raise LossMapError(f'{speeds.size} speed(s) and {currents.size} current(s): a grid '
                           'needs at least two of each')
    i = np.searchsorted(speeds, table['speed_rpm'])
    j = np.searchsorted(currents, table['current_A'])
    seen = np.zeros((speeds.size, currents.size), dtype=int)
    np.add.at(seen, (i, j), 1)
    if (seen != 1).any():
        a, b = np.argwhere(seen != 1)[0]
        raise LossMapError(f'not a full grid: {speeds[a]:g} r/min with {currents[b]:g} A '
                           f'appears {seen[a, b]} times (every speed with every current once)')
    losses = {}
    for name in LOSSES:
        grid = np.zeros(seen.shape)
        if name in table:
            grid[i, j] = table[name]
        losses[name] = grid
    return LossGrid(speeds, currents, losses)


def _numbers(rows, header) -> Dict[str, np.ndarray]:
    """Return the columns of the data ``rows`` (from the file's line 2) as checked arrays."""
    data = [(line, r) for line, r in enumerate(rows, start=2) if any(c.strip() for c in r)]
    if not data:
        raise LossMapError('no data rows')
    values = np.empty((len(data), len(header)))
    for n, (line, row) in enumerate(data):
        if len(row) != len(header):
            raise LossMapError(f'line {line}: {len(row)} values for {len(header)} columns')
        for k, cell in enumerate(row):
            try:
                v = float(cell)
            except ValueError:
                raise LossMapError(f'line {line}, {header[k]}: {cell!r} is not a number') \
                    from None
            if not np.isfinite(v) or v < 0.0:
                raise LossMapError(f'line {line}, {header[k]} = {cell.strip()}: expected a '
                                   'finite number >= 0')
            values[n, k] = v
    return {name: values[:, k] for k, name in enumerate(header)}
