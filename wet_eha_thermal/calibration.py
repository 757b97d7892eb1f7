"""
Calibration of the thermal model on bench logs: fit parameters to the thermocouples.

A log (a rosbag2-style MCAP holding the sensor topics and the thermocouples,
read as :mod:`.replay` reads it: the same topic mapping, the same stamps) is
read once. Its inputs are averaged onto a coarse grid (``calibration.
average_rate_Hz``: the current as the root of the mean of I^2, speed and
pressures as means, the position sampled at the end of each interval, as the
live estimator interpolates it), and kept in memory with the raw readings of
the thermocouples and the ambient. An evaluation of a parameter set then
reruns only the model: the real :class:`~.estimator.core.Estimator`, the live
twin's code path, configured with those values by
:func:`~.config.with_values`, at ``calibration.step_s`` with its averaging
grid on the pre-averaged samples, fed through ``add_many``/``advance``.

Assumptions, stated in the report too:

- a log starts in thermal equilibrium: every model temperature starts at the
  median over the thermocouples of their first readings (``START_WINDOW_S``);
  a warning names a log whose first readings spread by more than
  ``START_SPREAD_K``. The fit refines it: each fit log's start gets a uniform
  offset (within ``START_OFFSET_MAX_K``), a nuisance parameter eliminated by
  its linearised effect (one run started 1 K warmer), since 0.1 K on the start
  moved the fitted seal loss by 5 % in the tests. The errors reported use the
  readings' start, as the estimator would;
- the ambient of each minute is the mean of that minute's ambient readings
  (the configuration's ambient when the log has none);
- the thermocouples lag the temperature they measure by a first-order
  ``calibration.thermocouple_lag_s``, applied to the model before comparing;
- the model runs open-loop: a live correction (``estimator.correction``) is off.

Residuals: for every thermocouple, the model (at its step ends) and the
readings are averaged over windows of ``calibration.residual_interval_s``, and
their difference is divided by the standard error of the readings' mean
(sigma from the messages' variance, or ``calibration.thermocouple_sigma_K``
when it is 0). ``scipy.optimize.least_squares`` (trust region reflective,
within the bounds, ``x_scale='jac'``) fits the parameters, scaled to [0, 1]
over their bounds, with a forward-difference Jacobian whose columns, like the
logs, are evaluated in parallel worker processes (``jobs``; fork, each worker
holding the pre-averaged logs), or on the workers of a Dask ``client`` (a
cluster; the logs are sent to each worker once). Either way the same numbers.

Identifiability, judged twice:

- before the fit, on the scaled Jacobian at the nominal values: a parameter
  whose move across its bounds changes no thermocouple by ``min_effect_K``
  (RMS over a log) is held, and so is one whose effect is, to within
  ``1 / max_collinearity`` (the sine of the angle), a combination of the
  effects of parameters with larger ones (greedy, largest effect first);
- after the fit, from its 95 % interval: wider than ``max_ci_fraction`` of
  its bounds, it is held and the others are fitted again.

A held parameter stays at its nominal value and is reported as not
identifiable: it is never fitted to noise.

Intervals: 1.96 sigma from the covariance s^2 (J^T J)^-1, s^2 the residuals'
mean square, inflated by n / n_eff. The residuals after a fit are model error
more than sensor noise and autocorrelated, so each series (a log's
thermocouple) counts n / tau independent samples, tau its integrated
autocorrelation time (:func:`effective_samples`). The error of the fit step
itself is estimated once (``calibration.check_step_s``): the fitted model
runs at that finer step, and the parameter shift it implies (one linearised
Gauss-Newton step) is reported and added to the interval's half-width. The
interval otherwise assumes the model's structure.
"""

import dataclasses
from dataclasses import dataclass, field
import datetime
import hashlib
import math
import multiprocessing
import os
from pathlib import Path
import time
from typing import Callable, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from .config import (Calibration, CalibrationResult, Config, config_from_yaml, config_value,
                     ConfigError, from_dict, model_parameter, with_values)
from .estimator.core import Estimator
from .outputs import markdown_table, save_figure, write_text
from .ros import topics
from .ros.topics import THERMOCOUPLES

#: A log whose thermocouples first read further apart than this (K) did not start in equilibrium.
START_SPREAD_K = 2.0
#: Readings averaged per thermocouple for the starting temperature (s from its first one):
#: short, as the oil of a loaded rig heats by tenths of a kelvin in its first second.
START_WINDOW_S = 0.5
#: Length of the ambient segments (s): each gets the mean of its readings.
AMBIENT_SEGMENT_S = 60.0
#: Forward-difference step of the Jacobian, as a share of each parameter's bounds.
FD_STEP = 0.005
#: The fitted starting temperature of a log stays within this of its readings' (K).
START_OFFSET_MAX_K = 2.0
#: Largest integrated autocorrelation time counted (in residual intervals).
TAU_MAX = 100.0
#: z of a two-sided 95 % interval.
Z95 = 1.959964
#: Name of the calibrated configuration in the output folder.
CALIBRATED_YAML = 'calibrated.yaml'
#: Estimates of the thermocouples, in THERMOCOUPLES order.
CHANNELS = tuple(THERMOCOUPLES)


