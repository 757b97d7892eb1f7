"""
The live estimator without ROS: timestamped samples in, estimates and alerts out.

The estimator by its jobs: :mod:`.intake` takes the samples (buffers, checks,
sensor health, the receiving clock, data gaps); this module steps the model;
:mod:`.outlook` forecasts the limits and the margin current in the background;
:mod:`.correction` corrects the model with the thermocouples; :mod:`.alerts`
raises the alerts. Those parts are private: every caller (the live node,
replay, calibration, what-if, the tests) drives an estimator through one
:class:`~.session.EstimatorSession`, which decides what to publish.

``advance`` steps the coupled thermal model over the complete steps of
``step_s`` in *sample time* (the stamps, never the wall clock), so a replayed
log gives the same estimates as the live run. Inside a step each input is
averaged on a grid of ``block_rate_Hz``: current as the mean of I^2 (copper
loss is I^2 R: the square of a mean would alias), speed and pressures as
means, position interpolated (the actuator flow is its difference quotient);
the model then forms the flow-pressure products and losses per grid interval.
The estimator never waits for a stale input: it steps on the fallback, says
so in every estimate, and widens the uncertainty while it lasts. Implausible
combinations (speed with no current; actuator flow with no speed; the
position moving faster than the pump can drive it, which is then
rate-limited) are counted per step. The model never steps across a jump of
the receiving clock (:meth:`Estimator.restart_time`).

Bounded work: one ``advance`` makes at most ``max_steps_per_call`` model
steps; the rest waits for the next call (``behind`` tells). A silence of
every input of ``HOLD_AFTER_STEPS`` steps or more is crossed in held blocks,
each one exact step of the motor network and of the circuit on the
fallbacks, so an hour of silence costs a few dozen steps, not 180 000.

Thermocouple readings (``add_measured``) are shown beside the estimates they
measure and, with ``estimator.correction.enabled``, correct the model through
a Kalman filter in sample time; with no readings the model runs open loop,
bit for bit as without the filter, and the uncertainty of each estimate then
comes from the filter's covariance.
"""

from dataclasses import dataclass, field
import math
import sys
import time
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from .alerts import AlertEvent, AlertManager, rules_from_config
from .correction import ThermalCorrection
from .intake import ChannelHealth, DataGaps, DIFFERENTIAL_INPUTS, INPUTS, Intake
from .limits import CurrentLimits
from .outlook import Outlook
from .uncertainty import Propagation
from ..config import Config
from ..model import quantity_table
from ..model.compiled import jit
from ..model.eha import EHAModel, SampleBlock
from ..units import C_TO_K, L_MIN_PER_M3_S

#: how the estimator works on its outlook (its ``outlook`` argument)
OUTLOOK_MODES = ('off', 'background', 'inline')
#: A stretch of at least this many steps without a sample of any input is crossed in held
#: blocks; shorter ones step by step (the live twin's 50 Hz steps on fallbacks).
HOLD_AFTER_STEPS = 50
#: Held blocks start at HOLD_FIRST_S, double while the state moves less than HOLD_TOL_K in
#: one (a block is exact for fixed coefficients; the copper resistance, the viscosities
#: and the convection move with the temperatures), halve above twice that, and never
#: exceed HOLD_MAX_S. Against stepping step by step over an hour: benchmarks/bench_silence.py.
HOLD_FIRST_S = 1.0
HOLD_MAX_S = 512.0
HOLD_TOL_K = 2.0


