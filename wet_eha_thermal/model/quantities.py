"""
The named quantities of the model: one name per state, every output defined once.

As python-control names a system's states and outputs, the model names each
element of its state vector (the motor network's nodes with heat capacity by
their node names, such as ``winding.s3``, then the hydraulic nodes of
:data:`~.hydraulics.NODES`, such as ``case``) and defines each output over
those names, as one of:

- ``mean``: a weighted mean of states, e.g. ``winding_mean``, the copper
  nodes weighted by their share of the conductor length (what a resistance
  measurement sees), or ``frame``, the frame over the stack by volume;
- ``max``: the hottest of a set of states (``magnet``, ``oil``);
- ``peak``: the hottest point of a set of blocks, each point a linear form
  in a few node temperatures (:class:`~.hot_spot.PeakForms`): the winding's
  hot spot in the slot (``winding_hotspot``) and in the end windings
  (``end_winding_hotspot``); the state it takes is the hottest block's mean;
- ``state``: one state;
- ``port``: ``pump_outlet``, the pump port at the higher pressure (port A on
  a tie).

:meth:`WetMotor.outputs <.motor.WetMotor.outputs>`, :meth:`EHAModel.outputs
<.eha.EHAModel.outputs>`, the Kalman filter's measurement rows (a linear
output's row is its weights; a ``max`` or ``port`` output's the row of the
state it takes now), the names of the state the estimator publishes and,
through the estimates, the calibration's channels all read this map.
"""

from dataclasses import dataclass
from typing import Callable, Dict, Optional, Sequence, Tuple

import numpy as np

from .compiled import jit
from .hot_spot import end_winding_peak_forms, PeakForms, slot_peak_forms


MEAN, MAX, STATE, PORT, PEAK = 'mean', 'max', 'state', 'port', 'peak'
#: the kinds' codes in :func:`evaluate_outputs` (a peak is evaluated beside it)
_KIND_CODE = {MEAN: 0, MAX: 1, STATE: 2, PORT: 3, PEAK: 4}
#: the outputs that are one hydraulic node: output -> node of :data:`~.hydraulics.NODES`
HYDRAULIC_OUTPUTS = {'pump_case': 'case', 'pump_port_a': 'port_a', 'pump_port_b': 'port_b',
                     'chamber_a': 'chamber_a', 'chamber_b': 'chamber_b',
                     'accumulator': 'accumulator', 'line_a': 'line_a', 'line_b': 'line_b',
                     'pump_shell': 'pump_shell', 'actuator_shell': 'actuator_shell'}
#: the oil volumes whose hottest value is the ``oil`` output, checked against the oil limit
OIL_OUTPUTS = ('airgap_oil_outlet', 'motor_oil_outlet', 'pump_case', 'chamber_a', 'chamber_b',
               'accumulator')


@dataclass(frozen=True, eq=False)
class Quantity:
    """One output: its kind and the named states it is formed from (see the module docstring)."""

    kind: str
    states: Tuple[str, ...]
    #: a mean's weights, one per state (shares of the conductor length, frame volumes in m^3)
    weights: Optional[np.ndarray] = None
    #: a peak's blocks, one per state (in the order of ``states``)
    peaks: Tuple[PeakForms, ...] = ()


def motor_outputs(motor) -> Dict[str, Quantity]:
    """
    Return the outputs of a built :class:`~.motor.WetMotor` over its node names.

    The hot spot is the hottest point in the slot (:func:`~.hot_spot.slot_peak_forms`),
    the end windings' apart (:func:`~.hot_spot.end_winding_peak_forms`); the
    magnet the hottest magnet slice;
    ``airgap_oil_outlet`` the last airgap section; ``motor_oil_outlet`` the rear
    end space, where the oil leaves the motor.
    """
    copper = tuple(motor.copper_nodes)
    frame, magnet = motor.parts['frame'], motor.parts['magnet']
    slots = tuple(slot_peak_forms(motor))
    ends = tuple(p for side in ('front', 'rear') for p in end_winding_peak_forms(motor, side))
    return {
        'winding_mean': Quantity(MEAN, copper, motor.copper_share),
        'winding_hotspot': Quantity(PEAK, tuple(p.state for p in slots), peaks=slots),
        'end_winding_hotspot': Quantity(PEAK, tuple(p.state for p in ends), peaks=ends),
        'frame': Quantity(MEAN, tuple(frame.mean), np.array(frame.volume_m3)),
        'magnet': Quantity(MAX, tuple(magnet.mean)),
        'airgap_oil_outlet': Quantity(STATE, (motor.gap[-1],)),
        'motor_oil_outlet': Quantity(STATE, (motor.oil_nodes[-1],)),
    }


