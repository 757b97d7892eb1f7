"""
A replay's run: the bag's blocks through an estimator session, the estimates kept.

Each block's samples go to an :class:`~wet_eha_thermal.estimator.session.EstimatorSession`
with the stamps the live estimator used: the header stamp of a FluidPressure (the log
time when it is zero) and the log (receive) time of a Float64, which has no header.
The session steps in sample time, so a replay gives the estimates of the live run up
to the difference between the recorder's and the estimator's receive times of the
stamp-less inputs. What the session publishes (:class:`~.session.Output`) is kept at
``output_rate_Hz``: the CSV's columns, each output's uncertainty and the state (the
live node's messages), the alert summaries and every tick's limits.

The estimator works on its outlook inline, as the live one does in the background:
at the same sample times, from the same states, the same current limits for the
drive (every ``estimator.limits.period_s``), forecast and margin; ``outlook=False``
(``--no-outlook``) skips them for speed.
"""

from dataclasses import dataclass, field
import math
import os
import time
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from .plan import ReplayError, ReplayPlan
from ... import interface
from ...bag.reader import iter_column_blocks
from ...estimator.core import Estimate
from ...estimator.limits import CurrentLimits
from ...estimator.session import EstimatorSession, Output, Samples

#: Estimates written to the outputs (degC), in column order.
OUTPUT_ESTIMATES = interface.ESTIMATES


@dataclass
class ReplayResult:
    """Estimates at the output rate, thermocouple series and the run's figures."""

    plan: ReplayPlan
    stamp_s: np.ndarray                      # estimate stamps (sample time, s)
    temperatures_C: Dict[str, np.ndarray]
    sigma_K: np.ndarray                      # the largest uncertainty of all quantities (K)
    alert_level: np.ndarray
    stale_inputs: np.ndarray                 # number of inputs on fallback per estimate
    measured: Dict[str, tuple]               # thermocouple -> (stamps s, degC)
    inputs: Dict[str, tuple]                 # input -> (stamps s, values), decimated for plots
    alert_events: List[tuple]                # (stamp s, message)
    messages: int
    steps: int
    sample_time_s: float
    wall_s: float
    truncated: bool
    problem: Optional[str]
    health: Dict[str, dict] = field(default_factory=dict)
    implausible: Dict[str, int] = field(default_factory=dict)   # steps, per combination
    # live correction (estimator.correction): None when off; else learned heats (W) and
    # every thermocouple's status and counters
    correction: Optional[dict] = None
    # the estimator's limits (degC) of the estimates its alerts and forecast watch
    limits_C: Dict[str, float] = field(default_factory=dict)
    # the outlook (False: not computed, the fields below are empty)
    outlook: bool = False
    # per estimate: the latest forecast's time from its start to each limit (s; inf
    # beyond its horizon, NaN before the first), that start (sample time s), and the
    # latest continuous current limit (A RMS; NaN before the first)
    time_to_limit_s: Dict[str, np.ndarray] = field(default_factory=dict)
    forecast_stamp_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    margin_current_A: np.ndarray = field(default_factory=lambda: np.zeros(0))
    # every limit tick's current limits, how long each was in force (s of sample time:
    # until the next tick, the last until the log's end) and the RMS current (A) of the
    # log meanwhile (NaN for none)
    current_limits: List[CurrentLimits] = field(default_factory=list)
    limits_held_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    limits_current_A: np.ndarray = field(default_factory=lambda: np.zeros(0))
    # per estimate, each output's uncertainty (K, 1 sigma) and the model's state (K, one
    # row per estimate, columns named by ``state_names``): what the live node publishes
    uncertainty_K: Dict[str, np.ndarray] = field(default_factory=dict)
    state_K: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    state_names: Tuple[str, ...] = ()
    # the alert summaries as the session published them, each with the stamp of the
    # estimate it went out with (None: before the first)
    alerts: List[Tuple[Optional[float], dict]] = field(default_factory=list)

    @property
    def speed_x(self) -> float:
        """Return the replay speed in multiples of real time."""
        return self.sample_time_s / self.wall_s if self.wall_s > 0 else math.inf


class _Decimator:
    """Keep about one sample per ``interval_s`` of a series (for plots of long runs)."""

    def __init__(self, interval_s: float) -> None:
        self.interval_s = interval_s
        self.next_s = -math.inf
        self.t: List[np.ndarray] = []
        self.v: List[np.ndarray] = []

    def add(self, t: np.ndarray, v: np.ndarray) -> None:
        if not t.size:
            return
        bins = np.floor(t / self.interval_s)
        keep = np.concatenate([[True], bins[1:] != bins[:-1]]) & (t >= self.next_s)
        self.t.append(t[keep])
        self.v.append(v[keep])
        self.next_s = (bins[-1] + 1) * self.interval_s

    def arrays(self) -> tuple:
        if not self.t:
            return np.zeros(0), np.zeros(0)
        return np.concatenate(self.t), np.concatenate(self.v)


