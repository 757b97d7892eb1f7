"""
Kinetic (fluid-power and electrical) model of the wet EHA, for offline runs.

Turns a duty (actuator flow demand and load pressure over time) into the
signals the rig's sensors show (phase current, motor speed, both actuator
port pressures, accumulator pressure, LVDT position), so that the thermal
model is driven offline exactly as the live estimator is driven by the real
sensors, plus internal "truth" quantities (leakages, pump port pressures,
torque, loss powers) for energy checks.

Sign conventions (docs/model.md, The kinetic model; The reference rig): the load pressure is
dp = p_A - p_B across the actuator; a positive actuator flow Q goes into
chamber A (the piston moves toward B, the position x grows); a positive
speed makes the pump deliver into port A.

The relations of :mod:`.fluid_power` (leakage, pump friction, line drop) are
used, not re-implemented, so the kinetic and thermal sides share one physics.
"""

from dataclasses import dataclass, field
import math
import os
from pathlib import Path
from typing import Callable, Dict, List, Optional, Tuple, Union

import numpy as np

from .eha import SampleBlock
from .fluid_power import (check_gap_leakage, displacement_per_rad, gap_leakage,
                          line_pressure_drop, pump_friction_torque)
from .losses import copper_resistance
from .oil import Oil
from .validity import ValidityLog
from ..config import Config
from ..units import C_TO_K, L_MIN, MPA

#: 40 degC in kelvin, the default oil and winding temperature.
T40_K = C_TO_K + 40.0
#: Speed magnitude (rad/s) below which a friction power is not turned into a torque.
SPEED_EPS_RAD_S = 1.0e-6
#: Secant steps of :meth:`KineticModel.sample_limited`.
LIMIT_ITERATIONS = 6


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
    try:
        text = p.read_text(encoding='utf-8-sig')
    except FileNotFoundError:
        raise DutyError(f'duty file {p}: not found') from None
    except OSError as exc:
        raise DutyError(f'duty file {p}: cannot read it: {exc.strerror}') from None
    except UnicodeDecodeError as exc:
        line = _line_of_byte(p, exc.start)
        raise DutyError(f'{p} line {line}: not UTF-8 text') from None
    header: Optional[List[str]] = None
    header_line = 0
    cols: Dict[str, int] = {}
    rows: List[Tuple[int, float, float, float]] = []
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith('#'):
            continue
        fields = [f.strip() for f in line.split(',')]
        if header is None:
            header, header_line = fields, number
            for name in DUTY_COLUMNS:
                if header.count(name) > 1:
                    raise DutyError(f'{p} line {number}: column {name!r} appears twice')
                if name not in header:
                    raise DutyError(f'{p} line {number}: missing column {name!r}; the header '
                                    f'has {", ".join(repr(h) for h in header)}; needed: '
                                    f'{", ".join(DUTY_COLUMNS)}')
                cols[name] = header.index(name)
            continue
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
        t = values[0]
        where = f'{p} line {number}, column {DUTY_COLUMNS[0]!r}'
        if not rows and t != 0.0:
            raise DutyError(f'{where}: the first time must be 0, got '
                            f'{fields[cols[DUTY_COLUMNS[0]]]!r}')
        if rows and not t > rows[-1][1]:
            raise DutyError(f'{where}: time must increase strictly; {t:g} s follows '
                            f'{rows[-1][1]:g} s (line {rows[-1][0]})')
        rows.append((number, t, values[1], values[2]))
    if header is None:
        raise DutyError(f'{p} line 1: no header row (file empty or all comments); needed '
                        f'columns: {", ".join(DUTY_COLUMNS)}')
    if len(rows) < 2:
        last = rows[-1][0] if rows else header_line
        raise DutyError(f'{p} line {last}: needs at least 2 data rows, found {len(rows)}')
    data = np.array([r[1:] for r in rows])
    return TableDuty(data[:, 0], data[:, 1] * L_MIN, data[:, 2] * MPA, area_m2,
                     half_stroke_m, name=str(p))


def _line_of_byte(path: Path, offset: int) -> int:
    """Return the 1-based line number holding byte ``offset`` of the file at ``path``."""
    try:
        return path.read_bytes()[:offset].count(b'\n') + 1
    except OSError:
        return 1