class CalibrationError(ValueError):
    """Input that cannot be calibrated on (a log, a key, a mapping); the message says why."""


# ----------------------------------------------------------------------- logs
@dataclass
class LogData:
    """
    One log in memory: pre-averaged inputs, raw thermocouple and ambient readings.

    Times are seconds from the log's origin (one averaging interval before
    its first message).
    """

    name: str
    inputs: Dict[str, Tuple[np.ndarray, np.ndarray]]   # bin-end stamps, averaged values
    thermocouples: Dict[str, Tuple[np.ndarray, np.ndarray]]   # readings (degC)
    sigma_K: Dict[str, float]                        # 1 sigma of one reading
    ambient: Tuple[np.ndarray, np.ndarray]           # readings (degC); may be empty
    pressure_inputs: str                             # 'ports' or 'differential'
    start_C: float                                   # uniform starting temperature
    missing: List[str] = field(default_factory=list)     # inputs without a topic: fallback
    path: str = ''
    size_bytes: int = 0
    sha256: str = ''
    warnings: List[str] = field(default_factory=list)

    @property
    def t_start_s(self) -> float:
        """Return when every input has a value: where the model starts."""
        firsts = [t[0] for t, _ in self.inputs.values() if t.size]
        return max(firsts) if firsts else 0.0

    @property
    def duration_s(self) -> float:
        """Return the span of the inputs from the model's start (s)."""
        lasts = [t[-1] for t, _ in self.inputs.values() if t.size]
        return max(min(lasts) - self.t_start_s, 0.0) if lasts else 0.0


class InputAverager:
    """
    Average one input's samples onto the bins (k h, (k + 1) h], chunk by chunk.

    The current is averaged as the root of the mean of I^2, the position is
    the last sample of each bin (the live estimator interpolates it at grid
    times: its differences are the actuator flow), the rest are means. A
    sample on a bin end belongs to the bin it ends.
    """

    def __init__(self, name: str, rate_Hz: float) -> None:
        self.name = name
        self.rate_Hz = rate_Hz
        self.sums = np.zeros(0)
        self.counts = np.zeros(0, dtype=np.int64)

    def _grow(self, n: int) -> None:
        if n > self.sums.size:
            size = max(n, 2 * self.sums.size)
            self.sums = np.concatenate([self.sums, np.zeros(size - self.sums.size)])
            self.counts = np.concatenate([self.counts, np.zeros(size - self.counts.size,
                                                                dtype=np.int64)])

    def add(self, t_s: np.ndarray, values: np.ndarray) -> None:
        """Take samples stamped ``t_s`` (s from the origin, > 0)."""
        ok = np.isfinite(values) & (t_s > 0.0)
        t_s, values = t_s[ok], values[ok]
        if not t_s.size:
            return
        idx = np.ceil(t_s * self.rate_Hz - 1e-6).astype(np.int64) - 1
        np.maximum(idx, 0, out=idx)
        self._grow(int(idx.max()) + 1)
        if self.name == 'position_m':
            # the last sample of each bin, in file order
            rev = idx[::-1]
            bins, first = np.unique(rev, return_index=True)
            self.sums[bins] = values[::-1][first]
            self.counts[bins] = 1
            return
        v = values * values if self.name == 'current_A' else values
        n = int(idx.max()) + 1
        self.sums[:n] += np.bincount(idx, weights=v, minlength=n)
        self.counts[:n] += np.bincount(idx, minlength=n)

    def result(self) -> Tuple[np.ndarray, np.ndarray]:
        """Return the stamps (bin ends) and values of the bins holding samples."""
        filled = np.flatnonzero(self.counts)
        mean = self.sums[filled] / self.counts[filled]
        if self.name == 'current_A':
            mean = np.sqrt(mean)
        return (filled + 1) / self.rate_Hz, mean


