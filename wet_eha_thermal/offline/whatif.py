"""
What-if from a state: what a duty would do to the actuator from where it is now.

A test engineer planning the next run asks "what does it do from here?".
:func:`what_if` runs a duty from a copy of a model's state (the live
estimator's, the last of a replayed bag, or cold at the ambient) through
:func:`~.simulation.simulate`, and returns the trajectory of each named
quantity, its peak, and the time each limited quantity
(:data:`~..model.quantity_table.LIMITED`) reaches its limit. The duty is a
reference stage, a table of time with actuator flow and load, or a table of
time with the sensor signals themselves (current, speed, pressures), fed to
the model as they are. A request (:class:`WhatIfRequest`) is parsed from JSON
by :func:`parse_request`, with an error naming the field, the value and what
is allowed; the answer (:meth:`WhatIfResult.to_dict`) is strict JSON.

No ROS here: the estimator node serves the requests in a worker process
(:class:`~.whatif_worker.WhatIfWorker`), and ``wet-eha-thermal whatif``
runs them against a running estimator, a bag or a cold start.
"""

import copy
from dataclasses import dataclass, field
import json
import math
from pathlib import Path
import time
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

# a what-if is a simulation from a given state: simulate() runs it, the report's limit
# check finds the crossings
from .report import check_limit
from .simulation import SensorTable, simulate, ThermalRunaway
from .. import interface
from ..config import Config
from ..model import quantity_table
from ..model.duty import Duty, DutyError, stage_duty, STAGES, TableDuty
from ..model.eha import EHAModel
from ..model.oil import OIL_GRADES
from ..output_files import atomic, pyplot, save_figure
from ..units import C_TO_K, L_MIN, MPA

#: The longest what-if (s): a day of model time costs minutes of a core.
MAX_DURATION_S = 86400.0
#: Thermal model step (s): range and default (as ``simulate``'s).
DT_RANGE_S = (0.01, 60.0)
DEFAULT_DT_S = 1.0
#: Sensor samples per second that drive the model: range and default.
RATE_RANGE_HZ = (1.0, 10000.0)
DEFAULT_RATE_HZ = 200.0
#: Most samples one what-if may make (the work: a day at 200 Hz is 1.7e7).
MAX_SAMPLES = 2.0e7
#: Points of each trajectory by default, and at most.
DEFAULT_POINTS = 720
MAX_POINTS = 10000
#: Rows of a duty table at most.
MAX_ROWS = 100000
#: Longest request id (characters).
MAX_ID = 200
#: A table of flow and load: its columns, as ``--duty`` files have them.
TABLE_COLUMNS = ('time_s', 'flow_L_min', 'load_MPa')
#: A table of the sensor signals: its columns (position_m may be left out).
SAMPLE_COLUMNS = ('time_s',) + interface.INPUTS
#: The keys a request may have.
REQUEST_KEYS = ('id', 'stage', 'table', 'samples', 'duration_s', 'ambient_C', 'dt_s',
                'sample_rate_Hz', 'record_every_s', 'quantities')
#: Decimals of the temperatures (degC) and times (s) in the JSON answer: 0.1 mK and 1 us
#: are far below what the model resolves, and keep an hour of twelve quantities near 100 kB.
DECIMALS_C = 4
DECIMALS_S = 6


class RequestError(ValueError):
    """A what-if request that cannot be run; the message names the field, value and range."""


@dataclass(frozen=True)
class WhatIfRequest:
    """
    One what-if: a duty (exactly one of ``stage``, ``table``, ``samples``) and how to run it.

    ``table``: ``time_s`` with ``flow_L_min`` and ``load_MPa`` (a ``--duty``
    file's columns); ``samples``: ``time_s`` with the sensor signals of
    :data:`~..interface.INPUTS`, SI units. Both repeat with their last time
    as the period and start at the what-if's start. ``ambient_C`` None: the
    caller's (the estimator's present ambient). ``record_every_s`` None:
    about ``DEFAULT_POINTS`` points.
    """

    duration_s: float
    request_id: str = ''
    stage: Optional[int] = None
    table: Optional[Dict[str, Tuple[float, ...]]] = None
    samples: Optional[Dict[str, Tuple[float, ...]]] = None
    ambient_C: Optional[float] = None
    dt_s: float = DEFAULT_DT_S
    sample_rate_Hz: float = DEFAULT_RATE_HZ
    record_every_s: Optional[float] = None
    quantities: Tuple[str, ...] = interface.ESTIMATES

    @property
    def record_s(self) -> float:
        """Return the time between two trajectory points (s): a whole number of steps."""
        if self.record_every_s is not None:
            return self.record_every_s
        return self.dt_s * max(1, math.ceil(self.duration_s / (DEFAULT_POINTS * self.dt_s)))


