"""
Kinetic (fluid-power and electrical) model of the wet EHA, for offline runs.

Turns a duty (actuator flow demand and load pressure over time, :mod:`.duty`)
into the signals the rig's sensors show (phase current, motor speed, both actuator
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
from typing import Callable, Optional, Tuple, Union

import numpy as np

from .duty import Duty
from .eha import SampleBlock
from .fluid_power import (check_gap_leakage, displacement_per_rad, gap_leakage,
                          line_pressure_drop, pump_friction_torque)
from .losses import copper_resistance
from .oil import Oil
from .validity import ValidityLog
from ..config import Config
from ..units import C_TO_K

#: 40 degC in kelvin, the default oil and winding temperature.
T40_K = C_TO_K + 40.0
#: Speed magnitude (rad/s) below which a friction power is not turned into a torque.
SPEED_EPS_RAD_S = 1.0e-6
#: Secant steps of :meth:`KineticModel.sample_limited`.
LIMIT_ITERATIONS = 6


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
        q_int, q_ext, mu_ports = self._leakage(port_a, port_b, dpp, fb.pump_oil_K)
        # D w = Q + Q_int + s Q_ext, s = +1 when port A is the high port (docstring)
        w = q + q_int
        w += np.where(dpp >= 0.0, q_ext, -q_ext)
        w /= self.d_rad
        aw = np.abs(w)
        torque, t_fric, t_drag = self._shaft_torque(w, aw, dpp, mu_ports, fb)
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

    def _leakage(self, port_a: np.ndarray, port_b: np.ndarray, dpp: np.ndarray,
                 pump_oil_K: float) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """
        Return the internal and external leakage (m^3/s) and the viscosity between the ports.

        Internal: port A -> B, signed; external: high port -> case, >= 0. Oil
        properties at the pump oil temperature and each gap's mean pressure
        (class docstring).
        """
        n = dpp.size
        p_high = np.maximum(port_a, port_b)
        # viscosity at the mean pressure of each gap: port to port, high port to case
        p_gap = np.empty(2 * n)
        np.add(port_a, port_b, out=p_gap[:n])
        np.add(p_high, self.p_case, out=p_gap[n:])
        p_gap *= 0.5
        rho = self.oil.density(pump_oil_K, p_gap, self.log)
        mu = self.oil.kinematic_viscosity(pump_oil_K, p_gap, self.log) * rho
        mu_ports = mu[:n]
        q_int, re_int = gap_leakage(self._c_int, dpp, mu_ports, rho[:n], *self._gap)
        q_ext, re_ext = gap_leakage(self._c_ext, p_high - self.p_case, mu[n:], rho[n:],
                                    *self._gap)
        check_gap_leakage(self.log, re_int)
        check_gap_leakage(self.log, re_ext)
        np.maximum(q_ext, 0.0, out=q_ext)
        return q_int, q_ext, mu_ports

    def _shaft_torque(self, w: np.ndarray, aw: np.ndarray, dpp: np.ndarray,
                      mu_ports: np.ndarray, fb: ThermalFeedback
                      ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """
        Return the shaft torque (N m) at speed ``w`` (|w|: ``aw``), with its friction parts.

        ``(torque, pump friction, drag)``: T = D dp' + sgn(w) T_f + sgn(w) P_drag / |w|
        (class docstring); the drag is zero when the feedback has none.
        """
        sw = np.sign(w)
        t_fric = pump_friction_torque(w, dpp, mu_ports, self.d_rad, self._c_v, self._c_f,
                                      self._t_c)
        t_fric *= sw
        torque = self.d_rad * dpp
        torque += t_fric
        if fb.drag_W is no_loss:
            t_drag = np.zeros(w.size)
        else:
            t_drag = sw * np.asarray(fb.drag_W(aw), dtype=float)
            t_drag /= np.maximum(aw, SPEED_EPS_RAD_S)
            torque += t_drag
        return torque, t_fric, t_drag

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