class LogBuilder:
    """Collect one log's samples (chunk by chunk) and make a :class:`LogData`."""

    def __init__(self, name: str, inputs: Sequence[str], calib: Calibration,
                 ranges: Optional[Mapping[str, Tuple[float, float]]] = None) -> None:
        self.name = name
        self.calib = calib
        self.averagers = {n: InputAverager(n, calib.average_rate_Hz) for n in inputs}
        self.ranges = dict(ranges or {})       # plausible ranges: the estimator's channels
        self.tc: Dict[str, Tuple[list, list, list]] = {}
        self.amb: Tuple[list, list] = ([], [])

    def add_input(self, name: str, t_s: np.ndarray, values: np.ndarray) -> None:
        """Take samples of an input (SI units); drop those the estimator would reject."""
        t_s, values = np.asarray(t_s, float), np.asarray(values, float)
        if name in self.ranges:
            low, high = self.ranges[name]
            ok = (values >= low) & (values <= high)
            t_s, values = t_s[ok], values[ok]
        self.averagers[name].add(t_s, values)

    def add_thermocouple(self, name: str, t_s: np.ndarray, values_C: np.ndarray,
                         variance_K2: Optional[np.ndarray] = None) -> None:
        """Take readings of a thermocouple (degC) and the variances their messages give."""
        t, v, var = self.tc.setdefault(name, ([], [], []))
        t.append(np.asarray(t_s, float))
        v.append(np.asarray(values_C, float))
        var.append(np.zeros(len(t[-1])) if variance_K2 is None
                   else np.asarray(variance_K2, float))

    def add_ambient(self, t_s: np.ndarray, values_C: np.ndarray) -> None:
        """Take ambient readings (degC)."""
        self.amb[0].append(np.asarray(t_s, float))
        self.amb[1].append(np.asarray(values_C, float))

    def build(self, pressure_inputs: str, missing: Sequence[str] = (), **record) -> LogData:
        """Return the log; raise CalibrationError when it holds nothing to fit."""
        inputs = {n: a.result() for n, a in self.averagers.items()}
        inputs = {n: tv for n, tv in inputs.items() if tv[0].size}
        if not inputs:
            raise CalibrationError(f'{self.name}: no samples of any input')
        thermocouples, sigma = {}, {}
        for name in CHANNELS:
            if name not in self.tc:
                continue
            t, v, var = (np.concatenate(x) for x in self.tc[name])
            ok = np.isfinite(t) & np.isfinite(v)
            order = np.argsort(t[ok], kind='stable')
            if not order.size:
                continue
            thermocouples[name] = (t[ok][order], v[ok][order])
            positive = var[ok][var[ok] > 0.0]
            sigma[name] = float(math.sqrt(np.median(positive))) if positive.size \
                else self.calib.thermocouple_sigma_K
        if not thermocouples:
            raise CalibrationError(f'{self.name}: no thermocouple readings (sensor_msgs/'
                                   f'Temperature on {topics.MEASURED_PREFIX}/<name>, names '
                                   f'{", ".join(CHANNELS)}); map them with --map '
                                   'measured/<name>=/topic')
        amb_t = np.concatenate(self.amb[0]) if self.amb[0] else np.zeros(0)
        amb_v = np.concatenate(self.amb[1]) if self.amb[1] else np.zeros(0)
        ok = np.isfinite(amb_t) & np.isfinite(amb_v)
        order = np.argsort(amb_t[ok], kind='stable')
        log = LogData(name=self.name, inputs=inputs, thermocouples=thermocouples,
                      sigma_K=sigma, ambient=(amb_t[ok][order], amb_v[ok][order]),
                      pressure_inputs=pressure_inputs, start_C=0.0,
                      missing=list(missing) + [n for n in self.averagers if n not in inputs],
                      **record)
        if log.duration_s < 2 * self.calib.residual_interval_s:
            raise CalibrationError(f'{self.name}: {log.duration_s:.1f} s of inputs; a '
                                   f'calibration needs at least two residual intervals '
                                   f'(2 x {self.calib.residual_interval_s:g} s)')
        firsts = []
        for name, (t, v) in thermocouples.items():
            early = v[t <= t[0] + START_WINDOW_S]
            firsts.append(float(np.mean(early)))
        # the median: robust to an oil volume that moves fast from the start
        log.start_C = float(np.median(firsts))
        spread = max(firsts) - min(firsts)
        if spread > START_SPREAD_K:
            log.warnings.append(
                f'{self.name}: the thermocouples first read {min(firsts):.1f} to '
                f'{max(firsts):.1f} degC; the model starts uniform at their median '
                f'{log.start_C:.1f} degC (the log did not start in equilibrium)')
        return log


def channel_ranges(cfg: Config) -> Dict[str, Tuple[float, float]]:
    """Return the plausible range of every input channel of a configuration."""
    channels = cfg.estimator.channels
    return {f.name: (getattr(channels, f.name).low, getattr(channels, f.name).high)
            for f in dataclasses.fields(channels)}


def file_digest(paths: Sequence[os.PathLike]) -> str:
    """Return the sha256 hex digest of files read one after another (a bag's, in order)."""
    h = hashlib.sha256()
    for path in paths:
        with open(path, 'rb') as f:
            for chunk in iter(lambda: f.read(1 << 20), b''):
                h.update(chunk)
    return h.hexdigest()


