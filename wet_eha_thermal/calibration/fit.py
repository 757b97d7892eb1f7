"""
The fit: the parameters, their identifiability, their values and intervals (:func:`calibrate`).

:func:`calibrate` reads as the method's steps: the first batch of runs (the
nominal values, the Jacobian there, the start offsets' effect), the
screening, the least-squares fit (:class:`~.problem.FitProblem`) with the
intervals that hold a parameter after it, the step check, and the calibrated
runs and errors of every log.
"""

import dataclasses
from dataclasses import dataclass
import math
import time
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from .evaluator import (channel_errors, Evaluator, lagged_run, make_windows, residuals,
                        run_config, window_means, Windows)
from .logs import CalibrationError, CHANNELS, LogData
from .problem import FitProblem, START_OFFSET_MAX_K
from .results import CalibrationRun, LogFit, ParameterFit, result_record
from ..config import Calibration, Config, config_value, model_parameter, with_values

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
    say = on_progress or (lambda text: None)
    t_start = time.perf_counter()
    params = _nominal_parameters(cfg, fit_keys(cfg, keys))
    logs = list(fit_logs) + list(validate_logs)
    if not fit_logs:
        raise CalibrationError('no log to fit on')
    nominal = np.array([p.nominal for p in params])
    evaluator = Evaluator(logs, [run_config(cfg, log) for log in logs], [p.key for p in params],
                          jobs, client)
    try:
        problem = FitProblem(evaluator, list(range(len(fit_logs))), {}, params,
                             cfg.calibration, say)
        nominal_runs, jac_nominal = _start(problem, logs, nominal)
        kept = _screen_parameters(params, jac_nominal, cfg.calibration, say)
        fitted = _fit(problem, nominal, kept, t_start)
        if fitted.free and cfg.calibration.check_step_s:
            _check_step(problem, fitted.theta, fitted.free)
        _set_values(params, fitted)
        calibrated_runs = _calibrated_runs(problem, fitted.theta, len(logs))
        offsets_K = (problem.offsets[problem.key(nominal)],
                     problem.offsets[problem.key(fitted.theta)])
        evaluations = evaluator.runs
    finally:
        evaluator.close()
    log_fits = _log_fits(logs, len(fit_logs), problem.windows, nominal_runs, calibrated_runs,
                         offsets_K, cfg.calibration)
    run = CalibrationRun(base_cfg=cfg, config_source=config_source, parameters=params,
                         logs=log_fits, calibrated_cfg=with_values(
                             cfg, {p.key: p.value for p in params}),
                         evaluations=evaluations, iterations=fitted.iterations,
                         fit_s=time.perf_counter() - t_start, n_eff=fitted.n_eff,
                         n_residuals=sum(problem.windows[li].size for li in problem.fit_idx))
    _summarise(run, logs, len(fit_logs))
    return run


def _nominal_parameters(cfg: Config, keys: Sequence[str]) -> List[ParameterFit]:
    """Return the parameters ``keys`` at their nominal values, with their bounds."""
    params = []
    for key in keys:
        low, high = cfg.calibration.bounds[key]
        nominal = float(config_value(cfg, key))
        params.append(ParameterFit(key=key, low=low, high=high, nominal=nominal, value=nominal))
    return params