# --------------------------------------------------------------- thermal state
def no_loss(speed_rad_s: np.ndarray, *current_A: np.ndarray) -> np.ndarray:
    """Return zero loss (W) at every sample: the default of the loss callables."""
    return np.zeros(np.shape(speed_rad_s))


@dataclass
class ThermalFeedback:
    """
    The thermal state the kinetics needs (docs/model.md, The coupled model: oil properties back).

    :ivar pump_oil_K: oil temperature in the pump (K): leakage and friction viscosity.
    :ivar line_oil_K: oil temperature in the lines (K): line pressure drops.
    :ivar winding_K: winding temperature (K): phase resistance R(T).
    :ivar drag_W: the friction on the motor's shaft (W) at the given speed
        magnitudes |w| (rad/s, array): airgap, end faces and bearings, as the
        thermal model's ``WetMotor.shaft_drag_W`` computes it.
    :ivar electromagnetic_loss_W: the motor's electromagnetic losses but the
        DC copper loss (W) at the given |w| and RMS currents (A, arrays):
        stator iron, rotor eddy currents, the copper's AC excess
        (``WetMotor.electromagnetic_loss_W``).

    The defaults put everything at 40 degC with no drag and no losses but
    the DC copper loss; see :meth:`uniform`.
    """

    pump_oil_K: float = T40_K
    line_oil_K: float = T40_K
    winding_K: float = T40_K
    drag_W: Callable[[np.ndarray], np.ndarray] = field(default=no_loss)
    electromagnetic_loss_W: Callable[[np.ndarray, np.ndarray], np.ndarray] = \
        field(default=no_loss)

    @classmethod
    def uniform(cls, T_K: float = T40_K, **kw) -> 'ThermalFeedback':
        """Return a feedback with every temperature at ``T_K`` (default 40 degC)."""
        return cls(pump_oil_K=T_K, line_oil_K=T_K, winding_K=T_K, **kw)


# --------------------------------------------------------------------- samples
@dataclass
class Samples(SampleBlock):
    """
    Kinetic signals at the sample times, one array element per sample (SI units).

    The sensor channels (what the rig measures) are those of the
    :class:`SampleBlock` it extends, so a block of samples drives the thermal
    model as the rig's sensors do.

    Truth: ``flow_m3_s`` (actuator flow into A), ``load_power_W`` = (p_a -
    p_b) flow (work rate delivered to the load, signed), ``port_a_Pa``,
    ``port_b_Pa`` (pump ports), ``q_internal_m3_s`` (port A -> port B,
    signed), ``q_external_m3_s`` (high port -> case, >= 0; equal to the
    make-up from the accumulator into the low port), ``torque_Nm`` (shaft),
    ``electrical_power_W`` = copper + electromagnetic + torque speed
    (negative in regeneration), ``copper_W`` (DC), ``electromagnetic_W``
    (the other electromagnetic losses), ``pump_friction_W``, ``drag_W``
    (airgap, end faces, bearings).

    Energy balance (exact, see :class:`KineticModel`): electrical - load =
    copper + electromagnetic + pump friction + drag
    + q_internal (port_a - port_b) + q_external (p_high - p_acc)
    + q_external (p_acc - p_low) + 2 flow (port_a - p_a).
    """

    flow_m3_s: np.ndarray
    load_power_W: np.ndarray
    port_a_Pa: np.ndarray
    port_b_Pa: np.ndarray
    q_internal_m3_s: np.ndarray
    q_external_m3_s: np.ndarray
    torque_Nm: np.ndarray
    electrical_power_W: np.ndarray
    copper_W: np.ndarray
    electromagnetic_W: np.ndarray
    pump_friction_W: np.ndarray
    drag_W: np.ndarray