def plan_log(path: os.PathLike, config: tuple, mapping: Optional[Mapping[str, str]] = None):
    """
    Open a bag and choose its topics as a replay would; raise CalibrationError if unusable.

    ``config`` is the (configuration, source, text) of
    :func:`~.replay.choose_config`, one for all logs. Reads only the bag's
    summary: every log can be checked before any is read.
    """
    from .replay import plan_replay, ReplayError

    try:
        plan = plan_replay(path, mapping=mapping, config=config)
    except ReplayError as exc:
        raise CalibrationError(str(exc)) from None
    info = plan.info
    for name, topic in (mapping or {}).items():
        if topic not in info.topics:
            raise CalibrationError(f'{info.path}: --map {name}={topic}: no such topic in the '
                                   'bag')
    if not plan.thermocouples:
        raise CalibrationError(f'{info.path}: no thermocouple topics (sensor_msgs/Temperature '
                               f'on {topics.MEASURED_PREFIX}/<name>, names '
                               f'{", ".join(CHANNELS)}); map them with --map '
                               'measured/<name>=/topic')
    return plan


def read_log(plan, calib: Calibration, path: Optional[os.PathLike] = None) -> LogData:
    """Read a planned bag (:func:`plan_log`) into a :class:`LogData`, chunk by chunk."""
    from .bag.reader import BagError, iter_column_blocks

    info = plan.info
    h_ns = int(round(1e9 / calib.average_rate_Hz))
    origin_ns = info.start_time_ns - h_ns
    builder = LogBuilder(info.path.name, list(plan.inputs), calib, channel_ranges(plan.cfg))
    try:
        for block in iter_column_blocks(info.path, plan.specs):
            samples = plan.route(block, origin_ns)
            for name, (t, v) in samples.inputs.items():
                builder.add_input(name, t, v)
            for name, (t, v, variance) in samples.thermocouples.items():
                builder.add_thermocouple(name, t, v, variance)
            builder.add_ambient(*samples.ambient)
    except BagError as exc:
        raise CalibrationError(str(exc)) from None
    log = builder.build(plan.cfg.estimator.pressure_inputs, plan.missing,
                        path=str(path if path is not None else info.path),
                        size_bytes=sum(os.path.getsize(f) for f in info.files),
                        sha256=file_digest(info.files))
    if info.truncated:
        log.warnings.append(f'{info.path.name} is truncated ({info.problem}): used what could '
                            'be read')
    if plan.missing:
        log.warnings.append(f'{info.path.name}: no topic for {", ".join(plan.missing)}: on '
                            'its fallback all along')
    return log


def load_log(path: os.PathLike, config: tuple, calib: Calibration,
             mapping: Optional[Mapping[str, str]] = None) -> LogData:
    """Plan and read a bag into a :class:`LogData`; raise CalibrationError when unusable."""
    return read_log(plan_log(path, config, mapping), calib, path)


# ---------------------------------------------------------------- the model
def run_config(cfg: Config, log: LogData) -> Config:
    """Return the configuration a fit runs ``log`` with: its step, grid and inputs, open-loop."""
    c = cfg.calibration
    values = {'estimator.step_s': c.step_s, 'estimator.block_rate_Hz': c.average_rate_Hz,
              'estimator.pressure_inputs': log.pressure_inputs}
    correction = getattr(cfg.estimator, 'correction', None)
    if getattr(correction, 'enabled', False):
        values['estimator.correction.enabled'] = False
    return with_values(cfg, values)


def simulate(log: LogData, cfg: Config,
             start_offset_K: float = 0.0) -> Tuple[np.ndarray, np.ndarray]:
    """
    Run the estimator open-loop over a log; return step-end stamps and temperatures (degC).

    ``cfg`` is a :func:`run_config`. The columns are the estimates of
    :data:`CHANNELS`; the model starts uniform at ``log.start_C`` plus
    ``start_offset_K``.
    """
    est = Estimator(cfg)
    names = [THERMOCOUPLES[c] for c in CHANNELS]
    feed = {n: log.inputs[n] for n in est.inputs if n in log.inputs}
    amb_t, amb_v = log.ambient
    t_end = max(t[-1] for t, _ in feed.values())
    edges = np.arange(AMBIENT_SEGMENT_S, t_end + AMBIENT_SEGMENT_S, AMBIENT_SEGMENT_S)
    seg_of = np.searchsorted(edges, amb_t, side='left')
    stamps: List[float] = []
    rows: List[List[float]] = []

    def advance() -> None:
        for e in est.advance_all():
            stamps.append(e.stamp_s)
            temps = e.temperatures_C
            rows.append([temps[n] for n in names])

    # the model starts at the starting temperature: the estimator starts its model at
    # its ambient, so that is set to it first, and to the ambient once started
    est.add_ambient(0.0, log.start_C + start_offset_K)
    cursor = dict.fromkeys(feed, 0)
    for n, (t, v) in feed.items():
        est.add_many(n, t[:1], v[:1])
        cursor[n] = 1
    advance()
    for k, edge in enumerate(edges):
        here = amb_v[seg_of == k]
        last = int(np.searchsorted(amb_t, edge, side='right')) - 1     # latest reading so far
        ambient = float(np.mean(here)) if here.size else (
            float(amb_v[last]) if last >= 0 else cfg.estimator.ambient_C)
        est.add_ambient(edge - AMBIENT_SEGMENT_S, ambient)
        for n, (t, v) in feed.items():
            hi = int(np.searchsorted(t, edge, side='right'))
            if hi > cursor[n]:
                est.add_many(n, t[cursor[n]:hi], v[cursor[n]:hi])
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
    from .replay import error_stats

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


