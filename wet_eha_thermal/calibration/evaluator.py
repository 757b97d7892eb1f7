"""
The evaluator: the model run on a log and compared with its thermocouples.

:func:`simulate_log` runs the estimator open-loop over a :class:`~.logs.LogData`
(the configuration of :func:`run_config`); :func:`lagged` passes the run
through the thermocouples' lag; :func:`make_windows` and :func:`residuals`
compare it with the readings over the residual windows, and
:func:`channel_errors` states the errors in kelvin. :class:`Evaluator` runs
parameter sets over logs inline, in worker processes or on a Dask client:
the same numbers either way.
"""

from concurrent.futures import as_completed, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, replace
import math
import time
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from .logs import CalibrationError, CHANNELS, LogData
from ..config import Calibration, Config, with_values
from ..estimator.session import EstimatorSession
from ..interface import THERMOCOUPLES
from ..processes import child_context, stop_pool

#: Length of the ambient segments (s): each gets the mean of its readings.
AMBIENT_SEGMENT_S = 60.0


def run_config(cfg: Config, log: LogData) -> Config:
    """Return the configuration a fit runs ``log`` with: its step, grid and inputs, open-loop."""
    c = cfg.calibration
    values = {'estimator.step_s': c.step_s, 'estimator.block_rate_Hz': c.average_rate_Hz,
              'estimator.pressure_inputs': log.pressure_inputs}
    correction = getattr(cfg.estimator, 'correction', None)
    if getattr(correction, 'enabled', False):
        values['estimator.correction.enabled'] = False
    # a fit compares estimates, not their sigmas: no copies of the model to propagate them
    return replace(with_values(cfg, values), uncertainty=None)


def simulate_log(log: LogData, cfg: Config,
                 start_offset_K: float = 0.0) -> Tuple[np.ndarray, np.ndarray]:
    """
    Run the estimator open-loop over a log; return step-end stamps and temperatures (degC).

    ``cfg`` is a :func:`run_config`. The columns are the estimates of
    :data:`CHANNELS`; the model starts uniform at ``log.start_C`` plus
    ``start_offset_K``.
    """
    session = EstimatorSession(cfg)
    names = [THERMOCOUPLES[c] for c in CHANNELS]
    feed = {n: log.inputs[n] for n in session.inputs if n in log.inputs}
    amb_t, amb_v = log.ambient
    t_end = max(t[-1] for t, _ in feed.values())
    edges = np.arange(AMBIENT_SEGMENT_S, t_end + AMBIENT_SEGMENT_S, AMBIENT_SEGMENT_S)
    seg_of = np.searchsorted(edges, amb_t, side='left')
    stamps: List[float] = []
    rows: List[List[float]] = []

    def advance() -> None:
        for e in session.step(all_steps=True):
            stamps.append(e.stamp_s)
            temps = e.temperatures_C
            rows.append([temps[n] for n in names])

    # the model starts at the starting temperature: the estimator starts its model at
    # its ambient, so that is set to it first, and to the ambient once started
    session.add_ambient(0.0, log.start_C + start_offset_K)
    cursor = dict.fromkeys(feed, 0)
    for n, (t, v) in feed.items():
        session.add(n, t[:1], v[:1])
        cursor[n] = 1
    advance()
    for k, edge in enumerate(edges):
        here = amb_v[seg_of == k]
        last = int(np.searchsorted(amb_t, edge, side='right')) - 1     # latest reading so far
        ambient = float(np.mean(here)) if here.size else (
            float(amb_v[last]) if last >= 0 else cfg.estimator.ambient_C)
        session.add_ambient(edge - AMBIENT_SEGMENT_S, ambient)
        for n, (t, v) in feed.items():
            hi = int(np.searchsorted(t, edge, side='right'))
            if hi > cursor[n]:
                session.add(n, t[cursor[n]:hi], v[cursor[n]:hi])
                cursor[n] = hi
        advance()
    if not stamps:
        raise CalibrationError(f'{log.name}: not one model step could be made')
    return np.array(stamps), np.array(rows)


def lagged(y: np.ndarray, step_s: float, lag_s: float) -> np.ndarray:
    """Return the columns of ``y`` (one row per step) through a first-order lag."""
    if lag_s <= 0.0:
        return y
    from scipy.signal import lfilter

    a = 1.0 - math.exp(-step_s / lag_s)
    # y_lag[k] = y_lag[k-1] + a (y[k] - y_lag[k-1]), starting from y[0]
    zi = ((1.0 - a) * y[0])[None, :]
    out, _ = lfilter([a], [1.0, -(1.0 - a)], y, axis=0, zi=zi)
    return out


