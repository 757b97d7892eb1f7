"""
The estimator's outlook: when each limit would be reached, and the thermal margin.

Slow work, done in slices that fit a budget between estimates
(:meth:`Outlook.background`): a forecast that repeats the last
``forecast_window_s`` of duty on a copy of the model to find when the
winding, the magnets and the oil reach their limits, and the thermal margin
(the largest continuous current at the present oil temperature). It reads
the model through its public API only.
"""

from collections import deque
import copy
from dataclasses import dataclass, field
import itertools
import math
import time
from typing import Deque, Dict, Optional

import numpy as np

from ..config import Config
from ..model.eha import EHAModel, SampleBlock
from ..model.motor import MotorInputs, WetMotor
from ..units import C_TO_K

#: A forecast step doubles (from ``forecast_step_s`` to one pass of the repeated duty)
#: while the state moves less than this in one.
FORECAST_TOL_K = 0.5


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


class Outlook:
    """The recent duty, the forecast to the limits and the margin current, worked on in slices."""

    def __init__(self, cfg: Config, model: EHAModel, limits_C: Dict[str, float]) -> None:
        s = cfg.estimator
        self.cfg = cfg
        self.settings = s
        self.model = model
        self.limits_C = limits_C
        #: the recent steps' inputs, one block per step (the duty a forecast repeats)
        self.window: Deque[SampleBlock] = deque(maxlen=max(1, int(round(
            s.forecast_window_s / s.step_s))))
        self.forecast: Optional[_Forecast] = None
        #: the last finished forecast: time (s) from its start to each limit (None: beyond)
        self.result: Dict[str, Optional[float]] = {}
        #: when that forecast started (sample time s)
        self.stamp_s: Optional[float] = None
        self.margin_A: Optional[float] = None
        self.failures = 0
        self._next_forecast_s: Optional[float] = None
        self._margin_motor = WetMotor(cfg.motor, model.oil)
        self._next_margin_s: Optional[float] = None
        self._margin_job = None

    @property
    def busy(self) -> bool:
        """Tell whether a forecast or a margin is under way."""
        return self.forecast is not None or self._margin_job is not None

    def record(self, block: SampleBlock, steps: int = 1) -> None:
        """Add a step's inputs to the recent duty, ``steps`` times (a held block's)."""
        if steps == 1:
            self.window.append(block)
        else:
            self.window.extend(itertools.repeat(block, min(steps, self.window.maxlen)))

    def shift_time(self, delta_s: float) -> None:
        """Move the stored sample times by ``delta_s`` (a jump of the receiving clock)."""
        for attr in ('_next_forecast_s', '_next_margin_s', 'stamp_s'):
            if getattr(self, attr) is not None:
                setattr(self, attr, getattr(self, attr) + delta_s)
        if self.forecast is not None:
            self.forecast.start_s += delta_s

    def background(self, t_model: float, ambient_K: float, now_C: Dict[str, float],
                   budget_s: float) -> None:
        """
        Do forecast and margin work for at most about ``budget_s`` of wall time.

        ``t_model`` the model's sample time (s), ``ambient_K`` the ambient for
        a new forecast or margin, ``now_C`` the latest estimate's temperatures
        (a quantity already past its limit has no time left).
        """
        if not self.window:
            return
        deadline = time.perf_counter() + budget_s
        s = self.settings
        # the margin takes one steady solve (~7 ms) per call, between forecast slices
        if self._margin_job is None and (self._next_margin_s is None
                                         or t_model >= self._next_margin_s):
            self._margin_job = self._margin_steps(ambient_K)
            self._next_margin_s = t_model + s.forecast_period_s
        if self._margin_job is not None:
            try:
                next(self._margin_job)
            except StopIteration as done:
                self.margin_A = done.value
                self._margin_job = None
        if self.forecast is None and (self._next_forecast_s is None
                                      or t_model >= self._next_forecast_s):
            self._start_forecast(t_model, ambient_K)
            self._next_forecast_s = t_model + s.forecast_period_s
        while self.forecast is not None and time.perf_counter() < deadline:
            self._forecast_step(now_C)

    def _start_forecast(self, t_model: float, ambient_K: float) -> None:
        """Copy the model and take the recent duty to repeat."""
        blocks = list(self.window)
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
        self.forecast = _Forecast(model=model, start_s=t_model, duty=duty, ambient_K=ambient_K,
                                  crossed=dict.fromkeys(self.limits_C),
                                  n=max(1, int(round(self.settings.forecast_step_s
                                                     / self.settings.step_s))))

    def _forecast_step(self, now_C: Dict[str, float]) -> None:
        """Advance the forecast by one ``forecast_step_s`` of repeated duty."""
        try:
            self._forecast_step_unguarded(now_C)
        except (ArithmeticError, ValueError, RuntimeError):
            # a forecast is advice: give up on this one, never on the estimator
            self.failures += 1
            self.forecast = None

    def _forecast_step_unguarded(self, now_C: Dict[str, float]) -> None:
        """Step the forecast's model; note the limits crossed; finish at the horizon."""
        f = self.forecast
        s = self.settings
        n_all = f.duty['dx_m'].size
        n = f.n
        idx = (f.k + np.arange(n)) % n_all
        f.k = (f.k + n) % n_all
        span = n * s.step_s
        t = f.model.time_s + (np.arange(1, n + 1) / n) * span
        x = f.model.last_position_m + np.cumsum(f.duty['dx_m'][idx])
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
            self.result = {q: (0.0 if now_C.get(q, -1e9) >= self.limits_C[q] else v)
                           for q, v in f.crossed.items()}
            self.stamp_s = f.start_s
            self.forecast = None

    def margin_current(self, ambient_K: float) -> Optional[float]:
        """
        Return the largest continuous current (A RMS) at the present oil temperature and duty.

        The motor alone in steady state with its present cooling oil (the pump
        case temperature and the motor's flow) and the recent mean speed: the
        current whose steady winding hot-spot reaches the insulation limit,
        by secant iterations on I^2 (the rise is nearly linear in I^2), at
        ``ambient_K``; None before any step.
        """
        job = self._margin_steps(ambient_K)
        while True:
            try:
                next(job)
            except StopIteration as done:
                return done.value

    def _margin_steps(self, ambient_K: float):
        """Compute :meth:`margin_current` one steady solve per iteration (a generator)."""
        if not self.window:
            return None
        m, mot = self.model, self._margin_motor
        speeds = np.concatenate([b.speed_rad_s for b in self.window])
        u = MotorInputs(current_sq_mean_A2=0.0, speed_rad_s=np.abs(speeds).mean(),
                        oil_inlet_K=float(m.T_hyd[m.circuit.index('case')]),
                        oil_flow_m3_s=m.motor.coefficient_flow_m3_s,
                        ambient_K=ambient_K)
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