def id_of(text: str) -> str:
    """Return the ``id`` of a request's JSON text, '' when it has none or is not JSON."""
    try:
        data = json.loads(text)
    except ValueError:
        return ''
    value = data.get('id') if isinstance(data, dict) else None
    return value[:MAX_ID] if isinstance(value, str) else ''


def _number(data: Mapping[str, Any], key: str, low: float, high: float,
            default: Optional[float] = None, open_low: bool = False) -> Optional[float]:
    """Return ``data[key]`` as a float in [low, high] ((low, high] with ``open_low``)."""
    if key not in data or data[key] is None:
        return default
    value = data[key]
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value) and (low < value if open_low else low <= value) \
        and value <= high
    if not ok:
        bracket = '(' if open_low else '['
        raise RequestError(f'{key} = {value!r}: expected a number in {bracket}{low:g}, {high:g}]')
    return float(value)


def _only(given: Mapping[str, Any], allowed: Sequence[str], where: str, what: str) -> None:
    """Raise a :class:`RequestError` naming the first key of ``given`` not in ``allowed``."""
    unknown = sorted(set(given) - set(allowed))
    if unknown:
        raise RequestError(f'{where}{unknown[0]}: unknown {what}; the {what}s are '
                           f'{", ".join(allowed)}')


def _columns(data: Mapping[str, Any], key: str, columns: Sequence[str],
             optional: Sequence[str] = ()) -> Dict[str, Tuple[float, ...]]:
    """Return the table ``data[key]``: each of ``columns`` as a tuple of finite numbers."""
    table = data[key]
    if not isinstance(table, dict):
        raise RequestError(f'{key}: expected an object of columns {", ".join(columns)}')
    _only(table, columns, f'{key}.', 'column')
    out = {}
    for name in columns:
        if name not in table:
            if name in optional:
                continue
            raise RequestError(f'{key}.{name}: missing column')
        values = table[name]
        if not isinstance(values, list) or not 2 <= len(values) <= MAX_ROWS or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                for v in values):
            raise RequestError(f'{key}.{name}: expected a list of 2..{MAX_ROWS} finite numbers')
        out[name] = tuple(float(v) for v in values)
    lengths = {len(v) for v in out.values()}
    if len(lengths) > 1:
        raise RequestError(f'{key}: the columns differ in length '
                           f'({", ".join(f"{k} {len(v)}" for k, v in out.items())})')
    return out


def _check_ranges(cfg: Config, samples: Mapping[str, Tuple[float, ...]]) -> None:
    """Raise :class:`RequestError` for a sensor signal outside the estimator's plausible range."""
    for name, values in samples.items():
        if name == 'time_s':
            continue
        ch = getattr(cfg.estimator.channels, name)
        bad = next((v for v in values if not ch.low <= v <= ch.high), None)
        if bad is not None:
            raise RequestError(f'samples.{name} = {bad!r}: outside the plausible range '
                               f'[{ch.low:g}, {ch.high:g}] (estimator.channels.{name})')


def read_samples_csv(path: Path) -> Dict[str, List[float]]:
    """
    Return the :data:`SAMPLE_COLUMNS` of a CSV of numbers, as a request's ``samples``.

    Lines starting with ``#`` are comments; ``position_m`` may be left out.
    A file that cannot be read, a missing column or a value that is not a
    finite number raises :class:`RequestError` naming the file, column and row.
    """
    try:
        # comment lines dropped first: genfromtxt would take one before the header for it
        lines = [ln for ln in Path(path).read_text().splitlines()
                 if ln.strip() and not ln.lstrip().startswith('#')]
        data = np.genfromtxt(lines, delimiter=',', names=True, ndmin=1)
    except (OSError, ValueError) as exc:
        raise RequestError(f'{path}: cannot read it: {exc}') from None
    names = data.dtype.names or ()
    table = {}
    for name in SAMPLE_COLUMNS:
        if name not in names:
            if name == 'position_m':
                continue
            raise RequestError(f'{path}: missing column {name!r}; the header has '
                               f'{", ".join(names)}')
        values = np.atleast_1d(data[name])
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise RequestError(f'{path}: column {name!r}, data row {bad[0] + 1}: not a finite '
                               'number')
        table[name] = values.tolist()
    return table


