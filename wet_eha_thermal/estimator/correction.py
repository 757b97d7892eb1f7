"""
Live correction of the thermal model with the rig's thermocouples: a Kalman filter.

The filter's state is the coupled model's own state, the motor network's
states (K) and the 13 hydraulic node temperatures (K), augmented with up to
two random-walk disturbances: an unknown heat into the pump case oil (W) and
an unknown heat into the winding (W). A persistent model error, such as a
seal friction loss the friction law lacks, is then learned as a heat and
carried forward by the model itself (the case heat is added to the circuit's
``extra_loss_W``, the winding heat to the motor's copper sources), instead of
being fought anew at every step.

Each model step, once the filter is active:

- predict: the covariance goes through the step's exact transition, built
  from the model's linearisation of the step it just made
  (:meth:`~..model.eha.EHAModel.linearize`; the kernels are in
  :mod:`.kalman`): the motor's zero-order-hold matrices (``Ad``; the ``Bd``
  column of the oil inlet, which is the pump case temperature; the copper
  sources' columns with the linearised R(T) feedback dP/dT), the hydraulic
  step's matrix exponential, and the motor outlet's step-mean temperature
  (``Mx``, ``Mw``) that feeds the accumulator. Process
  noise is a white heat-rate error per node with heat capacity (``heat_noise_W``,
  K^2 = q^2 dt / C^2 per step), entered at the start of the step so that a
  fast oil node passes it on to its neighbours within the step, as heat does;
  the disturbances walk at their rates (their variance is capped at the prior).
- update: every thermocouple reading that passed its guards (below) is a
  scalar measurement of a linear output of the state, as the model's map of
  named quantities (:mod:`..model.quantities`) defines it: the winding mean
  and frame are weighted sums of nodes, the oil volumes single nodes, and
  the max-type outputs the hottest node. Scalar updates in turn, each in Joseph
  form (written as rank-one terms, O(n^2)), then the covariance symmetrised.
  The correction is written back into the model
  (:meth:`~..model.eha.EHAModel.correct`): motor states and node
  temperatures together (algebraic nodes through the network's output map),
  the hydraulic temperatures, and the pump case's previous temperature that
  the motor's inlet extrapolation uses, so the next step does not take the
  correction for a trend. The model's energy ledger books the learned heats
  (as sources) but not the state corrections themselves.

Sample time: a reading stamped ``t`` is used at the end of the first step
that starts at or after ``t``. A reading stamped exactly at a step's end
usually arrives after the live node made that step (the input sample that
closed the step triggered it), so this rule gives a replay of a bag and the
live run the same step, deterministically, for readings that arrive within a
step of their stamp. The delay (up to one step, 20 ms) is negligible against
a thermocouple's own lag (about 1 s), which is not modelled either.

Guards: a thermocouple is never trusted blindly. Per thermocouple:

- ``stale``: nothing for ``stale_timeout_s``; an older reading is not used.
- ``held``: the readings stayed within ``stuck_tolerance_K`` for
  ``stuck_window_s`` (a live sensor's noise moves it): not used. ``stuck``
  (dropped): held while the estimate of its point moved by more than
  ``stuck_motion_K``.
- ``noisy`` (dropped): the observed noise, from the median of the last
  ``noise_window`` differences of successive readings with the model's
  predicted change removed (a median, so that one jump does not count as
  noise), above ``noisy_ratio`` times ``sigma_K``, until it falls below half
  that; below it, a reading is weighted with the larger of the stated and the
  observed noise.
- ``gated`` readings (innovation beyond ``gate_sigma`` sigma) are not used;
  ``gate_count`` in a row drop the thermocouple (``implausible``), and
  ``recover_count`` readings in a row inside the gate take it back (the gate
  widens by itself while no thermocouple corrects the model, as the
  covariance grows).
- ``waiting``: fewer than 5 successive readings, or readings over less than
  half ``stuck_window_s`` (the noise is not known yet, nor whether it is frozen);
  ``absent``: no reading yet; ``unused``: ``use: false`` in the configuration.

The filter starts at the first usable reading: until then, and with no
thermocouples at all, the estimator runs open loop exactly as before (bit for
bit, and at no cost). It starts from the open-loop error model: every
temperature error has the 1 sigma ``estimator.model_uncertainty_K``, with
correlation ``initial_correlation`` between nodes (an open-loop error is
mostly a common offset: the oil that cools everything is off), and the
disturbances their prior sigma.
"""

