"""
The live estimator without ROS: timestamped samples in, estimates and alerts out.

Samples of the inputs arrive one by one, at any rate and in any
interleaving (``add``): current, speed, position and either the absolute
pressures of both ports and the accumulator or one differential pressure
(``estimator.pressure_inputs``). ``advance`` steps the coupled thermal model over every
complete step of ``step_s`` in *sample time* (the stamps, never the wall
clock), so a replayed log gives the same estimates as the live run. Inside a
step each input is averaged on a grid of ``block_rate_Hz``: current as the
mean of I^2 (copper loss is I^2 R: the square of a mean would alias), speed
and pressures as means, position interpolated (the actuator flow is its
difference quotient); the model then forms the flow-pressure products and
losses per grid interval.

Sensor health: a non-finite or out-of-range value, or a stamp going backwards,
is rejected and counted; an input with no sample for its ``timeout_s`` is
stale. The estimator never waits for a stale input: it keeps stepping on the
fallback (the last good value held; an input never seen takes its resting
value: no current, no speed, accumulator pressure, mid-stroke), says so in
every estimate, and widens the uncertainty for as long as it lasts.
Implausible combinations (speed with no current; actuator flow with no
speed; the position moving faster than the pump can drive it, which is then
rate-limited) are counted per step.

Thermocouple readings (``add_measured``) are shown beside the estimates they
measure and, with ``estimator.correction.enabled``, correct the model through
a Kalman filter (:mod:`.correction`) in sample time; with no readings the
model runs open loop, bit for bit as without the filter. The uncertainty of
each estimate then comes from the filter's covariance.

``background(budget_s)`` does the slow work in slices that fit a budget: a
forecast that repeats the last ``forecast_window_s`` of duty to find when the
winding, the magnets and the oil reach their limits, and the thermal margin
(the largest continuous current at the present oil temperature).
"""

import bisect
from collections import deque
import copy
from dataclasses import dataclass, field
import math
import time
from typing import Any, Deque, Dict, List, Optional, Tuple

import numpy as np

from .alerts import AlertEvent, AlertManager, rules_from_config
from .correction import ThermalCorrection
from ..config import Config
from ..model.eha import EHAModel, SampleBlock
from ..model.motor import C_TO_K, MotorInputs, WetMotor

INPUTS = ('current_A', 'speed_rad_s', 'p_a_Pa', 'p_b_Pa', 'p_acc_Pa', 'position_m')
# with one differential pressure sensor (estimator.pressure_inputs: differential)
DIFFERENTIAL_INPUTS = ('current_A', 'speed_rad_s', 'dp_Pa', 'position_m')


def sensor_inputs(cfg: Config) -> Tuple[str, ...]:
    """Return the estimator's inputs under configuration ``cfg``."""
    return DIFFERENTIAL_INPUTS if cfg.estimator.pressure_inputs == 'differential' else INPUTS


def sensor_signal(samples: SampleBlock, name: str) -> np.ndarray:
    """Return what input ``name`` reads from the model's ``samples`` (dp_Pa: p_A - p_B)."""
    if name == 'dp_Pa':
        return samples.p_a_Pa - samples.p_b_Pa
    return getattr(samples, name)


@dataclass
class ChannelHealth:
    """Counters and state of one input."""

    received: int = 0
    accepted: int = 0
    non_finite: int = 0
    out_of_range: int = 0
    backwards: int = 0
    late: int = 0            # arrived after the model had stepped past its stamp
    stale_events: int = 0    # times the input went stale
    stale: bool = False
    stale_since_s: Optional[float] = None
    last_stamp_s: Optional[float] = None
    last_value: Optional[float] = None

    @property
    def rejected(self) -> int:
        """Return the number of samples not used."""
        return self.non_finite + self.out_of_range + self.backwards + self.late


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
    margin_current_A: Optional[float]
    alert_level: int
    alert_events: List[AlertEvent]
    stale: List[str]
    implausible: List[str]
    step: int
    # live correction (None when it is off): active, learned heats (W), thermocouple statuses
    correction: Optional[Dict[str, Any]] = None


