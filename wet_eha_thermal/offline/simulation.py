"""
Offline duty-cycle simulation: kinetic EHA model -> sensor samples -> thermal model.

The kinetic model plays the rig: from a duty (a reference stage or a table)
it makes the sensor signals at ``sample_rate_Hz``, using the thermal model's
present oil temperatures for viscosity and its airgap friction. The thermal
model then consumes those samples block by block exactly as the live
estimator consumes the rig's, so an offline run exercises the same path. A
:class:`SensorTable` gives the sensor signals themselves instead of a duty.
"""

from dataclasses import dataclass, field
import functools
import math
from typing import Callable, Dict, List, Mapping, Optional, Union

import numpy as np

from ..config import Config
from ..interface import INPUTS
from ..model.duty import Duty, DutyError
from ..model.eha import EHAModel, SampleBlock
from ..model.kinetics import KineticModel, ThermalFeedback
from ..units import C_TO_K, MPA, RPM_PER_RAD_S

RUNAWAY_C = 300.0   # far past every limit (oil 135, insulation 180 degC): stop, do not extrapolate


class ThermalRunaway(RuntimeError):
    """A duty the cooling cannot hold: a temperature passed ``RUNAWAY_C``; has the partial run."""

    def __init__(self, message: str, result: 'SimulationResult') -> None:
        super().__init__(message)
        self.result = result


@dataclass
class SimulationResult:
    """Time histories (one row per recorded step) and the run's energy totals (J)."""

    time_s: List[float] = field(default_factory=list)
    temperatures_K: Dict[str, List[float]] = field(default_factory=dict)
    inputs: Dict[str, List[float]] = field(default_factory=dict)
    heat_W: Dict[str, List[float]] = field(default_factory=dict)
    electrical_J: float = 0.0
    load_work_J: float = 0.0
    model: Optional[EHAModel] = None

    def append(self, t: float, temps: Dict[str, float], inputs: Dict[str, float],
               heat: Dict[str, float]) -> None:
        """Add one recorded row."""
        self.time_s.append(t)
        for store, row in ((self.temperatures_K, temps), (self.inputs, inputs),
                           (self.heat_W, heat)):
            for k, v in row.items():
                store.setdefault(k, []).append(v)


class SensorTable:
    """
    A duty given as the sensor signals: time with current, speed, pressures (and position).

    ``columns`` maps each of :data:`~..interface.INPUTS` to its values at ``time_s`` (SI
    units; ``position_m`` may be left out: the piston then stands still at
    mid-stroke). The signals are linear between the rows and repeat with the
    period ``time_s[-1]``, as a :class:`~.model.duty.TableDuty` does; the
    table's time 0 is the model time ``start_s``. :func:`simulate` feeds them
    to the thermal model as they are, without the kinetic model, so a run on
    them has no electrical energy or load work (NaN). Raises
    :class:`~.model.duty.DutyError` for a table it cannot use.
    """

    def __init__(self, time_s, columns: Mapping[str, object], start_s: float = 0.0,
                 name: str = 'sensor table') -> None:
        """Check the table; raise :class:`DutyError` naming the column at fault."""
        self.name = str(name)
        t = np.array(time_s, dtype=float)
        if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)):
            raise DutyError(f'{self.name}: time_s must hold at least 2 finite times')
        if t[0] != 0.0 or np.any(np.diff(t) <= 0.0):
            raise DutyError(f'{self.name}: time_s must start at 0 and increase strictly')
        unknown = sorted(set(columns) - set(INPUTS))
        if unknown:
            raise DutyError(f'{self.name}: unknown column {unknown[0]!r}; the columns are '
                            f'{", ".join(INPUTS)}')
        self._values = {}
        for name in INPUTS:
            if name not in columns and name != 'position_m':
                raise DutyError(f'{self.name}: missing column {name}')
            v = np.array(columns.get(name, np.zeros(t.size)), dtype=float)
            if v.shape != t.shape or not np.all(np.isfinite(v)):
                raise DutyError(f'{self.name}: column {name} must hold {t.size} finite numbers, '
                                'one per time')
            self._values[name] = v
        self._t = t
        self.period_s = float(t[-1])
        self.start_s = float(start_s)

    def sample(self, t_s: np.ndarray, fb: Optional[ThermalFeedback] = None) -> SampleBlock:
        """Return the signals at the model times ``t_s`` (``fb``: unused, as the rig's are)."""
        t = np.asarray(t_s, dtype=float)
        local = np.mod(t - self.start_s, self.period_s)
        return SampleBlock(t, *(np.interp(local, self._t, self._values[n]) for n in INPUTS))


def feedback(model: EHAModel) -> ThermalFeedback:
    """Return the thermal state the kinetic model needs (viscosity temperatures, losses)."""
    ci, m = model.circuit, model.motor
    T = model.T_hyd
    return ThermalFeedback(
        pump_oil_K=float(T[ci.index('case')]),
        line_oil_K=float(0.5 * (T[ci.index('line_a')] + T[ci.index('line_b')])),
        winding_K=m.outputs()['winding_mean'],
        drag_W=m.shaft_drag_W, electromagnetic_loss_W=m.electromagnetic_loss_W)