def lagged_run(run: tuple, calib: Calibration) -> Tuple[np.ndarray, np.ndarray]:
    """Return a model run (stamps, temperatures) as the lagged thermocouples would read it."""
    t, y = run
    return t, lagged(y, calib.step_s, calib.thermocouple_lag_s)


@dataclass
class Windows:
    """The residual windows of one log: readings averaged per window and channel."""

    edges: np.ndarray                 # window k is (edges[k], edges[k + 1]]
    channels: List[str]               # in the order of the residual blocks
    index: List[np.ndarray]           # per channel: the windows that hold readings
    measured: List[np.ndarray]        # per channel: mean reading in those windows
    sigma: List[np.ndarray]           # per channel: standard error of that mean (K)

    @property
    def size(self) -> int:
        """Return the number of residuals."""
        return sum(i.size for i in self.index)


def make_windows(log: LogData, t_model: np.ndarray, interval_s: float) -> Windows:
    """Return the residual windows of ``log`` over the model's span (whole windows only)."""
    start = t_model[0] - (t_model[1] - t_model[0] if t_model.size > 1 else 0.0)
    n = int(math.floor((t_model[-1] - start) / interval_s + 1e-9))
    edges = start + interval_s * np.arange(n + 1)
    channels, index, measured, sigma = [], [], [], []
    for name in CHANNELS:
        if name not in log.thermocouples:
            continue
        t, v = log.thermocouples[name]
        k = np.searchsorted(edges, t, side='left') - 1
        inside = (k >= 0) & (k < n)
        counts = np.bincount(k[inside], minlength=n)
        sums = np.bincount(k[inside], weights=v[inside], minlength=n)
        keep = np.flatnonzero(counts)
        if not keep.size:
            continue
        channels.append(name)
        index.append(keep)
        measured.append(sums[keep] / counts[keep])
        sigma.append(log.sigma_K[name] / np.sqrt(counts[keep]))
    return Windows(edges, channels, index, measured, sigma)


def window_means(w: Windows, t_model: np.ndarray, y: np.ndarray) -> Dict[str, np.ndarray]:
    """Return per channel the model's mean over each window that holds readings."""
    n = w.edges.size - 1
    k = np.searchsorted(w.edges, t_model, side='left') - 1
    inside = (k >= 0) & (k < n)
    counts = np.bincount(k[inside], minlength=n)
    out = {}
    for c, idx in zip(w.channels, w.index):
        col = y[inside, CHANNELS.index(c)]
        sums = np.bincount(k[inside], weights=col, minlength=n)
        with np.errstate(invalid='ignore', divide='ignore'):
            out[c] = sums[idx] / counts[idx]
    return out