def parse_request(text: Union[str, Mapping[str, Any]], cfg: Config,
                  known: Sequence[str]) -> WhatIfRequest:
    """
    Return the request in ``text`` (JSON, or its object); :class:`RequestError` if it is bad.

    ``known``: the quantities the model names (its outputs). Every value is
    checked against its range, the duty's tables against the configuration
    (the stroke; the sensors' plausible ranges) when it is built.
    """
    try:
        data = json.loads(text) if isinstance(text, str) else text
    except ValueError as exc:
        raise RequestError(f'not JSON: {exc}') from None
    if not isinstance(data, dict):
        raise RequestError(f'expected a JSON object with {", ".join(REQUEST_KEYS)}')
    _only(data, REQUEST_KEYS, '', 'field')
    rid = data.get('id', '')
    if not isinstance(rid, str) or len(rid) > MAX_ID:
        raise RequestError(f'id = {rid!r}: expected a string of at most {MAX_ID} characters')
    duties = [k for k in ('stage', 'table', 'samples') if data.get(k) is not None]
    if len(duties) != 1:
        raise RequestError(f'give exactly one duty: stage, table or samples (got '
                           f'{", ".join(duties) or "none"})')
    stage = data.get('stage')
    if stage is not None and (isinstance(stage, bool) or stage not in STAGES):
        raise RequestError(f'stage = {stage!r}: expected one of '
                           f'{", ".join(str(k) for k in STAGES)}')
    if 'duration_s' not in data:
        raise RequestError(f'duration_s: missing; expected a number in (0, {MAX_DURATION_S:g}]')
    duration = _number(data, 'duration_s', 0.0, MAX_DURATION_S, open_low=True)
    dt = _number(data, 'dt_s', DT_RANGE_S[0], min(DT_RANGE_S[1], duration), DEFAULT_DT_S)
    rate = _number(data, 'sample_rate_Hz', max(RATE_RANGE_HZ[0], 1.0 / dt), RATE_RANGE_HZ[1],
                   DEFAULT_RATE_HZ)
    if duration / dt * max(1, round(rate * dt)) > MAX_SAMPLES:
        raise RequestError(f'duration_s {duration:g} at sample_rate_Hz {rate:g}: '
                           f'{duration * rate:.3g} samples, more than {MAX_SAMPLES:.3g}; '
                           'shorten it or lower the rate')
    record = _number(data, 'record_every_s', max(dt, duration / MAX_POINTS), duration)
    grade = OIL_GRADES[cfg.fluid.grade]
    ambient = _number(data, 'ambient_C', grade.T_min_K - C_TO_K, grade.T_max_K - C_TO_K)
    quantities = data.get('quantities', list(interface.ESTIMATES))
    if not isinstance(quantities, list) or not quantities or not all(
            isinstance(q, str) and q in known for q in quantities):
        bad = next((q for q in quantities if q not in known), quantities) \
            if isinstance(quantities, list) and quantities else quantities
        raise RequestError(f'quantities: {bad!r} is not a list of known names; known: '
                           f'{", ".join(known)}')
    table = _columns(data, 'table', TABLE_COLUMNS) if 'table' in duties else None
    samples = _columns(data, 'samples', SAMPLE_COLUMNS, optional=('position_m',)) \
        if 'samples' in duties else None
    if samples is not None:
        _check_ranges(cfg, samples)
    return WhatIfRequest(duration_s=duration, request_id=rid, stage=stage, table=table,
                         samples=samples, ambient_C=ambient, dt_s=dt, sample_rate_Hz=rate,
                         record_every_s=record, quantities=tuple(dict.fromkeys(quantities)))


def make_duty(cfg: Config, request: WhatIfRequest,
              start_s: float) -> Tuple[Union[Duty, SensorTable], str]:
    """
    Return the request's duty starting at the model time ``start_s``, and it in words.

    :class:`RequestError` names the table a duty cannot be built from (the
    piston beyond its stroke, times not increasing).
    """
    act = cfg.hydraulics.actuator
    try:
        if request.stage is not None:
            duty = stage_duty(cfg, request.stage)
            return Delayed(duty, start_s), duty.stage.describe()
        if request.table is not None:
            t = request.table
            duty = TableDuty(t['time_s'], np.array(t['flow_L_min']) * L_MIN,
                             np.array(t['load_MPa']) * MPA, act.area_m2, act.half_stroke_m,
                             name='table')
            return Delayed(duty, start_s), f'table of flow and load (period {duty.period_s:g} s)'
        columns = {k: v for k, v in request.samples.items() if k != 'time_s'}
        table = SensorTable(request.samples['time_s'], columns, start_s, name='samples')
        return table, f'table of sensor signals (period {table.period_s:g} s)'
    except DutyError as exc:
        raise RequestError(str(exc)) from None