@dataclass
class Estimate:
    """One model step's output: temperatures (degC), uncertainty (K, 1 sigma), heat flows (W)."""

    stamp_s: float
    temperatures_C: Dict[str, float]
    uncertainty_K: Dict[str, float]
    heat_W: Dict[str, float]
    limits_C: Dict[str, float]
    time_to_limit_s: Dict[str, Optional[float]]   # None: not within the forecast horizon
    forecast_stamp_s: Optional[float]              # when that forecast started (sample time)
    margin_current_A: Optional[float]              # the latest continuous current limit (A)
    alert_level: int
    alert_events: List[AlertEvent]
    stale: List[str]
    implausible: List[str]
    step: int
    # live correction (None when it is off): active, learned heats (W), thermocouple statuses
    correction: Optional[Dict[str, Any]] = None
    # what happened to the time base since the last estimate: data gaps, clock jumps
    notices: List[str] = field(default_factory=list)
    # each sensor input on the step's grid as the model took it (SI; the current as the
    # root of the mean square per grid interval; one value for a held block): arrays the
    # estimator never writes again, so a display can average them on another thread
    inputs: Dict[str, np.ndarray] = field(default_factory=dict)
    # the latest current limits published for the drive, with the status they went out
    # with (set by the session, :mod:`.session`; None before the first)
    current_limits: Optional[CurrentLimits] = None
    # the model's state after the step (K; the order of ``model.quantities.state_names``)
    state_K: np.ndarray = field(default_factory=lambda: np.zeros(0))