# ------------------------------------------------------------ parallel runs
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
        t, y = simulate(log, cfg, offset)
    except (ArithmeticError, ValueError, RuntimeError) as exc:
        # reported by the parent as one line, with the values that failed
        return vi, li, None, f'{type(exc).__name__}: {exc}', time.perf_counter() - t0
    return vi, li, t, y, time.perf_counter() - t0


def _evaluate(task: tuple) -> tuple:
    """Run one task on the logs the forked workers inherited (or inline)."""
    li = task[1]
    return evaluate_run(_WORKER['logs'][li], _WORKER['cfgs'][li], _WORKER['keys'], task)


class Evaluator:
    """
    Run parameter sets over logs: inline, in ``jobs`` forked processes, or on a Dask client.

    With ``client`` (a ``distributed.Client``), the logs and their
    configurations are sent to every worker once; each task then carries
    only its parameter values.
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
        if jobs > 1 and 'fork' in multiprocessing.get_all_start_methods():
            self.pool = multiprocessing.get_context('fork').Pool(jobs)

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
            from distributed import as_completed
            logs, cfgs = self.remote
            futures = [self.client.submit(evaluate_run, logs[task[1]], cfgs[task[1]], self.keys,
                                          task, pure=False) for task in tasks]
            results = (f.result() for f in as_completed(futures))
        elif self.pool is not None:
            results = self.pool.imap_unordered(_evaluate, tasks, chunksize=1)
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
        finally:
            if futures:       # after a failed run, the ones still queued would run for nothing
                self.client.cancel(futures)
        return out

    def close(self) -> None:
        """Stop the workers (a Dask client's are left to its owner)."""
        if self.pool is not None:
            self.pool.terminate()
            self.pool.join()
            self.pool = None
        if self.client is not None:
            self.client.cancel([f for part in self.remote for f in part])
        _WORKER.clear()


# ------------------------------------------------------------- the fit
@dataclass
class ParameterFit:
    """One parameter: bounds, nominal and fitted value, interval, identifiability."""

    key: str
    low: float
    high: float
    nominal: float
    value: float
    ci95: Optional[Tuple[float, float]] = None   # statistical, widened by the step shift
    identifiable: bool = True
    note: str = ''
    effect_K: float = math.nan          # largest RMS change of a reading across the bounds
    collinearity: float = math.nan      # 1 / sine of its effect's angle to the others'
    step_shift: float = 0.0             # the change a finer step implies (linearised)

    @property
    def span(self) -> float:
        """Return the width of the bounds."""
        return self.high - self.low

    def record(self) -> dict:
        """Return the configuration's record of this parameter (a CalibratedParameter)."""
        low, high = self.ci95 if self.ci95 is not None else (None, None)
        return {'key': self.key, 'nominal': self.nominal, 'value': self.value,
                'ci95_low': low, 'ci95_high': high, 'identifiable': self.identifiable,
                'step_shift': self.step_shift, 'note': self.note}


@dataclass
class LogFit:
    """One log's model runs (nominal, calibrated) and errors against its thermocouples."""

    log: LogData
    role: str                                  # 'fit' or 'validate'
    t_model: np.ndarray
    nominal_C: np.ndarray                      # lagged model, one row per step
    calibrated_C: np.ndarray
    windows: Windows
    start_offset_before_K: float = 0.0         # fitted to the starting temperature
    start_offset_after_K: float = 0.0
    before: Dict[str, dict] = field(default_factory=dict)
    after: Dict[str, dict] = field(default_factory=dict)


@dataclass
class CalibrationRun:
    """Everything a calibration found, for the report and the calibrated configuration."""

    base_cfg: Config
    config_source: str
    parameters: List[ParameterFit]
    logs: List[LogFit]
    calibrated_cfg: Config
    evaluations: int = 0                       # model runs of whole logs
    iterations: int = 0
    fit_s: float = 0.0
    read_s: float = 0.0
    rms_before_K: float = math.nan             # fit logs, window means, all channels
    rms_after_K: float = math.nan
    n_eff: float = math.nan
    n_residuals: int = 0
    messages: List[str] = field(default_factory=list)

    @property
    def fitted(self) -> List[ParameterFit]:
        """Return the parameters that were fitted."""
        return [p for p in self.parameters if p.identifiable]


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


def lagged_run(run: tuple, calib: Calibration) -> Tuple[np.ndarray, np.ndarray]:
    """Return a model run (stamps, temperatures) as the lagged thermocouples would read it."""
    t, y = run
    return t, lagged(y, calib.step_s, calib.thermocouple_lag_s)


def _window_errors(lf: LogFit, which: str) -> np.ndarray:
    """Return the window-mean errors (K) of all channels of a log, nominal or calibrated."""
    y = lf.nominal_C if which == 'nominal' else lf.calibrated_C
    means = window_means(lf.windows, lf.t_model, y)
    parts = [means[c] - m for c, m in zip(lf.windows.channels, lf.windows.measured)]
    return np.nan_to_num(np.concatenate(parts)) if parts else np.zeros(0)


def result_record(run: CalibrationRun) -> CalibrationResult:
    """Return the record of a calibration for the calibrated configuration, validated."""
    logs = [{'path': lf.log.path or lf.log.name, 'role': lf.role,
             'size_bytes': int(lf.log.size_bytes), 'sha256': lf.log.sha256,
             'duration_s': round(float(lf.log.duration_s), 3)} for lf in run.logs]
    record = {
        'created_utc': datetime.datetime.now(datetime.timezone.utc).isoformat(
            timespec='seconds'),
        'base_config': run.config_source, 'step_s': run.base_cfg.calibration.step_s,
        'parameters': [_plain(p.record()) for p in run.parameters], 'logs': logs,
        'fit_rms_before_K': round(run.rms_before_K, 4),
        'fit_rms_after_K': round(run.rms_after_K, 4)}
    return from_dict(CalibrationResult, record, 'calibration.result')


def _plain(x):
    """Return ``x`` with numpy scalars as Python numbers, tuples as lists (for YAML)."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x)
    return x


# ---------------------------------------------------------------- outputs
def config_yaml(cfg: Config, header: str = '') -> str:
    """Return ``cfg`` as YAML that :func:`~.config.load_config` reads back to an equal config."""
    import yaml

    text = yaml.safe_dump(_plain(dataclasses.asdict(cfg)), sort_keys=False,
                          default_flow_style=None, width=99)
    back = config_from_yaml(text, 'the calibrated configuration')
    if back != cfg:
        raise ConfigError('the calibrated configuration does not read back as written')
    lines = ''.join(f'# {line}'.rstrip() + '\n' for line in header.splitlines())
    return lines + text


def write_outputs(run: CalibrationRun, out_dir: Path, command: str = '') -> List[Path]:
    """
    Write the plots, ``report.md`` and ``calibrated.yaml`` (last); return their paths.

    Every file is written under a ``.partial`` name and renamed when complete;
    the report and the configuration of an earlier run are removed first, so a
    folder with ``calibrated.yaml`` holds one complete calibration.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    for name in (CALIBRATED_YAML, 'report.md'):
        (out_dir / name).unlink(missing_ok=True)
    images = write_plots(run, out_dir)
    report = write_text(out_dir / 'report.md', report_text(run, images, command))
    fitted = ', '.join(f'{p.key} = {p.value:.6g}' for p in run.fitted) or 'nothing'
    created = run.calibrated_cfg.calibration.result.created_utc
    header = (f'Calibrated by wet-eha-thermal calibrate, {created}\nfrom {run.config_source}.'
              f'\nFitted: {fitted}.\n'
              'calibration.result records each fitted value with its 95 % interval, what was '
              'not identifiable,\nand the logs used. Load it as any configuration (--config).')
    if command:
        header += f'\nCommand: {command}'
    path = write_text(out_dir / CALIBRATED_YAML, config_yaml(run.calibrated_cfg, header))
    return images + [report, path]


def _stem(run: CalibrationRun, k: int) -> str:
    names = [Path(lf.log.name).stem for lf in run.logs]
    stem = names[k]
    return stem if names.count(stem) == 1 else f'{k + 1}_{stem}'


def write_plots(run: CalibrationRun, out_dir: Path) -> List[Path]:
    """Write one PNG per log: measured, nominal and calibrated per thermocouple, and errors."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    images = []
    for k, lf in enumerate(run.logs):
        w = lf.windows
        n = len(w.channels)
        fig, axes = plt.subplots(n, 2, figsize=(12, 1.9 * n + 1.0), sharex=True, squeeze=False)
        t0 = lf.t_model[0]
        centres = 0.5 * (w.edges[1:] + w.edges[:-1])
        nom = window_means(w, lf.t_model, lf.nominal_C)
        cal = window_means(w, lf.t_model, lf.calibrated_C)
        for row, (c, idx, meas) in enumerate(zip(w.channels, w.index, w.measured)):
            col = CHANNELS.index(c)
            tm = (centres[idx] - t0) / 60.0
            ax = axes[row, 0]
            ax.plot(tm, meas, '.', ms=2.5, color='k', label='thermocouple')
            ax.plot((lf.t_model - t0) / 60.0, lf.nominal_C[:, col], lw=0.9, color='tab:blue',
                    label='nominal')
            ax.plot((lf.t_model - t0) / 60.0, lf.calibrated_C[:, col], lw=0.9,
                    color='tab:red', label='calibrated')
            ax.set_ylabel(f'{c}\n[degC]', fontsize=8)
            ax.grid(alpha=0.3)
            ax = axes[row, 1]
            ax.plot(tm, nom[c] - meas, lw=0.9, color='tab:blue', label='nominal')
            ax.plot(tm, cal[c] - meas, lw=0.9, color='tab:red', label='calibrated')
            ax.axhline(0.0, color='k', lw=0.5)
            ax.set_ylabel('model - tc [K]', fontsize=8)
            ax.grid(alpha=0.3)
        axes[0, 0].legend(fontsize=7)
        axes[0, 1].legend(fontsize=7)
        axes[-1, 0].set_xlabel('time [min]')
        axes[-1, 1].set_xlabel('time [min]')
        fig.suptitle(f'{lf.log.name} ({"fit" if lf.role == "fit" else "held out"}): '
                     f'{run.base_cfg.calibration.residual_interval_s:g} s means')
        images.append(save_figure(fig, out_dir / f'{_stem(run, k)}.png'))
    return images


def _fmt(x: float, digits: int = 4) -> str:
    return f'{x:.{digits}g}' if math.isfinite(x) else '-'


def error_table(lf: LogFit) -> List[str]:
    """Return a markdown table of a log's errors per thermocouple, before and after."""
    def row(c: str) -> tuple:
        before, after = lf.before[c], lf.after[c]
        return (c, before['estimate'], f'{before["max_abs_K"]:.2f}', f'{before["rms_K"]:.2f}',
                f'{before["bias_K"]:+.2f}', f'{after["max_abs_K"]:.2f}',
                f'{after["rms_K"]:.2f}', f'{after["bias_K"]:+.2f}',
                f'{after["max_abs_raw_K"]:.2f}')

    return markdown_table(('thermocouple', 'estimate', 'before: max abs', 'RMS', 'bias',
                           'after: max abs', 'RMS', 'bias', 'after, max abs of single readings'),
                          (row(c) for c in lf.windows.channels))


def report_text(run: CalibrationRun, images: Sequence[Path], command: str = '') -> str:
    """Return report.md: parameters, identifiability, errors before and after, plots."""
    c = run.base_cfg.calibration
    lines = ['# Calibration of the thermal model', '']
    if command:
        lines += [f'Command: `{command}`', '']
    lines += [f'- base configuration: {run.config_source}',
              f'- model step {c.step_s:g} s on inputs averaged at {c.average_rate_Hz:g} Hz; '
              f'thermocouples compared as {c.residual_interval_s:g} s means, lag '
              f'{c.thermocouple_lag_s:g} s applied to the model',
              f'- {run.evaluations} model runs of whole logs, {run.iterations} iterations; '
              f'wall time: reading {run.read_s:.1f} s, fit {run.fit_s:.1f} s',
              f'- fit logs, all thermocouples: RMS error {run.rms_before_K:.3f} K nominal, '
              f'{run.rms_after_K:.3f} K calibrated; {run.n_residuals} residuals, '
              f'{run.n_eff:.0f} effectively independent', '']
    lines += markdown_table(
        ('log', 'role', 'duration', 'size', 'sha256', 'start (readings)', 'start offset fitted'),
        ((lf.log.path or lf.log.name, lf.role, f'{lf.log.duration_s:.0f} s',
          f'{lf.log.size_bytes} B', lf.log.sha256[:16] or '(in memory)',
          f'{lf.log.start_C:.2f} degC',
          f'{lf.start_offset_after_K:+.2f} K' if lf.role == 'fit' else '-')
         for lf in run.logs))
    lines += ['', '## Parameters', '']
    lines += markdown_table(
        ('key', 'bounds', 'nominal', 'calibrated', '95 % interval', 'step shift', 'identifiable',
         'largest effect across the bounds', 'collinearity index', 'note'),
        ((p.key, f'{p.low:.4g} .. {p.high:.4g}', f'{p.nominal:.4g}', f'{p.value:.4g}',
          f'{p.ci95[0]:.4g} .. {p.ci95[1]:.4g}' if p.ci95 else '-',
          f'{p.step_shift:+.3g}' if p.identifiable and c.check_step_s else '-',
          'yes' if p.identifiable else '**no**', f'{_fmt(p.effect_K, 3)} K',
          _fmt(p.collinearity, 3), p.note) for p in run.parameters))
    check = (f'plus the step shift: the change of the parameter that the fitted model run once '
             f'at a {c.check_step_s:g} s step implies (linearised), for the error of the fit '
             f'step itself' if c.check_step_s else 'no step check (check_step_s: 0): the '
             'intervals do not cover the error of the fit step itself')
    lines += ['', 'Identifiability: before the fit, a parameter is held at its nominal value '
              f'when moving it across its bounds changes no thermocouple by {c.min_effect_K:g} '
              'K RMS, or when its effect is nearly a combination of those of parameters with '
              f'larger effects (collinearity index above {c.max_collinearity:g}); after the '
              f'fit, when its 95 % interval spans more than {100 * c.max_ci_fraction:.0f} % of '
              'its bounds.', '',
              'Intervals: 1.96 sigma from s^2 (J^T J)^-1, s^2 the mean square of the weighted '
              'residuals, inflated by n / n_eff: the residuals are autocorrelated, and each '
              "series (a log's thermocouple) counts its length over its integrated "
              f"autocorrelation time; {check}. They assume the model's structure otherwise.",
              '', 'Assumptions: each log starts in thermal equilibrium at the median of its '
              "thermocouples' first readings; the fit also fits a uniform offset of that "
              'start for each fit log (a nuisance parameter, table above), while the errors '
              "below use the readings' start, as the estimator would; the ambient of each "
              'minute is the mean of its readings; the model runs open-loop.']
    if run.messages:
        lines += ['', '## Warnings', ''] + [f'- {m}' for m in run.messages]
    for role, title in (('fit', 'Fit logs'), ('validate', 'Held-out logs')):
        chosen = [lf for lf in run.logs if lf.role == role]
        if not chosen:
            continue
        lines += ['', f'## {title}: model minus thermocouple (K), before (nominal) and after '
                  '(calibrated)', '',
                  f'Over {c.residual_interval_s:g} s means of the readings; the last column '
                  'compares every single reading (its noise included).']
        for lf in chosen:
            lines += ['', f'### {lf.log.name}', ''] + error_table(lf)
    lines += ['', '## Plots', ''] + [f'![{p.stem}]({p.name})' for p in images]
    return '\n'.join(lines) + '\n'


# ----------------------------------------------------------- in memory
def log_from_rig(rig, seconds: float, calib: Calibration, name: str = 'rig',
                 thermocouple_rate_Hz: float = 1.0) -> LogData:
    """
    Record ``seconds`` of a :class:`~.simulated_rig.SimulatedRig` straight into a LogData.

    The same averaging as a bag gets, without writing one (tests, studies).
    """
    from .simulated_rig import THERMOCOUPLE_SIGMA_K

    builder = LogBuilder(name, rig.inputs, calib, channel_ranges(rig.cfg))
    h = 1.0 / calib.average_rate_Hz
    tcs: Dict[str, Tuple[list, list]] = {c: ([], []) for c in CHANNELS}
    amb: Tuple[list, list] = ([], [])
    chunk: Dict[str, list] = {n: [] for n in ['t_s'] + list(rig.inputs)}
    for k, n_blocks, block, readings, ambient in rig.run(seconds, thermocouple_rate_Hz):
        for n in chunk:
            chunk[n].append(block[n])
        t_end = float(block['t_s'][-1]) + h
        if readings is not None:
            for c, v in readings.items():
                tcs[c][0].append(t_end)
                tcs[c][1].append(v)
        if ambient is not None:
            amb[0].append(t_end)
            amb[1].append(ambient)
        if len(chunk['t_s']) >= 500 or k == n_blocks - 1:
            t = np.concatenate(chunk['t_s']) + h     # the origin one interval before
            for n in rig.inputs:
                builder.add_input(n, t, np.concatenate(chunk[n]))
            chunk = {n: [] for n in chunk}
    sigma = THERMOCOUPLE_SIGMA_K if rig.noise else 0.0
    for c, (t, v) in tcs.items():
        builder.add_thermocouple(c, np.array(t), np.array(v), np.full(len(t), sigma ** 2))
    builder.add_ambient(np.array(amb[0]), np.array(amb[1]))
    return builder.build(rig.cfg.estimator.pressure_inputs)