class Delayed(Duty):
    """A duty whose time 0 is the model time ``start_s``: a what-if starts it now."""

    def __init__(self, duty: Duty, start_s: float) -> None:
        """Wrap ``duty``, started at ``start_s``."""
        self.duty = duty
        self.start_s = float(start_s)
        self.name = duty.name
        self.period_s = duty.period_s
        self.peak_position_m = duty.peak_position_m

    def demand(self, t_s: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the wrapped duty's demand ``start_s`` later."""
        return self.duty.demand(np.asarray(t_s, dtype=float) - self.start_s)


@dataclass
class WhatIfResult:
    """
    The answer to a what-if: trajectories from the start state, peaks, times to the limits.

    ``time_s`` counts from the start (its first point, 0, is the state the
    what-if starts from); ``temperatures_C`` holds each requested quantity
    there; ``time_to_limit_s`` of each limited quantity is its first
    crossing, linear between two points, None when not within the run;
    ``stopped`` says why a run ended early (a thermal runaway).
    """

    request: WhatIfRequest
    source: str
    start_stamp_s: Optional[float]
    ambient_C: float
    duty: str
    time_s: np.ndarray
    temperatures_C: Dict[str, np.ndarray]
    limits_C: Dict[str, float]
    time_to_limit_s: Dict[str, Optional[float]]
    stopped: Optional[str] = None
    wall_s: float = 0.0
    peaks_C: Dict[str, float] = field(init=False)
    peak_time_s: Dict[str, float] = field(init=False)

    def __post_init__(self) -> None:
        """Find each quantity's peak and when it comes."""
        peaks = {q: int(np.argmax(v)) for q, v in self.temperatures_C.items()}
        self.peaks_C = {q: float(self.temperatures_C[q][i]) for q, i in peaks.items()}
        self.peak_time_s = {q: float(self.time_s[i]) for q, i in peaks.items()}

    def to_dict(self) -> Dict[str, Any]:
        """Return the answer as strict JSON data (:data:`~.interface.WHATIF_RESPONSE_TOPIC`)."""
        def c(x):
            return round(float(x), DECIMALS_C)

        def s(x):
            return None if x is None else round(float(x), DECIMALS_S)

        return {'id': self.request.request_id, 'ok': True, 'error': None, 'source': self.source,
                'start_stamp_s': self.start_stamp_s, 'duty': self.duty,
                'duration_s': self.request.duration_s, 'dt_s': self.request.dt_s,
                'ambient_C': self.ambient_C, 'stopped': self.stopped,
                'wall_s': round(self.wall_s, 3), 'time_s': [s(t) for t in self.time_s],
                'temperatures_C': {q: [c(x) for x in v] for q, v in self.temperatures_C.items()},
                'peaks_C': {q: c(v) for q, v in self.peaks_C.items()},
                'peak_time_s': {q: s(v) for q, v in self.peak_time_s.items()},
                'limits_C': dict(self.limits_C),
                'time_to_limit_s': {q: s(v) for q, v in self.time_to_limit_s.items()}}


def error_answer(rid: str, message: str) -> Dict[str, Any]:
    """Return the answer to a request that was not run: ``ok`` false and the reason."""
    return {'id': rid, 'ok': False, 'error': message}


def what_if(cfg: Config, request: WhatIfRequest, model: Optional[EHAModel] = None,
            ambient_C: float = 20.0, source: str = 'cold',
            start_stamp_s: Optional[float] = None) -> WhatIfResult:
    """
    Run ``request`` from a copy of ``model``'s state; return the trajectories and limits.

    ``model`` None: cold, every temperature at the ambient. The model given
    is not changed. ``ambient_C``: used unless the request has one;
    ``source`` and ``start_stamp_s`` (the sample time of the state) are
    passed on to the answer.
    """
    t_wall = time.perf_counter()
    ambient = request.ambient_C if request.ambient_C is not None else ambient_C
    names = request.quantities
    wanted = set(names) | set(quantity_table.LIMITED)
    if model is not None:
        model = copy.deepcopy(model)
        model.defer_refresh = False     # a live model defers its coefficients by a step
        start, t_start = model.outputs(), model.time_s
    else:
        start, t_start = dict.fromkeys(wanted, ambient + C_TO_K), 0.0
    duty, words = make_duty(cfg, request, t_start)
    stopped = None
    try:
        res = simulate(cfg, duty, request.duration_s, dt_s=request.dt_s,
                       sample_rate_Hz=request.sample_rate_Hz, ambient_C=ambient,
                       record_every_s=request.record_s, model=model)
    except ThermalRunaway as exc:
        stopped, res = str(exc), exc.result
    t = np.concatenate([[0.0], np.asarray(res.time_s) - t_start])
    temps = {q: np.concatenate([[start[q]], res.temperatures_K.get(q, [])]) - C_TO_K
             for q in wanted}
    limits = quantity_table.limits_C(cfg)
    reached = {}
    for q, limit in limits.items():
        check = check_limit(q, t, temps[q], limit)
        reached[q] = check.time_to_limit_s if check.method == 'in run' else None
    return WhatIfResult(request=request, source=source, start_stamp_s=start_stamp_s,
                        ambient_C=ambient, duty=words, time_s=t,
                        temperatures_C={q: temps[q] for q in names}, limits_C=limits,
                        time_to_limit_s=reached, stopped=stopped,
                        wall_s=time.perf_counter() - t_wall)


def model_outputs(cfg: Config) -> Tuple[str, ...]:
    """Return the names of the model's outputs: the quantities a what-if may ask for."""
    return EHAModel(cfg).quantities.names


# ------------------------------------------------------------------ outputs
def format_answer(answer: Mapping[str, Any]) -> str:
    """Return an answer's peaks and times to the limits as a fixed-width table."""
    if not answer['ok']:
        return f'what-if {answer["id"]!r} not run: {answer["error"]}'
    head = f'{"quantity":<20} {"peak":>7} {"at":>8} {"limit":>6}  limit reached'
    stamp = answer['start_stamp_s']
    state = '' if stamp is None else f' (its state at sample time {stamp:.6f} s)'
    lines = [f'What-if from {answer["source"]}{state}: {answer["duty"]}, '
             f'{answer["duration_s"]:g} s at ambient {answer["ambient_C"]:g} degC '
             f'({answer["wall_s"]:.1f} s to compute)',
             head, f'{"":<20} {"degC":>7} {"s":>8} {"degC":>6}', '-' * len(head)]
    for q, peak in answer['peaks_C'].items():
        limit = answer['limits_C'].get(q)
        reached = answer['time_to_limit_s'].get(q)
        when = '' if limit is None else ('not within the run' if reached is None
                                         else f'at {reached:.0f} s')
        lines.append(f'{quantity_table.label(q):<20} {peak:7.2f} {answer["peak_time_s"][q]:8.0f} '
                     f'{"" if limit is None else f"{limit:6.0f}":>6}  {when}')
    if answer['stopped']:
        lines.append(f'stopped early: {answer["stopped"]}')
    return '\n'.join(lines)


def write_answer(answer: Mapping[str, Any], out_dir: Path) -> Tuple[Path, Path]:
    """Write an answer's trajectories as whatif.csv and whatif.png in ``out_dir``; their paths."""
    plt = pyplot()

    out_dir.mkdir(parents=True, exist_ok=True)
    names = list(answer['temperatures_C'])
    table = np.column_stack([answer['time_s']] + [answer['temperatures_C'][q] for q in names])
    csv_path, png_path = out_dir / 'whatif.csv', out_dir / 'whatif.png'
    with atomic(csv_path) as tmp:
        np.savetxt(tmp, table, fmt=['%.6f'] + ['%.4f'] * len(names), delimiter=',',
                   header=','.join(['time_s'] + [f'{q}_C' for q in names]), comments='')
    fig, ax = plt.subplots(figsize=(10, 5.5))
    minutes = np.asarray(answer['time_s']) / 60.0
    for k, q in enumerate(names):
        ax.plot(minutes, answer['temperatures_C'][q], lw=1.2, color=f'C{k % 10}',
                label=quantity_table.label(q))
        if q in answer['limits_C']:
            ax.axhline(answer['limits_C'][q], ls='--', lw=0.8, color=f'C{k % 10}',
                       label=quantity_table.LIMIT_LABELS[q])
    ax.set_xlabel('time from the start state [min]')
    ax.set_ylabel('degC')
    ax.set_title(f'What-if from {answer["source"]}: {answer["duty"]}', fontsize=9)
    ax.legend(fontsize=7, ncol=2)
    ax.grid(alpha=0.3)
    save_figure(fig, png_path)
    return csv_path, png_path
