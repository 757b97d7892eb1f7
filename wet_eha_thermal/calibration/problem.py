"""
The least-squares problem of a fit: residuals and Jacobian over the fit logs, runs cached.

The parameters are scaled to [0, 1] over their bounds (``u``); the Jacobian
is a forward difference of ``FD_STEP`` of the bounds (its columns run in
parallel) where the search starts; at the points it moves to, Broyden's
update of it from the step (the search's answer is the residuals' minimum
within its tolerances, whichever Jacobian guided it there; the intervals take
a forward difference at the answer).
"""

import time
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from .evaluator import Evaluator, lagged_run, residuals, Windows
from .results import ParameterFit
from ..config import Calibration

#: Forward-difference step of the Jacobian, as a share of each parameter's bounds.
FD_STEP = 0.005
#: The fitted starting temperature of a log stays within this of its readings' (K).
START_OFFSET_MAX_K = 2.0


class FitProblem:
    """
    The fit's residual function and Jacobian over the fit logs, with a cache of runs.

    Each fit log's starting temperature is a nuisance parameter: the
    residuals are those of the best uniform start offset (within
    ``START_OFFSET_MAX_K``), from the offset's linearised effect (a run
    started 1 K warmer at the nominal values).
    """

    def __init__(self, evaluator: Evaluator, fit_idx: List[int], windows: Dict[int, Windows],
                 params: List[ParameterFit], calib: Calibration,
                 say: Callable[[str], None]) -> None:
        self.evaluator, self.fit_idx, self.windows = evaluator, fit_idx, windows
        self.params, self.calib = params, calib
        self.free: List[int] = []
        self.say = say
        self.offset_cols: Dict[int, np.ndarray] = {}   # d residuals / d start (per K)
        self.cache: Dict[tuple, np.ndarray] = {}       # key of a parameter vector -> residuals
        self.offsets: Dict[tuple, Dict[int, float]] = {}   # and the start offsets (K)
        self.series: Dict[tuple, Dict[int, tuple]] = {}    # model runs of the base points
        self.t0 = time.perf_counter()
        self.calls = 0
        # the search's last point given a Jacobian: (u, residuals, Jacobian); None: a new search
        self.last: Optional[Tuple[np.ndarray, np.ndarray, np.ndarray]] = None

    def key(self, theta: np.ndarray) -> tuple:
        """
        Return the cache key of a parameter vector: its position in the bounds, rounded.

        The trust-region method moves a start on a bound 1e-10 inside; that is
        the same model run.
        """
        return tuple(round((float(x) - p.low) / p.span, 8) for x, p in zip(theta, self.params))

    def residuals(self, runs: Dict[int, tuple],
                  calib: Optional[Calibration] = None) -> Tuple[np.ndarray, Dict[int, float]]:
        """Return the weighted residuals of runs of the fit logs, and their start offsets."""
        parts, offsets = [], {}
        for li in self.fit_idx:
            r = residuals(self.windows[li], *lagged_run(runs[li], calib or self.calib))
            g = self.offset_cols.get(li)
            gg = float(np.dot(g, g)) if g is not None else 0.0
            if gg > 0.0:
                d = float(np.clip(-np.dot(g, r) / gg, -START_OFFSET_MAX_K, START_OFFSET_MAX_K))
                r = r + d * g
                offsets[li] = d
            parts.append(r)
        return np.concatenate(parts), offsets

    def store(self, theta: np.ndarray, runs: Dict[int, tuple], base: bool = False) -> np.ndarray:
        """Keep the residuals (and for a base point the runs) of a parameter vector."""
        k = self.key(theta)
        self.cache[k], self.offsets[k] = self.residuals(runs)
        if base:
            self.series[k] = runs
        return self.cache[k]

    def theta(self, u_free: np.ndarray, base: np.ndarray) -> np.ndarray:
        """Return the full parameter vector for the free parameters at ``u_free``."""
        theta = base.copy()
        for k, j in enumerate(self.free):
            p = self.params[j]
            theta[j] = p.low + float(np.clip(u_free[k], 0.0, 1.0)) * p.span
        return theta

    def steps(self, theta: np.ndarray, cols: Sequence[int]) -> List[float]:
        """Return the forward-difference step (parameter units) of each column; back if at top."""
        out = []
        for j in cols:
            p = self.params[j]
            h = FD_STEP * p.span
            out.append(h if theta[j] + h <= p.high else -h)
        return out

    def evaluate(self, thetas: List[np.ndarray]) -> List[np.ndarray]:
        """Return the residuals of each parameter vector (cached); the first is a base point."""
        todo = {self.key(theta): theta for theta in thetas if self.key(theta) not in self.cache}
        if todo:
            out = self.evaluator.run(list(todo.values()), [self.fit_idx] * len(todo))
            for (k, theta), runs in zip(todo.items(), out):
                self.store(theta, runs, base=k == self.key(thetas[0]))
        return [self.cache[self.key(theta)] for theta in thetas]

    def jacobian(self, theta: np.ndarray, cols: Sequence[int]) -> Tuple[np.ndarray, np.ndarray]:
        """Return r(theta) and the columns of dr/du (per unit of the bounds)."""
        fd_steps = self.steps(theta, cols)
        shifted = []
        for j, h in zip(cols, fd_steps):
            s = theta.copy()
            s[j] += h
            shifted.append(s)
        residuals_at = self.evaluate([theta] + shifted)
        jac = np.empty((residuals_at[0].size, len(cols)))
        for k, (j, h) in enumerate(zip(cols, fd_steps)):
            jac[:, k] = (residuals_at[1 + k] - residuals_at[0]) / (h / self.params[j].span)
        return residuals_at[0], jac

    def split(self, r: np.ndarray) -> List[np.ndarray]:
        """Return a residual vector cut into its series (one per log and thermocouple)."""
        parts, offset = [], 0
        for li in self.fit_idx:
            for idx in self.windows[li].index:
                parts.append(r[offset:offset + idx.size])
                offset += idx.size
        return parts

    # ----------------------------------------------- least_squares callbacks
    def fun(self, u: np.ndarray, base: np.ndarray) -> np.ndarray:
        """Return the residuals at ``u`` (least_squares' fun)."""
        theta = self.theta(u, base)
        self.calls += 1
        r = self.evaluate([theta])[0]
        cost = 0.5 * float(np.dot(r, r))
        self.say(f'  evaluation {self.calls}: cost {cost:.6g}, '
                 + ', '.join(f'{self.params[j].key.rsplit(".", 1)[-1]} {theta[j]:.4g}'
                             for j in self.free)
                 + f' ({time.perf_counter() - self.t0:.0f} s)')
        return r

    def jac(self, u: np.ndarray, base: np.ndarray) -> np.ndarray:
        """
        Return the Jacobian at ``u`` (least_squares' jac): differenced at the start, then updated.

        A forward difference costs a run per free parameter and log at every
        point the search accepts; Broyden's rank-one update of the last
        Jacobian by the step's secant costs none. The fit's few parameters act
        on the readings nearly linearly (a contact resistance, a heat), so the
        updated Jacobian leads the search as the differenced one did
        (test_calibration's known truth, 2026-11-28: the same four iterations,
        the fitted values within 0.2 % of their intervals' widths of the
        differenced search's, 42 model runs instead of 60).
        """
        theta = self.theta(u, base)
        if self.last is None:
            r, jac = self.jacobian(theta, self.free)
        else:
            u0, r0, jac0 = self.last
            r = self.evaluate([theta])[0]
            du = u - u0
            dd = float(np.dot(du, du))
            jac = jac0 + np.outer(r - r0 - jac0 @ du, du) / dd if dd > 0.0 else jac0
        self.last = (u.copy(), r, jac)
        return jac