class Estimator:
    """Turn timestamped samples into temperature estimates, alerts and forecasts."""

    def __init__(self, cfg: Config, model: Optional[EHAModel] = None,
                 outlook: str = 'off') -> None:
        if outlook not in OUTLOOK_MODES:
            raise ValueError(f'outlook {outlook!r}: expected one of {OUTLOOK_MODES}')
        self.cfg = cfg
        s = cfg.estimator
        self.settings = s
        # deferred refresh: the slow re-discretisation runs in prepare(), after the
        # estimate has left, and the coefficients lag by one 20 ms step
        self.model = model if model is not None else EHAModel(
            cfg, coefficient_filter_s=s.coefficient_filter_s, defer_refresh=True)
        self.n_grid = max(1, int(round(s.step_s * s.block_rate_Hz)))
        self._frac = np.arange(1, self.n_grid + 1) / self.n_grid   # grid times in a step
        # samples, their checks and health, the clock; stamps this close count as equal
        self._intake = Intake(cfg, resolution_s=1e-6 * s.step_s / self.n_grid)
        self.inputs = self._intake.inputs
        #: each input's counters and state (:class:`~.intake.ChannelHealth`), by name
        self.health: Dict[str, ChannelHealth] = self._intake.health
        #: silences of every input at once (:class:`~.intake.DataGaps`)
        self.gaps: DataGaps = self._intake.gaps
        self.ambient_K = s.ambient_C + C_TO_K
        self.measured_C: Dict[str, tuple] = {}
        # live correction with the thermocouples (estimator.correction): a Kalman filter
        # that starts at the first usable reading; until then the model runs open loop
        self._correction = ThermalCorrection(cfg, self.model) if s.correction.enabled else None
        self._alerts = AlertManager(rules_from_config(s.alerts))
        self.limits_C = quantity_table.limits_C(cfg)
        #: the limits and the forecast (:mod:`.outlook`): 'off', worked on in the
        #: 'background' (a live node), or 'inline' at each tick (offline)
        self.outlook_mode = outlook
        self._outlook = Outlook(cfg, self.model, self.limits_C, inline=outlook == 'inline')
        #: the uncertainty propagated from the configuration's stated sigmas (None: the
        #: constant ``model_uncertainty_K``)
        self.propagation = Propagation(cfg, self.model.quantities.names) \
            if cfg.uncertainty is not None else None
        self._t_origin = 0.0
        self.t_model: Optional[float] = None
        #: sample time at which the next step ends (-inf before the start): a sample
        #: stamped at or after it may let that step complete
        self.next_end_s = -math.inf
        self.steps = 0
        self.latest: Optional[Estimate] = None
        self.held_blocks = 0           # held blocks made across silences
        self._hold_s = HOLD_FIRST_S     # length of the next held block
        self._behind = False
        self._crossed: set = set()      # inputs with a sample past the next step's end
        self._needed = len(self.inputs)  # how many must be (the fresh ones)
        self.implausible_counts = {'speed_without_current': 0, 'flow_without_speed': 0,
                                   'position_faster_than_pump': 0}
        # the pump's geometric flow at the top of the speed range, over the piston area
        speed = s.channels.speed_rad_s
        self.max_stroke_speed_m_s = (cfg.hydraulics.pump.displacement_m3_rev / (2 * math.pi)
                                     * max(abs(speed.low), abs(speed.high))
                                     / cfg.hydraulics.actuator.area_m2)
        self._position_limited = False

    @property
    def clock_jumps(self) -> int:
        """Return how many jumps of the receiving clock re-started the model time."""
        return self._intake.clock_jumps

    # ----------------------------------------------------------------- input
    def push(self, channel: str, stamp_s: float, value: float) -> bool:
        """
        Take one sample (SI units) as a live node does; return whether a step may now be due.

        The sample goes, unchecked, to its input's buffer (all the work for
        most samples; a full buffer drops it, counted); it is checked at the
        next ``advance``. True once every fresh input reaches past the end of
        the next step: the caller then advances
        (:meth:`~.session.EstimatorSession.take`).
        """
        return self._intake.push(channel, stamp_s, value) and self._due(channel, stamp_s)

    def push_many(self, channel: str, stamps_s: np.ndarray, values: np.ndarray) -> bool:
        """Take a block of samples of one input (a batched message) as :meth:`push` takes one."""
        return bool(len(stamps_s)) and self._intake.push_many(channel, stamps_s, values) \
            and self._due(channel, float(stamps_s[-1]))

    def _due(self, channel: str, stamp_s: float) -> bool:
        """
        Tell whether ``advance`` may now complete a step, after a sample of ``channel`` (cheap).

        True once every input that was fresh at the last step has a sample
        at or after the end of the next step: the live node then advances once
        per step, not once per sample of an input that runs ahead of the
        others.
        """
        if stamp_s < self.next_end_s:
            return False
        self._crossed.add(channel)
        return len(self._crossed) >= self._needed

    def _late_before(self) -> float:
        """Return the stamp at or before which a sample is late (the model stepped past it)."""
        return self.t_model + self._intake.eps if self.t_model is not None else -math.inf

    def add_many(self, channel: str, stamps_s: np.ndarray, values: np.ndarray,
                 now_s: Optional[float] = None) -> int:
        """
        Take many samples of one input at once, checked; return how many were accepted.

        For replaying logs: the checks of :meth:`.intake.Intake.add_many`.
        ``now_s``: the receiving clock (s) for the future check, one reading
        for all or one per sample (a log's receive times); unlike
        ``advance``'s it is not taken as the clock.
        """
        return self._intake.add_many(channel, stamps_s, values, now_s, self._late_before())

    def add_ambient(self, stamp_s: float, value_C: float) -> bool:
        """Take an ambient temperature (degC) for the housings' heat loss."""
        if not (math.isfinite(value_C) and -60.0 <= value_C <= 150.0):
            return False
        self.ambient_K = value_C + C_TO_K
        return True

    def add_measured(self, name: str, stamp_s: float, value_C: float) -> bool:
        """
        Take a thermocouple reading (degC) of ``name`` (a key of ``interface.THERMOCOUPLES``).

        It is reported beside the estimate it measures and, with the live
        correction on, corrects the model at the end of the first step that
        starts at or after ``stamp_s``. Returns whether it was accepted; a
        reading stamped more than ``max_future_s`` ahead of the receiving
        clock is not.
        """
        correcting = self._correction is not None and name in self._correction.tcs
        latest = self._intake.latest_allowed()
        if not math.isfinite(value_C) or not stamp_s <= latest:
            if correcting:
                self._correction.add_reading(name, stamp_s, value_C, latest)   # counted there
            return False
        self.measured_C[name] = (stamp_s, value_C)
        if correcting:
            return self._correction.add_reading(name, stamp_s, value_C, latest)
        return True

    def acknowledge(self, quantity: Optional[str] = None) -> List[AlertEvent]:
        """Acknowledge latched alerts (all, or one quantity)."""
        stamp = self.t_model if self.t_model is not None else 0.0
        return self._alerts.acknowledge(quantity, stamp_s=stamp)

    # ------------------------------------------------------------- the clock
    def _observe_clock(self, now_s: float) -> None:
        """Take a reading of the receiving clock; a jump back re-starts the model time."""
        if self._intake.observe_clock(now_s):
            self.restart_time(now_s)

    def restart_time(self, now_s: float) -> None:
        """
        Re-start the model time at ``now_s`` (a jump of the receiving clock); keep the state.

        The model never steps across the jump: its next step starts at
        ``now_s``. Samples buffered under the old clock are discarded and
        counted per input (``discarded``); every input's last stamp is
        forgotten, so the new clock's samples are not taken for stamps going
        backwards; stored stamps (alert timers, the forecast's schedule, the
        open data gap) move by the jump, so their durations carry over; the
        thermocouples' stamps are forgotten. Called by ``advance``
        when the clock goes back by more than ``clock_jump_s``; a node that
        can tell a forward step of its clock from elapsed time calls it too.
        """
        # the first step after the jump ends at the reading that showed it, so that the
        # samples of the new clock stamped up to that reading are not late
        delta = now_s - self.settings.step_s - self.t_model if self.t_model is not None else 0.0
        self._intake.restart(now_s, delta)
        if self.t_model is None:
            return
        self.t_model += delta
        self._t_origin += delta
        self.next_end_s += delta
        self._intake.resolve(now_s)
        self._alerts.shift_time(delta)
        if self._correction is not None:
            self._correction.restart_time()
        self._outlook.shift_time(delta)
        self.measured_C = {k: (t + delta, v) for k, (t, v) in self.measured_C.items()}

    # ------------------------------------------------------------- stepping
    @property
    def behind(self) -> bool:
        """Tell whether complete steps wait for the next ``advance`` (its step limit hit)."""
        return self._behind

    def advance(self, now_s: Optional[float] = None,
                max_steps: Optional[int] = None) -> List[Estimate]:
        """
        Step the model through the complete steps that the samples allow; return the estimates.

        The model may step to the oldest latest stamp among the fresh inputs.
        ``now_s`` (the receiving clock, in the time base of the stamps, e.g.
        the ROS clock) lets silent inputs go stale and the model keep stepping
        without them. At most ``max_steps`` steps (default
        ``estimator.max_steps_per_call``; a held block across a silence counts
        as one) are made; ``behind`` then tells that more are due.
        """
        try:
            return self._advance(now_s, max_steps)
        finally:
            self._arm()

    def _arm(self) -> None:
        """Note which fresh inputs already reach past the next step's end (see ``_due``)."""
        fresh = [h for h in self.health.values() if not h.stale]
        self._needed = max(len(fresh), 1)
        self._crossed = {n for n, h in self.health.items() if not h.stale
                         and h.last_stamp_s is not None and h.last_stamp_s >= self.next_end_s}

    def _advance(self, now_s: Optional[float], max_steps: Optional[int]) -> List[Estimate]:
        """Step as :meth:`advance` says; the samples of the steps made are used up."""
        if now_s is not None:
            self._observe_clock(now_s)
        self._intake.screen(self._late_before())
        self._behind = False
        ref = self._intake.reference_time(now_s)
        if ref is None:
            return []
        stale = self._intake.update_staleness(ref)
        fresh = [n for n in self.inputs if n not in stale]
        horizon = min(self.health[n].last_stamp_s for n in fresh) if fresh else ref
        if self.t_model is None:
            # start once every input has spoken (or its timeout passed), at the latest
            # first stamp: each input then has a value at the start, live or replayed
            firsts = self._intake.first_stamps()
            if not firsts:
                self._start(horizon)
                return []
            patience_s = max(c.timeout_s for c in self._intake.channel_cfg.values())
            if len(firsts) < len(self.inputs) and ref - min(firsts) <= patience_s:
                return []
            self._start(max(firsts))
            stale = self._intake.update_staleness(ref)
            fresh = [n for n in self.inputs if n not in stale]
            horizon = min(self.health[n].last_stamp_s for n in fresh) if fresh else ref
        self._intake.track_gap(stale)
        budget = self.settings.max_steps_per_call if max_steps is None else max_steps
        out: List[Estimate] = []
        try:
            while len(out) < budget:
                n_steps = self._complete_steps(horizon)
                if not n_steps:
                    break
                held, n_run = self._silent_run(n_steps)
                if held:
                    # one held block per call: it costs as much as several steps
                    out.append(self._hold(n_run, stale))
                    break
                self._hold_s = HOLD_FIRST_S
                n_steps = min(n_run, budget - len(out))
                ends = [self._step_end(self.steps + k) for k in range(n_steps + 1)]
                grid_values = self._grid_block(np.array(ends))
                for k in range(n_steps):
                    out.append(self._step(ends[k], ends[k + 1], 1, stale,
                                          {n: v[k] for n, v in grid_values.items()}))
            self._behind = self._complete_steps(horizon) > 0
        finally:
            for n in self.inputs:          # the samples of the steps made are used up
                self._intake.drop_until(n, self.t_model)
        return out

    def advance_all(self, now_s: Optional[float] = None) -> List[Estimate]:
        """
        Step through every complete step at once, as ``advance`` would over several calls.

        For offline work that feeds seconds of samples before stepping (a
        replay, a calibration run): no step limit, and the grid averaging is
        vectorised over all the steps.
        """
        return self.advance(now_s, max_steps=sys.maxsize)

    def _complete_steps(self, horizon: float) -> int:
        """Return how many whole steps end at or before ``horizon`` (within eps)."""
        # from an integer count: a sum of dt drifts, and a sample stamped on a boundary
        # would then land in the neighbouring step (a phase-locked ripple would bias the
        # mean of I^2); the division only guesses, the comparisons decide
        limit = horizon + self._intake.eps
        k = max(int((limit - self._t_origin) / self.settings.step_s) - 1, self.steps)
        while self._step_end(k + 1) <= limit:
            k += 1
        while k > self.steps and self._step_end(k) > limit:
            k -= 1
        return k - self.steps

    def _silent_run(self, n_steps: int) -> Tuple[bool, int]:
        """
        Split the next ``n_steps`` steps at a long silence of every input.

        Returns ``(True, n)`` when the next ``n`` (at least HOLD_AFTER_STEPS)
        steps hold no sample of any input, else ``(False, n)``: the next ``n``
        steps, up to the first such silence, are made step by step.
        """
        if n_steps < HOLD_AFTER_STEPS:
            return False, n_steps
        span = np.array([self.t_model, self._step_end(self.steps + n_steps)]) + self._intake.eps
        stamps = self._intake.stamps_in(span[0], span[1])     # those of the steps ahead
        # the step of each sample: (end_{k-1}, end_k] holds step k
        step = self.settings.step_s
        k = np.ceil((stamps - self._intake.eps - self._t_origin) / step).astype(np.int64)
        k = np.unique(np.concatenate([[self.steps], k, [self.steps + n_steps + 1]]))
        empty = np.diff(k) - 1          # steps without a sample between two with samples
        long = np.flatnonzero(empty >= HOLD_AFTER_STEPS)
        if not long.size:
            return False, n_steps
        i = long[0]
        if k[i] == self.steps:
            return True, int(empty[i])
        return False, int(k[i] - self.steps)

    def _step_end(self, k: int) -> float:
        """Return the sample time (s) at which step ``k`` ends (step 0 ends at the start)."""
        return self._t_origin + k * self.settings.step_s

    def _start(self, t0: float) -> None:
        """Initialise the model at ambient with the inputs' values at ``t0``."""
        self.t_model = self._t_origin = t0
        self._intake.resolve(t0)
        self.next_end_s = self._step_end(1) - self._intake.eps
        values = self._intake.model_inputs({n: np.array([self._intake.value_at(n, t0)])
                                           for n in self.inputs})
        # the model runs on time since the start: stamps since the epoch (~1.8e9 s) carry
        # only ~0.2 us of resolution, which would make every step length differ
        first = SampleBlock(np.array([0.0]), *(values[n] for n in INPUTS))
        self.model.initialise(self.ambient_K, first)
        if self.propagation is not None:
            self.propagation.start(self.ambient_K, first)
        for n in self.inputs:
            self._intake.drop_until(n, t0)

    def _grid_block(self, ends: np.ndarray) -> Dict[str, np.ndarray]:
        """
        Average every input onto the grid of each step between ``ends``: one row per step.

        Step k takes the samples stamped in (ends[k], ends[k + 1]]: the current
        as the root of the mean of I^2 and speed and pressures as means over
        each grid interval (an empty interval holds the previous value, the
        first the value before the step), the position interpolated at the grid
        times; a step without samples holds the value before it. All the steps
        of a call at once, with the arithmetic of one step at a time: a replay
        makes hundreds of steps per call. The samples stay buffered.
        """
        out = {}
        for name in self.inputs:
            ts, vs = self._intake.until(name, ends[-1])
            prev = self._intake.prev[name]
            start = prev[1] if prev is not None else self._intake.value_at(name, ends[0])
            out[name] = grid_rows(ts, vs, ends, self._frac, self._intake.eps, start,
                                  prev[0] if prev is not None else math.nan, _MODE[name])
        return out

    def _step(self, t0: float, t1: float, m: int, stale: List[str],
              grid_values: Dict[str, np.ndarray]) -> Estimate:
        """
        Step the model over (t0, t1], ``m`` steps long, with the inputs on the step's grid.

        ``m`` > 1 is a held block (see :meth:`_hold`): one sample per input at
        its end, and one exact step of the motor over the whole block.
        """
        frac = self._frac if m == 1 else np.ones(1)
        sensors = dict(grid_values)      # the model's inputs below limit the position in place
        values = self._intake.model_inputs(grid_values)
        values['position_m'] = self._limit_position(values['position_m'], (t1 - t0) / frac.size)
        since_start = (self.steps + m * frac) * self.settings.step_s
        block = SampleBlock(since_start, *(values[n] for n in INPUTS))
        span_s = m * self.settings.step_s
        self.model.step(block, self.ambient_K, max_substep_s=span_s if m > 1 else None)
        corrected = None
        if self._correction is not None:
            corrected = self._correction.step(self.model, t0, t1, span_s, self._intake.eps)
        self.t_model = t1
        self.steps += m
        self.next_end_s = self._step_end(self.steps + 1) - self._intake.eps
        if m == 1:
            self._outlook.record(block)
        else:
            # the forecast repeats steps of the recent duty: the block's held values, as
            # many steps of them as the block held
            self._outlook.record(SampleBlock(self.settings.step_s * self._frac, *(
                np.full(self.n_grid, values[n][-1]) for n in INPUTS)), m)
        if self.propagation is not None:
            taken = self.propagation.record(since_start[-1], block, self.steps - m,
                                            self.steps, self.ambient_K)
            if taken and self._correction is not None and self.propagation.growth is not None:
                self._correction.add_parameter_growth(self.propagation.growth)
        implausible = self._plausibility(values, t1 - t0)
        outputs = corrected if corrected is not None else self.model.outputs()
        temps = {k: v - C_TO_K for k, v in outputs.items()}
        events = self._alerts.update(t1, temps)      # (it takes the quantities it has rules for)
        worst_stale = max((t1 - self.health[n].stale_since_s for n in stale
                           if self.health[n].stale_since_s is not None), default=0.0)
        on_fallback = self.settings.stale_uncertainty_K_per_s * max(worst_stale, 0.0)
        if self.propagation is not None:
            sigma = self.propagation.sigma_K() + on_fallback
        else:
            sigma = np.full(len(temps), self.settings.model_uncertainty_K + on_fallback)
        if corrected is not None:
            uncertainty = self._filtered_uncertainty(on_fallback, sigma)
        else:
            uncertainty = dict(zip(self.model.quantities.names, sigma.tolist()))
        if self.outlook_mode != 'off':
            self._outlook.tick(self.steps - m, self.steps, t1, self.ambient_K, temps,
                               uncertainty, stale, self.propagation.relative
                               if self.propagation is not None else None)
        notices, self._intake.notices = self._intake.notices, []
        est = Estimate(
            stamp_s=t1, temperatures_C=temps, uncertainty_K=uncertainty,
            heat_W=dict(self.model.heat_W), limits_C=dict(self.limits_C),
            time_to_limit_s=dict(self._outlook.result), forecast_stamp_s=self._outlook.stamp_s,
            margin_current_A=self._outlook.margin_A, alert_level=int(self._alerts.worst()),
            alert_events=events, stale=list(stale), implausible=implausible, step=self.steps,
            correction=self._correction.summary() if self._correction is not None else None,
            notices=notices, inputs=sensors, state_K=self.model.state)
        self.latest = est
        return est

    def _hold(self, n_silent: int, stale: List[str]) -> Estimate:
        """
        Cross part of a silence of every input in one held block; return its estimate.

        The block spans the next ``min(n_silent, HOLD length)`` steps with
        every input on its fallback, as step-by-step stepping would hold it,
        in one exact step of the motor network and of the circuit. The next
        block doubles while the state moves less than ``HOLD_TOL_K`` in one.
        """
        step = self.settings.step_s
        m = max(1, min(n_silent, int(round(self._hold_s / step))))
        t0, t1 = self.t_model, self._step_end(self.steps + m)
        values = {n: np.array([self._intake.value_at(n, t0)]) for n in self.inputs}
        before = self.model.state
        # the coefficients of the block's start, at once: deferred by a block of minutes
        # they would lag far behind the temperatures
        deferred, self.model.defer_refresh = self.model.defer_refresh, False
        try:
            est = self._step(t0, t1, m, stale, values)
        finally:
            self.model.defer_refresh = deferred
        moved = float(np.max(np.abs(self.model.state - before)))
        span = m * step
        if moved < HOLD_TOL_K:
            span *= 2.0
        elif moved > 2.0 * HOLD_TOL_K:
            span *= 0.5
        self._hold_s = min(max(span, HOLD_FIRST_S), HOLD_MAX_S)
        self.held_blocks += 1
        return est

    def _filtered_uncertainty(self, on_fallback: float,
                              open_loop: np.ndarray) -> Dict[str, float]:
        """
        Return each output's 1 sigma (K) from the filter's covariance.

        The filter's variance plus ``unmodelled_sigma_K`` in quadrature, plus
        the growth for inputs on their fallback (the filter does not model
        held inputs), never above the open-loop uncertainty: a filter that has
        not seen a thermocouple for long knows no more than the model alone.
        """
        u2 = self.settings.correction.unmodelled_sigma_K ** 2
        sigma = np.minimum(np.sqrt(self._correction.variances_K2 + u2) + on_fallback, open_loop)
        return dict(zip(self.model.quantities.names, sigma.tolist()))

    def prepare(self) -> bool:
        """
        Do the model's deferred re-discretisation now, for the next step; say if there was one.

        Cheap when nothing is pending; call it once an estimate has been
        published. The estimates are the same whether or not it is called.
        """
        return self.model.prepare(self.settings.step_s)

    def _limit_position(self, x: np.ndarray, h: float) -> np.ndarray:
        """
        Rate-limit the position on the grid to the fastest stroke the pump can drive.

        The actuator flow is the position's difference quotient: samples whose
        stamps bunch up (a receiver that stalled stamps a burst on arrival)
        would make a step in position look like a huge flow, and the model
        would book its throttling heat. Limited at the pump's geometric flow
        at the top of the speed range, the position catches up within a few
        steps; each limited step is counted as implausible.
        """
        out, self._position_limited = rate_limit(x, self.model.last_position_m,
                                                 self.max_stroke_speed_m_s * h)
        return out

    def _plausibility(self, values: Dict[str, np.ndarray], dt: float) -> List[str]:
        """Count physically implausible combinations of the step's inputs."""
        found = []
        no_current, no_speed = implausible_inputs(
            values['speed_rad_s'], values['current_A'], values['position_m'], dt,
            self.cfg.hydraulics.actuator.area_m2)
        if no_current:
            found.append('speed_without_current')
        if no_speed:
            found.append('flow_without_speed')
        if self._position_limited:
            found.append('position_faster_than_pump')
        for f in found:
            self.implausible_counts[f] += 1
        return found

    # ----------------------------------------------------------- background
    def background(self, budget_s: float = 0.005) -> None:
        """
        Work on the uncertainty's copies, the limits and the forecast for about ``budget_s``.

        A waiting period of the uncertainty's copies (:mod:`.uncertainty`) gets
        one copy's step first, then the outlook (:class:`~.outlook.Outlook`)
        the rest of the budget.
        """
        start = time.perf_counter()
        if self.propagation is not None:
            self.propagation.work(0.0)
        self._outlook.background(budget_s - (time.perf_counter() - start))