class _TickCurrent:
    """The RMS current of the steps between limit ticks, from the estimates' inputs."""

    def __init__(self) -> None:
        self.squares = 0.0      # sum over steps of each step's mean I^2 (A^2)
        self.steps = 0
        self.last_step = 0
        self.before: List[Tuple[int, float]] = []   # steps and RMS of the period ending at a tick

    def add(self, e: Estimate, tick: bool) -> None:
        """Add the steps of ``e`` (a held block counts as its steps); close a period at a tick."""
        n = e.step - self.last_step
        self.last_step = e.step
        self.squares += float(np.mean(e.inputs['current_A'] ** 2)) * n
        self.steps += n
        if tick:
            self.before.append(self._period())
            self.squares, self.steps = 0.0, 0

    def _period(self) -> Tuple[int, float]:
        return self.steps, math.sqrt(self.squares / self.steps) if self.steps else math.nan

    def in_force(self, step_s: float) -> Tuple[np.ndarray, np.ndarray]:
        """Return how long each tick's limits held (s) and the RMS current meanwhile (A)."""
        after = self.before[1:] + [self._period()] if self.before else []
        return (np.array([n * step_s for n, _ in after]),
                np.array([rms for _, rms in after]))


def _outlook_row(e: Estimate, limited: Sequence[str]) -> List[float]:
    """Return an estimate's times to limit, forecast start and margin (NaN: none yet)."""
    times = [e.time_to_limit_s.get(q, math.nan) for q in limited]    # None: beyond it
    return [math.inf if t is None else t for t in times] + [
        math.nan if v is None else v for v in (e.forecast_stamp_s, e.margin_current_A)]


class _KeptOutputs:
    """
    What the session publishes, kept at the output rate.

    The CSV's rows, each output's uncertainty and the state of every
    ``every``-th step; every alert event and summary and every tick's limits.
    """

    def __init__(self, every: int, limited: Sequence[str], outlook: bool) -> None:
        self.every = every
        self.limited = list(limited)
        self.outlook = outlook
        self.rows: List[np.ndarray] = []
        self.sigmas: List[List[float]] = []
        self.states: List[np.ndarray] = []
        self.events: List[tuple] = []
        self.alerts: List[Tuple[Optional[float], dict]] = []
        self.current_limits: List[CurrentLimits] = []
        self.tick_current = _TickCurrent()

    def __call__(self, out: Output) -> None:
        """Keep what ``out`` holds (the session's ``publish`` callback)."""
        # inline, a tick's limits are done within the step that made it: they come out
        # with its estimate
        ticks = {lim.stamp_s: lim for lim in out.limits}
        self.current_limits.extend(ticks.values())
        if out.alerts is not None:
            self.alerts.append((out.estimates[-1].stamp_s if out.estimates else None,
                                out.alerts))
        for e in out.estimates:
            for ev in e.alert_events:
                self.events.append((e.stamp_s, ev.message))
            if self.outlook:
                self.tick_current.add(e, e.stamp_s in ticks)
            if e.step % self.every == 0:
                self.rows.append(np.array(
                    [e.stamp_s] + [e.temperatures_C[n] for n in OUTPUT_ESTIMATES]
                    + [max(e.uncertainty_K.values()), e.alert_level, len(e.stale)]
                    + (_outlook_row(e, self.limited) if self.outlook else [])))
                self.sigmas.append([e.uncertainty_K[n] for n in OUTPUT_ESTIMATES])
                self.states.append(e.state_K)

    def fields(self, step_s: float) -> dict:
        """Return the :class:`ReplayResult` fields of what was kept (at least one row)."""
        table = np.vstack(self.rows)
        n = len(OUTPUT_ESTIMATES)
        ahead = table[:, 4 + n:]          # the outlook's columns (none when it is off)
        outlook = self.outlook
        held_s, current_A = self.tick_current.in_force(step_s)
        return {
            'stamp_s': table[:, 0],
            'temperatures_C': {name: table[:, 1 + k] for k, name in enumerate(OUTPUT_ESTIMATES)},
            'sigma_K': table[:, 1 + n], 'alert_level': table[:, 2 + n].astype(int),
            'stale_inputs': table[:, 3 + n].astype(int), 'alert_events': self.events,
            'time_to_limit_s': {q: ahead[:, k] for k, q in enumerate(self.limited) if outlook},
            'forecast_stamp_s': ahead[:, -2] if outlook else np.zeros(0),
            'margin_current_A': ahead[:, -1] if outlook else np.zeros(0),
            'current_limits': self.current_limits, 'limits_held_s': held_s,
            'limits_current_A': current_A,
            'uncertainty_K': {name: np.array([s[k] for s in self.sigmas])
                              for k, name in enumerate(OUTPUT_ESTIMATES)},
            'state_K': np.vstack(self.states), 'alerts': self.alerts}