def motor_heat(model: EHAModel) -> Dict[str, float]:
    """
    Return the model's heat flows of the last step (W), with where the motor's heat is made.

    :attr:`EHAModel.heat_W`, each motor loss as ``loss_<name>``
    (:data:`~.model.motor.LOSS_NAMES`) and the motor's heat paths as
    ``motor_<path>`` (:meth:`~.model.motor.WetMotor.heat_paths_W`).
    """
    heat = dict(model.heat_W)
    heat.update({f'loss_{k}': v for k, v in model.motor.losses_W.items()})
    heat.update({f'motor_{k}': v for k, v in model.motor.heat_paths_W().items()})
    return heat


class _InputMeans:
    """
    The inputs recorded with a row: their means over the record interval.

    A snapshot of a 1 Hz duty taken every second would always catch the same
    phase; the current is its RMS, the position the last sample's.
    """

    def __init__(self) -> None:
        self.acc = np.zeros(5)   # integrals over the record interval: I^2, |w|, p_a, p_b, time

    def add(self, s: SampleBlock, w: np.ndarray) -> None:
        """Add the samples ``s``, each weighted by the time it stands for (``w``, s)."""
        self.acc += [np.dot(s.current_A ** 2, w), np.dot(np.abs(s.speed_rad_s), w),
                     np.dot(s.p_a_Pa, w), np.dot(s.p_b_Pa, w), w.sum()]

    def take(self, s: SampleBlock) -> Dict[str, float]:
        """Return the means since the last call (in the units people read), and start again."""
        acc = self.acc
        span = acc[4]
        means = {'current_A_rms': float(np.sqrt(acc[0] / span)),
                 'speed_rpm': float(acc[1] / span * RPM_PER_RAD_S),
                 'p_a_MPa': float(acc[2] / span / MPA),
                 'p_b_MPa': float(acc[3] / span / MPA),
                 'position_mm': float(s.position_m[-1] * 1e3)}
        acc[:] = 0.0
        return means


def _stop_on_runaway(res: SimulationResult, t_s: float, out: Dict[str, float],
                     model: EHAModel) -> None:
    """Raise :class:`ThermalRunaway`, the row at ``t_s`` recorded, when an output passed it."""
    hottest = max(out.items(), key=lambda kv: kv[1])
    if hottest[1] - C_TO_K > RUNAWAY_C:
        res.append(t_s, out, {}, motor_heat(model))
        raise ThermalRunaway(f'thermal runaway: {hottest[0]} passed {RUNAWAY_C:.0f} degC at '
                             f't = {t_s:.0f} s; the cooling cannot hold this duty', res)


def simulate(cfg: Config, duty: Union[Duty, SensorTable], duration_s: float, dt_s: float = 1.0,
             sample_rate_Hz: float = 200.0, ambient_C: float = 20.0,
             initial_C: Optional[float] = None, record_every_s: float = 1.0,
             progress: Optional[Callable[[int, int, str], None]] = None,
             model: Optional[EHAModel] = None) -> SimulationResult:
    """
    Run ``duty`` for ``duration_s`` and return the recorded histories.

    ``dt_s`` is the thermal model step; each step gets ``sample_rate_Hz * dt_s``
    samples. All temperatures start at ``initial_C`` (default: ambient). A
    ``model`` that has already run continues from its state and time (and
    ``initial_C`` is ignored), so a long run can be split into pieces. A
    :class:`SensorTable` is fed to the thermal model as it is.

    Raises :class:`ThermalRunaway`, with the run so far, when a temperature
    passes ``RUNAWAY_C``: the leakage loss of a sustained high load grows as
    the oil thins, and nothing but the housings' natural convection removes it.
    """
    n_sub = max(1, int(round(sample_rate_Hz * dt_s)))
    steps = int(round(duration_s / dt_s))
    amb_K = ambient_C + C_TO_K
    model = model if model is not None else EHAModel(cfg)
    # the sensor signals at given times, from the thermal state: the kinetic model plays the
    # rig, or a sensor table gives them
    table = isinstance(duty, SensorTable)
    sample = duty.sample if table else functools.partial(
        KineticModel(cfg, model.oil, model.log).sample, duty)
    if model.T_hyd is None:
        start_K = (initial_C if initial_C is not None else ambient_C) + C_TO_K
        model.T_hyd = np.full(model.circuit.n, start_K)
        first = sample(np.array([0.0]), ThermalFeedback.uniform(start_K))
        model.initialise(start_K, first)
    t_start = model.time_s
    res = SimulationResult(model=model)
    if table:
        res.electrical_J = res.load_work_J = math.nan    # the signals alone do not tell them
    frac = np.arange(1, n_sub + 1) / n_sub
    record_every = max(1, int(round(record_every_s / dt_s)))
    report_every = max(1, steps // 100)
    means = _InputMeans()
    for k in range(steps):
        t = t_start + (k + frac) * dt_s
        s = sample(t, feedback(model))
        model.step(s, amb_K)
        out = model.outputs()
        _stop_on_runaway(res, float(t[-1]), out, model)
        w = np.diff(np.concatenate([[t_start + k * dt_s], t]))
        if not table:
            res.electrical_J += float(np.dot(s.electrical_power_W, w))
            res.load_work_J += float(np.dot(s.load_power_W, w))
        means.add(s, w)
        if (k + 1) % record_every == 0 or k == steps - 1:
            res.append(float(t[-1]), out, means.take(s), motor_heat(model))
        if progress is not None and (k % report_every == 0 or k == steps - 1):
            progress(k + 1, steps, f't = {t[-1]:.0f} s')
    return res
