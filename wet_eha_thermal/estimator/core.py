"""
The live estimator without ROS: timestamped samples in, estimates and alerts out.

Samples of the inputs arrive one by one, at any rate and in any
interleaving: current, speed, position and either the absolute pressures of
both ports and the accumulator or one differential pressure
(``estimator.pressure_inputs``). ``advance`` steps the coupled thermal model
over the complete steps of ``step_s`` in *sample time* (the stamps, never the
wall clock), so a replayed log gives the same estimates as the live run.
Inside a step each input is averaged on a grid of ``block_rate_Hz``: current
as the mean of I^2 (copper loss is I^2 R: the square of a mean would alias),
speed and pressures as means, position interpolated (the actuator flow is its
difference quotient); the model then forms the flow-pressure products and
losses per grid interval.

Three ways in: ``add`` checks one sample at once and says whether it was
accepted; ``add_many`` does the same for arrays (a replay); ``push`` only
appends to the input's preallocated buffer (the live node's per-sample work)
and the same checks run vectorised at the next ``advance``.

Sensor health: a non-finite or out-of-range value, a stamp going backwards, a
stamp the model already stepped past (late) or one more than ``max_future_s``
ahead of the receiving clock (future) is rejected and counted; a rejected
sample never moves its input's last stamp. Each input keeps at most
``buffer_samples`` samples the model has not stepped past; more are dropped
and counted (overflow). An input with no sample for its ``timeout_s`` is
stale. The estimator never waits for a stale input: it keeps stepping on the
fallback (the last good value held; an input never seen takes its resting
value: no current, no speed, accumulator pressure, mid-stroke), says so in
every estimate, and widens the uncertainty for as long as it lasts. A silence
of every input at once is a data gap: counted, timed, and told in the
estimates' notices. Implausible combinations (speed with no current; actuator
flow with no speed; the position moving faster than the pump can drive it,
which is then rate-limited) are counted per step.

The receiving clock is what ``advance(now_s)`` (or ``add(..., now_s=)``) is
given; with none ever given there is no future check. When it goes back by
more than ``clock_jump_s`` (sim time restarting, the wall clock stepped), the
rule is :meth:`Estimator.restart_time`: the model time re-starts at the new
clock, the thermal state is kept, samples buffered under the old clock are
discarded (counted), and the stored stamps move with the jump. The model never
steps across a jump.

Bounded work: one ``advance`` makes at most ``max_steps_per_call`` model
steps; the rest waits for the next call (``behind`` tells). A stretch of
``HOLD_AFTER_STEPS`` steps or more with no sample of any input (a silence
being caught up) is crossed in held blocks: the model steps with the inputs
on their fallbacks over blocks that grow from ``HOLD_FIRST_S`` to
``HOLD_MAX_S`` while the state moves less than ``HOLD_TOL_K`` per block. Each
block is one exact step of the motor network and of the circuit, so an hour of
silence costs a few dozen steps, not 180 000.

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

from collections import deque
import copy
from dataclasses import dataclass, field
import itertools
import math
import sys
import time
from typing import Any, Deque, Dict, List, Optional, Tuple

import numpy as np

from .alerts import AlertEvent, AlertManager, rules_from_config
from .correction import ThermalCorrection
from ..config import Config
from ..model.compiled import jit
from ..model.eha import EHAModel, SampleBlock
from ..model.motor import C_TO_K, MotorInputs, WetMotor

INPUTS = ('current_A', 'speed_rad_s', 'p_a_Pa', 'p_b_Pa', 'p_acc_Pa', 'position_m')
# with one differential pressure sensor (estimator.pressure_inputs: differential)
DIFFERENTIAL_INPUTS = ('current_A', 'speed_rad_s', 'dp_Pa', 'position_m')
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
#: A forecast step doubles (from ``forecast_step_s`` to one pass of the repeated duty)
#: while the state moves less than this in one.
FORECAST_TOL_K = 0.5
#: why ``check_samples`` rejected a sample (ACCEPTED: it did not)
ACCEPTED, NON_FINITE, OUT_OF_RANGE, FUTURE, BACKWARDS, LATE = range(6)


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
    future: int = 0          # stamped more than max_future_s ahead of the receiving clock
    overflow: int = 0        # dropped: the input's buffer was full
    discarded: int = 0       # accepted, then dropped at a jump of the receiving clock
    stale_events: int = 0    # times the input went stale
    stale: bool = False
    stale_since_s: Optional[float] = None
    last_stamp_s: Optional[float] = None
    last_value: Optional[float] = None
    heard_s: Optional[float] = None   # the receiving clock when a sample was last accepted

    @property
    def rejected(self) -> int:
        """Return the number of samples not used."""
        return (self.non_finite + self.out_of_range + self.backwards + self.late + self.future
                + self.overflow)


@dataclass
class DataGaps:
    """Silences of every input at once (all stale): how many, how long, the open one."""

    count: int = 0
    total_s: float = 0.0
    longest_s: float = 0.0
    open_since_s: Optional[float] = None
    last: Optional[Tuple[float, float]] = None     # (start, end) of the last closed gap (s)


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
    # what happened to the time base since the last estimate: data gaps, clock jumps
    notices: List[str] = field(default_factory=list)
    # each sensor input on the step's grid as the model took it (SI; the current as the
    # root of the mean square per grid interval; one value for a held block): arrays the
    # estimator never writes again, so a display can average them on another thread
    inputs: Dict[str, np.ndarray] = field(default_factory=dict)


@dataclass
class _Forecast:
    model: EHAModel
    start_s: float
    duty: Dict[str, np.ndarray]   # the recent samples; 'dx_m' position increments, drift-free
    ambient_K: float
    t_s: float = 0.0
    k: int = 0
    crossed: Dict[str, Optional[float]] = field(default_factory=dict)
    n: int = 1                    # model steps per forecast step (it grows, see FORECAST_TOL_K)


class _Samples:
    """
    One input's samples in preallocated arrays.

    ``t[lo:hi]``, ``v[lo:hi]``: accepted samples the model has not stepped
    past, stamps strictly increasing; ``t[hi:top]``: pushed, not yet checked.
    """

    __slots__ = ('t', 'v', 'lo', 'hi', 'top', 'size')

    def __init__(self, capacity: int) -> None:
        self.t = np.empty(capacity)
        self.v = np.empty(capacity)
        self.lo = self.hi = self.top = 0
        self.size = capacity

    def room(self, n: int = 1) -> int:
        """Make room at the end (moving the kept samples to the front); return up to ``n``."""
        if self.top + n > self.size and self.lo:
            k = self.top - self.lo
            self.t[:k] = self.t[self.lo:self.top]
            self.v[:k] = self.v[self.lo:self.top]
            self.hi -= self.lo
            self.top = k
            self.lo = 0
        return min(n, self.size - self.top)

    def stamps(self) -> np.ndarray:
        """Return a view of the accepted stamps."""
        return self.t[self.lo:self.hi]

    def clear(self) -> int:
        """Drop everything; return how many accepted samples there were."""
        n = self.hi - self.lo
        self.lo = self.hi = self.top = 0
        return n


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
        self._samples = {name: _Samples(s.buffer_samples) for name in self.inputs}
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
        self._eps_base = 1e-6 * s.step_s / self.n_grid   # stamps this close count as equal
        self._eps = self._eps_base
        self._t_origin = 0.0
        self.t_model: Optional[float] = None
        #: sample time at which the next step ends (-inf before the start): a sample
        #: stamped at or after it may let that step complete
        self.next_end_s = -math.inf
        self.steps = 0
        self.latest: Optional[Estimate] = None
        #: the receiving clock's latest reading (s), None while none was given
        self.clock_s: Optional[float] = None
        self.clock_jumps = 0
        self.last_clock_jump: Optional[Tuple[float, float]] = None   # (from, to) s
        self.gaps = DataGaps()
        # a silence of every input longer than the longest timeout is a data gap
        self._gap_after_s = max(c.timeout_s for c in self.channel_cfg.values())
        self._last_sample_s: Optional[float] = None   # latest accepted stamp of any input
        self.held_blocks = 0           # held blocks made across silences
        self._hold_s = HOLD_FIRST_S     # length of the next held block
        self._notices: List[str] = []
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
    def push(self, channel: str, stamp_s: float, value: float) -> bool:
        """
        Append one sample (SI units) unchecked; it is checked as ``add`` would at ``advance``.

        The live path's whole per-sample work. Returns False (and counts an
        overflow) when the input's buffer is full.
        """
        buf = self._samples[channel]          # KeyError names an unknown channel
        top = buf.top
        if top == buf.size and not buf.room():
            h = self.health[channel]
            h.received += 1
            h.overflow += 1
            return False
        buf.t[top] = stamp_s
        buf.v[top] = value
        buf.top = top + 1
        return True

    def due(self, channel: str, stamp_s: float) -> bool:
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

    def _latest_allowed(self) -> float:
        """Return the latest stamp a sample may carry now (the future guard)."""
        return self.clock_s + self.settings.max_future_s if self.clock_s is not None \
            else math.inf

    def add(self, channel: str, stamp_s: float, value: float,
            now_s: Optional[float] = None) -> bool:
        """
        Take one sample of an input (SI units); return whether it was accepted.

        ``now_s``: the receiving clock at its arrival (default: the latest reading).
        """
        buf = self._samples[channel]      # KeyError names an unknown channel
        if buf.top > buf.hi:
            self._screen(channel)          # pushed samples come first
        if now_s is not None:
            self._observe_clock(now_s)
        return self._accept_one(channel, stamp_s, value, self._latest_allowed())

    def _accept_one(self, channel: str, stamp_s: float, value: float, latest: float) -> bool:
        """Count and keep one sample if acceptable (``latest``: the future guard)."""
        h = self.health[channel]
        buf = self._samples[channel]
        h.received += 1
        c = self.channel_cfg[channel]
        if not (math.isfinite(value) and math.isfinite(stamp_s)):
            h.non_finite += 1
            return False
        if not c.low <= value <= c.high:
            h.out_of_range += 1
            return False
        if stamp_s > latest:
            h.future += 1
            return False
        if h.last_stamp_s is not None and stamp_s <= h.last_stamp_s:
            h.backwards += 1
            return False
        if self.t_model is not None and stamp_s <= self.t_model + self._eps:
            h.late += 1
            return False
        if not buf.room():
            h.overflow += 1
            return False
        h.accepted += 1
        h.last_stamp_s, h.last_value, h.heard_s = stamp_s, value, self.clock_s
        self._heard(stamp_s, stamp_s)
        buf.t[buf.hi] = stamp_s
        buf.v[buf.hi] = value
        buf.hi += 1
        buf.top = buf.hi
        return True

    def add_many(self, channel: str, stamps_s: np.ndarray, values: np.ndarray,
                 now_s: Optional[float] = None) -> int:
        """
        Take many samples of one input at once, as ``add`` would one by one; return how many.

        The same checks, vectorised, for replaying logs. ``now_s``: the
        receiving clock (s) for the future check, one reading for all or one
        per sample (a log's receive times); unlike ``advance``'s it is not
        taken as the clock (a replay feeds one input's block after another's,
        so these readings go back between calls).
        """
        buf = self._samples[channel]
        if buf.top > buf.hi:
            self._screen(channel)
        t = np.asarray(stamps_s, dtype=float)
        v = np.asarray(values, dtype=float)
        latest = self._latest_allowed() if now_s is None \
            else np.asarray(now_s, dtype=float) + self.settings.max_future_s
        return self._accept(channel, t, v, latest)

    def _screen(self, channel: str) -> None:
        """Check the pushed samples of ``channel`` as ``add`` would, keeping the accepted."""
        buf = self._samples[channel]
        t = buf.t[buf.hi:buf.top].copy()
        v = buf.v[buf.hi:buf.top].copy()
        buf.top = buf.hi
        self._accept(channel, t, v, self._latest_allowed())

    def _accept(self, channel: str, t: np.ndarray, v: np.ndarray, latest) -> int:
        """Count and keep the acceptable samples of ``t``, ``v`` (``latest``: future guard)."""
        h = self.health[channel]
        c = self.channel_cfg[channel]
        buf = self._samples[channel]
        h.received += t.size
        code = check_samples(t, v, c.low, c.high, np.broadcast_to(latest, t.shape),
                             h.last_stamp_s if h.last_stamp_s is not None else -math.inf,
                             self.t_model + self._eps if self.t_model is not None else -math.inf)
        counts = np.bincount(code, minlength=6).tolist()
        h.non_finite += counts[NON_FINITE]
        h.out_of_range += counts[OUT_OF_RANGE]
        h.future += counts[FUTURE]
        h.backwards += counts[BACKWARDS]
        h.late += counts[LATE]
        ok = code == ACCEPTED
        n = int(np.count_nonzero(ok))
        if not n:
            return 0
        ts, vs = t[ok], v[ok]
        room = buf.room(n)
        if room < n:                      # full: the newest are dropped
            h.overflow += n - room
            ts, vs, n = ts[:room], vs[:room], room
            if not n:
                return 0
        h.accepted += n
        h.last_stamp_s, h.last_value, h.heard_s = float(ts[-1]), float(vs[-1]), self.clock_s
        self._heard(float(ts[0]), h.last_stamp_s)
        buf.t[buf.hi:buf.hi + n] = ts
        buf.v[buf.hi:buf.hi + n] = vs
        buf.hi += n
        buf.top = buf.hi
        return n

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
        correcting = self.correction is not None and name in self.correction.tcs
        latest = self._latest_allowed()
        if not math.isfinite(value_C) or not stamp_s <= latest:
            if correcting:
                self.correction.add_reading(name, stamp_s, value_C, latest)   # counted there
            return False
        self.measured_C[name] = (stamp_s, value_C)
        if correcting:
            return self.correction.add_reading(name, stamp_s, value_C, latest)
        return True

    def acknowledge(self, quantity: Optional[str] = None) -> List[AlertEvent]:
        """Acknowledge latched alerts (all, or one quantity)."""
        stamp = self.t_model if self.t_model is not None else 0.0
        return self.alerts.acknowledge(quantity, stamp_s=stamp)

    # ------------------------------------------------------------- the clock
    def _observe_clock(self, now_s: float) -> None:
        """Take a reading of the receiving clock; a jump back re-starts the model time."""
        if not (math.isfinite(now_s) and now_s > 0.0):    # no clock reads that
            return
        if self.clock_s is not None and now_s < self.clock_s - self.settings.clock_jump_s:
            self.restart_time(now_s)
            return
        self.clock_s = now_s if self.clock_s is None else max(self.clock_s, now_s)

    def restart_time(self, now_s: float) -> None:
        """
        Re-start the model time at ``now_s`` (a jump of the receiving clock); keep the state.

        The model never steps across the jump: its next step starts at
        ``now_s``. Samples buffered under the old clock are discarded and
        counted per input (``discarded``); every input's last stamp is
        forgotten, so the new clock's samples are not taken for stamps going
        backwards; stored stamps (alert timers, the forecast's schedule, the
        open data gap) move by the jump, so their durations carry over; the
        thermocouples' stamps are forgotten. Called by ``advance``/``add``
        when the clock goes back by more than ``clock_jump_s``; a node that
        can tell a forward step of its clock from elapsed time calls it too.
        """
        self.clock_jumps += 1
        self.last_clock_jump = (float(self.clock_s) if self.clock_s is not None else math.nan,
                                float(now_s))
        self.clock_s = now_s
        # the first step after the jump ends at the reading that showed it, so that the
        # samples of the new clock stamped up to that reading are not late
        delta = now_s - self.settings.step_s - self.t_model if self.t_model is not None else 0.0
        for name in self.inputs:
            h = self.health[name]
            buf = self._samples[name]
            h.discarded += buf.clear()
            h.last_stamp_s = h.heard_s = None
            h.stale_since_s = None
            if self._prev[name] is not None:
                self._prev[name] = (self._prev[name][0] + delta, self._prev[name][1])
        self._last_sample_s = None
        self.gaps.open_since_s = None
        self._notices.append(
            f'receiving clock jumped from {self.last_clock_jump[0]:.3f} s to {now_s:.3f} s: '
            'model time re-started there, thermal state kept')
        if self.t_model is None:
            return
        self.t_model += delta
        self._t_origin += delta
        self.next_end_s += delta
        self._eps = max(self._eps_base, 8.0 * float(np.spacing(abs(now_s))))
        self.alerts.shift_time(delta)
        if self.correction is not None:
            self.correction.restart_time()
        for attr in ('_next_forecast_s', '_next_margin_s', '_forecast_stamp'):
            if getattr(self, attr) is not None:
                setattr(self, attr, getattr(self, attr) + delta)
        if self._forecast is not None:
            self._forecast.start_s += delta
        self.measured_C = {k: (t + delta, v) for k, (t, v) in self.measured_C.items()}

    # ------------------------------------------------------------- stepping
    def _reference_time(self, now_s: Optional[float]) -> Optional[float]:
        stamps = [h.last_stamp_s for h in self.health.values() if h.last_stamp_s is not None]
        if now_s is not None and math.isfinite(now_s) and now_s > 0.0:
            stamps.append(now_s)
        return max(stamps) if stamps else None

    def _update_staleness(self, ref: float) -> List[str]:
        """
        Mark the inputs stale whose last stamp is older than their timeout; return them.

        With a receiving clock, an input still arriving (a sample accepted
        within its timeout) whose stamps lag the clock by at most
        ``max_lag_s`` stays fresh and is waited for: a busy receiver delivers
        a source-stamped sample late, and stepping past it would lose it.
        """
        stale = []
        lag_s = self.settings.max_lag_s
        for name, h in self.health.items():
            limit = self.channel_cfg[name].timeout_s
            is_stale = h.last_stamp_s is None or (
                ref - h.last_stamp_s > limit
                and not (h.heard_s is not None and self.clock_s - h.heard_s <= limit
                         and ref - h.last_stamp_s <= lag_s))
            if is_stale and not h.stale and h.last_stamp_s is not None:
                h.stale_events += 1
                h.stale_since_s = h.last_stamp_s + limit
            if not is_stale:
                h.stale_since_s = None
            h.stale = is_stale
            if is_stale:
                stale.append(name)
        return stale

    def _heard(self, first_s: float, last_s: float) -> None:
        """Note accepted samples stamped ``first_s`` .. ``last_s``; close a data gap they end."""
        prev = self._last_sample_s
        if prev is not None and first_s - prev > self._gap_after_s:
            g = self.gaps
            length = first_s - prev
            g.count += 1
            g.total_s += length
            g.longest_s = max(g.longest_s, length)
            g.last = (prev, first_s)
            self._notices.append(
                f'data gap: no input sample for {length:.1f} s (from {prev:.3f} s to '
                f'{first_s:.3f} s); the model ran on the held inputs')
        if prev is None or last_s > prev:
            self._last_sample_s = last_s
        self.gaps.open_since_s = None

    def _track_gap(self, stale: List[str]) -> None:
        """Open a data gap when every input is stale (it closes with the next sample)."""
        if len(stale) == len(self.inputs) and self.gaps.open_since_s is None:
            self.gaps.open_since_s = self._last_sample_s

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
        """Note which fresh inputs already reach past the next step's end (see ``due``)."""
        fresh = [h for h in self.health.values() if not h.stale]
        self._needed = max(len(fresh), 1)
        self._crossed = {n for n, h in self.health.items() if not h.stale
                         and h.last_stamp_s is not None and h.last_stamp_s >= self.next_end_s}

    def _advance(self, now_s: Optional[float], max_steps: Optional[int]) -> List[Estimate]:
        if now_s is not None:
            self._observe_clock(now_s)
        for name in self.inputs:
            buf = self._samples[name]
            if buf.top > buf.hi:
                self._screen(name)
        self._behind = False
        ref = self._reference_time(now_s)
        if ref is None:
            return []
        stale = self._update_staleness(ref)
        fresh = [n for n in self.inputs if n not in stale]
        horizon = min(self.health[n].last_stamp_s for n in fresh) if fresh else ref
        if self.t_model is None:
            # start once every input has spoken (or its timeout passed), at the latest
            # first stamp: each input then has a value at the start, live or replayed
            firsts = [float(b.t[b.lo]) for b in self._samples.values() if b.hi > b.lo]
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
        self._track_gap(stale)
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
                self._drop_until(n, self.t_model)
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
        limit = horizon + self._eps
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
        span = np.array([self.t_model, self._step_end(self.steps + n_steps)]) + self._eps
        stamps = []
        for b in self._samples.values():       # those of the steps ahead
            a, z = np.searchsorted(b.stamps(), span, side='right')
            stamps.append(b.t[b.lo + a:b.lo + z])
        stamps = np.concatenate(stamps)
        # the step of each sample: (end_{k-1}, end_k] holds step k
        step = self.settings.step_s
        k = np.ceil((stamps - self._eps - self._t_origin) / step).astype(np.int64)
        k = np.unique(np.concatenate([[self.steps], k, [self.steps + n_steps + 1]]))
        empty = np.diff(k) - 1          # steps without a sample between two with samples
        long = np.flatnonzero(empty >= HOLD_AFTER_STEPS)
        if not long.size:
            return False, n_steps
        i = long[0]
        if k[i] == self.steps:
            return True, int(empty[i])
        return False, int(k[i] - self.steps)

    def ready(self, stamp_s: float) -> bool:
        """Tell whether a sample stamped ``stamp_s`` may let the next step complete (cheap)."""
        return stamp_s >= self.next_end_s

    def _step_end(self, k: int) -> float:
        """Return the sample time (s) at which step ``k`` ends (step 0 ends at the start)."""
        return self._t_origin + k * self.settings.step_s

    def _start(self, t0: float) -> None:
        """Initialise the model at ambient with the inputs' values at ``t0``."""
        self.t_model = self._t_origin = t0
        # stamps since the epoch are only resolved to ~0.2 us: equal means within a few ulps
        self._eps = max(self._eps_base, 8.0 * float(np.spacing(abs(t0))))
        self.next_end_s = self._step_end(1) - self._eps
        values = self._model_inputs({n: np.array([self._value_at(n, t0)]) for n in self.inputs})
        # the model runs on time since the start: stamps since the epoch (~1.8e9 s) carry
        # only ~0.2 us of resolution, which would make every step length differ
        first = SampleBlock(np.array([0.0]), *(values[n] for n in INPUTS))
        self.model.initialise(self.ambient_K, first)
        for n in self.inputs:
            self._drop_until(n, t0)

    def _count_until(self, name: str, t: float) -> int:
        """Return how many buffered samples of ``name`` are stamped at or before ``t``."""
        return int(np.searchsorted(self._samples[name].stamps(), t + self._eps, side='right'))

    def _value_at(self, name: str, t: float) -> float:
        """Return the last value at or before ``t`` (fallback: last good, else at rest)."""
        k = self._count_until(name, t)
        if k:
            buf = self._samples[name]
            return float(buf.v[buf.lo + k - 1])
        if self._prev[name] is not None:
            return self._prev[name][1]
        h = self.health[name]
        return h.last_value if h.last_value is not None else self.rest[name]

    def _drop_until(self, name: str, t: float) -> None:
        k = self._count_until(name, t)
        if k:
            buf = self._samples[name]
            j = buf.lo + k - 1
            self._prev[name] = (float(buf.t[j]), float(buf.v[j]))
            buf.lo += k

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
            k_all = self._count_until(name, ends[-1])
            prev = self._prev[name]
            start = prev[1] if prev is not None else self._value_at(name, ends[0])
            buf = self._samples[name]
            out[name] = grid_rows(buf.t[buf.lo:buf.lo + k_all], buf.v[buf.lo:buf.lo + k_all],
                                  ends, self._frac, self._eps, start,
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
        values = self._model_inputs(grid_values)
        values['position_m'] = self._limit_position(values['position_m'], (t1 - t0) / frac.size)
        since_start = (self.steps + m * frac) * self.settings.step_s
        block = SampleBlock(since_start, *(values[n] for n in INPUTS))
        span_s = m * self.settings.step_s
        self.model.step(block, self.ambient_K, max_substep_s=span_s if m > 1 else None)
        corrected = None
        if self.correction is not None:
            corrected = self.correction.step(self.model, t0, t1, span_s, self._eps)
        self.t_model = t1
        self.steps += m
        self.next_end_s = self._step_end(self.steps + 1) - self._eps
        if m == 1:
            self._window.append(block)
        else:
            # the forecast repeats steps of the recent duty: the block's held values, as
            # many steps of them as the block held (up to the whole window)
            held = SampleBlock(self.settings.step_s * self._frac, *(
                np.full(self.n_grid, values[n][-1]) for n in INPUTS))
            self._window.extend(itertools.repeat(held, min(m, self._window.maxlen)))
        implausible = self._plausibility(values, t1 - t0)
        outputs = corrected if corrected is not None else self.model.outputs()
        temps = {k: v - C_TO_K for k, v in outputs.items()}
        events = self.alerts.update(t1, temps)      # (it takes the quantities it has rules for)
        worst_stale = max((t1 - self.health[n].stale_since_s for n in stale
                           if self.health[n].stale_since_s is not None), default=0.0)
        on_fallback = self.settings.stale_uncertainty_K_per_s * max(worst_stale, 0.0)
        sigma = self.settings.model_uncertainty_K + on_fallback
        if corrected is not None:
            uncertainty = self._filtered_uncertainty(on_fallback, sigma)
        else:
            uncertainty = {k: sigma for k in temps}
        notices, self._notices = self._notices, []
        est = Estimate(
            stamp_s=t1, temperatures_C=temps, uncertainty_K=uncertainty,
            heat_W=dict(self.model.heat_W), limits_C=dict(self.limits_C),
            time_to_limit_s=dict(self._forecast_result), forecast_stamp_s=self._forecast_stamp,
            margin_current_A=self._margin, alert_level=int(self.alerts.worst()),
            alert_events=events, stale=list(stale), implausible=implausible, step=self.steps,
            correction=self.correction.summary() if self.correction is not None else None,
            notices=notices, inputs=sensors)
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
        values = {n: np.array([self._value_at(n, t0)]) for n in self.inputs}
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

    def _filtered_uncertainty(self, on_fallback: float, open_loop: float) -> Dict[str, float]:
        """
        Return each output's 1 sigma (K) from the filter's covariance.

        The filter's variance plus ``unmodelled_sigma_K`` in quadrature, plus
        the growth for inputs on their fallback (the filter does not model
        held inputs), never above the open-loop uncertainty: a filter that has
        not seen a thermocouple for long knows no more than the model alone.
        """
        u2 = self.settings.correction.unmodelled_sigma_K ** 2
        sigma = np.minimum(np.sqrt(self.correction.variances_K2 + u2) + on_fallback, open_loop)
        return dict(zip(self.model.quantities.names, sigma.tolist()))

    def _model_inputs(self, values: Dict[str, np.ndarray]) -> Dict[str, np.ndarray]:
        """
        Return the model's six inputs from the sensors' (the same arrays with port pressures).

        A differential pressure is split with its low side at the accumulator
        pressure: in a closed-circuit EHA the low port is fed from the
        accumulator through its check valve.
        """
        if not self.differential:
            return values
        p_a, p_b, p_acc = split_differential(values['dp_Pa'], self.rest['p_acc_Pa'])
        return {**values, 'p_a_Pa': p_a, 'p_b_Pa': p_b, 'p_acc_Pa': p_acc}

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
        out, self._position_limited = rate_limit(x, self.model._last[1],
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
        model.circuit.keep_transition = False     # no filter follows the forecast
        model.oil_substep_s = self.settings.forecast_substep_s
        self._forecast = _Forecast(model=model, start_s=self.t_model,
                                   duty=duty, ambient_K=self.ambient_K,
                                   crossed=dict.fromkeys(self.limits_C),
                                   n=max(1, int(round(self.settings.forecast_step_s
                                                      / self.settings.step_s))))

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
        n = f.n
        idx = (f.k + np.arange(n)) % n_all
        f.k = (f.k + n) % n_all
        span = n * s.step_s
        t = f.model.time_s + (np.arange(1, n + 1) / n) * span
        x = f.model._last[1] + np.cumsum(f.duty['dx_m'][idx])
        block = SampleBlock(t, *(f.duty[a][idx] for a in ('current_A', 'speed_rad_s', 'p_a_Pa',
                                                          'p_b_Pa', 'p_acc_Pa')), x)
        before = f.model.state
        f.model.step(block, f.ambient_K, max_substep_s=span)
        f.t_s += span
        # longer steps while the temperatures move slowly, up to one pass of the duty
        if float(np.max(np.abs(f.model.state - before))) < FORECAST_TOL_K:
            f.n = min(2 * n, max(n_all, n))
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


#: how ``grid_rows`` treats each input: interval means, the root of the mean square
#: (the current: copper loss is I^2 R), or interpolation at the grid times (the position)
_MODE = dict.fromkeys(INPUTS + DIFFERENTIAL_INPUTS, 0)
_MODE.update(current_A=1, position_m=2)


@jit
def split_differential(dp, p_acc):
    """Return the port pressures A and B and the accumulator's (Pa) from a differential one."""
    return p_acc + np.maximum(dp, 0.0), p_acc - np.minimum(dp, 0.0), np.full(dp.shape, p_acc)


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
    return w > 200.0 and i_rms < 0.05, flow > 0.5 / 60000 and w < 20.0


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


@jit
def check_samples(t, v, low, high, latest, last_s, model_s):
    """
    Return why each sample of one input is rejected (ACCEPTED, NON_FINITE, ...), in order.

    Non-finite stamp or value; value outside [``low``, ``high``]; stamp after
    its ``latest`` (the future guard); stamp not after the latest accepted so
    far (``last_s`` before these: backwards); stamp at or before ``model_s``
    (the model stepped past it: late). The checks of ``Estimator.add``, one
    compiled loop for a batch.
    """
    code = np.empty(t.size, dtype=np.int64)
    for i in range(t.size):
        if not (np.isfinite(t[i]) and np.isfinite(v[i])):
            code[i] = NON_FINITE
        elif not low <= v[i] <= high:
            code[i] = OUT_OF_RANGE
        elif t[i] > latest[i]:
            code[i] = FUTURE
        elif t[i] <= last_s:
            code[i] = BACKWARDS
        elif t[i] <= model_s:
            code[i] = LATE
        else:
            code[i] = ACCEPTED
            last_s = t[i]
    return code