class _BagSeries:
    """What the bag's samples show besides the model's run: thermocouples, inputs for plots."""

    def __init__(self, plan: ReplayPlan, plot_interval_s: float) -> None:
        self.first_s: Optional[float] = None
        self.measured = {tc: ([], []) for tc in plan.thermocouples}
        self.inputs = {name: _Decimator(plot_interval_s) for name in plan.inputs}

    def add(self, samples: Samples) -> None:
        """Add a routed block's thermocouple readings and inputs."""
        if samples.first_s is not None:
            self.first_s = samples.first_s if self.first_s is None else min(self.first_s,
                                                                            samples.first_s)
        for name, (t, v) in samples.inputs.items():
            self.inputs[name].add(t, v)
        for tc, (t, v, _) in samples.thermocouples.items():
            self.measured[tc][0].append(t)
            self.measured[tc][1].append(v)

    def fields(self) -> dict:
        """Return the :class:`ReplayResult` fields ``measured`` and ``inputs``."""
        return {'measured': {tc: (np.concatenate(t) if t else np.zeros(0),
                                  np.concatenate(v) if v else np.zeros(0))
                             for tc, (t, v) in self.measured.items()},
                'inputs': {name: d.arrays() for name, d in self.inputs.items()}}


def replay(plan: ReplayPlan, output_rate_Hz: float = 10.0,
           on_progress: Optional[Callable[[float, float, float], None]] = None,
           plot_interval_s: float = 0.1, prefetch: bool = True,
           session: Optional[EstimatorSession] = None, outlook: bool = True) -> ReplayResult:
    """
    Run the estimator over the bag of ``plan`` in sample time; return the estimates.

    Estimates are kept at ``output_rate_Hz`` (every step when it is at least
    the step rate). ``on_progress(fraction, sample_time_s, wall_s)`` is called
    after each block of about 10 s of log. ``prefetch``: read the bag in a
    forked child on another core (the same numbers either way; see
    :class:`~.bag.reader.ColumnBlocks`). ``outlook``: compute every tick's
    current limits, the forecast and the margin, inline (``False``: none).
    ``session``: the estimator session to run (its own outlook, not ``outlook``), new on
    ``plan.cfg`` by default, kept by the caller to start from its last state (a
    what-if from a bag).
    """
    session = session if session is not None else EstimatorSession(
        plan.cfg, outlook='inline' if outlook else 'off')
    outlook = session.outlook_mode != 'off'       # a caller's session has its own
    step_s = plan.cfg.estimator.step_s
    every = max(1, int(round(1.0 / (output_rate_Hz * step_s))))
    kept = _KeptOutputs(every, session.limits_C, outlook)
    series = _BagSeries(plan, plot_interval_s)
    t_wall = time.perf_counter()
    size = max(os.path.getsize(plan.info.path), 1)
    done_bytes = [0]
    # the next block is read and decoded on the other core while the model steps
    blocks = iter_column_blocks(plan.info.path, plan.specs, prefetch=prefetch,
                                on_progress=lambda done, total: done_bytes.__setitem__(0, done))
    session.publish = kept
    session.announce()            # the summary a node publishes first
    for block in blocks:
        samples = plan.route(block)
        series.add(samples)
        session.feed(samples)
        if on_progress is not None:
            first_s = series.first_s
            t_model = (session.t_model - first_s) if session.t_model is not None and first_s \
                else 0.0
            on_progress(done_bytes[0] / size, t_model, time.perf_counter() - t_wall)
    wall = time.perf_counter() - t_wall
    if not kept.rows:
        raise ReplayError(f'{plan.info.path}: not one model step could be made: the bag holds '
                          f'{blocks.message_count} messages of the mapped topics')
    status = session.status()
    return ReplayResult(
        plan=plan, **kept.fields(step_s), **series.fields(),
        messages=blocks.message_count, steps=status.steps,
        sample_time_s=status.steps * step_s, wall_s=wall, truncated=blocks.truncated,
        problem=blocks.problem,
        health={name: dict(vars(h)) for name, h in session.health.items()},
        implausible=session.implausible_counts, correction=session.correction_summary(),
        limits_C=session.limits_C, outlook=outlook,
        state_names=tuple(session.model.quantities.state_names))