def _start(problem: FitProblem, logs: Sequence[LogData],
           nominal: np.ndarray) -> Tuple[Dict[int, tuple], np.ndarray]:
    """
    Run the first batch and set the problem up; return the nominal runs and Jacobian there.

    One batch: every log at the nominal values (their step grid sets the
    residual windows), the Jacobian's columns at the nominal values, and the
    fit logs started 1 K warmer (the start offset's effect). Each
    parameter's largest effect is measured on the way. The runs returned are
    lagged, as the thermocouples read them.
    """
    calib, params, fit_idx = problem.calib, problem.params, problem.fit_idx
    all_idx = list(range(len(logs)))
    problem.say(f'nominal runs of {len(logs)} log(s), {len(params)} Jacobian column(s) and the '
                'start temperature on the fit logs')
    fd_steps = problem.steps(nominal, range(len(params)))
    sets = [nominal] + [nominal + h * np.eye(len(params))[j] for j, h in enumerate(fd_steps)]
    runs = problem.evaluator.run(sets + [nominal], [all_idx] + [fit_idx] * (len(params) + 1),
                                 [{}] * (len(params) + 1) + [{'start_offset_K': 1.0}])
    nominal_runs = {li: lagged_run(runs[0][li], calib) for li in all_idx}
    problem.windows = _residual_windows(logs, nominal_runs, calib)
    warmer_runs = runs[-1]
    for li in fit_idx:
        problem.offset_cols[li] = residuals(problem.windows[li],
                                            *lagged_run(warmer_runs[li], calib)) \
            - residuals(problem.windows[li], *nominal_runs[li])
    residuals_at = [problem.store(theta, runs[i], base=i == 0) for i, theta in enumerate(sets)]
    jac_nominal = np.column_stack([(residuals_at[1 + j] - residuals_at[0]) / (fd_steps[j] / p.span)
                                   for j, p in enumerate(params)])
    for j, p in enumerate(params):
        p.effect_K = _largest_effect(problem, runs[1 + j], nominal_runs, p.span / fd_steps[j])
    return nominal_runs, jac_nominal


def _residual_windows(logs: Sequence[LogData], nominal_runs: Dict[int, tuple],
                      calib: Calibration) -> Dict[int, Windows]:
    """Return the residual windows of every log over its nominal run; raise if one has none."""
    windows = {li: make_windows(log, nominal_runs[li][0], calib.residual_interval_s)
               for li, log in enumerate(logs)}
    for li, log in enumerate(logs):
        if not windows[li].size:
            raise CalibrationError(f'{log.name}: no thermocouple reading inside the span of the '
                                   'model run')
    return windows


def _largest_effect(problem: FitProblem, shifted_runs: Dict[int, tuple],
                    nominal_runs: Dict[int, tuple], per_step: float) -> float:
    """Return a parameter's largest effect across its bounds on one thermocouple (K, RMS)."""
    largest = 0.0
    for li in problem.fit_idx:
        dy = (lagged_run(shifted_runs[li], problem.calib)[1] - nominal_runs[li][1]) * per_step
        for c in problem.windows[li].channels:
            largest = max(largest, float(np.sqrt(np.mean(dy[:, CHANNELS.index(c)] ** 2))))
    return largest


def _screen_parameters(params: List[ParameterFit], jac_nominal: np.ndarray,
                       calib: Calibration, say: Callable[[str], None]) -> List[int]:
    """Hold the parameters the Jacobian at the nominal values cannot identify; return the rest."""
    kept, held, index = screen(jac_nominal, np.array([p.effect_K for p in params]),
                               calib.min_effect_K, calib.max_collinearity)
    for j, p in enumerate(params):
        p.collinearity = float(index[j])
        if j in held:
            p.identifiable, p.note = False, held[j]
            say(f'not identifiable, held at {p.nominal:.4g}: {p.key}: {held[j]}')
    return kept


@dataclass
class _Fitted:
    """Where the fit ended: the parameters, which are free, their standard errors."""

    theta: np.ndarray                   # every parameter, the held ones at nominal
    free: List[int]                     # the parameters fitted
    sigma_u: Dict[int, float]           # 1 sigma of each, as a share of its bounds
    n_eff: float                        # effectively independent residuals
    iterations: int


