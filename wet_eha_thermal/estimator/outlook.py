"""
The estimator's outlook: the drive's current limits, when each limit would be reached.

Everything here is computed at defined sample times from the state at those
times, so a replay reproduces it bit for bit; only *when* it is done depends
on the CPU. At every limit tick (each ``estimator.limits.period_s`` of
sample time, :meth:`Outlook.tick`) the outlook saves the model (:mod:`~..model.snapshot`) and
the recent duty, and queues a job that works out the drive's current limits
(:mod:`.limits`). At every forecast tick (each ``forecast_period_s``, which
falls on a limit tick, and the run's first tick) it queues a margin job, the
continuous limit (the steady margin: the largest current whose steady winding
hot-spot, with the tick's oil, reaches its limit less k sigma; some 100 ms of
steady solves), which every tick at least ``MARGIN_DELAY_S`` later takes, and
a forecast job that repeats the last ``forecast_window_s`` of duty on a copy
of the model to find when the winding, the magnets and the oil reach their
limits. A live node works the jobs in slices that fit a budget between
estimates (:meth:`Outlook.background`); offline (``inline``) each is done at
once. The limits drop to the configured conservative value, saying why, at a
tick with a stale input or too uncertain an estimate, and for a tick not
computed within ``max_age_s`` (behind). It reads the model through its public API only.
"""

from collections import deque
from dataclasses import dataclass, field
import itertools
import math
import time
from typing import Callable, Deque, Dict, Generator, List, Optional, Sequence, Tuple

import numpy as np

from .limits import (ceiling_K, ceilings_K, current_limits, CurrentLimits, fallback_limits,
                     HeldDuty, limit_steps, Linearised, probing, RATING, step_statistics)
from ..config import Config
from ..interface import INPUTS, LimitStatus
from ..model import snapshot
from ..model.eha import EHAModel, SampleBlock
from ..model.motor import MotorInputs, WetMotor
from ..units import C_TO_K

#: A forecast step doubles (from ``forecast_step_s`` to one pass of the repeated duty)
#: while the state moves less than this in one.
FORECAST_TOL_K = 0.5
#: A tick takes the continuous limit of the last forecast tick at least this much before it
#: (sample time s): the margin's steady solves have that long to finish in the background
MARGIN_DELAY_S = 10.0
#: Limit jobs waiting at most; a new tick beyond drops the oldest (its limits are published
#: as the fallback, behind; a dropped forecast tick's continuous limit is not computed, so
#: the next ticks keep the one before, where a replay, never behind, has the new one)
MAX_LIMIT_JOBS = 2
#: The inputs as a forecast repeats them, in the SampleBlock's order: the current as
#: each step's RMS, the others but the position as step means, the position by its motion
CURRENT, *MEAN_INPUTS, POSITION = INPUTS


def copy_model(saved: bytes) -> EHAModel:
    """Return a model from its saved bytes (:mod:`~..model.snapshot`; faster than ``deepcopy``)."""
    return snapshot.copy(saved)


@dataclass
class _Forecast:
    start_s: float
    ambient_K: float
    now_C: Dict[str, float]       # the estimate at the start (a quantity past its limit)
    saved: bytes                  # the tick's model, pickled: copied by the first slice
    blocks: List[SampleBlock]     # the recent duty, steps of samples: summed by the first slice
    model: Optional[EHAModel] = None
    duty: Dict[str, np.ndarray] = field(default_factory=dict)   # 'dx_m': drift-free moves
    t_s: float = 0.0
    k: int = 0
    crossed: Dict[str, Optional[float]] = field(default_factory=dict)
    n: int = 1                    # model steps per forecast step (it grows, see FORECAST_TOL_K)


@dataclass
class _LimitJob:
    stamp_s: float
    steps: Optional[Generator]    # None: a ready fallback
    margin_tick: Optional[int]    # the forecast tick whose continuous limit it takes
    values: Optional[List[Tuple[float, str]]] = None    # each horizon's, once computed
    ready: Optional[CurrentLimits] = None   # a fallback decided at the tick, waiting its turn