# ---------------------------------------------------------------------- model
class KineticModel:
    """
    Quasi-static fluid-power and electrical model of the EHA, vectorised over samples.

    Assumptions: quasi-static (each sample is an equilibrium); the oil is
    incompressible in the flow balances (the compressibility flows
    V / K_S dp/dt of the port, line and chamber volumes are neglected, as is
    line inertia: the hydraulic natural frequency, 27-120 Hz, is far above
    the duty's 0.2-3 Hz, and the neglected flow, reversible and in phase
    with the actuator flow, is 1.6-5 % of it, docs/model.md, Why the oil
    stays incompressible); the rotor and pump inertia are neglected (the datasheet
    gives none), so the shaft torque is the pump torque; the accumulator
    holds its working pressure ``cfg.hydraulics.accumulator.pressure_Pa``.

    Per sample, with D the displacement per radian and p_case = p_acc (the
    case drains through the motor to the accumulator):

    - chambers: the low side sits at p_acc; p_A = p_acc + max(dp, 0),
      p_B = p_acc + max(-dp, 0).
    - lines (both carry Q; balanced cylinder): dp_l = line drop at the line
      oil temperature (properties at p_acc); pump ports p_a' = p_A + dp_l,
      p_b' = p_B - dp_l; dp' = p_a' - p_b'.
    - leakage (viscosity and density at the pump oil temperature and, by
      Barus, at the mean pressure of each gap's two ends), by
      :func:`~.fluid_power.gap_leakage` as the thermal model takes it: laminar
      Q = C dp / mu blended into the orifice law at high gap Reynolds numbers;
      internal Q_int from C_int and dp' (A -> B, signed); external Q_ext
      from C_ext and p_high - p_case, >= 0, from the high port
      p_high = max(p_a', p_b') to the case.
    - port mass balances, with s = +1 when port A is the high port
      (dp' >= 0) else -1, and the make-up check valve of the low port
      (p_low) feeding M = Q_ext from the accumulator:
      port A: D w + M_A = Q + Q_int + E_A;
      port B: Q + Q_int + M_B = D w + E_B;
      with E_A = Q_ext, M_B = Q_ext (A high) or E_B = Q_ext, M_A = Q_ext
      (B high), hence D w = Q + Q_int + s Q_ext in all four quadrants
      (motoring or regenerating, either direction), and make-up = leakage to
      the case, so the accumulator's net flow is zero.
    - torque: T = D dp' + sgn(w) T_f(w, dp', mu) + sgn(w) P_drag(|w|) / max(|w|, eps),
      T_f from :func:`pump_friction_torque`, P_drag the feedback's shaft
      friction (airgap, end faces, bearings); no friction torque at w = 0.
    - current I = |T| / k_t; copper = n_ph I^2 R(T_w); the other
      electromagnetic losses P_em(|w|, I) from the feedback's callable;
      electrical = copper + P_em + T w.

    Energy: T w = D w dp' + P_friction + P_drag, and with D w dp' =
    Q dp + 2 Q dp_l + Q_int dp' + Q_ext (p_high - p_low), the electrical
    power minus the load power is copper + P_em + pump friction + drag
    + Q_int dp' + Q_ext (p_high - p_case) (leakage into the case)
    + Q_ext (p_case - p_low) (make-up throttled across one line drop into
    the low port; tens of mW on the reference rig, about 1e-4 of the power,
    slightly negative near load reversals where the line drop lifts the low
    port above p_acc) + 2 Q dp_l (lines).
    """

    def __init__(self, cfg: Config, oil: Oil, log: Optional[ValidityLog] = None) -> None:
        """Precompute the constants of ``cfg`` for fast, vectorised sampling."""
        hyd = cfg.hydraulics
        pump = hyd.pump
        self.cfg = cfg
        self.oil = oil
        self.log = log
        self.d_rad = displacement_per_rad(pump.displacement_m3_rev)
        self._c_int = pump.internal_leak_coeff_m3
        self._c_ext = pump.external_leak_coeff_m3
        self._gap = (pump.leak_gap_height_m, pump.leak_gap_length_m, pump.leak_discharge_coeff)
        self._c_v = pump.viscous_friction_coeff
        self._c_f = pump.pressure_friction_coeff
        self._t_c = pump.coulomb_torque_Nm
        self.p_acc = hyd.accumulator.pressure_Pa
        self.p_case = self.p_acc
        self._line_len = hyd.lines.length_m
        self._line_bore = hyd.lines.bore_m
        self._k_t = cfg.motor.torque_constant_Nm_A
        w = cfg.motor.winding
        self._phases = w.phases
        self._r20 = w.phase_resistance_20C_ohm
        self._tempco = w.copper_tempco_1_K
        self._line_key: Optional[float] = None
        self._line_props = (0.0, 0.0)
        self._r_key: Optional[float] = None
        self._r_phase = 0.0

    def line_properties(self, T_K: float) -> Tuple[float, float]:
        """Return the line oil ``(rho, mu)`` at ``T_K`` and the accumulator pressure (cached)."""
        if T_K != self._line_key:
            self._line_props = (float(self.oil.density(T_K, self.p_acc, self.log)),
                                float(self.oil.dynamic_viscosity(T_K, self.p_acc, self.log)))
            self._line_key = T_K
        return self._line_props

    def phase_resistance(self, T_K: float) -> float:
        """Return the phase resistance (ohm) at winding temperature ``T_K`` (cached)."""
        if T_K != self._r_key:
            self._r_phase = float(copper_resistance(self._r20, self._tempco, T_K))
            self._r_key = T_K
        return self._r_phase

    def sample(self, duty: Duty, t_s: np.ndarray, fb: ThermalFeedback,
               load_scale: Union[float, np.ndarray] = 1.0) -> Samples:
        """
        Return the :class:`Samples` of ``duty`` at the times ``t_s`` (s) in state ``fb``.

        Vectorised over ``t_s`` (1-D); the feedback temperatures are held over
        the call. ``load_scale`` (a number or one per sample) multiplies the
        duty's load pressure: the part of the load a current-limited drive
        holds (:meth:`sample_limited`).
        """
        t = np.asarray(t_s, dtype=float)
        n = t.size
        q, dp, x = duty.demand(t)
        if np.any(load_scale != 1.0):
            dp = dp * load_scale
        p_acc = self.p_acc
        p_a = np.maximum(dp, 0.0)
        p_a += p_acc
        p_b = np.maximum(-dp, 0.0)
        p_b += p_acc
        rho_l, mu_l = self.line_properties(fb.line_oil_K)
        dpl = line_pressure_drop(q, self._line_len, self._line_bore, rho_l, mu_l, self.log)
        port_a = p_a + dpl
        port_b = p_b - dpl
        dpp = port_a - port_b
        p_high = np.maximum(port_a, port_b)
        # viscosity at the mean pressure of each gap: port to port, high port to case
        p_gap = np.empty(2 * n)
        np.add(port_a, port_b, out=p_gap[:n])
        np.add(p_high, self.p_case, out=p_gap[n:])
        p_gap *= 0.5
        rho = self.oil.density(fb.pump_oil_K, p_gap, self.log)
        mu = self.oil.kinematic_viscosity(fb.pump_oil_K, p_gap, self.log) * rho
        mu_ports = mu[:n]
        q_int, re_int = gap_leakage(self._c_int, dpp, mu_ports, rho[:n], *self._gap)
        q_ext, re_ext = gap_leakage(self._c_ext, p_high - self.p_case, mu[n:], rho[n:],
                                    *self._gap)
        check_gap_leakage(self.log, re_int)
        check_gap_leakage(self.log, re_ext)
        np.maximum(q_ext, 0.0, out=q_ext)
        # D w = Q + Q_int + s Q_ext, s = +1 when port A is the high port (docstring)
        w = q + q_int
        w += np.where(dpp >= 0.0, q_ext, -q_ext)
        w /= self.d_rad
        sw = np.sign(w)
        aw = np.abs(w)
        t_fric = pump_friction_torque(w, dpp, mu_ports, self.d_rad, self._c_v, self._c_f,
                                      self._t_c)
        t_fric *= sw
        torque = self.d_rad * dpp
        torque += t_fric
        if fb.drag_W is no_loss:
            t_drag = np.zeros(n)
        else:
            t_drag = sw * np.asarray(fb.drag_W(aw), dtype=float)
            t_drag /= np.maximum(aw, SPEED_EPS_RAD_S)
            torque += t_drag
        current = np.abs(torque)
        current /= self._k_t
        copper = current * current
        copper *= self._phases * self.phase_resistance(fb.winding_K)
        if fb.electromagnetic_loss_W is no_loss:
            em = np.zeros(n)
        else:
            em = np.asarray(fb.electromagnetic_loss_W(aw, current), dtype=float)
            if em.shape != w.shape:
                em = np.broadcast_to(em, w.shape).copy()
        electrical = torque * w
        electrical += copper
        electrical += em
        return Samples(
            t_s=t, current_A=current, speed_rad_s=w, p_a_Pa=p_a, p_b_Pa=p_b,
            p_acc_Pa=np.full(n, p_acc), position_m=x, flow_m3_s=q, load_power_W=(p_a - p_b) * q,
            port_a_Pa=port_a, port_b_Pa=port_b, q_internal_m3_s=q_int, q_external_m3_s=q_ext,
            torque_Nm=torque, electrical_power_W=electrical, copper_W=copper,
            electromagnetic_W=em, pump_friction_W=t_fric * w, drag_W=t_drag * w)

    def sample_limited(self, duty: Duty, t_s: np.ndarray, fb: ThermalFeedback,
                       limit_A: float) -> Tuple[Samples, np.ndarray]:
        """
        Return the samples of a drive that limits the phase current to ``limit_A``, and the demand.

        The drive limits its torque (the current is the torque over k_t), so
        where the duty asks for more than ``limit_A`` the pump cannot hold the
        full load: the load pressure is scaled down until the current is the
        limit, the rest of the sample (flow, hence speed and position)
        following the duty as before, as if the rig's load gave way. Samples
        within the limit are left alone. The torque is nearly affine in the
        load scale (D dp' plus a friction rising with dp', plus drag and line
        drop that do not), so a few steps of regula falsi (Illinois) find the
        scale; the samples keep the end of its bracket within the limit. Two
        cases cut more than needed or cannot: where the scale takes the speed
        through zero, the Coulomb friction's jump lies between the bracket's
        ends (on the reference rig's stage 1, up to one clamped sample in 20,
        cut by up to 2 A more);
        a limit below the unloaded current (friction and drag alone) leaves
        the load at zero and the current above the limit: this drive derates
        by load, not by speed.

        :return: ``(samples, demanded_A)``: the samples the drive makes and
            the current the duty asked for, per sample.
        """
        full = self.sample(duty, t_s, fb)
        demanded = full.current_A.copy()
        over = np.flatnonzero(demanded > limit_A)
        if not over.size:
            return full, demanded
        t = full.t_s[over]
        # signed torque: in regeneration the friction opposes the load's torque
        target = np.sign(full.torque_Nm[over]) * limit_A * self._k_t
        lo, f_lo = np.zeros(over.size), self.sample(duty, t, fb, 0.0).torque_Nm - target
        hi, f_hi = np.ones(over.size), full.torque_Nm[over] - target
        hi[np.sign(f_lo) == np.sign(f_hi)] = 0.0     # over the limit even unloaded
        kept = np.zeros(over.size)      # +1: lo moved last, -1: hi moved last
        for _ in range(LIMIT_ITERATIONS):
            scale = lo + (hi - lo) * np.clip(f_lo / np.where(f_lo != f_hi, f_lo - f_hi, 1.0),
                                             0.0, 1.0)
            miss = self.sample(duty, t, fb, scale).torque_Nm - target
            low = np.sign(miss) == np.sign(f_lo)
            # Illinois: an end left behind twice has its value halved, so that both ends move
            f_hi = np.where(low & (kept > 0), 0.5 * f_hi, f_hi)
            f_lo = np.where(~low & (kept < 0), 0.5 * f_lo, f_lo)
            lo, f_lo = np.where(low, scale, lo), np.where(low, miss, f_lo)
            hi, f_hi = np.where(low, hi, scale), np.where(low, f_hi, miss)
            kept = np.where(low, 1.0, -1.0)
        part = self.sample(duty, t, fb, lo)      # the bracket's end within the limit
        for name in Samples.__dataclass_fields__:
            getattr(full, name)[over] = getattr(part, name)
        return full, demanded
