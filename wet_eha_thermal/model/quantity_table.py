"""
What people are shown of the named quantities: their labels and their limits.

:mod:`.quantities` defines every output once; this table, beside it, says
how a report, a plot or /diagnostics names an output, which outputs have a
temperature limit and which configuration key holds each limit. The
estimator's forecast and margin current and the offline reports check the
same outputs against the same keys.

>>> label('winding_hotspot'), label('pump_case')
('winding hot-spot', 'pump case')
>>> LIMITED
('winding_hotspot', 'magnet', 'oil')
"""

from typing import Dict

from ..config import Config, config_value

#: The outputs with a temperature limit, in the order they are shown, and the configuration
#: key of each limit (degC)
LIMIT_KEYS = {'winding_hotspot': 'motor.winding.insulation_limit_C',
              'magnet': 'motor.rotor.magnet_limit_C',
              'oil': 'fluid.oil_limit_C'}
LIMITED = tuple(LIMIT_KEYS)
#: How a plot names each limit
LIMIT_LABELS = {'winding_hotspot': 'insulation limit', 'magnet': 'magnet limit',
                'oil': 'oil limit'}
#: How tables and plots name an output, where not its name with spaces (:func:`label`)
LABELS = {'winding_hotspot': 'winding hot-spot', 'end_winding_hotspot': 'end-winding hot-spot',
          'magnet': 'magnet (hottest)',
          'oil': 'oil (hottest node)', 'chamber_a': 'chamber A', 'chamber_b': 'chamber B'}
#: How tables and plots name the motor's losses (:data:`~.motor.LOSS_NAMES`)
LOSS_LABELS = {'copper_slot': 'copper, slots', 'copper_end': 'copper, end windings',
               'core_yoke': 'iron, yoke', 'core_teeth': 'iron, teeth',
               'gap_friction': 'airgap friction', 'magnet': 'magnets', 'sleeve': 'sleeve',
               'rotor_core': 'rotor core', 'end_face_friction': 'end-face friction',
               'bearings': 'bearings'}


def label(name: str) -> str:
    """Return how tables and plots name an output."""
    return LABELS.get(name, name.replace('_', ' '))


def limits_C(cfg: Config) -> Dict[str, float]:
    """Return the limit (degC) of each output in :data:`LIMITED`, from the configuration."""
    return {name: config_value(cfg, key) for name, key in LIMIT_KEYS.items()}