#: how ``grid_rows`` treats each input: interval means, the root of the mean square
#: (the current: copper loss is I^2 R), or interpolation at the grid times (the position)
_MODE = dict.fromkeys(INPUTS + DIFFERENTIAL_INPUTS, 0)
_MODE.update(current_A=1, position_m=2)


@jit
def implausible_inputs(speed, current, position, dt, area):
    """
    Tell whether a step's inputs spin the pump without current, or move oil without speed.

    Speed (rad/s) mean of its magnitude above 200 with the current's RMS (A)
    below 0.05 (spinning oil needs torque); the actuator's flow (the
    position's change in m over ``dt`` s times ``area`` m^2) above 0.5 L/min
    with the mean speed below 20 (the pump nearly still).
    """
    w = np.abs(speed).sum() / speed.size
    i_rms = np.sqrt((current * current).sum() / current.size)
    flow = abs(position[-1] - position[0]) / dt * area
    return w > 200.0 and i_rms < 0.05, flow > 0.5 / L_MIN_PER_M3_S and w < 20.0


@jit
def rate_limit(x, x_prev, step):
    """Return ``x`` moved at most ``step`` per sample from ``x_prev`` on, and if it was cut."""
    out = np.empty_like(x)
    clipped = False
    for k in range(x.size):
        move = x[k] - x_prev
        if abs(move) > step:
            move = math.copysign(step, move)
            clipped = True
        x_prev += move
        out[k] = x_prev
    return out, clipped


