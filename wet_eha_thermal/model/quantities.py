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
- ``max``: the hottest of a set of states (``winding_hotspot``, ``magnet``,
  ``oil``);
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
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np


MEAN, MAX, STATE, PORT = 'mean', 'max', 'state', 'port'
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


def motor_outputs(motor) -> Dict[str, Quantity]:
    """
    Return the outputs of a built :class:`~.motor.WetMotor` over its node names.

    The hot spot is the hottest winding node (slot slices and end windings; the
    peak inside a block is not resolved); the magnet the hottest magnet slice;
    ``airgap_oil_outlet`` the last airgap section; ``motor_oil_outlet`` the rear
    end space, where the oil leaves the motor.
    """
    copper = tuple(motor.copper_nodes)
    frame, magnet = motor.parts['frame'], motor.parts['magnet']
    return {
        'winding_mean': Quantity(MEAN, copper, motor.copper_share),
        'winding_hotspot': Quantity(MAX, copper),
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
        self._states: Dict[str, np.ndarray] = {}      # positions in the state vector
        self._values: Dict[str, np.ndarray] = {}      # positions in the vector of values
        # how values() forms each output; the single states and ports are read in one go
        self._plan = []
        singles = []
        for name, q in outputs.items():
            missing = [s for s in q.states if s not in state_of]
            if missing:
                raise ValueError(f'output {name}: no state named {", ".join(missing)}')
            self._states[name] = np.array([state_of[s] for s in q.states])
            idx = self._values[name] = np.array([value_index(s) for s in q.states])
            if q.kind == MEAN:
                self._plan.append((name, q.kind, idx, q.weights, q.weights.sum()))
            elif q.kind == MAX:
                self._plan.append((name, q.kind, idx, None, None))
            else:
                self._plan.append((name, q.kind, len(singles), None, None))
                singles.extend(idx.tolist())
        self._singles = np.array(singles, dtype=int)

    def __deepcopy__(self, memo) -> 'QuantityMap':
        """Return the map itself: it never changes, so a copied model (a forecast's) shares it."""
        return self

    def values(self, v: np.ndarray, port_a_high: Optional[bool] = None) -> Dict[str, float]:
        """Return every output (in the unit of ``v``); a ``port`` one only with ``port_a_high``."""
        single = v[self._singles].tolist()
        out = {}
        for name, kind, at, w, w_sum in self._plan:
            if kind == MEAN:
                out[name] = float(np.dot(w, v[at]) / w_sum)
            elif kind == MAX:
                out[name] = float(v[at].max())
            elif kind == STATE:
                out[name] = single[at]
            elif port_a_high is not None:
                out[name] = single[at if port_a_high else at + 1]
        return out

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

    def states_taken(self, names: Sequence[str], v: np.ndarray, port_a_high: bool) -> List[int]:
        """Return the state each single-state output takes now: the hottest of a max, the port."""
        taken = []
        for name in names:
            q, states = self.outputs[name], self._states[name]
            if q.kind == MAX:
                taken.append(int(states[int(np.argmax(v[self._values[name]]))]))
            elif q.kind == PORT:
                taken.append(int(states[0 if port_a_high else 1]))
            elif q.kind == STATE:
                taken.append(int(states[0]))
            else:
                raise ValueError(f'output {name} is a weighted mean of {len(states)} states')
        return taken
