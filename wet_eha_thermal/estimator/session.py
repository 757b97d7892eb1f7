"""
One estimator session: how every caller drives the estimator, and what it hands back.

The live node, replay, the calibration's evaluator, what-if and the tests all
make the same calls on an :class:`EstimatorSession`; none reaches into the
estimator's parts (:class:`~.core.Estimator` keeps them private). Samples go
in one at a time (:meth:`~EstimatorSession.take`, as a node receives them;
:meth:`~EstimatorSession.push` without stepping), as arrays
(:meth:`~EstimatorSession.add`) or as a routed block of a log
(:meth:`~EstimatorSession.feed`); the model steps when a sample completes a
step, at :meth:`~EstimatorSession.step` and at the node's timer
(:meth:`~EstimatorSession.tick`).

What a call makes leaves by one channel, the ``publish`` callback, as
:class:`Output` records in the order a node sends them: first the estimates
(with the alert summary when it changed, and what to log), at once; then,
after the slow work (the model's deferred re-discretisation and the
outlook's slices within ``budget_s``), the current limits that work
finished. The session decides the limits' status (a tick finished while the
model is behind its inputs goes out as the fallback), so the drive, the view
and /diagnostics see the same limits with the same status
(:attr:`EstimatorSession.limits`, ``Estimate.current_limits``); a caller
that stops publishing says so with :meth:`EstimatorSession.stop_limits`
(the drive's last limits, the fallback). A failure of
the model's step is counted and never raised; while the model fails the
last good estimate goes out again, stamped with the clock
(:attr:`Output.held`). The alert summary (the JSON the node publishes on
``/eha/alerts``) carries the data gaps, the clock jumps and every event
since the last summary (alerts raised or cleared, gaps, clock steps).

The message building (:mod:`wet_eha_thermal.messages`) turns these records
into the estimator's topics, for the node and for replay alike. What the
session has done so far (ready, behind, gaps, clock jumps, the limits' status,
the counts) is one :class:`SessionStatus` (:meth:`EstimatorSession.status`).
"""

from dataclasses import dataclass, field, replace
import math
from types import MappingProxyType
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from .alerts import AlertEvent, AlertRule
from .core import Estimate, Estimator
from .intake import DataGaps
from .limits import CurrentLimits, fallback_limits
from ..config import Config
from ..interface import HARDWARE_ID, InputCounts, LimitStatus
from ..model.eha import EHAModel
from ..units import C_TO_K


@dataclass
class Output:
    """What one call of a session made, in the order a node publishes it."""

    #: new estimates, oldest first (a node publishes the last)
    estimates: List[Estimate] = field(default_factory=list)
    #: the last good estimate and the clock (s) to stamp it with: the model is failing
    held: Optional[Tuple[Estimate, float]] = None
    #: current limits for the drive, oldest first, with the status they go out with
    limits: List[CurrentLimits] = field(default_factory=list)
    #: the alert summary (JSON-safe) when it changed since the last one published, else None
    alerts: Optional[Dict[str, Any]] = None
    #: (level, text) to log: 'error', 'warning' or 'info'
    log: List[Tuple[str, str]] = field(default_factory=list)
    #: the receiving clock jumped: estimate stamps start over
    restarted: bool = False

    @property
    def empty(self) -> bool:
        """Tell whether there is nothing to publish or log."""
        return not (self.estimates or self.held or self.limits or self.alerts is not None
                    or self.log)


