"""
The fit: which parameters, their identifiability, the least-squares problem, :func:`calibrate`.

The parameters are scaled to [0, 1] over their bounds; the residuals are those
of :func:`~.evaluator.residuals` over the fit logs, each log's starting
temperature a nuisance parameter eliminated by its linearised effect.
"""

import dataclasses
import math
import time
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from .evaluator import (channel_errors, Evaluator, lagged_run, make_windows, residuals,
                        run_config, window_means, Windows)
from .logs import CalibrationError, CHANNELS, LogData
from .results import CalibrationRun, LogFit, ParameterFit, result_record
from ..config import Calibration, Config, config_value, model_parameter, with_values

#: Forward-difference step of the Jacobian, as a share of each parameter's bounds.
FD_STEP = 0.005
#: The fitted starting temperature of a log stays within this of its readings' (K).
START_OFFSET_MAX_K = 2.0
#: Largest integrated autocorrelation time counted (in residual intervals).
TAU_MAX = 100.0
#: z of a two-sided 95 % interval.
Z95 = 1.959964


def fit_keys(cfg: Config, requested: Optional[Sequence[str]] = None) -> List[str]:
    """Return the keys to fit (``requested``, else ``calibration.fit``), each with bounds."""
    keys = list(requested) if requested else list(cfg.calibration.fit)
    if not keys:
        raise CalibrationError('no parameters to fit: name them with --fit KEY ..., or list '
                               'them in calibration.fit of the configuration')
    for key in keys:
        model_parameter(key, f'--fit {key}')
        if key not in cfg.calibration.bounds:
            raise CalibrationError(f'--fit {key}: has no bounds; add "{key}: [low, high]" (in '
                                   "the key's unit) to calibration.bounds of the configuration")
        if keys.count(key) > 1:
            raise CalibrationError(f'--fit {key}: named twice')
    return keys


def screen(jac: np.ndarray, effect_K: np.ndarray, min_effect_K: float,
           max_collinearity: float) -> Tuple[List[int], Dict[int, str], np.ndarray]:
    """
    Choose the parameters the data can identify, from the Jacobian at the start.

    ``jac`` holds the weighted residuals' derivatives per unit of each
    parameter's bounds (columns); ``effect_K`` each parameter's largest RMS
    change of one thermocouple over a log across its bounds (K). Returns the
    kept column indices, the reason for each one held, and each column's
    collinearity index (1 / sine of its angle to the span of the columns kept
    before it; inf for a zero column). Largest effect first: of two
    parameters with the same effect, the one that shows more is kept.
    """
    p = jac.shape[1]
    order = sorted(range(p), key=lambda j: -effect_K[j])
    kept: List[int] = []
    held: Dict[int, str] = {}
    index = np.full(p, np.inf)
    basis = np.zeros((jac.shape[0], 0))
    for j in order:
        norm = float(np.linalg.norm(jac[:, j]))
        if norm == 0.0 or not effect_K[j] >= min_effect_K:
            held[j] = (f'moving it across its bounds changes no thermocouple by more than '
                       f'{effect_K[j]:.3g} K RMS (< {min_effect_K:g} K)')
            continue
        col = jac[:, j] / norm
        rest = col - basis @ (basis.T @ col) if basis.shape[1] else col
        sine = float(np.linalg.norm(rest))
        index[j] = 1.0 / sine if sine > 0.0 else np.inf
        if index[j] > max_collinearity:
            held[j] = ("its effect is nearly a combination of the other parameters' "
                       f'(collinearity index {index[j]:.3g} > {max_collinearity:g})')
            continue
        kept.append(j)
        basis = np.column_stack([basis, rest / sine])
    return sorted(kept), held, index