def _fit(problem: FitProblem, nominal: np.ndarray, kept: List[int], t_start: float) -> _Fitted:
    """
    Fit the kept parameters; hold any whose interval is too wide and fit the others again.

    The covariance is s^2 (J^T J)^-1, s^2 the residuals' mean square,
    inflated for their autocorrelation by n / n_eff.
    """
    params, calib, say = problem.params, problem.calib, problem.say
    fitted = _Fitted(theta=nominal.copy(), free=list(kept), sigma_u={}, n_eff=math.nan,
                     iterations=0)

    def progress(intermediate_result) -> None:
        fitted.iterations += 1
        say(f'iteration {fitted.iterations}: cost {intermediate_result.cost:.6g} '
            f'({time.perf_counter() - t_start:.0f} s)')

    while fitted.free:
        fitted.theta = _least_squares(problem, fitted.theta, fitted.free, progress)
        r, jac = problem.jacobian(fitted.theta, fitted.free)
        fitted.n_eff = effective_samples(problem.split(r))
        s2 = float(np.dot(r, r)) / max(r.size - len(fitted.free), 1)
        try:
            cov = np.linalg.inv(jac.T @ jac) * s2 * (r.size / fitted.n_eff)
            fitted.sigma_u = {j: float(math.sqrt(max(cov[k, k], 0.0)))
                              for k, j in enumerate(fitted.free)}
        except np.linalg.LinAlgError:
            fitted.sigma_u = dict.fromkeys(fitted.free, math.inf)
        worst, worst_ratio = None, calib.max_ci_fraction
        for j in fitted.free:
            ratio = 2.0 * Z95 * fitted.sigma_u[j]          # the interval's share of the bounds
            if ratio > worst_ratio:
                worst, worst_ratio = j, ratio
        if worst is None:
            break
        p = params[worst]
        p.identifiable = False
        p.note = (f'its 95 % interval after the fit spans {100 * worst_ratio:.0f} % of its '
                  f'bounds (> {100 * calib.max_ci_fraction:.0f} %)')
        say(f'not identifiable, held at {p.nominal:.4g}: {p.key}: {p.note}')
        fitted.theta[worst] = p.nominal
        fitted.free = [j for j in fitted.free if j != worst]
    return fitted


def _least_squares(problem: FitProblem, theta: np.ndarray, free: List[int],
                   progress: Callable) -> np.ndarray:
    """Return ``theta`` with the ``free`` parameters fitted (trust region, within bounds)."""
    from scipy.optimize import least_squares

    problem.free, problem.last = free, None
    params = problem.params
    u_start = np.array([(theta[j] - params[j].low) / params[j].span for j in free])
    problem.say(f'fitting {", ".join(params[j].key for j in free)}')
    base = theta.copy()
    solution = least_squares(problem.fun, u_start, jac=problem.jac, bounds=(0.0, 1.0),
                             x_scale='jac', method='trf', ftol=1e-4, xtol=1e-4, gtol=1e-8,
                             max_nfev=problem.calib.max_iterations, args=(base,),
                             callback=progress)
    return problem.theta(solution.x, base)


def _check_step(problem: FitProblem, theta: np.ndarray, free: List[int]) -> None:
    """
    Set each fitted parameter's step shift: the error of the fit's step itself.

    The fitted model runs once at ``calibration.check_step_s``; the shift is
    the parameter change that implies (one Gauss-Newton step, linearised).
    """
    calib = problem.calib
    problem.say(f'checking the step: the fit logs at {calib.check_step_s:g} s')
    fine_runs = problem.evaluator.run([theta], [problem.fit_idx],
                                      [{'estimator.step_s': calib.check_step_s}])[0]
    r_fine, _ = problem.residuals(fine_runs,
                                  dataclasses.replace(calib, step_s=calib.check_step_s))
    r, jac = problem.jacobian(theta, free)
    du = -np.linalg.lstsq(jac, r_fine - r, rcond=None)[0]
    for k, j in enumerate(free):
        problem.params[j].step_shift = float(du[k] * problem.params[j].span)


