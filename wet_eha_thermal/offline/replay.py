"""
Offline replay of recorded runs through the estimator: no ROS graph, sample time, full speed.

A bag (rosbag2-style MCAP: ours, or ``ros2 bag record -s mcap`` with the same
message types) is read in blocks of decoded columns
(:func:`~wet_eha_thermal.bag.reader.iter_column_blocks`), so memory stays flat
however long the log. Each block's samples go to the estimator core with the
stamps the live estimator used: the header stamp of a FluidPressure (the log
time when it is zero) and the log (receive) time of a Float64, which has no
header. The core steps in sample time, so a replay gives the estimates of the
live run up to the difference between the recorder's and the estimator's
receive times of the stamp-less inputs.

The topics that feed each input are the live defaults (:mod:`.interface`)
unless mapped otherwise; thermocouples (``/eha/measured/<name>``) are compared
with the estimate each one measures. The configuration is, in this order, the
one given, the one the recorder stored in the bag, or the shipped reference
rig.

The estimator works on its outlook inline, as the live one does in the
background: at the same sample times, from the same states, the same current
limits for the drive (every ``estimator.limits.period_s``), forecast and
margin; ``outlook=False`` (``--no-outlook``) skips them for speed.

Outputs go to one folder, each written under a ``.partial`` name and renamed
when complete: ``estimates.csv`` and ``estimates.mcap`` at ``output_rate_Hz``
(the MCAP with every tick's limits on the live node's topics),
``limits.csv`` (one row per tick), and with :func:`write_report` the plots
and ``report.md``.
"""

import csv
import dataclasses
from dataclasses import dataclass, field
import math
import os
from pathlib import Path
import time
from typing import Callable, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from .. import interface
from ..bag.reader import BagError, BagInfo, Columns, iter_column_blocks, open_bag
from ..config import (Config, config_from_yaml, ConfigError, default_config_path, load_config,
                      with_values)
from ..estimator.core import Estimate, Estimator
from ..estimator.intake import INPUTS, sensor_inputs
from ..estimator.limits import CurrentLimits
from ..model import quantity_table
from ..output_files import atomic, markdown_table, pyplot, save_figure, write_text

#: Estimates written to the outputs (degC), in column order.
OUTPUT_ESTIMATES = interface.ESTIMATES


class ReplayError(ValueError):
    """A bag or a topic mapping that cannot be replayed; the message says why."""