@dataclass
class _Forecast:
    model: EHAModel
    start_s: float
    duty: Dict[str, np.ndarray]   # the recent samples; 'dx_m' position increments, drift-free
    ambient_K: float
    t_s: float = 0.0
    k: int = 0
    crossed: Dict[str, Optional[float]] = field(default_factory=dict)


class Estimator:
    """Turn timestamped samples into temperature estimates, alerts and forecasts."""

    def __init__(self, cfg: Config, model: Optional[EHAModel] = None) -> None:
        self.cfg = cfg
        s = cfg.estimator
        self.settings = s
        # deferred refresh: the slow re-discretisation runs in prepare(), after the
        # estimate has left, and the coefficients lag by one 20 ms step
        self.model = model if model is not None else EHAModel(
            cfg, coefficient_filter_s=s.coefficient_filter_s, defer_refresh=True)
        self.inputs = sensor_inputs(cfg)
        self.differential = self.inputs == DIFFERENTIAL_INPUTS
        self.channel_cfg = {name: getattr(s.channels, name) for name in self.inputs}
        self.health = {name: ChannelHealth() for name in self.inputs}
        # buffered samples per input: (stamps, values), two flat lists (no tuple per sample,
        # which would also keep the garbage collector busy in a replay)
        self._buf: Dict[str, Tuple[List[float], List[float]]] = {
            name: ([], []) for name in self.inputs}
        self._prev: Dict[str, Optional[tuple]] = dict.fromkeys(self.inputs)
        p_acc = cfg.hydraulics.accumulator.pressure_Pa
        self.rest = {'current_A': 0.0, 'speed_rad_s': 0.0, 'p_a_Pa': p_acc, 'p_b_Pa': p_acc,
                     'p_acc_Pa': p_acc, 'dp_Pa': 0.0, 'position_m': 0.0}
        self.ambient_K = s.ambient_C + C_TO_K
        self.measured_C: Dict[str, tuple] = {}
        # live correction with the thermocouples (estimator.correction): a Kalman filter
        # that starts at the first usable reading; until then the model runs open loop
        self.correction = ThermalCorrection(cfg, self.model) if s.correction.enabled else None
        self.alerts = AlertManager(rules_from_config({
            q: vars(getattr(s.alerts, q)) for q in ('winding_hotspot', 'magnet', 'oil')}))
        self.limits_C = {'winding_hotspot': cfg.motor.winding.insulation_limit_C,
                         'magnet': cfg.motor.rotor.magnet_limit_C, 'oil': cfg.fluid.oil_limit_C}
        self.n_grid = max(1, int(round(s.step_s * s.block_rate_Hz)))
        self._frac = np.arange(1, self.n_grid + 1) / self.n_grid   # grid times in a step
        self._eps = 1e-6 * s.step_s / self.n_grid   # stamps this close count as equal
        self._t_origin = 0.0
        self.t_model: Optional[float] = None
        self.steps = 0
        self.latest: Optional[Estimate] = None
        self.implausible_counts = {'speed_without_current': 0, 'flow_without_speed': 0,
                                   'position_faster_than_pump': 0}
        # the pump's geometric flow at the top of the speed range, over the piston area
        speed = s.channels.speed_rad_s
        self.max_stroke_speed_m_s = (cfg.hydraulics.pump.displacement_m3_rev / (2 * math.pi)
                                     * max(abs(speed.low), abs(speed.high))
                                     / cfg.hydraulics.actuator.area_m2)
        self._position_limited = False
        self._window: Deque[SampleBlock] = deque(maxlen=max(1, int(round(
            s.forecast_window_s / s.step_s))))
        self._forecast: Optional[_Forecast] = None
        self._forecast_result: Dict[str, Optional[float]] = {}
        self._forecast_stamp: Optional[float] = None
        self._next_forecast_s: Optional[float] = None
        self._margin: Optional[float] = None
        self._margin_motor = WetMotor(cfg.motor, self.model.oil)
        self._next_margin_s: Optional[float] = None
        self._margin_job = None
        self.forecast_failures = 0

    # ----------------------------------------------------------------- input
    def add(self, channel: str, stamp_s: float, value: float) -> bool:
        """Take one sample of an input (SI units); return whether it was accepted."""
        h = self.health[channel]          # KeyError names an unknown channel
        h.received += 1
        c = self.channel_cfg[channel]
        if not (math.isfinite(value) and math.isfinite(stamp_s)):
            h.non_finite += 1
            return False
        if not c.low <= value <= c.high:
            h.out_of_range += 1
            return False
        if h.last_stamp_s is not None and stamp_s <= h.last_stamp_s:
            h.backwards += 1
            return False
        if self.t_model is not None and stamp_s <= self.t_model + self._eps:
            h.late += 1
            return False
        h.accepted += 1
        h.last_stamp_s, h.last_value = stamp_s, value
        stamps, vals = self._buf[channel]
        stamps.append(stamp_s)
        vals.append(value)
        return True

    def add_many(self, channel: str, stamps_s: np.ndarray, values: np.ndarray) -> int:
        """
        Take many samples of one input at once, as ``add`` would one by one; return how many.

        The same checks, vectorised, for replaying logs: non-finite, out of
        range, not after the previous accepted stamp, or at or before the
        model time are counted and dropped.
        """
        h = self.health[channel]
        c = self.channel_cfg[channel]
        t = np.asarray(stamps_s, dtype=float)
        v = np.asarray(values, dtype=float)
        h.received += t.size
        finite = np.isfinite(t) & np.isfinite(v)
        in_range = finite & (v >= c.low) & (v <= c.high)
        # backwards: not after the latest accepted stamp so far; only samples after the
        # model time can be accepted, and a backwards one never raises the maximum
        after_model = t > self.t_model + self._eps if self.t_model is not None else finite
        last = h.last_stamp_s if h.last_stamp_s is not None else -np.inf
        before = np.maximum.accumulate(np.concatenate(
            [[last], np.where(in_range & after_model, t, -np.inf)]))[:-1]
        backwards = in_range & (t <= before)
        late = in_range & ~backwards & ~after_model
        ok = in_range & ~backwards & after_model
        h.non_finite += int(np.count_nonzero(~finite))
        h.out_of_range += int(np.count_nonzero(finite & ~in_range))
        h.backwards += int(np.count_nonzero(backwards))
        h.late += int(np.count_nonzero(late))
        n = int(np.count_nonzero(ok))
        if n:
            h.accepted += n
            ts, vs = t[ok], v[ok]
            h.last_stamp_s, h.last_value = float(ts[-1]), float(vs[-1])
            stamps, vals = self._buf[channel]
            stamps.extend(ts.tolist())
            vals.extend(vs.tolist())
        return n

    def add_ambient(self, stamp_s: float, value_C: float) -> bool:
        """Take an ambient temperature (degC) for the housings' heat loss."""
        if not (math.isfinite(value_C) and -60.0 <= value_C <= 150.0):
            return False
        self.ambient_K = value_C + C_TO_K
        return True

    def add_measured(self, name: str, stamp_s: float, value_C: float) -> bool:
        """
        Take a thermocouple reading (degC) of ``name`` (a key of ``topics.THERMOCOUPLES``).

        It is reported beside the estimate it measures and, with the live
        correction on, corrects the model at the end of the first step that
        starts at or after ``stamp_s``. Returns whether it was accepted.
        """
        if not math.isfinite(value_C):
            if self.correction is not None and name in self.correction.tcs:
                self.correction.add_reading(name, stamp_s, value_C)    # counted there
            return False
        self.measured_C[name] = (stamp_s, value_C)
        if self.correction is not None and name in self.correction.tcs:
            return self.correction.add_reading(name, stamp_s, value_C)
        return True

    def acknowledge(self, quantity: Optional[str] = None) -> List[AlertEvent]:
        """Acknowledge latched alerts (all, or one quantity)."""
        stamp = self.t_model if self.t_model is not None else 0.0
        return self.alerts.acknowledge(quantity, stamp_s=stamp)

    # ------------------------------------------------------------- stepping
    def _reference_time(self, now_s: Optional[float]) -> Optional[float]:
        stamps = [h.last_stamp_s for h in self.health.values() if h.last_stamp_s is not None]
        if now_s is not None:
            stamps.append(now_s)
        return max(stamps) if stamps else None

    def _update_staleness(self, ref: float) -> List[str]:
        stale = []
        for name, h in self.health.items():
            limit = self.channel_cfg[name].timeout_s
            is_stale = h.last_stamp_s is None or ref - h.last_stamp_s > limit
            if is_stale and not h.stale and h.last_stamp_s is not None:
                h.stale_events += 1
                h.stale_since_s = (h.last_stamp_s + limit) if h.last_stamp_s is not None \
                    else ref
            if not is_stale:
                h.stale_since_s = None
            h.stale = is_stale
            if is_stale:
                stale.append(name)
        return stale

    def advance(self, now_s: Optional[float] = None) -> List[Estimate]:
        """
        Step the model through every complete step that the samples allow; return the estimates.

        The model may step to the oldest latest stamp among the fresh inputs.
        ``now_s`` (a clock in the same time base, e.g. the ROS clock) lets
        silent inputs go stale and the model keep stepping without them.
        """
        ref = self._reference_time(now_s)
        if ref is None:
            return []
        stale = self._update_staleness(ref)
        fresh = [n for n in self.inputs if n not in stale]
        horizon = min(self.health[n].last_stamp_s for n in fresh) if fresh else ref
        if self.t_model is None:
            # start once every input has spoken (or its timeout passed), at the latest
            # first stamp: each input then has a value at the start, live or replayed
            firsts = [self._buf[n][0][0] for n in self.inputs if self._buf[n][0]]
            if not firsts:
                self._start(horizon)
                return []
            patience_s = max(c.timeout_s for c in self.channel_cfg.values())
            if len(firsts) < len(self.inputs) and ref - min(firsts) <= patience_s:
                return []
            self._start(max(firsts))
            stale = self._update_staleness(ref)
            fresh = [n for n in self.inputs if n not in stale]
            horizon = min(self.health[n].last_stamp_s for n in fresh) if fresh else ref
        out = []
        # step ends from an integer count: a sum of dt drifts, and a sample stamped on
        # a boundary would then land in the neighbouring step (a phase-locked ripple
        # would bias the mean of I^2)
        n_steps = 0
        while self._step_end(self.steps + n_steps + 1) <= horizon + self._eps:
            n_steps += 1
        if not n_steps:
            return out
        ends = [self._step_end(self.steps + k) for k in range(n_steps + 1)]
        grid_values = self._grid_block(np.array(ends))
        try:
            for k in range(n_steps):
                out.append(self._step(ends[k], ends[k + 1], stale,
                                      {n: v[k] for n, v in grid_values.items()}))
        finally:
            for n in self.inputs:          # the samples of the steps made are used up
                self._drop_until(n, self.t_model)
        return out

    def ready(self, stamp_s: float) -> bool:
        """Tell whether a sample stamped ``stamp_s`` may let the next step complete (cheap)."""
        return self.t_model is None or stamp_s >= self._step_end(self.steps + 1) - self._eps

    def _step_end(self, k: int) -> float:
        """Return the sample time (s) at which step ``k`` ends (step 0 ends at the start)."""
        return self._t_origin + k * self.settings.step_s

    def _start(self, t0: float) -> None:
        """Initialise the model at ambient with the inputs' values at ``t0``."""
        self.t_model = self._t_origin = t0
        # stamps since the epoch are only resolved to ~0.2 us: equal means within a few ulps
        self._eps = max(self._eps, 8.0 * float(np.spacing(abs(t0))))
        values = self._model_inputs({n: np.array([self._value_at(n, t0)]) for n in self.inputs})
        # the model runs on time since the start: stamps since the epoch (~1.8e9 s) carry
        # only ~0.2 us of resolution, which would make every step length differ
        first = SampleBlock(np.array([0.0]), *(values[n] for n in INPUTS))
        self.model.initialise(self.ambient_K, first)
        for n in self.inputs:
            self._drop_until(n, t0)

    def _count_until(self, name: str, t: float) -> int:
        """Return how many buffered samples of ``name`` are stamped at or before ``t``."""
        # accepted stamps strictly increase: a replay buffers a whole block, so bisect
        return bisect.bisect_right(self._buf[name][0], t + self._eps)

    def _value_at(self, name: str, t: float) -> float:
        """Return the last value at or before ``t`` (fallback: last good, else at rest)."""
        k = self._count_until(name, t)
        if k:
            return self._buf[name][1][k - 1]
        if self._prev[name] is not None:
            return self._prev[name][1]
        h = self.health[name]
        return h.last_value if h.last_value is not None else self.rest[name]

    def _drop_until(self, name: str, t: float) -> None:
        k = self._count_until(name, t)
        if k:
            stamps, vals = self._buf[name]
            self._prev[name] = (stamps[k - 1], vals[k - 1])
            del stamps[:k]
            del vals[:k]

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
        n, n_steps, eps = self.n_grid, ends.size - 1, self._eps
        t0 = ends[:-1]
        out = {}
        for name in self.inputs:
            k_all = self._count_until(name, ends[-1])
            prev = self._prev[name]
            start = prev[1] if prev is not None else self._value_at(name, ends[0])
            if not k_all:
                out[name] = np.full((n_steps, n), start)
                continue
            stamps, vals = self._buf[name]
            ts, vs = np.array(stamps[:k_all]), np.array(vals[:k_all])
            # the samples of step k are ts[lo[k]:hi[k]]; the one before them starts it
            first = np.searchsorted(ts, ends + eps, side='right')
            first[0] = 0
            lo, hi = first[:-1], first[1:]
            starts = np.where(lo > 0, vs[lo - 1], start)
            empty = lo == hi
            if name == 'position_m':
                # position at the grid times: its differences are the actuator flow
                t_prev = prev[0] if prev is not None else None
                grids = t0[:, None] + (ends[1:] - t0)[:, None] * self._frac
                rows = np.empty((n_steps, n))
                for k, (a, b) in enumerate(zip(lo.tolist(), hi.tolist())):
                    if a == b:
                        rows[k] = starts[k]
                        continue
                    t_start = ts[a - 1] if a else (t_prev if t_prev is not None else t0[k])
                    rows[k] = np.interp(grids[k], np.concatenate([[t_start], ts[a:b]]),
                                        np.concatenate([[starts[k]], vs[a:b]]))
                out[name] = rows
                continue
            held = starts
            if name == 'current_A':
                vs = vs * vs
                held = starts * starts
            # grid interval of every sample, counted over all the steps
            step_of = np.repeat(np.arange(n_steps), hi - lo)
            idx = np.ceil((ts - t0[step_of] - eps) / ((ends[1:] - t0) / n)[step_of]).astype(int)
            idx -= 1
            np.maximum(idx, 0, out=idx)         # np.clip, without its wrapper's overhead
            np.minimum(idx, n - 1, out=idx)
            idx += step_of * n
            counts = np.bincount(idx, minlength=n_steps * n)
            table = np.empty((n_steps, n + 1))
            table[:, 0] = held
            with np.errstate(invalid='ignore'):       # 0/0 in empty intervals: not used
                table[:, 1:] = (np.bincount(idx, weights=vs, minlength=n_steps * n)
                                / counts).reshape(n_steps, n)
            # an empty interval takes the last filled one before it in its step (column 0
            # holds the value before the step)
            filled = np.ones((n_steps, n + 1), dtype=bool)
            filled[:, 1:] = counts.reshape(n_steps, n) > 0
            pick = np.where(filled, np.arange(n + 1), 0)
            np.maximum.accumulate(pick, axis=1, out=pick)
            rows = np.take_along_axis(table, pick[:, 1:], axis=1)
            if name == 'current_A':
                rows = np.sqrt(rows)
            rows[empty] = starts[empty, None]
            out[name] = rows
        return out

    def _step(self, t0: float, t1: float, stale: List[str],
              grid_values: Dict[str, np.ndarray]) -> Estimate:
        """Step the model over (t0, t1] with the inputs on the step's grid; return the estimate."""
        frac = self._frac
        values = self._model_inputs(grid_values)
        values['position_m'] = self._limit_position(values['position_m'], (t1 - t0) / self.n_grid)
        since_start = (self.steps + frac) * self.settings.step_s
        block = SampleBlock(since_start, *(values[n] for n in INPUTS))
        self.model.step(block, self.ambient_K)
        corrected = None
        if self.correction is not None:
            corrected = self.correction.step(self.model, t0, t1, self.settings.step_s,
                                             self._eps)
        self.t_model = t1
        self.steps += 1
        self._window.append(block)
        implausible = self._plausibility(values, t1 - t0)
        outputs = corrected if corrected is not None else self.model.outputs()
        temps = {k: v - C_TO_K for k, v in outputs.items()}
        events = self.alerts.update(t1, {q: temps[q] for q in self.limits_C})
        worst_stale = max((t1 - self.health[n].stale_since_s for n in stale
                           if self.health[n].stale_since_s is not None), default=0.0)
        on_fallback = self.settings.stale_uncertainty_K_per_s * max(worst_stale, 0.0)
        sigma = self.settings.model_uncertainty_K + on_fallback
        if corrected is not None:
            uncertainty = self._filtered_uncertainty(outputs, on_fallback, sigma)
        else:
            uncertainty = {k: sigma for k in temps}
        est = Estimate(
            stamp_s=t1, temperatures_C=temps, uncertainty_K=uncertainty,
            heat_W=dict(self.model.heat_W), limits_C=dict(self.limits_C),
            time_to_limit_s=dict(self._forecast_result), forecast_stamp_s=self._forecast_stamp,
            margin_current_A=self._margin, alert_level=int(self.alerts.worst()),
            alert_events=events, stale=list(stale), implausible=implausible, step=self.steps,
            correction=self.correction.summary() if self.correction is not None else None)
        self.latest = est
        return est

    def _filtered_uncertainty(self, outputs: Dict[str, float], on_fallback: float,
                              open_loop: float) -> Dict[str, float]:
        """
        Return each output's 1 sigma (K) from the filter's covariance.

        The filter's variance plus ``unmodelled_sigma_K`` in quadrature, plus
        the growth for inputs on their fallback (the filter does not model
        held inputs), never above the open-loop uncertainty: a filter that has
        not seen a thermocouple for long knows no more than the model alone.
        """
        u2 = self.settings.correction.unmodelled_sigma_K ** 2
        return {k: min(math.sqrt(v + u2) + on_fallback, open_loop)
                for k, v in self.correction.variances(self.model, outputs).items()}

    def _model_inputs(self, values: Dict[str, np.ndarray]) -> Dict[str, np.ndarray]:
        """
        Return the model's six inputs from the sensors' (the same arrays with port pressures).

        A differential pressure is split with its low side at the accumulator
        pressure: in a closed-circuit EHA the low port is fed from the
        accumulator through its check valve.
        """
        if not self.differential:
            return values
        dp = values['dp_Pa']
        p_acc = np.full_like(dp, self.rest['p_acc_Pa'])
        return {**values, 'p_a_Pa': p_acc + np.maximum(dp, 0.0),
                'p_b_Pa': p_acc + np.maximum(-dp, 0.0), 'p_acc_Pa': p_acc}

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
        x_prev = self.model._last[1]
        step = self.max_stroke_speed_m_s * h
        out = np.empty_like(x)
        clipped = False
        for k, target in enumerate(x.tolist()):
            move = target - x_prev
            if abs(move) > step:
                move = math.copysign(step, move)
                clipped = True
            x_prev += move
            out[k] = x_prev
        self._position_limited = clipped
        return out

    def _plausibility(self, values: Dict[str, np.ndarray], dt: float) -> List[str]:
        """Count physically implausible combinations of the step's inputs."""
        found = []
        # means as np.mean forms them (the sum over the count), without its overhead
        w, i = values['speed_rad_s'], values['current_A']
        speed = float(np.abs(w).sum() / w.size)
        current = float(np.sqrt((i ** 2).sum() / i.size))
        x = values['position_m']
        flow = abs(x[-1] - x[0]) / dt * self.cfg.hydraulics.actuator.area_m2
        if speed > 200.0 and current < 0.05:          # spinning oil needs torque
            found.append('speed_without_current')
        if flow > 0.5 / 60000 and speed < 20.0:        # 0.5 L/min moved, pump nearly still
            found.append('flow_without_speed')
        if self._position_limited:
            found.append('position_faster_than_pump')
        for f in found:
            self.implausible_counts[f] += 1
        return found

    # ----------------------------------------------------------- background
    def background(self, budget_s: float = 0.005) -> None:
        """Do forecast and margin work for at most about ``budget_s`` of wall time."""
        if self.t_model is None or not self._window:
            return
        deadline = time.perf_counter() + budget_s
        s = self.settings
        # the margin takes one steady solve (~7 ms) per call, between forecast slices
        if self._margin_job is None and (self._next_margin_s is None
                                         or self.t_model >= self._next_margin_s):
            self._margin_job = self._margin_steps()
            self._next_margin_s = self.t_model + s.forecast_period_s
        if self._margin_job is not None:
            try:
                next(self._margin_job)
            except StopIteration as done:
                self._margin = done.value
                self._margin_job = None
        if self._forecast is None and (self._next_forecast_s is None
                                       or self.t_model >= self._next_forecast_s):
            self._start_forecast()
            self._next_forecast_s = self.t_model + s.forecast_period_s
        while self._forecast is not None and time.perf_counter() < deadline:
            self._forecast_step()

    def _start_forecast(self) -> None:
        """Copy the model and take the recent duty to repeat."""
        blocks = list(self._window)
        # one sample per model step (the step's means; I^2 for the current): a forecast
        # step of seconds then costs about a millisecond
        duty = {a: np.array([getattr(b, a).mean() for b in blocks])
                for a in ('speed_rad_s', 'p_a_Pa', 'p_b_Pa', 'p_acc_Pa')}
        duty['current_A'] = np.array([math.sqrt(np.mean(b.current_A ** 2)) for b in blocks])
        x = np.array([b.position_m[-1] for b in blocks])
        # repeat the motion, not the positions: increments with the window's net drift
        # removed, so the repeated duty is periodic and stays inside the stroke
        dx = np.diff(x, prepend=x[0])
        duty['dx_m'] = dx - dx.mean()
        model = copy.deepcopy(self.model)
        model.defer_refresh = False       # forecast steps are seconds long: no lag there
        self._forecast = _Forecast(model=model, start_s=self.t_model,
                                   duty=duty, ambient_K=self.ambient_K,
                                   crossed=dict.fromkeys(self.limits_C))

    def _forecast_step(self) -> None:
        """Advance the forecast by one ``forecast_step_s`` of repeated duty."""
        try:
            self._forecast_step_unguarded()
        except (ArithmeticError, ValueError, RuntimeError):
            # a forecast is advice: give up on this one, never on the estimator
            self.forecast_failures += 1
            self._forecast = None

    def _forecast_step_unguarded(self) -> None:
        f = self._forecast
        s = self.settings
        n_all = f.duty['dx_m'].size
        n = max(1, int(round(s.forecast_step_s / s.step_s)))
        idx = (f.k + np.arange(n)) % n_all
        f.k = (f.k + n) % n_all
        span = n * s.step_s
        t = f.model.time_s + (np.arange(1, n + 1) / n) * span
        x = f.model._last[1] + np.cumsum(f.duty['dx_m'][idx])
        block = SampleBlock(t, *(f.duty[a][idx] for a in ('current_A', 'speed_rad_s', 'p_a_Pa',
                                                          'p_b_Pa', 'p_acc_Pa')), x)
        f.model.step(block, f.ambient_K)
        f.t_s += span
        temps = {k: v - C_TO_K for k, v in f.model.outputs().items()}
        for q, lim in self.limits_C.items():
            if f.crossed[q] is None and temps[q] >= lim:
                f.crossed[q] = f.t_s
        if f.t_s >= s.forecast_horizon_s or all(v is not None for v in f.crossed.values()):
            # a quantity already past its limit now has zero time left
            now = self.latest.temperatures_C if self.latest is not None else {}
            self._forecast_result = {q: (0.0 if now.get(q, -1e9) >= self.limits_C[q] else v)
                                     for q, v in f.crossed.items()}
            self._forecast_stamp = f.start_s
            self._forecast = None

    def margin_current(self) -> Optional[float]:
        """
        Return the largest continuous current (A RMS) at the present oil temperature and duty.

        The motor alone in steady state with its present cooling oil (the pump
        case temperature and the motor's flow) and the recent mean speed: the
        current whose steady winding hot-spot reaches the insulation limit,
        by secant iterations on I^2 (the rise is nearly linear in I^2).
        """
        job = self._margin_steps()
        while True:
            try:
                next(job)
            except StopIteration as done:
                return done.value

    def _margin_steps(self):
        """Compute :meth:`margin_current` one steady solve per iteration (a generator)."""
        if not self._window:
            return None
        m, mot = self.model, self._margin_motor
        speeds = np.concatenate([b.speed_rad_s for b in self._window])
        u = MotorInputs(current_sq_mean_A2=0.0, speed_rad_s=np.abs(speeds).mean(),
                        oil_inlet_K=float(m.T_hyd[m.circuit.index('case')]),
                        oil_flow_m3_s=m.motor._refreshed_at[1] if m.motor._refreshed_at else 0.0,
                        ambient_K=self.ambient_K)
        target = self.limits_C['winding_hotspot'] + C_TO_K

        def hot(i_sq: float):
            """Yield per fixed-point iteration; return the steady hot-spot (K), inf if none."""
            u.current_sq_mean_A2 = i_sq
            try:
                yield from mot.steady_state_steps(u, tol_K=1e-4, max_iter=60)
            except RuntimeError:      # no steady state: far past any limit
                mot.T = None          # do not start the next solve from a runaway
                return math.inf
            return mot.outputs()['winding_hotspot']

        a = 0.0
        fa = yield from hot(a)
        if fa >= target:
            return 0.0
        b = (self.cfg.motor.max_continuous_current_A) ** 2
        fb = yield from hot(b)
        for _ in range(12):
            if abs(fb - target) < 0.05:
                break
            if not math.isfinite(fb):         # runaway: halve the step back
                b = 0.5 * (a + b)
            else:
                a, fa, b = b, fb, max(b + (target - fb) * (b - a) / (fb - fa), 0.0)
            fb = yield from hot(b)
        return float(math.sqrt(b))