def residuals(w: Windows, t_model: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Weigh the model-minus-readings differences by the readings' standard errors."""
    means = window_means(w, t_model, y)
    parts = [(means[c] - m) / s for c, m, s in zip(w.channels, w.measured, w.sigma)]
    r = np.concatenate(parts) if parts else np.zeros(0)
    return np.nan_to_num(r, nan=0.0)


def channel_errors(log: LogData, w: Windows, t_model: np.ndarray,
                   y: np.ndarray) -> Dict[str, dict]:
    """
    Return per thermocouple the model's error (model minus readings, K).

    Max abs, RMS and bias over the window means (the readings' noise averaged
    out), and the max abs against every single reading (noise included).
    """
    # the replay report's statistics, so that a fit's errors and a replay's compare
    from ..offline.replay import error_stats

    means = window_means(w, t_model, y)
    out = {}
    for c, m in zip(w.channels, w.measured):
        stats = error_stats(means[c] - m)
        t, v = log.thermocouples[c]
        inside = (t >= t_model[0]) & (t <= t_model[-1])
        raw = np.interp(t[inside], t_model, y[:, CHANNELS.index(c)]) - v[inside]
        stats['max_abs_raw_K'] = float(np.max(np.abs(raw))) if raw.size else math.nan
        stats['estimate'] = THERMOCOUPLES[c]
        out[c] = stats
    return out


_WORKER: dict = {}


def evaluate_run(log: LogData, cfg: Config, keys: Sequence[str], task: tuple) -> tuple:
    """
    Run ``log`` with the parameter set of ``task`` (set index, log index, values, extra).

    Returns (set index, log index, t, y, wall s), or with t None and y the
    failure as one line. A pure function of its arguments: in a forked
    worker, on a Dask worker or inline, the same numbers.
    """
    vi, li, values, extra = task
    extra = dict(extra)
    offset = extra.pop('start_offset_K', 0.0)
    changes = {**dict(zip(keys, values)), **extra}
    t0 = time.perf_counter()
    try:
        cfg = with_values(cfg, changes) if changes else cfg
        t, y = simulate_log(log, cfg, offset)
    except (ArithmeticError, ValueError, RuntimeError) as exc:
        # reported by the parent as one line, with the values that failed
        return vi, li, None, f'{type(exc).__name__}: {exc}', time.perf_counter() - t0
    return vi, li, t, y, time.perf_counter() - t0


def _start_worker(state: dict) -> None:
    """Keep the logs, configurations and keys a worker process is given at its start."""
    _WORKER.update(state)


def _evaluate(task: tuple) -> tuple:
    """Run one task on the logs the worker was given at its start (or inline)."""
    li = task[1]
    return evaluate_run(_WORKER['logs'][li], _WORKER['cfgs'][li], _WORKER['keys'], task)


def _worker_died(exc: BrokenProcessPool) -> CalibrationError:
    """Return the error of a run whose worker process died."""
    return CalibrationError(f'a calibration worker process died ({exc}); it may have been '
                            'killed or run out of memory: try fewer jobs (--jobs)')


class Evaluator:
    """
    Run parameter sets over logs: inline, in ``jobs`` worker processes, or on a Dask client.

    The logs and their configurations reach every worker once, at its start
    (forked workers inherit them; from the fork server, when the caller runs
    threads, they are pickled): each task then carries only its parameter
    values. With ``client`` (a ``distributed.Client``) they are scattered to
    its workers. A worker that dies (killed, or out of memory) fails the run
    with a :class:`CalibrationError`: a pool that replaced it would wait for
    ever for the task it held.
    """

    def __init__(self, logs: Sequence[LogData], cfgs: Sequence[Config], keys: Sequence[str],
                 jobs: int = 1, client=None) -> None:
        self.logs, self.keys = list(logs), list(keys)
        self.cost_s = [max(log.duration_s, 1.0) for log in self.logs]   # until measured
        self.runs = 0
        self.pool = None
        self.client = client
        if client is not None:
            self.remote = (client.scatter(self.logs, broadcast=True),
                           client.scatter(list(cfgs), broadcast=True))
            return
        _WORKER.update(logs=self.logs, cfgs=list(cfgs), keys=self.keys)
        if jobs > 1:
            self.pool = ProcessPoolExecutor(
                jobs, mp_context=child_context(preload=[__name__]), initializer=_start_worker,
                initargs=(dict(_WORKER),))

    def run(self, sets: Sequence[Sequence[float]], which: Sequence[Sequence[int]],
            extras: Optional[Sequence[dict]] = None) -> list:
        """
        Return ``out[i][log] = (t, y)`` for parameter set ``sets[i]`` on the logs ``which[i]``.

        ``extras[i]``: more configuration values for set i (e.g. another step),
        and ``start_offset_K``, added to each log's starting temperature. The
        longest runs are handed out first.
        """
        extras = extras or [{}] * len(sets)
        tasks = [(i, li, tuple(float(x) for x in values), extras[i])
                 for i, values in enumerate(sets) for li in which[i]]
        tasks.sort(key=lambda task: -self.cost_s[task[1]])
        out: List[dict] = [{} for _ in sets]
        futures = []
        if self.client is not None:
            from distributed import as_completed as dask_completed
            logs, cfgs = self.remote
            futures = [self.client.submit(evaluate_run, logs[task[1]], cfgs[task[1]], self.keys,
                                          task, pure=False) for task in tasks]
            results = (f.result() for f in dask_completed(futures))
        elif self.pool is not None:
            try:
                futures = [self.pool.submit(_evaluate, task) for task in tasks]
            except BrokenProcessPool as exc:
                raise _worker_died(exc) from None
            results = (f.result() for f in as_completed(futures))
        else:
            results = map(_evaluate, tasks)
        try:
            for i, li, t, y, seconds in results:
                if t is None:
                    values = ', '.join(f'{k} = {v:.6g}' for k, v in zip(self.keys, sets[i]))
                    raise CalibrationError(
                        f'{self.logs[li].name}: the model failed with {values}'
                        f'{" and " + str(extras[i]) if extras[i] else ""}: {y}')
                out[i][li] = (t, y)
                self.cost_s[li] = seconds
                self.runs += 1
        except BrokenProcessPool as exc:
            raise _worker_died(exc) from None
        finally:
            # after a failed run, the ones still queued would run for nothing
            if self.client is not None and futures:
                self.client.cancel(futures)
            else:
                for f in futures:
                    f.cancel()
        return out

    def close(self) -> None:
        """Stop the workers, at once even mid-task (a Dask client's are left to its owner)."""
        if self.pool is not None:
            stop_pool(self.pool)
            self.pool = None
        if self.client is not None:
            self.client.cancel([f for part in self.remote for f in part])
        _WORKER.clear()