from collections import deque
from dataclasses import dataclass, field
import math
from typing import Deque, Dict, List, Optional, Tuple

import numpy as np

from .kalman import FilterLayout, output_variances, predict_covariance, scalar_update, symmetrise
from ..config import Config
from ..interface import THERMOCOUPLES
from ..model.eha import EHAModel
from ..model.quantities import MEAN
from ..units import C_TO_K

#: Readings outside this range (degC) are rejected as implausible values.
READING_RANGE_C = (-60.0, 400.0)
#: Successive readings needed before a thermocouple's noise is known and it may be used.
MIN_READINGS = 5
#: Statuses in which a thermocouple is dropped from the correction (reported as such).
DROPPED = ('stuck', 'noisy', 'implausible')
#: readings of one thermocouple kept until the model steps to them (at 10 Hz, 100 s)
PENDING_READINGS = 1000
#: sigma of a reading from the median |difference| of two: 1 / (0.6745 sqrt(2))
_MEDIAN_TO_SIGMA = 1.0 / (0.6744897501960817 * math.sqrt(2.0))


def _median(values) -> float:
    """Return the median of ``values``, as :func:`statistics.median` (without its overhead)."""
    ordered = sorted(values)
    n = len(ordered)
    return ordered[n // 2] if n % 2 else (ordered[n // 2 - 1] + ordered[n // 2]) / 2


@dataclass
class ThermocoupleHealth:
    """Status and counters of one thermocouple in the correction (reported in diagnostics)."""

    quantity: str                   # the estimate it measures
    sigma_K: float                  # stated 1-sigma noise
    use: bool                       # configured for the correction
    status: str = 'absent'   # absent, waiting, ok, held, stuck, noisy, implausible, stale, unused
    received: int = 0
    rejected: int = 0               # non-finite, out of range, stamp not increasing or ahead
    used: int = 0                   # readings that corrected the model
    gated: int = 0                  # readings beyond the innovation gate
    late: int = 0                   # processed a step or more after their stamp
    stale_events: int = 0
    dropped_events: int = 0
    recovered: int = 0              # returns from a drop
    last_stamp_s: Optional[float] = None
    last_value_C: Optional[float] = None
    innovation_K: Optional[float] = None       # last reading minus the prior estimate
    innovation_sigma_K: Optional[float] = None  # its predicted 1 sigma
    noise_K: Optional[float] = None            # observed noise (1 sigma)
    reason: str = ''

    @property
    def dropped(self) -> bool:
        """Tell whether the thermocouple is dropped from the correction now."""
        return self.status in DROPPED


@dataclass
class _Guard:
    """Per-thermocouple memory of the guards."""

    # readings wait here for the step of their stamp; while the model does not step (no
    # input at all) the oldest go first, being stale by then anyway
    pending: Deque[Tuple[float, float]] = field(
        default_factory=lambda: deque(maxlen=PENDING_READINGS))
    # for the stuck test: the stamps (s) and readings (K) of the last stuck_window_s
    recent_s: Deque[float] = field(default_factory=deque)
    recent_K: Deque[float] = field(default_factory=deque)
    diffs: Deque[float] = field(default_factory=deque)                  # |differences| (K)
    prev_value: Optional[float] = None     # last reading (K)
    prev_post: Optional[float] = None      # estimate after the step of that reading (K)
    frozen_since: Optional[float] = None
    frozen_from_K: Optional[float] = None  # the estimate when the readings froze
    gated_run: int = 0
    ok_run: int = 0
    status_before_stale: str = 'waiting'


def filter_layout(model: EHAModel, i_case_d: int = -1, i_wind_d: int = -1) -> FilterLayout:
    """
    Return where the couplings of :func:`~.kalman.coupled_transition` sit in ``model``.

    ``i_case_d``, ``i_wind_d``: the filter states of the learned case and
    winding heats (-1: none; the transition of the model's state alone).
    """
    q, net = model.quantities, model.motor.net
    return FilterLayout(
        s_copper=q.state_indices('winding_mean'),
        col_copper=net.nb + np.array(model.motor.src_copper),
        col_inlet=net.boundary_index('oil_inlet'), w_copper=q.weights('winding_mean'),
        s_outlet=int(q.state_indices('motor_oil_outlet')[0]),
        i_case=model.circuit.index('case'), i_case_d=i_case_d, i_wind_d=i_wind_d)


class ThermalCorrection:
    """Kalman filter on the coupled model, fed by timestamped thermocouple readings."""

    def __init__(self, cfg: Config, model: EHAModel) -> None:
        c = cfg.estimator.correction
        self.settings = c
        self.sigma0_K = cfg.estimator.model_uncertainty_K
        mo = model.motor
        net = mo.net
        self.dynamic = net.dynamic
        self.m = int(self.dynamic.size)
        self.nh = model.circuit.n
        # disturbance states: (name, prior sigma W, rate W/s^0.5)
        dist = []
        if c.case_heat_sigma_W > 0.0:
            dist.append(('case_oil', c.case_heat_sigma_W, c.case_heat_rate_W_per_sqrt_s))
        if c.winding_heat_sigma_W > 0.0:
            dist.append(('winding', c.winding_heat_sigma_W, c.winding_heat_rate_W_per_sqrt_s))
        self.disturbance_names = [d[0] for d in dist]
        self._d_prior = np.array([d[1] for d in dist]) ** 2
        self._d_rate2 = np.array([d[2] for d in dist]) ** 2
        self.nd = len(dist)
        self.n = self.m + self.nh + self.nd
        self.d = np.zeros(self.nd)            # learned disturbances (W)
        self._i_case_d = self.m + self.nh + self.disturbance_names.index('case_oil') \
            if 'case_oil' in self.disturbance_names else None
        self._i_wind_d = self.m + self.nh + self.disturbance_names.index('winding') \
            if 'winding' in self.disturbance_names else None
        self.base_extra_loss_W = model.circuit.extra_loss_W
        # the measurement rows and the copper feedback read the model's map of named states
        # (an output node without heat capacity would not be a state: the map refuses it);
        # the winding mean is over the copper nodes, in the order of their sources
        q = model.quantities
        self._s_copper = q.state_indices('winding_mean')
        self._w_copper = q.weights('winding_mean')
        self._s_outlet = int(q.state_indices('motor_oil_outlet')[0])
        self._src_copper = np.array(mo.src_copper)
        model.circuit.keep_transition = True        # _predict reads it after every step
        # the outputs that are weighted means of states: their (fixed) rows
        means = [name for name, o in q.outputs.items() if o.kind == MEAN]
        self._mean_row = {name: k for k, name in enumerate(means)}
        self._H_mean = np.zeros((len(means), self.n))
        for k, name in enumerate(means):
            self._H_mean[k, q.state_indices(name)] = q.weights(name)
        self._mean_of_output = np.array([self._mean_row.get(name, -1) for name in q.names])
        self._output_position = {name: k for k, name in enumerate(q.names)}
        self._layout = filter_layout(model, -1 if self._i_case_d is None else self._i_case_d,
                                     -1 if self._i_wind_d is None else self._i_wind_d)
        wd = cfg.motor.winding
        self._alpha_cu = wd.copper_tempco_1_K
        self.P: Optional[np.ndarray] = None
        #: the variance (K^2) of every output after the last step, in the model map's order
        self.variances_K2: Optional[np.ndarray] = None
        self.tcs: Dict[str, ThermocoupleHealth] = {}
        for name, quantity in THERMOCOUPLES.items():
            tc = getattr(c.thermocouples, name)
            self.tcs[name] = ThermocoupleHealth(quantity=quantity, sigma_K=tc.sigma_K,
                                                use=tc.use,
                                                status='absent' if tc.use else 'unused')
        self._guards = {name: _Guard() for name in self.tcs}
        self._last_t0: Optional[float] = None
        self._received = False          # any reading buffered for the correction, ever
        self.updates = 0
        self.failures = 0               # numerical failures: the filter restarted
        self.last_failure = ''

    # ------------------------------------------------------------- readings
    @property
    def active(self) -> bool:
        """Tell whether the filter runs (it starts at the first usable reading)."""
        return self.P is not None

    def add_reading(self, name: str, stamp_s: float, value_C: float,
                    latest_s: float = math.inf) -> bool:
        """
        Buffer one reading (degC) of thermocouple ``name``; return whether it was accepted.

        A reading stamped after ``latest_s`` (the receiving clock plus the
        estimator's ``max_future_s``) is rejected: its stamp would make every
        later good reading look older.
        """
        h = self.tcs[name]                  # KeyError names an unknown thermocouple
        h.received += 1
        lo, hi = READING_RANGE_C
        if not (math.isfinite(stamp_s) and math.isfinite(value_C) and lo <= value_C <= hi) \
                or (h.last_stamp_s is not None and stamp_s <= h.last_stamp_s) \
                or stamp_s > latest_s:
            h.rejected += 1
            return False
        h.last_stamp_s, h.last_value_C = stamp_s, value_C
        if h.use:
            self._guards[name].pending.append((stamp_s, value_C + C_TO_K))
            self._received = True
        return True

    def restart_time(self) -> None:
        """Forget every stamp after a jump of the receiving clock; the filter's state stays."""
        for h in self.tcs.values():
            h.last_stamp_s = None
        for g in self._guards.values():
            g.pending.clear()
            g.recent_s.clear()
            g.recent_K.clear()
            g.prev_value = None
            g.frozen_since = None
        self._last_t0 = None

    def warm_up(self, model: EHAModel, dt: float) -> None:
        """
        Run the filter's kernels once, on a throw-away covariance, after a step of ``model``.

        Compiles them (or loads numba's cache) before a live start, where the
        filter would otherwise first run at the first usable reading; the
        filter's own state is not touched.
        """
        P = self.P
        try:
            self._start()
            self._predict(model, dt)
            _, taken = model.outputs_and_states()
            output_variances(self.P, taken, self._H_mean, self._mean_of_output)
            scalar_update(self.P, self._H_mean[0], 0.0, 0.0, 1.0, 1.0, True, np.zeros(self.n))
            symmetrise(self.P)
        finally:
            self.P = P

    # ------------------------------------------------------------------ step
    def step(self, model: EHAModel, t0: float, t1: float, dt: float,
             eps: float) -> Optional[Dict[str, float]]:
        """
        Correct the model after its step over (t0, t1] of ``dt`` s (time since the start).

        Readings stamped at or before ``t0`` (within ``eps``) are used. Returns
        the model's outputs (K) after the correction while the filter is
        active, None while it is not (the model was not touched). A numerical
        failure (a singular or non-finite covariance) is counted and restarts
        the filter at the next usable reading; it never stops the estimator.
        """
        if self.P is None and not self._received:
            return None
        try:
            return self._step(model, t0, t1, dt, eps)
        except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
            self.failures += 1
            self.last_failure = f'{type(exc).__name__}: {exc}'
            self.P = None
            self._last_t0 = t0
            return None

    def _step(self, model: EHAModel, t0: float, t1: float, dt: float,
              eps: float) -> Optional[Dict[str, float]]:
        batch: Dict[str, List[Tuple[float, float]]] = {}
        for name, g in self._guards.items():
            if g.pending and g.pending[0][0] <= t0 + eps:
                items = []
                while g.pending and g.pending[0][0] <= t0 + eps:
                    items.append(g.pending.popleft())
                batch[name] = items
        self._update_staleness(t1, batch)
        if self.P is None and not batch:
            self._last_t0 = t0
            return None
        if self.P is not None:
            self._predict(model, dt)
        prior, taken = model.outputs_and_states()
        candidates = []
        for name, items in batch.items():
            y = self._screen(name, items, prior[self.tcs[name].quantity], t0, t1, eps)
            if y is not None:
                candidates.append((name, y))
        if candidates and self.P is None:
            self._start()
        delta = np.zeros(self.n) if self.P is not None else None
        for name, y in candidates:
            h = self.tcs[name]
            r = max(h.sigma_K, h.noise_K or 0.0) ** 2
            self._gate_and_update(name, self._row(h.quantity, taken), y, prior[h.quantity],
                                  r, delta)
        post = prior
        if delta is not None and delta.any():
            self._write_back(model, delta)
            post, taken = model.outputs_and_states()
        for name in batch:
            self._guards[name].prev_post = post[self.tcs[name].quantity]
        self._last_t0 = t0
        if self.P is None:
            return None
        self.variances_K2 = output_variances(self.P, taken, self._H_mean, self._mean_of_output)
        return post

    def _update_staleness(self, t1: float, batch) -> None:
        timeout = self.settings.stale_timeout_s
        for name, h in self.tcs.items():
            if not h.use or h.last_stamp_s is None:
                continue
            g = self._guards[name]
            fresh = name in batch or bool(g.pending)
            if h.status == 'stale':
                if fresh and t1 - h.last_stamp_s <= timeout:
                    h.status = g.status_before_stale
                    h.reason = ''
                continue
            if t1 - h.last_stamp_s > timeout:
                g.status_before_stale = h.status
                h.status = 'stale'
                h.stale_events += 1
                h.reason = f'no reading for {t1 - h.last_stamp_s:.1f} s'
                g.prev_value = None          # no difference across the gap
                g.recent_s.clear()
                g.recent_K.clear()
                g.frozen_since = None

    def _screen(self, name: str, items, prior_K: float, t0: float, t1: float,
                eps: float) -> Optional[float]:
        """Run the guards over a thermocouple's new readings; return the one to use (K)."""
        s = self.settings
        h, g = self.tcs[name], self._guards[name]
        use = None
        for stamp, y in items:
            if self._last_t0 is not None and stamp <= self._last_t0 + eps:
                h.late += 1
            if t1 - stamp > s.stale_timeout_s:
                continue                      # too old to use
            # observed noise: successive differences with the predicted change removed,
            # by their median (a single jump is not noise: the gate sees to it)
            if g.prev_value is not None and g.prev_post is not None:
                g.diffs.append(abs((y - g.prev_value) - (prior_K - g.prev_post)))
                if len(g.diffs) > s.noise_window:
                    g.diffs.popleft()
                h.noise_K = _MEDIAN_TO_SIGMA * _median(g.diffs)
            g.prev_value = y
            g.prev_post = prior_K              # until this step's update, the prior
            # frozen readings
            g.recent_s.append(stamp)
            g.recent_K.append(y)
            while g.recent_s[0] < stamp - s.stuck_window_s:
                g.recent_s.popleft()
                g.recent_K.popleft()
            span = stamp - g.recent_s[0]
            frozen = (len(g.recent_K) >= 3 and span >= 0.5 * s.stuck_window_s
                      and max(g.recent_K) - min(g.recent_K) <= s.stuck_tolerance_K)
            if frozen:
                if g.frozen_since is None:
                    g.frozen_since, g.frozen_from_K = stamp, prior_K
                moved = abs(prior_K - g.frozen_from_K)
                self._set(h, 'stuck' if moved > s.stuck_motion_K or h.status == 'stuck'
                          else 'held',
                          f'reading frozen at {y - C_TO_K:.2f} degC for '
                          f'{stamp - g.frozen_since + span:.1f} s while the estimate moved '
                          f'{moved:.2f} K')
                continue
            g.frozen_since = None
            noisy_limit = s.noisy_ratio * h.sigma_K
            if h.noise_K is not None and (h.noise_K > noisy_limit or (
                    h.status == 'noisy' and h.noise_K > 0.5 * noisy_limit)):
                self._set(h, 'noisy', f'observed noise {h.noise_K:.2f} K against '
                          f'sigma_K {h.sigma_K:g} K')
                continue
            # a new thermocouple waits until it could have shown itself frozen: a broken
            # junction reading a constant from the start is then never used
            if len(g.diffs) < MIN_READINGS - 1 or (
                    h.status in ('absent', 'waiting') and span < 0.5 * s.stuck_window_s):
                self._set(h, 'waiting', 'learning its noise')
                continue
            if h.status in ('absent', 'waiting', 'held', 'stuck', 'noisy'):
                self._set(h, 'ok', '')
            use = y
        return use

    def _set(self, h: ThermocoupleHealth, status: str, reason: str) -> None:
        """Change a thermocouple's status, counting drops and recoveries."""
        if status in DROPPED and not h.dropped:
            h.dropped_events += 1
        elif h.dropped and status not in DROPPED:
            h.recovered += 1
        h.status, h.reason = status, reason

    def _gate_and_update(self, name: str, row: np.ndarray, y: float, prior: float, r: float,
                         delta: np.ndarray) -> None:
        """
        Gate one reading ``y`` (K) and, if it passes, do the scalar update (Joseph form).

        ``prior``: the estimate before the step's updates (``delta``, which
        this one adds to).
        """
        s = self.settings
        h, g = self.tcs[name], self._guards[name]
        # a thermocouple coming back from implausible is used after recover_count in a row
        use = h.status != 'implausible' or g.ok_run + 1 >= s.recover_count
        innovation, var, inside = scalar_update(self.P, row, y, prior, r, s.gate_sigma ** 2,
                                                use, delta)
        if not (math.isfinite(innovation) and math.isfinite(var) and var > 0.0):
            raise FloatingPointError(f'{name}: innovation {innovation} K, variance {var} K^2')
        h.innovation_K = innovation
        h.innovation_sigma_K = math.sqrt(var)
        if not inside:
            h.gated += 1
            g.gated_run += 1
            g.ok_run = 0
            if g.gated_run >= s.gate_count and h.status != 'implausible':
                self._set(h, 'implausible', f'{g.gated_run} readings in a row beyond '
                          f'{s.gate_sigma:g} sigma (last {innovation:+.2f} K, sigma '
                          f'{math.sqrt(var):.2f} K)')
            return
        g.gated_run = 0
        if not use:
            g.ok_run += 1
            return
        if h.status == 'implausible':
            self._set(h, 'ok', '')
        g.ok_run = 0
        h.used += 1
        self.updates += 1

    # ------------------------------------------------------------ the filter
    def _start(self) -> None:
        """Start the covariance from the open-loop error model."""
        c = self.settings.initial_correlation
        nt = self.m + self.nh
        P = np.zeros((self.n, self.n))
        P[:nt, :nt] = self.sigma0_K ** 2 * c
        P[np.arange(nt), np.arange(nt)] = self.sigma0_K ** 2
        if self.nd:
            P[nt:, nt:] = np.diag(self._d_prior)
        self.P = P

    def add_parameter_growth(self, growth_K2: np.ndarray) -> None:
        """
        Add the growth of the parameter uncertainty over a period (K^2, over the model's states).

        The uncertain parameters are constants: Schmidt's consider filter
        would carry their cross-covariance with the state. Here their effect
        enters as process noise, the covariance of the change of the state
        sensitivities over the period (:mod:`.uncertainty`): a filter that
        sees thermocouples corrects the state each step, so what a parameter
        adds between corrections is its recent change, not its whole effect.
        Nothing before the filter starts (it starts from its prior).
        """
        if self.P is None:
            return
        nt = self.m + self.nh
        self.P[:nt, :nt] += growth_K2

    def _predict(self, model: EHAModel, dt: float) -> None:
        """Propagate the covariance through the step just made (``dt`` s)."""
        lin = model.linearize()
        self.P = predict_covariance(
            self.P, lin.motor, lin.circuit, lin.copper_K, lin.copper_power_W, self._alpha_cu,
            self._layout, lin.motor_capacity_J_K, lin.circuit_capacity_J_K,
            self.settings.heat_noise_W ** 2 * dt, self._d_rate2 * dt, self._d_prior)

    def _write_back(self, model: EHAModel, delta: np.ndarray) -> None:
        """Put the corrected state into the model, and the learned heats into its sources."""
        mo, m, nh = model.motor, self.m, self.nh
        model.correct(delta[:m + nh])
        if self.nd:
            self.d = self.d + delta[m + nh:]
            if self._i_case_d is not None:
                model.circuit.extra_loss_W = self.base_extra_loss_W + float(
                    self.d[self._i_case_d - m - nh])
            if self._i_wind_d is not None:
                mo.extra_power_W = np.zeros(mo.net.ns)
                mo.extra_power_W[self._src_copper] = \
                    self.d[self._i_wind_d - m - nh] * self._w_copper
        symmetrise(self.P)

    # ------------------------------------------------------------ outputs
    def _row(self, quantity: str, taken: np.ndarray) -> np.ndarray:
        """Return the output's sensitivity to the filter state (``taken``: the states taken)."""
        k = self._mean_row.get(quantity)
        if k is not None:
            return self._H_mean[k]
        row = np.zeros(self.n)
        row[taken[self._output_position[quantity]]] = 1.0
        return row

    def summary(self) -> Dict[str, object]:
        """Return what an estimate reports: active, learned heats (W), thermocouple statuses."""
        return {'active': self.active,
                'disturbance_W': dict(zip(self.disturbance_names, self.d.tolist())),
                'thermocouples': {name: h.status for name, h in self.tcs.items()
                                  if h.received}}