@jit
def grid_rows(ts, vs, ends, frac, eps, start, t_prev, mode):
    """
    Return one input's values on the grid of each step between ``ends`` (steps x grid).

    Step k takes the samples stamped in (ends[k], ends[k + 1]] (``eps`` s of
    slack; the first step also those before it). ``mode`` 0: the mean over
    each grid interval, 1: the root of the mean square, in both an empty
    interval holding the one before it (the first the value before the step);
    2: the value interpolated at the grid times ``frac`` of the step, from the
    sample before the step (stamped ``t_prev``; NaN: at the step's start). A
    step without samples holds the value before it, ``start`` before the
    first sample. A loop over the samples: compiled, one live step costs a few
    microseconds where numpy's calls cost a few hundred.
    """
    n, n_steps = frac.size, ends.size - 1
    rows = np.empty((n_steps, n))
    sums = np.empty(n)
    counts = np.empty(n)
    j = 0
    before, t_before = start, t_prev
    for k in range(n_steps):
        t0, t1 = ends[k], ends[k + 1]
        first = j
        while j < ts.size and ts[j] <= t1 + eps:
            j += 1
        if j == first:
            rows[k, :] = before
        elif mode == 2:
            xp = np.empty(j - first + 1)
            fp = np.empty(j - first + 1)
            xp[0] = t_before if not np.isnan(t_before) else t0
            fp[0] = before
            xp[1:] = ts[first:j]
            fp[1:] = vs[first:j]
            rows[k, :] = np.interp(t0 + (t1 - t0) * frac, xp, fp)
        else:
            h = (t1 - t0) / n
            sums[:] = 0.0
            counts[:] = 0.0
            for i in range(first, j):
                idx = int(np.ceil((ts[i] - t0 - eps) / h)) - 1
                idx = min(max(idx, 0), n - 1)
                sums[idx] += vs[i] * vs[i] if mode == 1 else vs[i]
                counts[idx] += 1.0
            last = before * before if mode == 1 else before
            for i in range(n):
                if counts[i] > 0.0:
                    last = sums[i] / counts[i]
                rows[k, i] = np.sqrt(last) if mode == 1 else last
        if j > first:
            before, t_before = vs[j - 1], ts[j - 1]
    return rows