def effective_samples(series: Sequence[np.ndarray]) -> float:
    """
    Return the effective number of independent residuals of autocorrelated series.

    Each series counts n / tau, tau = 1 + 2 sum_k rho_k its integrated
    autocorrelation time, the sum over the lags until rho_k first falls to 0
    or below (the initial positive sequence), capped at ``TAU_MAX``.
    """
    n_eff = 0.0
    for r in series:
        n = r.size
        if n < 3:
            n_eff += n
            continue
        d = r - r.mean()
        den = float(np.dot(d, d))
        tau = 1.0
        if den > 0.0:
            acf = np.correlate(d, d, mode='full')[n:] / den      # lags 1 .. n-1
            for rho in acf[:n // 2]:
                if rho <= 0.0:
                    break
                tau += 2.0 * float(rho)
        n_eff += n / min(tau, TAU_MAX)
    return max(n_eff, 1.0)


class _Problem:
    """
    The fit's residual function and Jacobian over the fit logs, with a cache of runs.

    Each fit log's starting temperature is a nuisance parameter: the
    residuals are those of the best uniform start offset (within
    ``START_OFFSET_MAX_K``), from the offset's linearised effect (a run
    started 1 K warmer at the nominal values).
    """

    def __init__(self, evaluator: Evaluator, fit_idx: List[int], windows: Dict[int, Windows],
                 params: List[ParameterFit], calib: Calibration,
                 on_progress: Callable[[str], None]) -> None:
        self.ev, self.fit_idx, self.windows = evaluator, fit_idx, windows
        self.params, self.calib = params, calib
        self.free: List[int] = []
        self.on_progress = on_progress
        self.offset_cols: Dict[int, np.ndarray] = {}   # d residuals / d start (per K)
        self.cache: Dict[tuple, np.ndarray] = {}       # key of a parameter vector -> residuals
        self.offsets: Dict[tuple, Dict[int, float]] = {}   # and the start offsets (K)
        self.series: Dict[tuple, Dict[int, tuple]] = {}    # model runs of the base points
        self.t0 = time.perf_counter()
        self.previous = 'jac'
        self.calls = 0

    def key(self, th: np.ndarray) -> tuple:
        """
        Return the cache key of a parameter vector: its position in the bounds, rounded.

        The trust-region method moves a start on a bound 1e-10 inside; that is
        the same model run.
        """
        return tuple(round((float(x) - p.low) / p.span, 8) for x, p in zip(th, self.params))

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

    def store(self, th: np.ndarray, runs: Dict[int, tuple], base: bool = False) -> np.ndarray:
        """Keep the residuals (and for a base point the runs) of a parameter vector."""
        k = self.key(th)
        self.cache[k], self.offsets[k] = self.residuals(runs)
        if base:
            self.series[k] = runs
        return self.cache[k]

    def theta(self, u_free: np.ndarray, base: np.ndarray) -> np.ndarray:
        """Return the full parameter vector for the free parameters at ``u_free``."""
        th = base.copy()
        for k, j in enumerate(self.free):
            p = self.params[j]
            th[j] = p.low + float(np.clip(u_free[k], 0.0, 1.0)) * p.span
        return th

    def steps(self, th: np.ndarray, cols: Sequence[int]) -> List[float]:
        """Return the forward-difference step (parameter units) of each column; back if at top."""
        out = []
        for j in cols:
            p = self.params[j]
            h = FD_STEP * p.span
            out.append(h if th[j] + h <= p.high else -h)
        return out

    def evaluate(self, thetas: List[np.ndarray]) -> List[np.ndarray]:
        """Return the residuals of each parameter vector (cached); the first is a base point."""
        todo = {self.key(th): th for th in thetas if self.key(th) not in self.cache}
        if todo:
            out = self.ev.run(list(todo.values()), [self.fit_idx] * len(todo))
            for (k, th), runs in zip(todo.items(), out):
                self.store(th, runs, base=k == self.key(thetas[0]))
        return [self.cache[self.key(th)] for th in thetas]

    def jacobian(self, th: np.ndarray, cols: Sequence[int]) -> Tuple[np.ndarray, np.ndarray]:
        """Return r(th) and the columns of dr/du (per unit of the bounds)."""
        hs = self.steps(th, cols)
        shifted = []
        for j, h in zip(cols, hs):
            s = th.copy()
            s[j] += h
            shifted.append(s)
        rs = self.evaluate([th] + shifted)
        J = np.empty((rs[0].size, len(cols)))
        for k, (j, h) in enumerate(zip(cols, hs)):
            J[:, k] = (rs[1 + k] - rs[0]) / (h / self.params[j].span)
        return rs[0], J

    # ----------------------------------------------- least_squares callbacks
    def fun(self, u: np.ndarray, base: np.ndarray) -> np.ndarray:
        """Return the residuals at ``u`` (least_squares' fun)."""
        th = self.theta(u, base)
        self.calls += 1
        if self.key(th) not in self.cache:
            if self.previous == 'jac':
                # least_squares asks for the Jacobian at every point it accepts: evaluate
                # its columns with the point, all runs in parallel at once
                self.jacobian(th, self.free)
            else:
                # the point before was rejected (fun twice in a row): this one may be too
                self.evaluate([th])
        self.previous = 'fun'
        r = self.cache[self.key(th)]
        cost = 0.5 * float(np.dot(r, r))
        self.on_progress(f'  evaluation {self.calls}: cost {cost:.6g}, '
                         + ', '.join(f'{self.params[j].key.rsplit(".", 1)[-1]} '
                                     f'{th[j]:.4g}' for j in self.free)
                         + f' ({time.perf_counter() - self.t0:.0f} s)')
        return r

    def jac(self, u: np.ndarray, base: np.ndarray) -> np.ndarray:
        """Return the Jacobian at ``u`` (least_squares' jac)."""
        self.previous = 'jac'
        return self.jacobian(self.theta(u, base), self.free)[1]


def _split(r: np.ndarray, windows: Dict[int, Windows], fit_idx: Sequence[int]) -> list:
    """Return the residual vector cut into its series (one per log and thermocouple)."""
    parts, offset = [], 0
    for li in fit_idx:
        for idx in windows[li].index:
            parts.append(r[offset:offset + idx.size])
            offset += idx.size
    return parts


def calibrate(fit_logs: Sequence[LogData], cfg: Config, keys: Sequence[str], *,
              validate_logs: Sequence[LogData] = (), config_source: str = 'given',
              jobs: int = 1, client=None,
              on_progress: Optional[Callable[[str], None]] = None) -> CalibrationRun:
    """
    Fit ``keys`` of ``cfg`` to the thermocouples of ``fit_logs``; check on ``validate_logs``.

    Returns the parameters (fitted, or held at nominal with the reason), the
    model runs and errors of every log before and after, and the calibrated
    configuration (with its ``calibration.result`` record). The model runs
    go to ``client`` (a ``distributed.Client``) when given, else to ``jobs``
    forked processes.
    """
    from scipy.optimize import least_squares

    say = on_progress or (lambda text: None)
    t_start = time.perf_counter()
    calib = cfg.calibration
    keys = fit_keys(cfg, keys)
    params = []
    for key in keys:
        low, high = calib.bounds[key]
        nominal = float(config_value(cfg, key))
        params.append(ParameterFit(key=key, low=low, high=high, nominal=nominal, value=nominal))
    logs = list(fit_logs) + list(validate_logs)
    n_fit = len(fit_logs)
    if not n_fit:
        raise CalibrationError('no log to fit on')
    fit_idx, all_idx = list(range(n_fit)), list(range(len(logs)))
    nominal = np.array([p.nominal for p in params])
    n_par = len(params)
    ev = Evaluator(logs, [run_config(cfg, log) for log in logs], keys, jobs, client)
    try:
        # one batch: nominal runs of every log (their step grid sets the windows), the
        # Jacobian at the nominal values, and the fit logs started 1 K warmer
        say(f'nominal runs of {len(logs)} log(s), {n_par} Jacobian column(s) and the start '
            'temperature on the fit logs')
        problem = _Problem(ev, fit_idx, {}, params, calib, say)
        hs = problem.steps(nominal, range(n_par))
        sets = [nominal] + [nominal + h * np.eye(n_par)[j] for j, h in enumerate(hs)]
        runs = ev.run(sets + [nominal], [all_idx] + [fit_idx] * (n_par + 1),
                      [{}] * (n_par + 1) + [{'start_offset_K': 1.0}])
        lag0 = {li: lagged_run(runs[0][li], calib) for li in all_idx}
        windows = {li: make_windows(logs[li], lag0[li][0], calib.residual_interval_s)
                   for li in all_idx}
        for li in all_idx:
            if not windows[li].size:
                raise CalibrationError(f'{logs[li].name}: no thermocouple reading inside the '
                                       'span of the model run')
        problem.windows = windows
        for li in fit_idx:
            t1, y1 = lagged_run(runs[-1][li], calib)
            problem.offset_cols[li] = residuals(windows[li], t1, y1) \
                - residuals(windows[li], *lag0[li])
        rs = [problem.store(th, runs[i], base=i == 0) for i, th in enumerate(sets)]
        J0 = np.column_stack([(rs[1 + j] - rs[0]) / (hs[j] / p.span)
                              for j, p in enumerate(params)])
        # each parameter's largest effect on one thermocouple (K, RMS over a log)
        for j, p in enumerate(params):
            best = 0.0
            for li in fit_idx:
                dy = (lagged_run(runs[1 + j][li], calib)[1] - lag0[li][1]) * (p.span / hs[j])
                for c in windows[li].channels:
                    best = max(best, float(np.sqrt(np.mean(dy[:, CHANNELS.index(c)] ** 2))))
            p.effect_K = best
        kept, held, index = screen(J0, np.array([p.effect_K for p in params]),
                                   calib.min_effect_K, calib.max_collinearity)
        for j, p in enumerate(params):
            p.collinearity = float(index[j])
            if j in held:
                p.identifiable, p.note = False, held[j]
                say(f'not identifiable, held at {p.nominal:.4g}: {p.key}: {held[j]}')
        theta = nominal.copy()
        free = list(kept)
        iterations = 0
        n_eff = math.nan
        sd: Dict[int, float] = {}
        while free:
            problem.free = free
            u0 = np.array([(theta[j] - params[j].low) / params[j].span for j in free])
            say(f'fitting {", ".join(params[j].key for j in free)}')

            def progress(intermediate_result):
                nonlocal iterations
                iterations += 1
                say(f'iteration {iterations}: cost {intermediate_result.cost:.6g} '
                    f'({time.perf_counter() - t_start:.0f} s)')

            base = theta.copy()
            sol = least_squares(problem.fun, u0, jac=problem.jac, bounds=(0.0, 1.0),
                                x_scale='jac', method='trf', ftol=1e-4, xtol=1e-4, gtol=1e-8,
                                max_nfev=calib.max_iterations, args=(base,),
                                callback=progress)
            theta = problem.theta(sol.x, base)
            r, J = problem.jacobian(theta, free)
            # covariance: s^2 (J^T J)^-1, s^2 the residuals' mean square, inflated for
            # their autocorrelation by n / n_eff
            n_eff = effective_samples(_split(r, windows, fit_idx))
            s2 = float(np.dot(r, r)) / max(r.size - len(free), 1)
            try:
                cov = np.linalg.inv(J.T @ J) * s2 * (r.size / n_eff)
                sd = {j: float(math.sqrt(max(cov[k, k], 0.0))) for k, j in enumerate(free)}
            except np.linalg.LinAlgError:
                sd = dict.fromkeys(free, math.inf)
            worst, worst_ratio = None, calib.max_ci_fraction
            for j in free:
                ratio = 2.0 * Z95 * sd[j]          # the interval's share of the bounds
                if ratio > worst_ratio:
                    worst, worst_ratio = j, ratio
            if worst is None:
                break
            p = params[worst]
            p.identifiable = False
            p.note = (f'its 95 % interval after the fit spans {100 * worst_ratio:.0f} % of its '
                      f'bounds (> {100 * calib.max_ci_fraction:.0f} %)')
            say(f'not identifiable, held at {p.nominal:.4g}: {p.key}: {p.note}')
            theta[worst] = p.nominal
            free = [j for j in free if j != worst]
        if free and calib.check_step_s:
            # the step's own error: the fitted model once at a finer step, and the
            # parameter shift that implies (one Gauss-Newton step, linearised)
            say(f'checking the step: the fit logs at {calib.check_step_s:g} s')
            fine = ev.run([theta], [fit_idx], [{'estimator.step_s': calib.check_step_s}])[0]
            r_fine, _ = problem.residuals(
                fine, dataclasses.replace(calib, step_s=calib.check_step_s))
            r, J = problem.jacobian(theta, free)
            du = -np.linalg.lstsq(J, r_fine - r, rcond=None)[0]
            for k, j in enumerate(free):
                params[j].step_shift = float(du[k] * params[j].span)
        for j, p in enumerate(params):
            if not p.identifiable:
                theta[j] = p.value = p.nominal
                continue
            p.value = float(theta[j])
            half = Z95 * sd.get(j, math.inf) * p.span + abs(p.step_shift)
            p.ci95 = (max(p.value - half, p.low), min(p.value + half, p.high))
            edge = 1e-3 * p.span
            if p.value - p.low < edge or p.high - p.value < edge:
                p.note = 'ended on a bound: the fit wants it outside; check the bounds'
        # the calibrated runs: the fit logs' from the cache, the held-out logs' now
        problem.evaluate([theta])
        final = dict(problem.series.get(problem.key(theta), {}))
        need = [li for li in all_idx if li not in final]
        if need:
            final.update(ev.run([theta], [need])[0])
        offsets_before = problem.offsets[problem.key(nominal)]
        offsets_after = problem.offsets[problem.key(theta)]
        evaluations = ev.runs
    finally:
        ev.close()
    calibrated = with_values(cfg, {p.key: p.value for p in params})
    log_fits = []
    for li, log in enumerate(logs):
        t_nom, y_nom = lag0[li]
        t_cal, y_cal = lagged_run(final[li], calib)
        lf = LogFit(log=log, role='fit' if li < n_fit else 'validate', t_model=t_nom,
                    nominal_C=y_nom, calibrated_C=y_cal, windows=windows[li])
        # errors as the estimator would run: from the readings' starting temperature
        lf.start_offset_before_K = offsets_before.get(li, 0.0)
        lf.start_offset_after_K = offsets_after.get(li, 0.0)
        lf.before = channel_errors(log, windows[li], t_nom, lf.nominal_C)
        lf.after = channel_errors(log, windows[li], t_cal, lf.calibrated_C)
        log_fits.append(lf)
    run = CalibrationRun(base_cfg=cfg, config_source=config_source, parameters=params,
                         logs=log_fits, calibrated_cfg=calibrated, evaluations=evaluations,
                         iterations=iterations, fit_s=time.perf_counter() - t_start,
                         n_eff=n_eff, n_residuals=int(rs[0].size))
    r_before = np.concatenate([_window_errors(lf, 'nominal') for lf in log_fits[:n_fit]])
    r_after = np.concatenate([_window_errors(lf, 'calibrated') for lf in log_fits[:n_fit]])
    run.rms_before_K = float(np.sqrt(np.mean(r_before ** 2)))
    run.rms_after_K = float(np.sqrt(np.mean(r_after ** 2)))
    for log in logs:
        run.messages.extend(log.warnings)
    for lf in log_fits:
        if abs(lf.start_offset_after_K) >= START_OFFSET_MAX_K:
            run.messages.append(f'{lf.log.name}: the fitted starting temperature hit its '
                                f'limit ({lf.start_offset_after_K:+.1f} K): the log did not '
                                'start uniform')
    run.calibrated_cfg = dataclasses.replace(calibrated, calibration=dataclasses.replace(
        calibrated.calibration, result=result_record(run)))
    return run


def _window_errors(lf: LogFit, which: str) -> np.ndarray:
    """Return the window-mean errors (K) of all channels of a log, nominal or calibrated."""
    y = lf.nominal_C if which == 'nominal' else lf.calibrated_C
    means = window_means(lf.windows, lf.t_model, y)
    parts = [means[c] - m for c, m in zip(lf.windows.channels, lf.windows.measured)]
    return np.nan_to_num(np.concatenate(parts)) if parts else np.zeros(0)