def _set_values(params: List[ParameterFit], fitted: _Fitted) -> None:
    """Set each parameter's value and 95 % interval (a held one: its nominal value)."""
    for j, p in enumerate(params):
        if not p.identifiable:
            fitted.theta[j] = p.value = p.nominal
            continue
        p.value = float(fitted.theta[j])
        half = Z95 * fitted.sigma_u.get(j, math.inf) * p.span + abs(p.step_shift)
        p.ci95 = (max(p.value - half, p.low), min(p.value + half, p.high))
        edge = 1e-3 * p.span
        if p.value - p.low < edge or p.high - p.value < edge:
            p.note = 'ended on a bound: the fit wants it outside; check the bounds'


def _calibrated_runs(problem: FitProblem, theta: np.ndarray, n_logs: int) -> Dict[int, tuple]:
    """Return the runs of every log at ``theta``: the fit logs' from the cache, the others new."""
    problem.evaluate([theta])
    runs = dict(problem.series.get(problem.key(theta), {}))
    need = [li for li in range(n_logs) if li not in runs]
    if need:
        runs.update(problem.evaluator.run([theta], [need])[0])
    return runs


def _log_fits(logs: Sequence[LogData], n_fit: int, windows: Dict[int, Windows],
              nominal_runs: Dict[int, tuple], calibrated_runs: Dict[int, tuple],
              offsets_K: Tuple[Dict[int, float], Dict[int, float]],
              calib: Calibration) -> List[LogFit]:
    """Return each log's runs and errors, nominal and calibrated."""
    log_fits = []
    for li, log in enumerate(logs):
        t_nominal, y_nominal = nominal_runs[li]
        t_calibrated, y_calibrated = lagged_run(calibrated_runs[li], calib)
        log_fit = LogFit(log=log, role='fit' if li < n_fit else 'validate', t_model=t_nominal,
                         nominal_C=y_nominal, calibrated_C=y_calibrated, windows=windows[li])
        # errors as the estimator would run: from the readings' starting temperature
        log_fit.start_offset_before_K = offsets_K[0].get(li, 0.0)
        log_fit.start_offset_after_K = offsets_K[1].get(li, 0.0)
        log_fit.before = channel_errors(log, windows[li], t_nominal, log_fit.nominal_C)
        log_fit.after = channel_errors(log, windows[li], t_calibrated, log_fit.calibrated_C)
        log_fits.append(log_fit)
    return log_fits


def _summarise(run: CalibrationRun, logs: Sequence[LogData], n_fit: int) -> None:
    """Set the fit logs' RMS errors, the warnings and the calibrated configuration's record."""
    before = np.concatenate([_window_errors(log_fit, 'nominal') for log_fit in run.logs[:n_fit]])
    after = np.concatenate([_window_errors(log_fit, 'calibrated') for log_fit in
                            run.logs[:n_fit]])
    run.rms_before_K = float(np.sqrt(np.mean(before ** 2)))
    run.rms_after_K = float(np.sqrt(np.mean(after ** 2)))
    for log in logs:
        run.messages.extend(log.warnings)
    for log_fit in run.logs:
        if abs(log_fit.start_offset_after_K) >= START_OFFSET_MAX_K:
            run.messages.append(f'{log_fit.log.name}: the fitted starting temperature hit its '
                                f'limit ({log_fit.start_offset_after_K:+.1f} K): the log did '
                                'not start uniform')
    calibrated = run.calibrated_cfg
    run.calibrated_cfg = dataclasses.replace(calibrated, calibration=dataclasses.replace(
        calibrated.calibration, result=result_record(run)))


def _window_errors(log_fit: LogFit, which: str) -> np.ndarray:
    """Return the window-mean errors (K) of all channels of a log, nominal or calibrated."""
    y = log_fit.nominal_C if which == 'nominal' else log_fit.calibrated_C
    means = window_means(log_fit.windows, log_fit.t_model, y)
    parts = [means[c] - m for c, m in zip(log_fit.windows.channels, log_fit.windows.measured)]
    return np.nan_to_num(np.concatenate(parts)) if parts else np.zeros(0)