class Outlook:
    """The recent duty, and the limits and the forecast of each tick, worked on in jobs."""

    def __init__(self, cfg: Config, model: EHAModel, limits_C: Dict[str, float],
                 inline: bool = False) -> None:
        s = cfg.estimator
        self.cfg = cfg
        self.settings = s
        self.lim = s.limits
        self.model = model
        self.limits_C = limits_C
        #: compute each tick's work at once (offline), not in background slices
        self.inline = inline
        #: the recent steps' inputs, one block per step (the duty a forecast repeats)
        self.window: Deque[SampleBlock] = deque(maxlen=max(1, int(round(
            s.forecast_window_s / s.step_s))))
        self._stats = np.zeros((self.window.maxlen, 4))
        self._stat_next = self._stat_count = 0
        self.tick_steps = max(1, int(round(self.lim.period_s / s.step_s)))
        self.forecast_ticks = max(1, int(round(s.forecast_period_s
                                               / (self.tick_steps * s.step_s))))
        self.forecast: Optional[_Forecast] = None
        #: the last finished forecast: time (s) from its start to each limit (None: beyond)
        self.result: Dict[str, Optional[float]] = {}
        #: when that forecast started (sample time s)
        self.stamp_s: Optional[float] = None
        #: the latest continuous limit (A RMS)
        self.margin_A: Optional[float] = None
        #: each forecast tick's continuous limit (A, what binds), by tick number
        self._margins: Dict[int, Tuple[float, str]] = {}
        self._margin_jobs: Deque[Tuple[int, Generator]] = deque()
        self._forecast_tick_numbers: Deque[int] = deque(maxlen=8)
        self._margin_tick_numbers: Deque[int] = deque(maxlen=8)
        self._margin_owed = False       # a forecast tick's margin not started yet
        #: the latest limits (any tick's, fallback or not); those not yet taken
        self.limits: Optional[CurrentLimits] = None
        self._new: List[CurrentLimits] = []
        self._jobs: Deque[_LimitJob] = deque()
        self.failures = 0
        self.limits_behind = 0         # ticks whose limits were not computed (fallback)
        self.forecasts_skipped = 0     # forecast ticks while a forecast was under way
        self._margin_motor = WetMotor(cfg.motor, model.oil)
        self._probing = probing(model, list(limits_C))
        #: where the limits' searches start: the last answers (:func:`~.limits.limit_steps`)
        self._guesses: Dict[Tuple[float, int], float] = {}
        #: the last tick linearised, whose linearisations the ticks close to it take
        self._linearised: Optional[Linearised] = None

    @property
    def busy(self) -> bool:
        """Tell whether a forecast, a margin or limits are under way."""
        return self.forecast is not None or bool(self._jobs) or bool(self._margin_jobs)

    def record(self, block: SampleBlock, steps: int = 1) -> None:
        """Add a step's inputs to the recent duty, ``steps`` times (a held block's)."""
        n = min(steps, self.window.maxlen)
        if steps == 1:
            self.window.append(block)
        else:
            self.window.extend(itertools.repeat(block, n))
        # the limits' held duty: each step's statistics in a ring, averaged at a tick
        size = self._stats.shape[0]
        rows = (self._stat_next + np.arange(n)) % size if n > 1 else self._stat_next
        self._stats[rows] = step_statistics(block)
        self._stat_next = (self._stat_next + n) % size
        self._stat_count = min(self._stat_count + n, self._stats.shape[0])

    def held_duty(self) -> HeldDuty:
        """Return the recent duty as the limits hold it (:class:`~.limits.HeldDuty`)."""
        return HeldDuty.from_statistics(self._stats[:self._stat_count],
                                        float(self.window[-1].position_m[-1]))

    def shift_time(self, delta_s: float) -> None:
        """Move the stored sample times by ``delta_s`` (a jump of the receiving clock)."""
        if self.stamp_s is not None:
            self.stamp_s += delta_s
        if self.forecast is not None:
            self.forecast.start_s += delta_s
        for job in self._jobs:
            job.stamp_s += delta_s

    # ---------------------------------------------------------------- ticks
    def tick(self, steps_before: int, steps_after: int, stamp_s: float, ambient_K: float,
             now_C: Dict[str, float], sigma_K: Dict[str, float], stale: Sequence[str],
             relative: Optional[Callable[..., Optional[Dict[str, float]]]] = None) -> None:
        """
        Start the work of a tick if the step from ``steps_before`` to ``steps_after`` made one.

        ``stamp_s`` the step's end (sample time), ``now_C`` and ``sigma_K``
        its estimate and 1-sigma uncertainty, ``stale`` its stale inputs,
        ``relative`` gives each quantity's 1 sigma per K of rise for the
        held duty, the ambient, the stamp and the limited quantities, where
        the propagated uncertainty knows it, or None while it works it out (the limits are then the
        fallback, and the margin waits):
        :meth:`~.uncertainty.Propagation.relative`, :func:`~.limits.ceiling_K`.
        ``relative`` None: the constant sigma.
        Call it after the model's step and its correction: the tick's state
        is the model's as it stands.
        """
        p = self.tick_steps
        if steps_after // p == steps_before // p or not self.window:
            return
        tick = steps_after // p
        held = self.held_duty()
        per_rise = relative(held, ambient_K, stamp_s, self.limits_C) if relative else {}
        why = self._distrust(sigma_K, stale, per_rise)   # (code, detail) of a fallback, or None
        # at every forecast tick and at the first tick of the run
        forecast_tick = tick % self.forecast_ticks == 0 or not self._forecast_tick_numbers
        # a margin with each forecast, or the first tick after one that knew no sigma per K
        # of rise to set its target with
        self._margin_owed |= forecast_tick
        start_margin = self._margin_owed and per_rise is not None
        # the state saved only for work that reads it (1 ms inside the estimator's step)
        saved = snapshot.save(self.model) if forecast_tick or start_margin or not why else b''
        if forecast_tick:
            self._forecast_tick_numbers.append(tick)
            self._start_forecast(saved, stamp_s, ambient_K, now_C)
        if start_margin:
            self._start_margin(tick, saved, held.speed_rad_s, ambient_K, ceiling_K(
                self.limits_C['winding_hotspot'], sigma_K['winding_hotspot'],
                self.lim.k_sigma, per_rise.get('winding_hotspot'), ambient_K))
        if why:
            self._fall_back(stamp_s, *why)
            return
        x0 = self.model.state
        # decided here, in sample order: a live node and a replay take the same ticks'
        kept = self._linearised = Linearised.for_tick(
            self._linearised, saved, x0, held, ambient_K,
            ceilings_K(self.limits_C, sigma_K, self.lim.k_sigma, per_rise, ambient_K))
        steps = limit_steps(saved, x0, self._probing, held, ambient_K, sigma_K, self.limits_C,
                            self.lim.k_sigma, self.lim.horizons_s, self.lim.period_s,
                            self.cfg.motor.peak_current_A, per_rise, self._guesses, kept)
        delay = int(round(MARGIN_DELAY_S / self.lim.period_s))
        margin_tick = max((f for f in self._margin_tick_numbers if f <= tick - delay),
                          default=None)
        self._jobs.append(_LimitJob(stamp_s, steps, margin_tick))
        while len(self._jobs) > MAX_LIMIT_JOBS:
            self._give_up(self._jobs.popleft())
        if self.inline:
            self.run(math.inf)

    def _fall_back(self, stamp_s: float, code: LimitStatus, detail: str) -> None:
        """Publish a tick's limits as the fallback, behind the ticks still worked on."""
        # behind them, so that the stamps go out in order
        fallback = fallback_limits(stamp_s, self.lim.horizons_s, self.lim.fallback_current_A,
                                   code, detail)
        if self._jobs:
            self._jobs.append(_LimitJob(stamp_s, None, None, ready=fallback))
        else:
            self._finish(fallback)

    def _distrust(self, sigma_K: Dict[str, float], stale: Sequence[str],
                  per_rise: Optional[Dict[str, float]]) -> Optional[Tuple[LimitStatus, str]]:
        """Return why a tick's limits cannot be trusted, (code, detail); None if they can."""
        if stale:
            return LimitStatus.STALE_INPUTS, ', '.join(stale)
        if per_rise is None:
            return LimitStatus.UNCERTAIN, ('the sigma at the horizons is being worked out '
                                           '(the uncertainty copies heated on a cold start)')
        worst = max(self.limits_C, key=lambda q: sigma_K.get(q, 0.0))
        if sigma_K.get(worst, 0.0) > self.lim.max_sigma_K:
            return (LimitStatus.UNCERTAIN,
                    f'{worst} 1 sigma {sigma_K[worst]:.1f} K > {self.lim.max_sigma_K:g} K')
        return None

    def _give_up(self, job: _LimitJob) -> None:
        """Publish a waiting tick's limits as the fallback: not computed in time (behind)."""
        if job.ready is not None:
            self._finish(job.ready)
            return
        self.limits_behind += 1
        self._finish(fallback_limits(job.stamp_s, self.lim.horizons_s,
                                     self.lim.fallback_current_A, LimitStatus.BEHIND,
                                     'the estimator had no time to compute them'))

    def _finish(self, limits: CurrentLimits) -> None:
        """Make ``limits`` the latest and queue them for publishing."""
        self.limits = limits
        self._new.append(limits)

    def take_limits(self, model_time_s: Optional[float] = None) -> List[CurrentLimits]:
        """
        Return the limits finished since the last call, oldest first.

        With ``model_time_s``, a waiting tick older than ``max_age_s`` is
        given up: its limits are the fallback (behind).
        """
        if model_time_s is not None:
            while self._jobs and model_time_s - self._jobs[0].stamp_s > self.lim.max_age_s:
                self._give_up(self._jobs.popleft())
        out, self._new = self._new, []
        return out

    # ----------------------------------------------------------- background
    def background(self, budget_s: float) -> None:
        """Work the waiting jobs (the limits first, then the forecast) for about ``budget_s``."""
        self.run(time.perf_counter() + budget_s)

    def run(self, deadline: float) -> None:
        """
        Work the jobs until the wall clock (``time.perf_counter``) passes ``deadline``.

        The oldest tick's limits first; when they wait for their continuous
        limit, its margin job; then the forecast.
        """
        while time.perf_counter() < deadline:
            job = self._jobs[0] if self._jobs else None
            if job is not None and job.ready is not None:
                self._jobs.popleft()
                self._finish(job.ready)
            elif job is not None and job.values is None:
                self._work_on(job)
            elif job is not None and (job.margin_tick is None
                                      or job.margin_tick in self._margins):
                self._jobs.popleft()
                self._finish(self._completed(job))
            elif self._margin_jobs:
                self._margin_step()
            else:
                break
        while self.forecast is not None and time.perf_counter() < deadline:
            self._forecast_step()

    def _work_on(self, job: _LimitJob) -> None:
        """Do a slice of a tick's limits; on a failure the tick falls back."""
        try:
            next(job.steps)
        except StopIteration as done:
            job.values = done.value
        except (ArithmeticError, ValueError, RuntimeError, np.linalg.LinAlgError):
            # advice must never stop the estimator
            self.failures += 1
            self._jobs.popleft()
            self._finish(fallback_limits(job.stamp_s, self.lim.horizons_s,
                                         self.lim.fallback_current_A, LimitStatus.FAILED,
                                         'the limits could not be computed'))

    def _start_margin(self, tick: int, saved: bytes, speed_rad_s: float, ambient_K: float,
                      target_K: float) -> None:
        """Queue the margin (the continuous limit) of ``tick``, to the hot spot at ``target_K``."""
        self._margin_owed = False
        self._margin_tick_numbers.append(tick)
        self._margin_jobs.append(
            (tick, self._margin_steps(saved, speed_rad_s, ambient_K, target_K)))

    def _margin_step(self) -> None:
        """Do a slice of the oldest margin job; a failure leaves that tick's margin unknown."""
        tick, steps = self._margin_jobs[0]
        try:
            next(steps)
        except StopIteration as done:
            self._margin_jobs.popleft()
            amps = min(done.value, self.cfg.motor.peak_current_A)
            self._margins[tick] = (amps, 'winding_hotspot' if amps < self.cfg.motor.peak_current_A
                                   else RATING)
        except (ArithmeticError, ValueError, RuntimeError, np.linalg.LinAlgError):
            self.failures += 1
            self._margin_jobs.popleft()
            self._margins[tick] = (math.nan, 'failed')
        while len(self._margins) > self._margin_tick_numbers.maxlen:
            self._margins.pop(min(self._margins))

    def _completed(self, job: _LimitJob) -> CurrentLimits:
        """
        Return a tick's limits: its horizons' and the continuous of its forecast tick.

        The continuous is never above the longest horizon's: the steady
        margin holds the oil where it is, and a current that cannot be held
        that long cannot be held for ever. Before the first margin, and
        after a failed one, it is the fallback current.
        """
        per_horizon = job.values
        longest = per_horizon[-1]
        margin = self._margins.get(job.margin_tick, (math.nan, 'pending'))
        if not math.isfinite(margin[0]):
            continuous = (self.lim.fallback_current_A, margin[1])
        elif longest[0] < margin[0]:
            continuous = longest
        else:
            continuous = margin
        self.margin_A = continuous[0]
        return current_limits(job.stamp_s, self.lim.horizons_s, continuous, per_horizon)

    def _start_forecast(self, saved: bytes, t_model: float, ambient_K: float,
                        now_C: Dict[str, float]) -> None:
        """Take the saved model and the recent duty to repeat (skipped while one runs)."""
        if self.forecast is not None:
            self.forecasts_skipped += 1
            return
        # the duty's averages and the model's copy take tens of ms: the first slice's work,
        # not the tick's (which is the estimator's step)
        self.forecast = _Forecast(start_s=t_model, ambient_K=ambient_K, now_C=dict(now_C),
                                  saved=saved, blocks=list(self.window),
                                  crossed=dict.fromkeys(self.limits_C),
                                  n=max(1, int(round(self.settings.forecast_step_s
                                                     / self.settings.step_s))))
        if self.inline:
            while self.forecast is not None:
                self._forecast_step()

    def _prepare_forecast(self, f: _Forecast) -> None:
        """Copy the forecast's model and average its duty: one sample per model step."""
        blocks = f.blocks
        # the step's means, I^2 for the current: a forecast step of seconds then costs
        # about a millisecond
        duty = {a: np.array([getattr(b, a).mean() for b in blocks]) for a in MEAN_INPUTS}
        duty[CURRENT] = np.array([math.sqrt(np.mean(getattr(b, CURRENT) ** 2)) for b in blocks])
        x = np.array([getattr(b, POSITION)[-1] for b in blocks])
        # repeat the motion, not the positions: increments with the window's net drift
        # removed, so the repeated duty is periodic and stays inside the stroke
        dx = np.diff(x, prepend=x[0])
        duty['dx_m'] = dx - dx.mean()
        model = copy_model(f.saved)
        model.defer_refresh = False       # forecast steps are seconds long: no lag there
        model.circuit.keep_transition = False     # no filter follows the forecast
        model.oil_substep_s = self.settings.forecast_substep_s
        f.model, f.duty, f.saved, f.blocks = model, duty, b'', []

    def _forecast_step(self) -> None:
        """Advance the forecast by one ``forecast_step_s`` of repeated duty."""
        try:
            self._forecast_step_unguarded()
        except (ArithmeticError, ValueError, RuntimeError):
            # a forecast is advice: give up on this one, never on the estimator
            self.failures += 1
            self.forecast = None

    def _forecast_step_unguarded(self) -> None:
        """Step the forecast's model; note the limits crossed; finish at the horizon."""
        f = self.forecast
        if f.model is None:
            self._prepare_forecast(f)
            return
        s = self.settings
        n_all = f.duty['dx_m'].size
        n = f.n
        idx = (f.k + np.arange(n)) % n_all
        f.k = (f.k + n) % n_all
        span = n * s.step_s
        t = f.model.time_s + (np.arange(1, n + 1) / n) * span
        x = f.model.last_position_m + np.cumsum(f.duty['dx_m'][idx])
        block = SampleBlock(t, *(f.duty[a][idx] for a in (CURRENT, *MEAN_INPUTS)), x)
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
            self.result = {q: (0.0 if f.now_C.get(q, -1e9) >= self.limits_C[q] else v)
                           for q, v in f.crossed.items()}
            self.stamp_s = f.start_s
            self.forecast = None

    def _margin_steps(self, saved: bytes, speed_rad_s: float, ambient_K: float,
                      target_K: float):
        """
        Return the largest continuous current (A RMS) at the oil and flow of a saved model.

        The motor alone in steady state with the cooling oil of the pickled
        model ``saved`` (the pump case temperature and the motor's flow) at
        ``speed_rad_s``: the current whose steady winding hot-spot reaches
        ``target_K``, by secant iterations on I^2 (the rise is nearly linear
        in I^2), at ``ambient_K``. A generator: it yields once per fixed-point
        iteration of a steady solve, each solve from the same start, so the
        result depends on the inputs alone.
        """
        model = copy_model(saved)
        mot = self._margin_motor
        u = MotorInputs(current_sq_mean_A2=0.0, speed_rad_s=speed_rad_s,
                        oil_inlet_K=float(model.T_hyd[model.circuit.index('case')]),
                        oil_flow_m3_s=model.motor.coefficient_flow_m3_s,
                        ambient_K=ambient_K)

        def hot(i_sq: float):
            """Yield per fixed-point iteration; return the steady hot-spot (K), inf if none."""
            u.current_sq_mean_A2 = i_sq
            mot.T = None
            try:
                yield from mot.steady_state_steps(u, tol_K=1e-4, max_iter=60)
            except RuntimeError:      # no steady state: far past any limit
                return math.inf
            return mot.outputs()['winding_hotspot']

        a = 0.0
        fa = yield from hot(a)
        if fa >= target_K:
            return 0.0
        b = (self.cfg.motor.max_continuous_current_A) ** 2
        fb = yield from hot(b)
        for _ in range(12):
            if abs(fb - target_K) < 0.05:
                break
            if not math.isfinite(fb):         # runaway: halve the step back
                b = 0.5 * (a + b)
            else:
                a, fa, b = b, fb, max(b + (target_K - fb) * (b - a) / (fb - fa), 0.0)
            fb = yield from hot(b)
        return float(math.sqrt(b))
