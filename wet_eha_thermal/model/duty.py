"""
The duties the actuator is asked to follow: flow demand and load pressure over time.

A duty is the reference rig's sinusoidal stage (:class:`SinusoidalDuty`, the
six :data:`STAGES` of docs/model.md) or a table (:class:`TableDuty`, from a
CSV file by :func:`load_duty_csv`); :class:`~.kinetics.KineticModel` turns it
into the signals the rig's sensors show.

Sign conventions (docs/model.md, The kinetic model; The reference rig): the load pressure is
dp = p_A - p_B across the actuator; a positive actuator flow Q goes into
chamber A (the piston moves toward B, the position x grows).
"""

from dataclasses import dataclass
import math
import os
from pathlib import Path
from typing import Dict, Iterator, List, Optional, Tuple, Union

import numpy as np

from ..config import Config
from ..units import L_MIN, MPA


class DutyError(ValueError):
    """A duty that is malformed, or that would drive the piston beyond its stroke."""


# --------------------------------------------------------------------- stages
@dataclass(frozen=True)
class Stage:
    """
    One sinusoidal operating stage of the reference rig (SI units).

    Load pressure dp(t) = dp_a sin(2 pi f t) (p_A - p_B), actuator flow
    Q(t) = Q_a cos(2 pi f t) (into chamber A when positive).
    """

    number: int
    load_dp_amplitude_Pa: float
    flow_amplitude_m3_s: float
    frequency_Hz: float

    def describe(self) -> str:
        """Return ``stage N (load .. MPa, flow .. L/min, .. Hz)``, in the units people read."""
        return (f'stage {self.number} (load {self.load_dp_amplitude_Pa / MPA:g} MPa, flow '
                f'{self.flow_amplitude_m3_s / L_MIN:g} L/min, {self.frequency_Hz:g} Hz)')


def _stage(number: int, dp_MPa: float, q_L_min: float, f_Hz: float) -> Stage:
    return Stage(number, dp_MPa * MPA, q_L_min * L_MIN, f_Hz)


#: The reference rig's six stages (docs/model.md): flight-control duty; 6 is the no-load test.
STAGES: Dict[int, Stage] = {s.number: s for s in (
    _stage(1, 16.0, 2.0, 0.2),
    _stage(2, 12.0, 4.0, 0.5),
    _stage(3, 8.0, 6.0, 1.0),
    _stage(4, 6.0, 8.0, 2.0),
    _stage(5, 4.0, 10.0, 3.0),
    _stage(6, 0.0, 12.0, 1.0),
)}


