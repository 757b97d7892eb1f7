"""
Logs: a bag read once into memory, its inputs averaged onto the fit's grid.

:func:`plan_log` chooses a bag's topics as a replay does and checks it before
anything is read; :func:`read_log` routes its samples as a replay does
(:meth:`~wet_eha_thermal.offline.replay.ReplayPlan.route`, the same stamps) into a
:class:`LogBuilder`, which averages the inputs (:class:`InputAverager`), keeps
the thermocouple and ambient readings raw and takes the starting temperature
from the thermocouples' first readings: a :class:`LogData`. :func:`log_from_rig`
builds one from a simulated rig without a bag.
"""

import dataclasses
from dataclasses import dataclass, field
import hashlib
import math
import os
from typing import Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from .. import interface
from ..config import Calibration, Config
from ..interface import THERMOCOUPLES

#: A log whose thermocouples first read further apart than this (K) did not start in equilibrium.
START_SPREAD_K = 2.0
#: Readings averaged per thermocouple for the starting temperature (s from its first one):
#: short, as the oil of a loaded rig heats by tenths of a kelvin in its first second.
START_WINDOW_S = 0.5
#: Estimates of the thermocouples, in THERMOCOUPLES order.
CHANNELS = tuple(THERMOCOUPLES)


class CalibrationError(ValueError):
    """Input that cannot be calibrated on (a log, a key, a mapping); the message says why."""


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
                                   f'Temperature on {interface.MEASURED_PREFIX}/<name>, names '
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


def log_from_rig(rig, seconds: float, calib: Calibration, name: str = 'rig',
                 thermocouple_rate_Hz: float = 1.0):
    """
    Record ``seconds`` of a :class:`SimulatedRig` straight into a calibration's LogData.

    The same averaging as a bag gets, without writing one (tests, studies).
    """
    # here, not at the top: the rig's ROS node imports this module and has no use for the
    # calibration package
    from ..calibration.logs import channel_ranges, CHANNELS, LogBuilder

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
    sigma = rig.thermocouple_sigma_K
    for c, (t, v) in tcs.items():
        builder.add_thermocouple(c, np.array(t), np.array(v), np.full(len(t), sigma ** 2))
    builder.add_ambient(np.array(amb[0]), np.array(amb[1]))
    return builder.build(rig.cfg.estimator.pressure_inputs)


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
    :func:`~wet_eha_thermal.offline.replay.choose_config`, one for all logs. Reads only the bag's
    summary: every log can be checked before any is read.
    """
    # the replay's topic plan: a log is read as a replay of it would read it
    from ..offline.replay import plan_replay, ReplayError

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
                               f'on {interface.MEASURED_PREFIX}/<name>, names '
                               f'{", ".join(CHANNELS)}); map them with --map '
                               'measured/<name>=/topic')
    return plan


def read_log(plan, calib: Calibration, path: Optional[os.PathLike] = None) -> LogData:
    """Read a planned bag (:func:`plan_log`) into a :class:`LogData`, chunk by chunk."""
    from ..bag.reader import BagError, iter_column_blocks

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