def coupled_outputs(motor) -> Dict[str, Quantity]:
    """Return the outputs of the coupled model: the motor's, the hydraulic ones, ``oil``."""
    out = motor_outputs(motor)
    out.update({name: Quantity(STATE, (node,)) for name, node in HYDRAULIC_OUTPUTS.items()})
    out['pump_outlet'] = Quantity(PORT, ('port_a', 'port_b'))
    out['oil'] = Quantity(MAX, tuple(s for name in OIL_OUTPUTS for s in out[name].states))
    return out


class QuantityMap:
    """
    The named states of a model and its outputs over them.

    ``value_index`` places a state's name in the vector of values the outputs
    are evaluated on (the motor's node temperatures hold its algebraic nodes
    too, so that vector is not the state vector).
    """

    def __init__(self, state_names: Sequence[str], outputs: Dict[str, Quantity],
                 value_index: Callable[[str], int]) -> None:
        self.state_names = tuple(state_names)
        self.outputs = outputs
        state_of = {name: i for i, name in enumerate(self.state_names)}
        if len(state_of) < len(self.state_names):
            raise ValueError('two states share a name')
        self.names = tuple(outputs)
        self._states: Dict[str, np.ndarray] = {}      # positions in the state vector
        for name, q in outputs.items():
            missing = [s for s in q.states if s not in state_of]
            if missing:
                raise ValueError(f'output {name}: no state named {", ".join(missing)}')
            self._states[name] = np.array([state_of[s] for s in q.states])
        # the whole map as flat tables, for one compiled pass over every output: the
        # states' positions in the vector of values and in the state vector
        qs = list(outputs.values())
        self._kinds = np.array([_KIND_CODE[q.kind] for q in qs])
        self._offsets = np.cumsum([0] + [len(q.states) for q in qs])
        self._value_at = np.array([value_index(s) for q in qs for s in q.states])
        self._state_at = np.concatenate([self._states[name] for name in self.names])
        self._weights = np.concatenate([q.weights if q.kind == MEAN else np.zeros(len(q.states))
                                        for q in qs])
        self._weight_sums = np.array([q.weights.sum() if q.kind == MEAN else 1.0 for q in qs])
        # a peak's blocks (its states): the values each weighs, and its parts (the rows of
        # ``_rows`` between ``_part_rows`` offsets), for the same compiled pass
        width = max([len(p.values) for q in qs for p in q.peaks], default=1)
        self._peak_at = np.zeros((self._value_at.size, width), np.int64)
        self._part_of = np.zeros((self._value_at.size, 2), np.int64)
        parts, rows, starts = [], [], {}
        i = 0
        for q in qs:
            for k in range(len(q.states)):
                if q.kind == PEAK:
                    p = q.peaks[k]
                    self._peak_at[i, :len(p.values)] = [value_index(v) for v in p.values]
                    self._part_of[i] = (len(parts), len(parts) + len(p.parts))
                    for f in p.parts:
                        if id(f) not in starts:      # blocks that share their forms
                            starts[id(f)] = sum(len(r) for r in rows)
                            rows.append(np.pad(f, ((0, 0), (0, width - f.shape[1]))))
                        parts.append((starts[id(f)], starts[id(f)] + len(f)))
                i += 1
        self._part_rows = np.array(parts, np.int64).reshape(-1, 2)
        self._rows = np.concatenate(rows) if rows else np.zeros((0, width))

    def __deepcopy__(self, memo) -> 'QuantityMap':
        """Return the map itself: it never changes, so a copied model (a forecast's) shares it."""
        return self

    def evaluate(self, v: np.ndarray, port_a_high: Optional[bool] = None) -> tuple:
        """
        Return every output's value (in the unit of ``v``) and the state it takes.

        In the order of :attr:`names`. The state is the position in the state
        vector of a single-state output (the hottest of a ``max``, the port), -1
        for a mean; a ``port`` output is NaN, state -1, without ``port_a_high``.
        """
        return evaluate_outputs(v, -1 if port_a_high is None else int(port_a_high),
                                self._kinds, self._offsets, self._value_at, self._state_at,
                                self._weights, self._weight_sums, self._peak_at,
                                self._part_of, self._part_rows, self._rows)

    def values(self, v: np.ndarray, port_a_high: Optional[bool] = None) -> Dict[str, float]:
        """Return every output (in the unit of ``v``); a ``port`` one only with ``port_a_high``."""
        return self.values_and_states(v, port_a_high)[0]

    def values_and_states(self, v: np.ndarray,
                          port_a_high: Optional[bool] = None) -> Tuple[Dict[str, float],
                                                                       np.ndarray]:
        """Return :meth:`values` and the states the outputs take (:meth:`evaluate`)."""
        vals, taken = self.evaluate(v, port_a_high)
        out = dict(zip(self.names, vals.tolist()))
        if port_a_high is None:
            for name, q in self.outputs.items():
                if q.kind == PORT:
                    del out[name]
        return out, taken

    def state_indices(self, name: str) -> np.ndarray:
        """Return the positions in the state vector of the states an output is formed from."""
        return self._states[name]

    def weights(self, name: str) -> np.ndarray:
        """Return a linear output's weights over its states (they sum to 1)."""
        q = self.outputs[name]
        if q.kind == STATE:
            return np.ones(1)
        if q.kind != MEAN:
            raise ValueError(f'output {name} ({q.kind}) is not linear in the state')
        return q.weights / q.weights.sum()