@dataclass
class Samples:
    """One block of a bag by what it feeds: stamps (s) and values, in SI units and degC."""

    inputs: Dict[str, Tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    # stamps, readings (degC) and the variances the messages give (K^2)
    thermocouples: Dict[str, Tuple[np.ndarray, np.ndarray, np.ndarray]] = field(
        default_factory=dict)
    ambient: Tuple[np.ndarray, np.ndarray] = (np.zeros(0), np.zeros(0))
    first_s: Optional[float] = None            # the earliest stamp of the block


@dataclass
class ReplayPlan:
    """What feeds what: the configuration and the topic of every input and thermocouple."""

    cfg: Config
    config_source: str
    config_yaml: str                       # the file's text (before a pressure-input switch)
    inputs: Dict[str, str]                 # estimator input -> topic (found in the bag)
    missing: List[str]                     # inputs with no topic in the bag: on fallback
    thermocouples: Dict[str, str]          # thermocouple name -> topic
    ambient: Optional[str]
    info: BagInfo

    @property
    def specs(self) -> Dict[str, str]:
        """Return topic -> message type of every topic to decode."""
        specs = {topic: interface.INPUT_TYPES[name] for name, topic in self.inputs.items()}
        specs.update({topic: interface.TEMPERATURE for topic in self.thermocouples.values()})
        if self.ambient is not None:
            specs[self.ambient] = interface.TEMPERATURE
        return specs

    def route(self, block: Dict[str, Columns], origin_ns: int = 0) -> Samples:
        """
        Return a block of decoded columns (:func:`iter_column_blocks`) by what each topic feeds.

        Stamps are seconds from ``origin_ns``. Every name mapped to a topic
        gets its samples; thermocouples in the order of the block's topics.
        """
        samples = Samples()
        for topic, columns in block.items():
            if not len(columns):
                continue
            t = (columns.time_ns - origin_ns).astype(np.float64) * 1e-9
            samples.first_s = float(t[0]) if samples.first_s is None \
                else min(samples.first_s, float(t[0]))
            for name, input_topic in self.inputs.items():
                if input_topic == topic:
                    samples.inputs[name] = (t, next(iter(columns.values.values())))
            if topic == self.ambient:
                samples.ambient = (t, columns.values['temperature'])
            for tc, tc_topic in self.thermocouples.items():
                if tc_topic == topic:
                    samples.thermocouples[tc] = (t, columns.values['temperature'],
                                                 columns.values['variance'])
        return samples


def choose_config(info: BagInfo, config_path: Optional[os.PathLike]) -> tuple:
    """Return (configuration, where it came from, its YAML text): given, stored, or shipped."""
    if config_path is not None:
        cfg = load_config(config_path)        # a ConfigError names an unreadable file
        return cfg, str(config_path), Path(config_path).read_text()
    stored = info.metadata.get(interface.CONFIG_METADATA, {}).get(interface.CONFIG_METADATA_KEY)
    if stored:
        try:
            cfg = config_from_yaml(stored, f'{info.path} (stored configuration)')
        except ConfigError as exc:
            # a bag outlives the model it was recorded with: its configuration may lack what
            # a later model needs (or hold what it dropped)
            raise ConfigError(f'{exc}; the configuration stored in the bag does not fit this '
                              'version of the model (recorded by an older one?): replay it '
                              'with --config YOUR_RIG.yaml') from exc
        return cfg, f'stored in {info.path.name}', stored
    return load_config(None), 'shipped reference_eha.yaml (the bag stores none)', \
        default_config_path().read_text()


def _match_pressure_inputs(cfg: Config, wanted, source: str, info: BagInfo,
                           mapping: Mapping[str, str]) -> tuple:
    """Switch between three pressures and one differential when the bag holds only the other."""
    def present(names):
        return any(mapping.get(n, interface.INPUT_TOPICS[n]) in info.topics for n in names)

    ports, differential = ('p_a_Pa', 'p_b_Pa', 'p_acc_Pa'), ('dp_Pa',)
    mine, other, mode = (ports, differential, 'differential') if 'p_a_Pa' in wanted else \
        (differential, ports, 'ports')
    if present(mine) or not present(other):
        return cfg, wanted, source
    cfg = dataclasses.replace(cfg, estimator=dataclasses.replace(cfg.estimator,
                                                                 pressure_inputs=mode))
    return cfg, sensor_inputs(cfg), f'{source}, with pressure_inputs: {mode} (what the bag holds)'


def plan_replay(path: os.PathLike, config_path: Optional[os.PathLike] = None,
                mapping: Optional[Mapping[str, str]] = None,
                config: Optional[tuple] = None) -> ReplayPlan:
    """
    Open a bag and decide which topics feed the estimator; raise ReplayError when none does.

    ``mapping`` maps input or thermocouple names (``current_A``, ...,
    ``measured/frame``, ``ambient``) to topics, replacing the defaults.
    ``config`` (a :func:`choose_config` tuple) is used instead of choosing one
    for this bag, e.g. one configuration for several bags.
    """
    try:
        info = open_bag(path)
    except BagError as exc:
        raise ReplayError(str(exc)) from exc
    cfg, source, text = config if config is not None else choose_config(info, config_path)
    mapping = dict(mapping or {})
    known = set(INPUTS) | {'dp_Pa', 'ambient'} | {f'measured/{tc}' for tc in
                                                  interface.THERMOCOUPLES}
    unknown = sorted(set(mapping) - known)
    if unknown:
        raise ReplayError(f'cannot map {unknown[0]!r}: the names are '
                          f'{", ".join(sorted(known))}')
    wanted = sensor_inputs(cfg)
    cfg, wanted, source = _match_pressure_inputs(cfg, wanted, source, info, mapping)
    inputs, missing = {}, []
    for name in wanted:
        topic = mapping.get(name, interface.INPUT_TOPICS[name])
        found = info.topics.get(topic)
        if found is None:
            missing.append(name)
            continue
        if found.type_name != interface.INPUT_TYPES[name]:
            raise ReplayError(f'{info.path}: topic {topic} (input {name}) holds '
                              f'{found.type_name}; expected {interface.INPUT_TYPES[name]}')
        inputs[name] = topic
    if not inputs:
        listing = ', '.join(f'{t} ({i.type_name})' for t, i in sorted(info.topics.items()))
        raise ReplayError(
            f'{info.path}: no topic of the mapping is in the bag (looked for '
            f'{", ".join(mapping.get(n, interface.INPUT_TOPICS[n]) for n in wanted)}); the bag '
            f'has: {listing or "no topics"}. Map them with --map name=/topic.')
    thermocouples = {}
    for tc in interface.THERMOCOUPLES:
        topic = mapping.get(f'measured/{tc}', f'{interface.MEASURED_PREFIX}/{tc}')
        found = info.topics.get(topic)
        if found is not None and found.type_name == interface.TEMPERATURE:
            thermocouples[tc] = topic
    amb = mapping.get('ambient', interface.AMBIENT_TOPIC)
    ambient = amb if (amb in info.topics
                      and info.topics[amb].type_name == interface.TEMPERATURE) else None
    return ReplayPlan(cfg=cfg, config_source=source, config_yaml=text, inputs=inputs,
                      missing=missing, thermocouples=thermocouples, ambient=ambient, info=info)


@dataclass
class ReplayOptions:
    """What a replay runs with besides its bag: the options of ``wet-eha-thermal replay``."""

    config_path: Optional[Path] = None
    mapping: Dict[str, str] = field(default_factory=dict)
    output_rate_Hz: float = 10.0
    report: bool = True
    open_loop: bool = False       # estimator.correction off: the thermocouples only compared
    outlook: bool = True          # the current limits, forecast and margin (off: faster)

    def plan(self, path: os.PathLike) -> ReplayPlan:
        """Return the :func:`plan_replay` of the bag ``path`` under these options."""
        plan = plan_replay(path, self.config_path, self.mapping)
        if self.open_loop:
            plan.cfg = with_values(plan.cfg, {'estimator.correction.enabled': False})
        return plan


@dataclass
class ReplayResult:
    """Estimates at the output rate, thermocouple series and the run's figures."""

    plan: ReplayPlan
    stamp_s: np.ndarray                      # estimate stamps (sample time, s)
    temperatures_C: Dict[str, np.ndarray]
    sigma_K: np.ndarray
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


def _feed(est: Estimator, samples: Samples, advance: Callable[[], None]) -> None:
    """Give one routed block to the estimator in stamp order, calling ``advance`` to step."""
    series, ambient = samples.inputs, samples.ambient
    for tc, (t, v, _) in samples.thermocouples.items():
        # for the live correction (and the display): each reading is used by stamp, so
        # the whole block may go in before the steps
        for stamp, value in zip(t.tolist(), v.tolist()):
            est.add_measured(tc, stamp, value)
    # an ambient reading applies from its stamp on, as it does live: feed the inputs
    # up to each reading, step, then take it
    cuts = {name: np.searchsorted(t, ambient[0], side='right')
            for name, (t, _) in series.items()}
    for k in range(ambient[0].size + 1):
        for name, (t, v) in series.items():
            lo = cuts[name][k - 1] if k else 0
            hi = cuts[name][k] if k < ambient[0].size else t.size
            if hi > lo:
                est.add_many(name, t[lo:hi], v[lo:hi])
        advance()
        if k < ambient[0].size:
            est.add_ambient(float(ambient[0][k]), float(ambient[1][k]))


def _correction_summary(est: Estimator) -> Optional[dict]:
    """Return the live correction's learned heats and thermocouple counters; None when off."""
    if est.correction is None:
        return None
    return {'active': est.correction.active, 'updates': est.correction.updates,
            'disturbance_W': dict(zip(est.correction.disturbance_names,
                                      est.correction.d.tolist())),
            'thermocouples': {tc: dict(vars(h)) for tc, h in est.correction.tcs.items()
                              if h.received}}


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


def replay(plan: ReplayPlan, output_rate_Hz: float = 10.0,
           on_progress: Optional[Callable[[float, float, float], None]] = None,
           plot_interval_s: float = 0.1, prefetch: bool = True,
           estimator: Optional[Estimator] = None, outlook: bool = True) -> ReplayResult:
    """
    Run the estimator over the bag of ``plan`` in sample time; return the estimates.

    Estimates are kept at ``output_rate_Hz`` (every step when it is at least
    the step rate). ``on_progress(fraction, sample_time_s, wall_s)`` is called
    after each block of about 10 s of log. ``prefetch``: read the bag in a
    forked child on another core (the same numbers either way; see
    :class:`~.bag.reader.ColumnBlocks`). ``outlook``: compute every tick's
    current limits, the forecast and the margin, inline (``False``: none).
    ``estimator``: the one to run (its own outlook, not ``outlook``), new on ``plan.cfg``
    by default, kept by the caller to start from its last state (a what-if
    from a bag).
    """
    est = estimator if estimator is not None else Estimator(
        plan.cfg, outlook='inline' if outlook else 'off')
    outlook = est.outlook_mode != 'off'       # a caller's estimator has its own
    limited = list(est.limits_C)
    current_limits: List[CurrentLimits] = []
    tick_current = _TickCurrent()
    step_s = plan.cfg.estimator.step_s
    every = max(1, int(round(1.0 / (output_rate_Hz * step_s))))
    rows: List[np.ndarray] = []
    events: List[tuple] = []
    measured = {tc: ([], []) for tc in plan.thermocouples}
    inputs_plot = {name: _Decimator(plot_interval_s) for name in plan.inputs}
    t_wall = time.perf_counter()
    first_s: Optional[float] = None
    size = max(os.path.getsize(plan.info.path), 1)
    done_bytes = [0]
    # the next block is read and decoded on the other core while the model steps
    blocks = iter_column_blocks(plan.info.path, plan.specs, prefetch=prefetch,
                                on_progress=lambda done, total: done_bytes.__setitem__(0, done))

    def advance() -> None:
        estimates = est.advance_all()
        # inline, a tick's limits are done within the step that made it
        ticks = {lim.stamp_s: lim for lim in est.outlook.take_limits()}
        current_limits.extend(ticks.values())
        for e in estimates:
            for ev in e.alert_events:
                events.append((e.stamp_s, ev.message))
            if outlook:
                tick_current.add(e, e.stamp_s in ticks)
            if e.step % every == 0:
                rows.append(np.array(
                    [e.stamp_s] + [e.temperatures_C[n] for n in OUTPUT_ESTIMATES]
                    + [max(e.uncertainty_K.values()), e.alert_level, len(e.stale)]
                    + (_outlook_row(e, limited) if outlook else [])))

    for block in blocks:
        samples = plan.route(block)
        if samples.first_s is not None:
            first_s = samples.first_s if first_s is None else min(first_s, samples.first_s)
        for name, (t, v) in samples.inputs.items():
            inputs_plot[name].add(t, v)
        for tc, (t, v, _) in samples.thermocouples.items():
            measured[tc][0].append(t)
            measured[tc][1].append(v)
        _feed(est, samples, advance)
        if on_progress is not None:
            wall = time.perf_counter() - t_wall
            t_model = (est.t_model - first_s) if est.t_model is not None and first_s else 0.0
            on_progress(done_bytes[0] / size, t_model, wall)
    wall = time.perf_counter() - t_wall
    if not rows:
        raise ReplayError(f'{plan.info.path}: not one model step could be made: the bag holds '
                          f'{blocks.message_count} messages of the mapped topics')
    table = np.vstack(rows)
    n = len(OUTPUT_ESTIMATES)
    ahead = table[:, 4 + n:]          # the outlook's columns (none when it is off)
    held_s, current_A = tick_current.in_force(step_s)
    return ReplayResult(
        plan=plan, stamp_s=table[:, 0],
        temperatures_C={name: table[:, 1 + k] for k, name in enumerate(OUTPUT_ESTIMATES)},
        sigma_K=table[:, 1 + n], alert_level=table[:, 2 + n].astype(int),
        stale_inputs=table[:, 3 + n].astype(int),
        measured={tc: (np.concatenate(t) if t else np.zeros(0),
                       np.concatenate(v) if v else np.zeros(0))
                  for tc, (t, v) in measured.items()},
        inputs={name: d.arrays() for name, d in inputs_plot.items()},
        alert_events=events, messages=blocks.message_count, steps=est.steps,
        sample_time_s=est.steps * step_s, wall_s=wall, truncated=blocks.truncated,
        problem=blocks.problem,
        health={name: dict(vars(h)) for name, h in est.health.items()},
        implausible=dict(est.implausible_counts), correction=_correction_summary(est),
        limits_C=dict(est.limits_C), outlook=outlook,
        time_to_limit_s={q: ahead[:, k] for k, q in enumerate(limited) if outlook},
        forecast_stamp_s=ahead[:, -2] if outlook else np.zeros(0),
        margin_current_A=ahead[:, -1] if outlook else np.zeros(0),
        current_limits=current_limits, limits_held_s=held_s, limits_current_A=current_A)


# ------------------------------------------------------------------ outputs
def write_csv(result: ReplayResult, path: Path) -> Path:
    """
    Write the estimates (degC) with stamps, uncertainty and alert level; return the path.

    With the outlook, also the latest forecast's time to each limit from its
    start (``inf``: beyond its horizon; ``nan``: no forecast yet), that start
    and the continuous current limit.
    """
    header = ['stamp_s'] + [f'{n}_C' for n in OUTPUT_ESTIMATES] + [
        'sigma_K', 'alert_level', 'inputs_on_fallback']
    columns = [result.stamp_s] + [result.temperatures_C[n] for n in OUTPUT_ESTIMATES] + [
        result.sigma_K, result.alert_level, result.stale_inputs]
    fmt = ['%.6f'] + ['%.4f'] * len(OUTPUT_ESTIMATES) + ['%.3f', '%d', '%d']
    if result.outlook:
        header += [f'time_to_limit_{q}_s' for q in result.time_to_limit_s] + [
            'forecast_stamp_s', 'margin_current_A']
        columns += list(result.time_to_limit_s.values()) + [result.forecast_stamp_s,
                                                            result.margin_current_A]
        fmt += ['%.1f'] * len(result.time_to_limit_s) + ['%.6f', '%.3f']
    table = np.column_stack(columns)
    with atomic(path) as tmp:
        np.savetxt(tmp, table, fmt=fmt, delimiter=',', header=','.join(header), comments='')
    return path


def write_limits_csv(result: ReplayResult, path: Path) -> Path:
    """
    Write every tick's current limits, one row each; return the path.

    Columns: the tick's stamp (sample time, s), the binding limit (A RMS),
    then for each limit (``continuous``, ``10s``, ...) its value (A RMS) and
    what binds it, the status, why it fell back, how long the limits were in
    force and the RMS current the log carried meanwhile. Values at full
    precision: a replay's limits are reproducible bit for bit.
    """
    names = result.current_limits[0].names if result.current_limits else ()
    header = ['stamp_s', 'binding_A'] + [c for name in names
                                         for c in (f'limit_{name}_A', f'binds_{name}')] + [
        'status', 'reason', 'held_s', 'current_rms_A']
    with atomic(path) as tmp, open(tmp, 'w', newline='') as f:
        writer = csv.writer(f)
        writer.writerow(header)
        for lim, held, current in zip(result.current_limits, result.limits_held_s.tolist(),
                                      result.limits_current_A.tolist()):
            writer.writerow([repr(lim.stamp_s), repr(lim.binding_A)]
                            + [c for v, b in zip(lim.limits_A, lim.binds) for c in (repr(v), b)]
                            + [lim.status, lim.reason, repr(held), repr(current)])
    return path


def write_mcap(result: ReplayResult, path: Path) -> Path:
    """
    Write the estimates as /eha/estimate/<name> Temperature messages, with the config.

    With the outlook, every tick's limits too, as the live estimator node
    publishes them: a JointState on CURRENT_LIMITS_TOPIC and the binding
    limit as a Float64 on CURRENT_LIMIT_TOPIC, logged at the tick's sample time.
    """
    from ..bag import cdr
    from ..bag.writer import BagWriter, offered_qos

    cfg_yaml = result.plan.config_yaml
    metadata = {interface.CONFIG_METADATA: {interface.CONFIG_METADATA_KEY: cfg_yaml,
                                            'source': result.plan.config_source}}
    stamps_ns = np.round(result.stamp_s * 1e9).astype(np.int64)
    variance = result.sigma_K * result.sigma_K
    with atomic(path) as tmp, BagWriter(tmp, metadata=metadata, flush_interval_s=3600.0) as w:
        messages = []
        for name in OUTPUT_ESTIMATES:
            topic = f'{interface.ESTIMATE_PREFIX}/{name}'
            w.add_topic(topic, interface.TEMPERATURE, offered_qos(depth=10))
            messages.append((topic, cdr.encode_stamped(
                stamps_ns, 'eha', np.column_stack([result.temperatures_C[name], variance]))))
        w.add_topic(interface.ALERT_TOPIC, interface.STRING,
                    offered_qos(durability='transient_local', depth=1))
        for k, ns in enumerate(stamps_ns.tolist()):
            for topic, data in messages:
                w.write(topic, data[k], ns)
        for stamp, text in result.alert_events:
            w.write(interface.ALERT_TOPIC, cdr.encode_string(text), int(round(stamp * 1e9)))
        if result.outlook:
            # the live node's publishers: reliable, volatile, 10 deep
            w.add_topic(interface.CURRENT_LIMITS_TOPIC, interface.JOINT_STATE,
                        offered_qos(depth=10))
            w.add_topic(interface.CURRENT_LIMIT_TOPIC, interface.FLOAT64, offered_qos(depth=10))
        for lim in result.current_limits:
            ns = int(round(lim.stamp_s * 1e9))
            w.write(interface.CURRENT_LIMITS_TOPIC, cdr.encode_joint_state(
                ns, interface.limits_frame_id(lim.status, lim.reason), lim.names,
                lim.horizons_s, (), lim.limits_A), ns)
            w.write(interface.CURRENT_LIMIT_TOPIC, cdr.encode_float64(lim.binding_A), ns)
    return path


def write_outputs(result: ReplayResult, out_dir: Path, report: bool = True) -> List[Path]:
    """Write estimates.csv, estimates.mcap, limits.csv and the report; return the paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    files = [write_csv(result, out_dir / 'estimates.csv'),
             write_mcap(result, out_dir / 'estimates.mcap')]
    if result.outlook:
        files.append(write_limits_csv(result, out_dir / 'limits.csv'))
    if report:
        files.append(write_report(result, out_dir))
    return files


def thermocouple_errors(result: ReplayResult) -> Dict[str, dict]:
    """
    Return, per thermocouple, the error of its estimate (estimate - measured, K).

    The estimate is interpolated at the thermocouple's stamps inside the
    estimated span: max abs, RMS, bias (mean) and the count compared.
    """
    out = {}
    for tc, (t, v) in result.measured.items():
        est = result.temperatures_C[interface.THERMOCOUPLES[tc]]
        inside = (t >= result.stamp_s[0]) & (t <= result.stamp_s[-1])
        if not np.any(inside):
            continue
        err = np.interp(t[inside], result.stamp_s, est) - v[inside]
        out[tc] = {'estimate': interface.THERMOCOUPLES[tc], **error_stats(err),
                   't_s': t[inside], 'error_K': err}
    return out


def error_stats(err: np.ndarray) -> Dict[str, float]:
    """Return the count, max abs, RMS and bias (mean) of errors (K); NaN for none."""
    if not err.size:
        return {'n': 0, 'max_abs_K': math.nan, 'rms_K': math.nan, 'bias_K': math.nan}
    return {'n': int(err.size), 'max_abs_K': float(np.max(np.abs(err))),
            'rms_K': float(np.sqrt(np.mean(err ** 2))), 'bias_K': float(np.mean(err))}


def write_report(result: ReplayResult, out_dir: Path) -> Path:
    """Write the PNG plots (inputs, temperatures, errors, alerts, limits) and report.md."""
    out_dir.mkdir(parents=True, exist_ok=True)
    errors = thermocouple_errors(result)
    images = _write_plots(result, errors, out_dir)
    lines = _summary_lines(result) + _temperature_lines(result) + _error_lines(errors) \
        + _health_lines(result) + _correction_lines(result.correction) + _limits_lines(result)
    lines += [''] + [f'![{p.stem}]({p.name})' for p in images]
    return write_text(out_dir / 'report.md', '\n'.join(lines) + '\n')


def _write_plots(result: ReplayResult, errors: Dict[str, dict], out_dir: Path) -> List[Path]:
    """Write the report's PNGs (errors.png with thermocouples, limits.png with limits)."""
    plt = pyplot()

    t0 = float(result.stamp_s[0])
    t_min = (result.stamp_s - t0) / 60.0
    images = [save_figure(_plot_inputs(plt, result, t0), out_dir / 'inputs.png'),
              save_figure(_plot_temperatures(plt, result, t0, t_min),
                          out_dir / 'temperatures.png')]
    if errors:
        images.append(save_figure(_plot_errors(plt, errors, t0), out_dir / 'errors.png'))
    images.append(save_figure(_plot_alerts(plt, result, t_min), out_dir / 'alerts.png'))
    if result.current_limits:
        images.append(save_figure(_plot_limits(plt, result, t0), out_dir / 'limits.png'))
    return images


def _plot_inputs(plt, result: ReplayResult, t0: float):
    """Return the figure of the inputs as replayed, one panel each."""
    fig, axes = plt.subplots(len(result.inputs), 1, figsize=(10, 1.8 * len(result.inputs) + 1),
                             sharex=True, squeeze=False)
    for ax, (name, (t, v)) in zip(axes[:, 0], result.inputs.items()):
        ax.plot((t - t0) / 60.0, v, lw=0.6)
        ax.set_ylabel(name, fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel('time since the first estimate [min]')
    fig.suptitle(f'inputs of {result.plan.info.path.name}')
    return fig


#: The estimates the temperature figure always shows (besides those a thermocouple measures)
PLOTTED_ESTIMATES = ('winding_hotspot', 'winding_mean', 'magnet', 'frame', 'pump_case', 'oil')


def _plot_temperatures(plt, result: ReplayResult, t0: float, t_min: np.ndarray):
    """
    Return a small multiple of the estimates: one panel each, sharing the time axis.

    A panel shows an estimate (line), the thermocouples that measure it (dots)
    and its limit (dashed) when the limit is within reach of the data; a
    limit out of reach is named in the panel's title instead.
    """
    measures = {}
    for tc, estimate in interface.THERMOCOUPLES.items():
        if tc in result.measured and result.measured[tc][0].size:
            measures.setdefault(estimate, []).append(tc)
    names = [n for n in OUTPUT_ESTIMATES if n in PLOTTED_ESTIMATES or n in measures]
    rows = math.ceil(len(names) / 2)
    fig, axes = plt.subplots(rows, 2, figsize=(10, 1.9 * rows + 0.6), sharex=True,
                             squeeze=False)
    limits = quantity_table.limits_C(result.plan.cfg)
    for ax, name in zip(axes.flat, names):
        estimate = result.temperatures_C[name]
        # the line over the dots: ten readings a second would hide it
        ax.plot(t_min, estimate, color='C0', lw=1.5, label='estimate', zorder=3)
        top = float(np.max(estimate))
        for tc in measures.get(name, []):
            t, v = result.measured[tc]
            ax.plot((t - t0) / 60.0, v, '.', color='C3', ms=1.5, alpha=0.6, label='thermocouple')
            top = max(top, float(np.max(v)))
        title = quantity_table.label(name)
        if name in measures:
            title += f' (thermocouple {", ".join(measures[name])})'
        if name in limits:
            value = limits[name]
            if value < 1.3 * top:
                ax.axhline(value, ls='--', lw=1.0, color='grey',
                           label=quantity_table.LIMIT_LABELS[name])
            else:
                title += f'; {quantity_table.LIMIT_LABELS[name]} {value:g} degC, off the scale'
        ax.set_title(title, fontsize=9, loc='left')
        ax.set_ylabel('degC', fontsize=8)
        ax.tick_params(labelsize=8)
        ax.grid(alpha=0.3)
    for ax in axes.flat[len(names):]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel('time since the first estimate [min]', fontsize=8)
    # one key for all panels, in the first that has every kind of line it needs
    keyed = next((ax for ax, n in zip(axes.flat, names) if n in measures), axes[0, 0])
    keyed.legend(fontsize=7, loc='best')
    return fig


def _plot_errors(plt, errors: Dict[str, dict], t0: float):
    """Return the figure of each thermocouple's estimate minus its readings."""
    fig, ax = plt.subplots(figsize=(10, 4))
    for tc, e in errors.items():
        ax.plot((e['t_s'] - t0) / 60.0, e['error_K'], lw=0.8,
                label=f'{e["estimate"]} - {tc}')
    ax.axhline(0.0, color='k', lw=0.5)
    ax.set_xlabel('time [min]')
    ax.set_ylabel('estimate - thermocouple [K]')
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    return fig


def _plot_alerts(plt, result: ReplayResult, t_min: np.ndarray):
    """Return the figure of the alert level over time."""
    fig, ax = plt.subplots(figsize=(10, 2.2))
    ax.step(t_min, result.alert_level, where='post')
    ax.set_yticks([0, 1, 2], ['OK', 'WARN', 'CRITICAL'])
    ax.set_xlabel('time [min]')
    ax.set_title('alert level')
    ax.grid(alpha=0.3)
    return fig


def _limit_table(result: ReplayResult) -> tuple:
    """Return the ticks' stamps (s), limits (A, ticks x limits) and fallback flags."""
    lims = result.current_limits
    return (np.array([lim.stamp_s for lim in lims]), np.array([lim.limits_A for lim in lims]),
            np.array([lim.status != 'ok' for lim in lims]))


def _runs(flags: np.ndarray) -> List[Tuple[int, int]]:
    """Return the [start, stop) index ranges where ``flags`` holds."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flags.astype(np.int8), [0]])))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def _plot_limits(plt, result: ReplayResult, t0: float):
    """
    Return the figure of the current limits over time, with the RMS current of the log.

    Each tick's limits hold until the next tick (steps); the binding one (the
    shortest horizon's) is thick, the fallback periods are shaded, and the
    RMS current of each period is drawn over them: where it rises above the
    binding limit, a drive applying that limit would have clamped it.
    """
    stamps, values, fallback = _limit_table(result)
    first = result.current_limits[0]
    period = result.plan.cfg.estimator.limits.period_s
    # each tick's limits (and the current under them) hold until the next: the last too
    t = (np.append(stamps, stamps[-1] + result.limits_held_s[-1]) - t0) / 60.0
    values = np.vstack([values, values[-1]])
    current = np.append(result.limits_current_A, result.limits_current_A[-1])
    fig, ax = plt.subplots(figsize=(10, 3.8))
    binding = int(np.argmin(first.horizons_s))
    others = iter(('C0', 'C2', 'C4', 'C1', 'C5', 'C6'))     # red is the binding one's
    for k, name in enumerate(first.names):
        if k == binding:
            # under the others: a limit equal to it (at the rating) stays visible on it
            style = {'color': 'C3', 'lw': 2.2, 'label': f'{name} (binding)', 'zorder': 1.5}
        elif math.isinf(first.horizons_s[k]):
            style = {'color': 'grey', 'lw': 1.0, 'ls': '--', 'label': name}
        else:
            style = {'color': next(others, 'C7'), 'lw': 1.0, 'label': name}
        ax.step(t, values[:, k], where='post', **style)
    ax.step(t, current, where='post', color='k', lw=0.8,
            label=f'RMS current over each {period:g} s', zorder=4)
    for k, (lo, hi) in enumerate(_runs(fallback)):
        ax.axvspan(t[lo], t[hi], color='orange', alpha=0.25, lw=0,
                   label='fallback' if k == 0 else None)
    ax.set_ylim(bottom=0.0)
    ax.set_xlabel('time since the first estimate [min]')
    ax.set_ylabel('A RMS')
    ax.set_title('current limits for the drive', fontsize=10, loc='left')
    ax.legend(fontsize=7, loc='upper left', bbox_to_anchor=(1.01, 1.0))
    ax.grid(alpha=0.3)
    return fig


def _limits_lines(result: ReplayResult) -> List[str]:
    """
    Return the report's section on the current limits for the drive.

    Per limit its lowest value, when, what bound it, and how long the RMS
    current (per tick period) was above it; the time on the fallback and why.
    Times are those the limits held (:attr:`ReplayResult.limits_held_s`).
    """
    lines = ['', '## Current limits for the drive', '']
    if not result.outlook:
        return lines + ['Not computed (`--no-outlook`).']
    if not result.current_limits:
        return lines + ['The log ends before the first limit tick.']
    lim_cfg = result.plan.cfg.estimator.limits
    stamps, values, fallback = _limit_table(result)
    t0 = float(result.stamp_s[0])
    first = result.current_limits[0]
    binding = int(np.argmin(first.horizons_s))
    lines += [f'{len(stamps)} ticks, one every {lim_cfg.period_s:g} s of sample time, each at '
              f'the estimate + {lim_cfg.k_sigma:g} sigma, as the live estimator publishes them '
              f'on `{interface.CURRENT_LIMITS_TOPIC}` (all in `limits.csv`). "Current above": '
              f'the time the RMS current over a tick period exceeded the limit of its tick; '
              f'above the binding ({first.names[binding]}) limit, a drive applying it would '
              f'have clamped the current.', '']
    held = result.limits_held_s
    rows = []
    for k, name in enumerate(first.names):
        i = int(np.argmin(values[:, k]))
        with np.errstate(invalid='ignore'):
            above = result.limits_current_A > values[:, k]
        rows.append((name + (' (binding)' if k == binding else ''), f'{values[i, k]:.2f}',
                     f'{stamps[i] - t0:.1f}', result.current_limits[i].binds[k],
                     f'{held[above].sum():.1f}'))
    lines += markdown_table(('limit', 'lowest (A RMS)', 'at (s)', 'bound by',
                             'current above (s)'), rows)
    lines += ['', f'On the fallback ({lim_cfg.fallback_current_A:g} A at most): '
              f'{held[fallback].sum():.1f} s of {held.sum():.1f} s.']
    causes: Dict[str, List[int]] = {}
    for k in np.flatnonzero(fallback).tolist():
        causes.setdefault(result.current_limits[k].reason.split(':')[0], []).append(k)
    if causes:
        lines += [''] + markdown_table(
            ('cause', 'time (s)', 'first at (s)', 'first reason'),
            ((cause, f'{held[ks].sum():.1f}', f'{stamps[ks[0]] - t0:.1f}',
              result.current_limits[ks[0]].reason) for cause, ks in causes.items()))
    if math.isfinite(result.forecast_stamp_s[-1]):
        horizon = result.plan.cfg.estimator.forecast_horizon_s
        reach = ', '.join(f'{q} beyond {horizon:g} s' if math.isinf(v[-1])
                          else f'{q} {v[-1]:.0f} s' for q, v in result.time_to_limit_s.items())
        lines += ['', f'The last forecast (from {result.forecast_stamp_s[-1] - t0:.1f} s, the '
                  f'recent duty repeated) reaches each limit after: {reach}.']
    return lines


def _summary_lines(result: ReplayResult) -> List[str]:
    """Return the report's title and what was replayed, how fast."""
    lines = [f'# Replay of {result.plan.info.path.name}', '',
             f'- configuration: {result.plan.config_source}',
             '- inputs: ' + ', '.join(f'{n} <- {t}' for n, t in result.plan.inputs.items()),
             f'- on fallback all along (no topic): {", ".join(result.plan.missing) or "none"}',
             f'- {result.messages} messages, {result.steps} model steps, '
             f'{result.sample_time_s:.1f} s of sample time in {result.wall_s:.1f} s '
             f'({result.speed_x:.0f}x real time)']
    if result.truncated:
        lines.append(f'- **the bag is truncated**: replayed what could be read ({result.problem})')
    return lines


def _temperature_lines(result: ReplayResult) -> List[str]:
    """Return the report's table of the estimates at the end and at their peak."""
    return ['', '## Temperatures at the end and at their peak (degC)', ''] + markdown_table(
        ('estimate', 'end', 'peak'),
        ((n, f'{v[-1]:.1f}', f'{np.max(v):.1f}') for n, v in result.temperatures_C.items()))


def _error_lines(errors: Dict[str, dict]) -> List[str]:
    """Return the report's table of estimate minus thermocouple."""
    lines = ['', '## Estimate minus thermocouple (K)', '']
    if not errors:
        return lines + ['The bag holds no thermocouple topics.']
    return lines + markdown_table(
        ('thermocouple', 'estimate', 'samples', 'max abs', 'RMS', 'bias'),
        ((tc, e['estimate'], e['n'], f'{e["max_abs_K"]:.2f}', f'{e["rms_K"]:.2f}',
          f'{e["bias_K"]:+.2f}') for tc, e in errors.items()))


def _health_lines(result: ReplayResult) -> List[str]:
    """Return the report's alerts, input health and implausible steps."""
    t0 = float(result.stamp_s[0])
    lines = ['', '## Alerts', '']
    lines += [f'- {s - t0:9.1f} s: {text}' for s, text in result.alert_events] or ['- none']
    lines += ['', '## Input health', '']
    lines += markdown_table(
        ('input', 'received', 'accepted', 'rejected'),
        ((name, h['received'], h['accepted'],
          h['non_finite'] + h['out_of_range'] + h['backwards'] + h['late'])
         for name, h in result.health.items()))
    implausible = ', '.join(f'{k} {v}' for k, v in result.implausible.items())
    return lines + ['', f'Implausible steps: {implausible}']


def _correction_lines(c: Optional[dict]) -> List[str]:
    """Return the report's section on the live correction (:func:`_correction_summary`)."""
    lines = ['', '## Live correction', '']
    if c is None:
        return lines + ['Off (`--open-loop`, or estimator.correction.enabled: false): the '
                        'estimates are open loop.']
    if not c['active']:
        return lines + ['On, but no thermocouple reading was usable: the estimates are open '
                        'loop.']
    heats = ', '.join(f'{k} {v:.2f} W' for k, v in c['disturbance_W'].items()) or 'none'
    lines += [f'On: {c["updates"]} updates; learned heats at the end: {heats}. The errors '
              'above compare the corrected estimates with the thermocouples that '
              'corrected them.', '']
    return lines + markdown_table(
        ('thermocouple', 'status', 'received', 'used', 'gated', 'stale', 'dropped'),
        ((tc, h['status'], h['received'], h['used'], h['gated'], h['stale_events'],
          h['dropped_events']) for tc, h in c['thermocouples'].items()))


def parse_mapping(items: Sequence[str]) -> Dict[str, str]:
    """Parse ``name=/topic`` items of the command line into a mapping."""
    out = {}
    for item in items:
        name, sep, topic = item.partition('=')
        if not sep or not name or not topic.startswith('/'):
            raise ReplayError(f'--map {item!r}: expected name=/topic, e.g. '
                              'current_A=/rig/phase_current')
        out[name] = topic
    return out