@dataclass
class Samples:
    """One block of a log by what it feeds: stamps (s) and values, in SI units and degC."""

    inputs: Dict[str, Tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    # stamps, readings (degC) and the variances the messages give (K^2)
    thermocouples: Dict[str, Tuple[np.ndarray, np.ndarray, np.ndarray]] = field(
        default_factory=dict)
    ambient: Tuple[np.ndarray, np.ndarray] = (np.zeros(0), np.zeros(0))
    first_s: Optional[float] = None            # the earliest stamp of the block


@dataclass(frozen=True)
class SessionStatus:
    """
    A session at one moment (:meth:`EstimatorSession.status`), read in one call.

    What /diagnostics, the node's report and replay's show. Sample times in
    s; ``None`` where there is nothing yet.
    """

    ready: bool                     # an estimate exists (the model has stepped)
    behind: bool                    # complete steps wait for the next call (step limit hit)
    t_model_s: Optional[float]      # the sample time the model has stepped to
    last_sample_s: Optional[float]  # the latest accepted sample's stamp, any input
    steps: int
    held_blocks: int                # silences crossed in one held block
    stale: Tuple[str, ...]          # the inputs on their fallback value
    inputs: Dict[str, InputCounts]  # each input's samples
    gaps: DataGaps                  # a copy: the silences of every input at once
    clock_jumps: int
    last_clock_jump: Optional[Tuple[float, float]]   # (from s, to s)
    alert_level: int                # the highest reported: 0 OK, 1 WARN, 2 CRITICAL
    alert_message: str              # 'OK' or the alerts, worst first
    limits: Optional[CurrentLimits]     # the latest published, with its status
    limits_published: int
    limits_fallback: int            # of those, sent as the fallback
    limit_ticks_behind: int         # ticks given up (not computed in time)
    outlook_failures: int           # limits and forecasts that failed
    forecasts_skipped: int          # a forecast tick while one was under way
    model_errors: int
    model_error: Optional[str]      # the failing step's error while the model fails, else None
    background_errors: int


def json_safe(value):
    """Return ``value`` with enums as ints and non-finite floats as None, for strict JSON."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    return str(value)


def _ignore(out: Output) -> None:
    """Publish nothing (a session whose caller reads the estimates it returns)."""


class EstimatorSession:
    """Drive one estimator: samples and ticks in, estimates, limits and alerts out."""

    def __init__(self, cfg: Config, outlook: str = 'off', model: Optional[EHAModel] = None,
                 publish: Optional[Callable[[Output], None]] = None, budget_s: float = 0.0,
                 hardware_id: str = HARDWARE_ID) -> None:
        self._est = Estimator(cfg, model=model, outlook=outlook)
        #: where the outputs go (see :class:`Output`)
        self.publish = publish if publish is not None else _ignore
        #: wall time (s) given to the outlook after each step that made estimates
        self.budget_s = budget_s
        self.hardware_id = hardware_id
        self._model_errors = 0
        self._model_error = ''
        self._model_failing = False
        self._background_errors = 0
        self._limits_published = 0      # limits sent, and those as the fallback
        self._limits_fallback = 0
        #: the latest limits published (None before the first)
        self.limits: Optional[CurrentLimits] = None
        self._last: Optional[Estimate] = None
        self._alert_key = None
        self._events: List[str] = []
        self._tick_clock: Optional[Tuple[float, float]] = None

    # ------------------------------------------------------------ samples in
    def push(self, channel: str, stamp_s: float, value: float) -> bool:
        """Take one sample as :meth:`take` does, without stepping; return whether a step is due."""
        return self._est.push(channel, stamp_s, value)

    def take(self, channel: str, stamp_s: float, value: float,
             now_s: Optional[float] = None) -> List[Estimate]:
        """
        Take one sample (SI units) as a live node does; return the estimates it completed.

        Most samples are only buffered; one that lets every fresh input reach
        past the end of the next step steps the model to the receiving clock
        ``now_s`` (:meth:`step`). A failure before the step (a bad channel)
        raises.
        """
        if not self._est.push(channel, stamp_s, value):
            return []
        return self.step(now_s)

    def take_many(self, channel: str, stamps_s: np.ndarray, values: np.ndarray,
                  now_s: Optional[float] = None) -> List[Estimate]:
        """Take a block of samples of one input (a batched message) as :meth:`take` takes one."""
        if not self._est.push_many(channel, stamps_s, values):
            return []
        return self.step(now_s)

    def add(self, channel: str, stamps_s: Sequence[float], values: Sequence[float],
            now_s=None) -> int:
        """
        Take many samples of one input at once, checked; return how many were accepted.

        ``now_s``: the receiving clock (s) for the future check, one reading
        for all or one per sample (a log's receive times); it is not taken
        as the clock. Nothing steps until :meth:`step`.
        """
        return self._est.add_many(channel, stamps_s, values, now_s)

    def add_measured(self, name: str, stamp_s: float, value_C: float) -> bool:
        """Take a thermocouple reading (degC); return whether it was accepted."""
        return self._est.add_measured(name, stamp_s, value_C)

    def add_ambient(self, stamp_s: float, value_C: float) -> bool:
        """Take an ambient temperature (degC) for the housings' heat loss."""
        return self._est.add_ambient(stamp_s, value_C)

    def feed(self, block: Samples) -> List[Estimate]:
        """
        Take a routed block of a log in stamp order, stepping through it; return the estimates.

        The thermocouple readings go in first (each is used by its stamp);
        an ambient reading applies from its stamp on, as it does live: the
        inputs are fed up to each reading and stepped, then it is taken.
        """
        for tc, (t, v, _) in block.thermocouples.items():
            for stamp, value in zip(t.tolist(), v.tolist()):
                self._est.add_measured(tc, stamp, value)
        series, ambient = block.inputs, block.ambient
        cuts = {name: np.searchsorted(t, ambient[0], side='right')
                for name, (t, _) in series.items()}
        out: List[Estimate] = []
        for k in range(ambient[0].size + 1):
            for name, (t, v) in series.items():
                lo = cuts[name][k - 1] if k else 0
                hi = cuts[name][k] if k < ambient[0].size else t.size
                if hi > lo:
                    self._est.add_many(name, t[lo:hi], v[lo:hi])
            out += self.step(all_steps=True)
            if k < ambient[0].size:
                self._est.add_ambient(float(ambient[0][k]), float(ambient[1][k]))
        return out

    # ------------------------------------------------------------- stepping
    def step(self, now_s: Optional[float] = None, all_steps: bool = False) -> List[Estimate]:
        """
        Step the model as far as the samples (and the clock ``now_s``) allow; publish.

        At most ``estimator.max_steps_per_call`` steps unless ``all_steps``
        (offline work that feeds seconds of samples at once). The estimates
        go out at once (:class:`Output`), then the slow work runs and the
        limits it finished go out. A failure of the step is counted, logged
        and not raised: the last good estimate goes out again instead.
        """
        est = self._est
        jumps = est.clock_jumps
        out = Output()
        try:
            out.estimates = est.advance_all(now_s) if all_steps else est.advance(now_s)
            self._model_failing = False
        except Exception as exc:  # noqa: B902 - any failure of the step is the model's
            self._model_errors += 1
            self._model_error = f'{type(exc).__name__}: {exc}'
            self._model_failing = True
            out.log.append(('error', f'model step failed: {self._model_error}'))
        out.restarted = est.clock_jumps != jumps
        self._report(out, now_s)
        self.publish(out)
        if not out.estimates:
            return out.estimates
        later = Output()
        try:
            est.prepare()
            if self.budget_s > 0.0:
                est.background(self.budget_s)
        except Exception as exc:  # noqa: B902 - the slow work never stops the estimates
            self._background_errors += 1
            later.log.append(('error', f'forecast/margin failed: {type(exc).__name__}: {exc}'))
        later.limits = self._take_limits()
        if not later.empty:
            self.publish(later)
        return out.estimates

    def tick(self, now_s: float, steady_s: Optional[float] = None) -> List[Estimate]:
        """
        Step to the clock ``now_s`` at a node's timer (silent inputs go stale); publish.

        ``steady_s``: the steady clock (s), None under sim time; the clock
        moving ahead of it by more than ``estimator.clock_jump_s`` between
        two ticks was stepped (the system clock), and re-starts the model
        time, so that the model never steps across it. Nothing is done while
        the samples keep the model current.
        """
        s = self._est.settings
        if steady_s is not None and self._tick_clock is not None:
            ahead = (now_s - self._tick_clock[0]) - (steady_s - self._tick_clock[1])
            if ahead > s.clock_jump_s:
                self._est.restart_time(now_s)
        self._tick_clock = (now_s, steady_s) if steady_s is not None else None
        t_model = self._est.t_model
        if t_model is not None and now_s - t_model < 2.0 * s.step_s:
            return []
        return self.step(now_s)

    def restart_time(self, now_s: float) -> None:
        """Re-start the model time at ``now_s`` (a jump of the receiving clock); keep the state."""
        self._est.restart_time(now_s)

    def work(self, budget_s: float) -> bool:
        """Work on the outlook for ``budget_s`` and publish the limits it finished; say if busy."""
        self._est.background(budget_s)
        limits = self._take_limits()
        if limits:
            self.publish(Output(limits=limits))
        return self._est._outlook.busy

    def acknowledge(self, quantity: Optional[str] = None) -> List[AlertEvent]:
        """
        Acknowledge latched alerts (all, or one ``quantity``); publish the alert summary.

        A quantity without an alert rule raises ValueError.
        """
        events = self._est.acknowledge(quantity)
        self._events += [e.message for e in events]
        self.publish(Output(alerts=self.alert_summary(force=True),
                            log=[('info', e.message) for e in events]))
        return events

    def stop_limits(self, why: str) -> None:
        """
        Publish the drive's last limits: the fallback, status STOPPED, saying ``why``.

        For a node that stops publishing (a managed node deactivated): the
        drive falls back at once instead of when its watchdog finds the
        limits old. Ticks still waiting are given up first (as behind), so
        none follows; the stamp is the model's time, never before the last
        limits. Nothing while the model has not stepped.
        """
        est = self._est
        if est.t_model is None:
            return
        out = self._take_limits(math.inf)
        lim = est.settings.limits
        stamp_s = max(est.t_model, self.limits.stamp_s if self.limits is not None else -math.inf)
        last = fallback_limits(stamp_s, lim.horizons_s, lim.fallback_current_A,
                               LimitStatus.STOPPED, why)
        self._limits_published += 1
        self._limits_fallback += 1
        self.limits = last
        self.publish(Output(limits=out + [last]))

    def announce(self) -> None:
        """Publish the alert summary as it is now (a node's first, latched)."""
        self.publish(Output(alerts=self.alert_summary(force=True)))

    # ---------------------------------------------------------- what goes out
    def _report(self, out: Output, now_s: Optional[float]) -> None:
        """Fill ``out``: what to log, the held estimate, the limits and alerts to publish."""
        for e in out.estimates:
            for text in e.notices:
                out.log.append(('warning', text))
                self._events.append(text)
            for ev in e.alert_events:
                out.log.append(('warning' if ev.kind in ('raised', 'escalated') else 'info',
                                ev.message))
                self._events.append(ev.message)
        if out.estimates:
            self._last = out.estimates[-1]
        elif self._model_failing and self._last is not None and now_s is not None:
            out.held = (self._last, now_s)
        out.limits = self._take_limits() if out.estimates else []
        for e in out.estimates:
            e.current_limits = self.limits
        if out.estimates or now_s is not None:
            out.alerts = self.alert_summary()

    def _take_limits(self, model_time_s: Optional[float] = None) -> List[CurrentLimits]:
        """
        Return the current limits finished since the last call, oldest first, to publish.

        A tick waiting longer than ``estimator.limits.max_age_s`` of model
        time (``model_time_s``, by default the model's) is given up (its
        fallback goes out instead); while the model
        itself is behind its inputs, a finished tick's limits are for a state
        already past, and go out as the fallback too.
        """
        est = self._est
        out = []
        for limits in est._outlook.take_limits(
                est.t_model if model_time_s is None else model_time_s):
            if est.behind and limits.code == LimitStatus.OK:
                limits = limits.fallback(est.settings.limits.fallback_current_A,
                                         LimitStatus.BEHIND,
                                         'the model is catching up with its inputs')
            out.append(limits)
            self._limits_published += 1
            self._limits_fallback += limits.code != LimitStatus.OK
        if out:
            self.limits = out[-1]
            if est.latest is not None:
                est.latest.current_limits = self.limits
        return out

    def alert_summary(self, force: bool = False) -> Optional[Dict[str, Any]]:
        """
        Return the alert summary (JSON-safe) if it changed since the last one, else None.

        The alerts' levels and acknowledgements, the data gaps, the clock
        jumps and the events since the last summary; ``force``: return it
        even unchanged.
        """
        summary = self._est._alerts.summary()
        gaps = self._est.gaps
        key = (int(summary['level']), gaps.open_since_s) + tuple(
            (q, d['reported'], d['active'], d['acknowledged'])
            for q, d in sorted(summary['quantities'].items()))
        if not force and key == self._alert_key and not self._events:
            return None
        self._alert_key = key
        summary['level'] = int(summary['level'])
        summary['hardware_id'] = self.hardware_id
        # the estimates of a data gap run on held inputs: say so beside the alerts
        summary['data_gaps'] = {'count': gaps.count, 'longest_s': gaps.longest_s,
                                'total_s': gaps.total_s, 'open_since_s': gaps.open_since_s,
                                'last': list(gaps.last) if gaps.last else None}
        summary['clock_jumps'] = self._est.clock_jumps
        summary['events'], self._events = self._events, []
        return json_safe(summary)

    # ------------------------------------------------------ read-only views
    def status(self) -> SessionStatus:
        """Return the session as it stands: what /diagnostics and the reports show."""
        est = self._est
        o = est._outlook
        health = est.health
        stamps = [h.last_stamp_s for h in health.values() if h.last_stamp_s is not None]
        return SessionStatus(
            ready=est.latest is not None, behind=est.behind, t_model_s=est.t_model,
            last_sample_s=max(stamps) if stamps else None, steps=est.steps,
            held_blocks=est.held_blocks,
            stale=tuple(n for n in est.inputs if health[n].stale),
            inputs={n: InputCounts(h.received, h.accepted, h.rejected, h.stale_events)
                    for n, h in health.items()},
            gaps=replace(est.gaps), clock_jumps=est.clock_jumps,
            last_clock_jump=est._intake.last_clock_jump,
            alert_level=int(est._alerts.worst()),
            alert_message=est._alerts.summary()['message'], limits=self.limits,
            limits_published=self._limits_published, limits_fallback=self._limits_fallback,
            limit_ticks_behind=o.limits_behind, outlook_failures=o.failures,
            forecasts_skipped=o.forecasts_skipped, model_errors=self._model_errors,
            model_error=self._model_error if self._model_failing else None,
            background_errors=self._background_errors)

    @property
    def cfg(self) -> Config:
        """Return the configuration the session runs on."""
        return self._est.cfg

    @property
    def model(self) -> EHAModel:
        """Give the model, to read or copy (what-if snapshots, the state's names)."""
        return self._est.model

    @property
    def inputs(self) -> Tuple[str, ...]:
        """Return the sensor inputs the estimator takes, in order."""
        return self._est.inputs

    @property
    def health(self) -> Mapping[str, Any]:
        """Return each input's counters and state (:class:`~.intake.ChannelHealth`)."""
        return MappingProxyType(self._est.health)

    @property
    def gaps(self):
        """Return the silences of every input at once (:class:`~.intake.DataGaps`)."""
        return self._est.gaps

    @property
    def clock_jumps(self) -> int:
        """Return how many jumps of the receiving clock re-started the model time."""
        return self._est.clock_jumps

    @property
    def rest(self) -> Mapping[str, float]:
        """Return each input's resting value (its fallback before any sample)."""
        return MappingProxyType(self._est._intake.rest)

    @property
    def channel_cfg(self) -> Mapping[str, Any]:
        """Return each input's configuration (timeout, range)."""
        return MappingProxyType(self._est._intake.channel_cfg)

    @property
    def t_model(self) -> Optional[float]:
        """Return the sample time (s) the model has stepped to (None before the start)."""
        return self._est.t_model

    @property
    def steps(self) -> int:
        """Return how many model steps were made."""
        return self._est.steps

    @property
    def latest(self) -> Optional[Estimate]:
        """Return the latest estimate (None before the first)."""
        return self._est.latest

    @property
    def behind(self) -> bool:
        """Tell whether complete steps wait for the next call (its step limit hit)."""
        return self._est.behind

    @property
    def ambient_C(self) -> float:
        """Return the ambient temperature the model runs at (degC)."""
        return self._est.ambient_K - C_TO_K

    @property
    def ambient_K(self) -> float:
        """Return the ambient the model runs on (K): the configured one, or the last reading."""
        return self._est.ambient_K

    @property
    def measured_C(self) -> Dict[str, Tuple[float, float]]:
        """Return the latest reading of each thermocouple: (stamp s, degC), a copy."""
        return dict(self._est.measured_C)

    @property
    def limits_C(self) -> Dict[str, float]:
        """Return the limits (degC) of the estimates the alerts and the forecast watch."""
        return dict(self._est.limits_C)

    @property
    def implausible_counts(self) -> Dict[str, int]:
        """Return the implausible steps per combination, a copy."""
        return dict(self._est.implausible_counts)

    @property
    def alert_rules(self) -> List[AlertRule]:
        """Return the alert rules, one per watched quantity."""
        return list(self._est._alerts.rules)

    @property
    def outlook_mode(self) -> str:
        """Return how the outlook is worked on: 'off', 'background' or 'inline'."""
        return self._est.outlook_mode

    @property
    def outlook_busy(self) -> bool:
        """Tell whether limit or forecast work waits for :meth:`work`."""
        return self._est._outlook.busy

    @property
    def correcting(self) -> bool:
        """Tell whether the live correction is configured (estimator.correction.enabled)."""
        return self._est._correction is not None

    @property
    def thermocouples(self) -> Mapping[str, Any]:
        """Return each thermocouple's health in the live correction (empty when it is off)."""
        c = self._est._correction
        return MappingProxyType(c.tcs if c is not None else {})

    def correction_summary(self) -> Optional[Dict[str, Any]]:
        """
        Return the live correction's figures; None when it is off.

        ``active``, ``updates``, ``failures``, ``last_failure``,
        ``disturbance_W`` (the learned heats by name) and ``thermocouples``
        (the counters of each that received a reading).
        """
        c = self._est._correction
        if c is None:
            return None
        return {'active': c.active, 'updates': c.updates, 'failures': c.failures,
                'last_failure': c.last_failure,
                'disturbance_W': dict(zip(c.disturbance_names, c.d.tolist())),
                'thermocouples': {tc: dict(vars(h)) for tc, h in c.tcs.items() if h.received}}