@jit
def evaluate_outputs(v, port_a_high, kinds, offsets, value_at, state_at, weights, weight_sums,
                     peak_at, part_of, part_rows, rows):
    """
    Return the outputs' values and the states they take (:meth:`QuantityMap.evaluate`).

    Output ``k`` is formed from ``value_at[offsets[k]:offsets[k + 1]]`` (the
    positions of its states in ``v``), ``state_at`` the same states in the
    state vector; ``kinds`` 0 mean (by ``weights``, which sum to
    ``weight_sums[k]``), 1 max, 2 state, 3 port
    (A then B; ``port_a_high`` 1 A, 0 B, -1 unknown); 4 peak: state ``i``'s
    block weighs the values ``v[peak_at[i]]``, its value is the sum over its
    parts ``part_of[i, 0] <= j < part_of[i, 1]`` of the largest of the rows
    ``rows[part_rows[j, 0]:part_rows[j, 1]]`` applied to them.
    """
    n = kinds.size
    vals = np.empty(n)
    taken = np.full(n, -1, np.int64)
    for k in range(n):
        a, b = offsets[k], offsets[k + 1]
        g = np.empty(b - a)
        for i in range(a, b):
            g[i - a] = v[value_at[i]]
        if kinds[k] == 0:
            vals[k] = np.dot(weights[a:b], g) / weight_sums[k]
            continue
        if kinds[k] == 4:
            for i in range(a, b):
                g[i - a] = _block_peak(v[peak_at[i]], part_of[i], part_rows, rows)
        if kinds[k] == 1 or kinds[k] == 4:
            j = np.argmax(g)              # the first NaN, if any, as numpy's max
        elif kinds[k] == 2:
            j = 0
        elif port_a_high >= 0:
            j = 0 if port_a_high == 1 else 1
        else:
            vals[k] = np.nan
            continue
        vals[k] = g[j]
        taken[k] = state_at[a + j]
    return vals, taken


@jit
def _block_peak(g, parts, part_rows, rows):
    """Return a block's peak: the sum over its parts of each part's largest row . ``g``."""
    total = 0.0
    for j in range(parts[0], parts[1]):
        top = -np.inf
        for r in range(part_rows[j, 0], part_rows[j, 1]):
            s = 0.0
            for c in range(g.size):         # a loop: a BLAS call per row costs more
                s += rows[r, c] * g[c]
            top = max(top, s)
        total += top
    return total