# ----------------------------------------------------------------------- duties
class Duty:
    """
    Base of the duties: actuator flow demand, load pressure and position over time.

    Subclasses set ``name`` (used in messages), ``period_s`` and
    ``peak_position_m`` and implement :meth:`demand`.
    """

    name: str = 'duty'
    period_s: float = math.inf
    peak_position_m: float = 0.0

    def demand(self, t_s: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """
        Return ``(flow_m3_s, load_dp_Pa, position_m)`` at the sample times ``t_s`` (s).

        Flow into chamber A (m^3/s), load pressure p_A - p_B (Pa) and piston
        position (m, centred), each an array shaped like ``t_s``.
        """
        raise NotImplementedError

    def _check_stroke(self, half_stroke_m: Optional[float], detail: str) -> None:
        if half_stroke_m is not None and self.peak_position_m > half_stroke_m:
            raise DutyError(
                f'duty {self.name}: the piston would travel +-{self.peak_position_m * 1e3:.2f} mm'
                f', beyond the half stroke of {half_stroke_m * 1e3:.2f} mm ({detail})')


class SinusoidalDuty(Duty):
    """
    A sinusoidal stage: Q = Q_a cos(2 pi f t), dp = dp_a sin(2 pi f t).

    Position x = Q_a / (A 2 pi f) sin(2 pi f t), the exact integral of Q / A
    centred on mid-stroke. ``stage`` is a :class:`Stage` or a stage number of
    :data:`STAGES`; ``area_m2`` the piston area. When ``half_stroke_m`` is
    given, a stage whose peak |x| exceeds it raises :class:`DutyError`
    (pass the configuration's half stroke, or use :func:`stage_duty`).
    """

    def __init__(self, stage: Union[Stage, int], area_m2: float,
                 half_stroke_m: Optional[float] = None) -> None:
        """Set up the stage; raise :class:`DutyError` if it leaves the stroke."""
        if not isinstance(stage, Stage):
            try:
                stage = STAGES[stage]
            except (KeyError, TypeError):
                raise DutyError(f'unknown stage {stage!r}; known stages: '
                                f'{", ".join(str(k) for k in STAGES)}') from None
        if not area_m2 > 0.0:
            raise DutyError(f'stage {stage.number}: piston area {area_m2!r} m^2 must be > 0')
        if not stage.frequency_Hz > 0.0:
            raise DutyError(f'stage {stage.number}: frequency {stage.frequency_Hz!r} Hz '
                            'must be > 0')
        self.stage = stage
        self.name = f'stage {stage.number}'
        self.area_m2 = float(area_m2)
        self.period_s = 1.0 / stage.frequency_Hz
        self._omega = 2.0 * math.pi * stage.frequency_Hz
        self._q_a = stage.flow_amplitude_m3_s
        self._dp_a = stage.load_dp_amplitude_Pa
        self._x_a = self._q_a / (self.area_m2 * self._omega)
        self.peak_position_m = abs(self._x_a)
        self._check_stroke(half_stroke_m, (
            f'flow amplitude {self._q_a / L_MIN:g} L/min at {stage.frequency_Hz:g} Hz on '
            f'{self.area_m2 * 1e6:.1f} mm^2'))

    def demand(self, t_s: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(flow_m3_s, load_dp_Pa, position_m)`` at the sample times ``t_s``."""
        phase = self._omega * np.asarray(t_s, dtype=float)
        s = np.sin(phase)
        return self._q_a * np.cos(phase), self._dp_a * s, self._x_a * s


class TableDuty(Duty):
    """
    A tabulated duty: flow and load pressure linear between the nodes, periodic.

    ``time_s`` starts at 0 and increases strictly; the table repeats with
    period ``time_s[-1]`` when asked beyond its end (or before 0). The
    position is the exact integral of the piecewise-linear flow over the
    piston area (cumulative trapezoid at the nodes plus the partial segment,
    quadratic inside a segment) with its mean over one period removed, so
    the motion is centred on mid-stroke. A table whose flow does not
    integrate to zero over the period moves the piston by
    ``net_displacement_m`` every repeat (the exact integral keeps that drift);
    asking for times where that takes the piston beyond ``half_stroke_m``
    raises :class:`DutyError`, as does a first period beyond it.
    """

    def __init__(self, time_s, flow_m3_s, load_dp_Pa, area_m2: float,
                 half_stroke_m: Optional[float] = None, name: str = 'table') -> None:
        """Check and precompute the table; raise :class:`DutyError` if it is unusable."""
        self.name = str(name)
        t = np.array(time_s, dtype=float)
        q = np.array(flow_m3_s, dtype=float)
        dp = np.array(load_dp_Pa, dtype=float)
        if t.ndim != 1 or q.shape != t.shape or dp.shape != t.shape:
            raise DutyError(f'duty {self.name}: time, flow and load must be 1-D arrays of one '
                            f'length, got shapes {t.shape}, {q.shape}, {dp.shape}')
        if t.size < 2:
            raise DutyError(f'duty {self.name}: needs at least 2 rows, got {t.size}')
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q))
                and np.all(np.isfinite(dp))):
            raise DutyError(f'duty {self.name}: every value must be a finite number')
        if t[0] != 0.0:
            raise DutyError(f'duty {self.name}: the first time must be 0, got {t[0]!r}')
        steps = np.diff(t)
        if np.any(steps <= 0.0):
            i = int(np.argmax(steps <= 0.0)) + 1
            raise DutyError(f'duty {self.name}: time must increase strictly; row {i} has '
                            f'{t[i]!r} after {t[i - 1]!r}')
        if not area_m2 > 0.0:
            raise DutyError(f'duty {self.name}: piston area {area_m2!r} m^2 must be > 0')
        self.area_m2 = float(area_m2)
        self.half_stroke_m = half_stroke_m
        self.period_s = float(t[-1])
        self._t, self._q, self._dp, self._h = t, q, dp, steps
        self._q_slope = np.diff(q) / steps
        self._dp_slope = np.diff(dp) / steps
        # swept volume at the nodes (exact for a piecewise-linear flow)
        vol = np.concatenate(([0.0], np.cumsum(0.5 * (q[:-1] + q[1:]) * steps)))
        # mean volume over one period: segment integral V_i h + h^2 (2 Q_i + Q_i+1) / 6
        seg = vol[:-1] * steps + steps ** 2 * (2.0 * q[:-1] + q[1:]) / 6.0
        self._vol = vol - float(np.sum(seg)) / self.period_s
        self.net_displacement_m = float(vol[-1]) / self.area_m2
        # per segment: start time, flow, flow slope, load, load slope, centred volume
        self._t_inner = t[1:-1]
        self._coef = np.column_stack((t[:-1], q[:-1], self._q_slope, dp[:-1], self._dp_slope,
                                      self._vol[:-1]))
        # peak |x| over one period: nodes, and the extrema where the flow crosses zero
        x_nodes = self._vol / self.area_m2
        peak = float(np.max(np.abs(x_nodes)))
        cross = np.flatnonzero(q[:-1] * q[1:] < 0.0)
        if cross.size:
            x_ext = self._position(t[cross] + q[cross] * steps[cross]
                                   / (q[cross] - q[cross + 1]), cross)
            peak = max(peak, float(np.max(np.abs(x_ext))))
        self.peak_position_m = peak
        self._check_stroke(half_stroke_m, f'piston area {self.area_m2 * 1e6:.1f} mm^2')

    def rows(self) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return copies of the table: ``(time_s, flow_m3_s, load_dp_Pa)`` at its nodes."""
        return self._t.copy(), self._q.copy(), self._dp.copy()

    def _position(self, tm: np.ndarray, idx: np.ndarray) -> np.ndarray:
        tau = tm - self._t[idx]
        vol = self._vol[idx] + tau * (self._q[idx] + 0.5 * self._q_slope[idx] * tau)
        return vol / self.area_m2

    def demand(self, t_s: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(flow_m3_s, load_dp_Pa, position_m)`` at the sample times ``t_s``."""
        t = np.asarray(t_s, dtype=float)
        k, tm = np.divmod(t, self.period_s)
        # segment of each time (the last one for rounding up to the period)
        idx = np.searchsorted(self._t_inner, tm, side='right')
        t0, q0, qs, dp0, dps, v0 = self._coef[idx].T
        tau = tm - t0
        flow = qs * tau
        flow += q0
        load = dps * tau
        load += dp0
        x = flow + q0
        x *= 0.5 * tau
        x += v0
        x *= 1.0 / self.area_m2
        if self.net_displacement_m != 0.0:
            x = x + k * self.net_displacement_m
            if self.half_stroke_m is not None and x.size:
                worst = float(np.max(np.abs(x)))
                if worst > self.half_stroke_m:
                    raise DutyError(
                        f'duty {self.name}: the flow does not integrate to zero over the '
                        f'period ({self.net_displacement_m * 1e3:+.3g} mm per repeat); at '
                        f't = {float(t.flat[int(np.argmax(np.abs(x)))]):g} s the piston '
                        f'would be at {worst * 1e3:.2f} mm, beyond the half stroke of '
                        f'{self.half_stroke_m * 1e3:.2f} mm')
        return flow, load, x


def stage_duty(cfg: Config, stage: Union[Stage, int]) -> SinusoidalDuty:
    """Return the sinusoidal duty of ``stage`` on the configured actuator (stroke checked)."""
    act = cfg.hydraulics.actuator
    return SinusoidalDuty(stage, act.area_m2, act.half_stroke_m)


#: Columns a duty CSV must have.
DUTY_COLUMNS = ('time_s', 'flow_L_min', 'load_MPa')


def load_duty_csv(path: Union[str, os.PathLike], area_m2: float,
                  half_stroke_m: float) -> TableDuty:
    """
    Read a duty table from a CSV file.

    The first line that is neither blank nor a comment (``#`` first) is the
    header; it must name the columns ``time_s`` (s, first value 0, strictly
    increasing), ``flow_L_min`` (actuator flow demand, L/min, into chamber A
    when positive) and ``load_MPa`` (p_A - p_B, MPa), in any order; other
    columns are ignored. At least two data rows. Every problem raises one
    :class:`DutyError` naming the file, the line (1-based, as an editor
    shows it) and the column.

    :param path: the CSV file.
    :param area_m2: piston area (m^2).
    :param half_stroke_m: travel each side of centre (m); a table that goes
        beyond it raises :class:`DutyError`.
    :return: the :class:`TableDuty`, named after the file.
    """
    p = Path(path)
    cols: Optional[Dict[str, int]] = None
    header_line = 0
    rows: List[Tuple[int, float, float, float]] = []
    for number, fields in _data_lines(_read_text(p)):
        if cols is None:
            cols, header_line = _header_columns(p, number, fields), number
            continue
        t, flow, load = _row_values(p, number, fields, cols)
        where = f'{p} line {number}, column {DUTY_COLUMNS[0]!r}'
        if not rows and t != 0.0:
            raise DutyError(f'{where}: the first time must be 0, got '
                            f'{fields[cols[DUTY_COLUMNS[0]]]!r}')
        if rows and not t > rows[-1][1]:
            raise DutyError(f'{where}: time must increase strictly; {t:g} s follows '
                            f'{rows[-1][1]:g} s (line {rows[-1][0]})')
        rows.append((number, t, flow, load))
    if cols is None:
        raise DutyError(f'{p} line 1: no header row (file empty or all comments); needed '
                        f'columns: {", ".join(DUTY_COLUMNS)}')
    if len(rows) < 2:
        last = rows[-1][0] if rows else header_line
        raise DutyError(f'{p} line {last}: needs at least 2 data rows, found {len(rows)}')
    data = np.array([r[1:] for r in rows])
    return TableDuty(data[:, 0], data[:, 1] * L_MIN, data[:, 2] * MPA, area_m2,
                     half_stroke_m, name=str(p))


def _read_text(p: Path) -> str:
    """Return the text of the duty file ``p``; DutyError when it cannot be read as UTF-8."""
    try:
        return p.read_text(encoding='utf-8-sig')
    except FileNotFoundError:
        raise DutyError(f'duty file {p}: not found') from None
    except OSError as exc:
        raise DutyError(f'duty file {p}: cannot read it: {exc.strerror}') from None
    except UnicodeDecodeError as exc:
        line = _line_of_byte(p, exc.start)
        raise DutyError(f'{p} line {line}: not UTF-8 text') from None


def _data_lines(text: str) -> Iterator[Tuple[int, List[str]]]:
    """Yield the number (1-based) and the fields of each line but blank and comment lines."""
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if line and not line.startswith('#'):
            yield number, [f.strip() for f in line.split(',')]


def _header_columns(p: Path, number: int, header: List[str]) -> Dict[str, int]:
    """Return the field of each of :data:`DUTY_COLUMNS`; DutyError unless each is there once."""
    cols = {}
    for name in DUTY_COLUMNS:
        if header.count(name) > 1:
            raise DutyError(f'{p} line {number}: column {name!r} appears twice')
        if name not in header:
            raise DutyError(f'{p} line {number}: missing column {name!r}; the header '
                            f'has {", ".join(repr(h) for h in header)}; needed: '
                            f'{", ".join(DUTY_COLUMNS)}')
        cols[name] = header.index(name)
    return cols


def _row_values(p: Path, number: int, fields: List[str],
                cols: Dict[str, int]) -> List[float]:
    """Return a data row's values in the order of :data:`DUTY_COLUMNS`; DutyError if one is bad."""
    values = []
    for name in DUTY_COLUMNS:
        j = cols[name]
        where = f'{p} line {number}, column {name!r} (field {j + 1})'
        if j >= len(fields) or not fields[j]:
            raise DutyError(f'{where}: missing value')
        try:
            v = float(fields[j])
        except ValueError:
            raise DutyError(f'{where}: {fields[j]!r} is not a number') from None
        if not math.isfinite(v):
            raise DutyError(f'{where}: {fields[j]!r} is not a finite number')
        values.append(v)
    return values


def _line_of_byte(path: Path, offset: int) -> int:
    """Return the 1-based line number holding byte ``offset`` of the file at ``path``."""
    try:
        return path.read_bytes()[:offset].count(b'\n') + 1
    except OSError:
        return 1
