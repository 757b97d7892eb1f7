"""
The coupled wet-EHA thermal model: wet motor plus hydraulic control nodes.

It is driven by blocks of sensor samples (phase current, speed, both actuator
port pressures, accumulator pressure, actuator position), one block per model
step, whether they come from the rig (the live estimator) or from the kinetic
simulator. From the samples it derives, at the current oil temperatures, the
flows (actuator flow from the position signal, leakage from the pressures and
the viscosity, pump displacement flow from the speed), the mean of every
flow-pressure product, the pump friction and the motor losses, and steps:

- the pump case leakage (external leakage) enters the motor as its cooling
  flow at the case oil temperature, and the motor's outlet oil returns to the
  accumulator: that flow is the coupling of the two sub-models;
- the oil viscosity at the present temperatures sets leakage and friction.

The motor's speed- and flow-dependent coefficients follow a low-pass filter
in sample time (``coefficient_filter_s``), so the motor carries a smoothed
leakage flow; the pump case oil buffers the difference with the pulsating
leakage (a few mL of its 40 mL), and the buffer's content feeds back into the
motor's flow so that it cannot drift. Mass and energy balance exactly at
every step, and no oil takes a path the rig does not have.
"""

from dataclasses import dataclass
import functools
from typing import Dict, NamedTuple, Optional, Tuple

import numpy as np

from . import fluid_power as fp
from .eha_kernels import (ActuatorGeometry, FlowConstants, node_pressures, step_flows_kernel,
                          substep_volumes)
from .hydraulics import (CASE, HydraulicCircuit, LINE_A, LINE_B, NODES, PORT_A, PORT_B, StepFlows,
                         SubSteps)
from .motor import MotorInputs, WetMotor
from .oil import get_oil, Oil
from .quantities import coupled_outputs, QuantityMap
from .validity import ValidityLog, within
from ..config import Config
from ..units import L_MIN_PER_M3_S

#: the case oil may fall this far below its nominal volume (a fraction), never further
CASE_BUFFER_FLOOR = 0.75


@dataclass
class SampleBlock:
    """
    Sensor samples of one model step, as numpy arrays of equal length.

    Times ``t_s`` are strictly increasing; each sample stands for the interval
    since the previous one. Units: A RMS, rad/s, Pa (absolute port pressures of
    the actuator's chambers A and B, and of the accumulator), m (LVDT).
    """

    t_s: np.ndarray
    current_A: np.ndarray
    speed_rad_s: np.ndarray
    p_a_Pa: np.ndarray
    p_b_Pa: np.ndarray
    p_acc_Pa: np.ndarray
    position_m: np.ndarray


class MotorTransition(NamedTuple):
    """
    The motor network's exact step: x_end = Ad x + Bd w, its mean Mx x + Mw w, ``substeps`` times.

    ``w`` is the network's inputs, the boundary temperatures (K) then the
    source powers (W); numba kernels take the tuple as it is.
    """

    Ad: np.ndarray
    Bd: np.ndarray
    Mx: np.ndarray
    Mw: np.ndarray
    substeps: int


class CircuitTransition(NamedTuple):
    """
    The hydraulic circuit's step: T_end = Phi T + g_acc T_outlet + g_case Q_case + the rest.

    ``g_acc`` the response to the motor outlet's step-mean temperature (K/K),
    ``g_case`` to extra heat into the case oil (K/W); numba kernels take it as it is.
    """

    Phi: np.ndarray
    g_acc: np.ndarray
    g_case: np.ndarray


@dataclass(frozen=True)
class Linearisation:
    """
    The coupled model's last step as linear maps, named, for a state estimator.

    States (``state_names``): the motor network's states, then the hydraulic
    nodes (K), as :attr:`EHAModel.state`. The motor's inputs
    (``motor_input_names``) are its network's boundaries (K) and sources (W);
    the circuit takes the motor outlet (K) and a heat into the case (W). The
    copper losses depend on their temperatures: ``copper_K`` and
    ``copper_power_W`` give the operating point of that feedback, the DC part
    (as R(T)) less the AC excess (as 1 / R(T)), without a heat the caller
    added (:attr:`WetMotor.extra_power_W`): dP/dT = alpha copper_power_W /
    (1 + alpha (T - 20 degC)).
    """

    state_names: Tuple[str, ...]
    motor_input_names: Tuple[str, ...]
    motor: MotorTransition
    circuit: CircuitTransition
    motor_capacity_J_K: np.ndarray     # heat capacity of each motor state
    circuit_capacity_J_K: np.ndarray   # heat capacity of each hydraulic node
    copper_K: np.ndarray
    copper_power_W: np.ndarray


class EHAModel:
    """
    One coupled thermal model of the wet EHA, one state vector, named outputs.

    The state is the motor network's states followed by the 13 hydraulic
    node temperatures (K). ``step(block, ambient_K)`` advances to the last
    sample time of the block; ``outputs()`` gives the named temperatures (K)
    and heat flows (W) of the last step.
    """

    def __init__(self, cfg: Config, oil: Optional[Oil] = None,
                 log: Optional[ValidityLog] = None, coefficient_filter_s: float = 4.0,
                 defer_refresh: bool = False) -> None:
        self.cfg = cfg
        self.oil = oil if oil is not None else get_oil(cfg.fluid.grade)
        self.log = log if log is not None else ValidityLog()
        # with filtered coefficients, sub-steps would not track anything faster: the
        # network step is exact for inputs held over the step
        # friction and R(T) follow the present temperatures every step, so the 0.5 K
        # refresh threshold only bounds the convection coefficients (~1.5 %/K)
        # defer_refresh: see WetMotor; the live estimator re-discretises after publishing
        self.motor = WetMotor(cfg.motor, self.oil, self.log, refresh_dT_K=0.5,
                              max_substep_s=1.0, coefficient_filter_s=coefficient_filter_s,
                              defer_refresh=defer_refresh)
        self.circuit = HydraulicCircuit(cfg.hydraulics, self.oil)
        # the outputs are evaluated on the motor's node temperatures, then the circuit's
        net = self.motor.net
        circuit_value = {name: net.n + i for i, name in enumerate(NODES)}
        #: the named states (those of :attr:`state`) and the outputs over them
        self.quantities = QuantityMap(
            net.state_names + list(NODES), coupled_outputs(self.motor),
            lambda name: circuit_value[name] if name in circuit_value else net.index(name))
        h = cfg.hydraulics
        self.area = h.actuator.area_m2
        self.d_rad = fp.displacement_per_rad(h.pump.displacement_m3_rev)
        # the leakage gaps: laminar coefficients (internal, external) and the gap geometry
        self._leak_coeffs = np.array([[h.pump.internal_leak_coeff_m3],
                                      [h.pump.external_leak_coeff_m3]])
        self._leak_gap = (h.pump.leak_gap_height_m, h.pump.leak_gap_length_m,
                          h.pump.leak_discharge_coeff)
        # the constants of the flows kernel (see step_flows_kernel)
        self._geometry = ActuatorGeometry(self.area, self.d_rad, h.lines.length_m,
                                          h.lines.bore_m, h.actuator.dead_volume_m3,
                                          h.actuator.half_stroke_m)
        ci = self.circuit
        self._flow_constants = tuple(FlowConstants(
            self._geometry, self._leak_coeffs, *self._leak_gap, h.pump.viscous_friction_coeff,
            h.pump.pressure_friction_coeff, h.pump.coulomb_torque_Nm, self.oil.laws, ci.u, ci.d,
            ci.oil_volumes))
        #: longest sub-step of the oil volumes (s); a forecast, on smoothed duty, takes longer
        self.oil_substep_s = h.substep_s
        self.T_hyd: Optional[np.ndarray] = None
        self.case_buffer_m3 = 0.0      # case oil above its nominal volume
        self.case_floor_hits = 0       # (sub-)steps where the case would have emptied (a guard)
        self._case_prev_K, self._dt_prev = 0.0, 0.0
        # slower than the two filter stages, so buffer -> filter -> flow stays damped
        self.buffer_time_s = max(3.0 * coefficient_filter_s, 1.0)
        self._last: Optional[tuple] = None   # last sample: t, x, node pressures
        self.flows: Optional[StepFlows] = None
        self.heat_W: Dict[str, float] = {}
        self.time_s = 0.0

    # ------------------------------------------------------------------ state
    def initialise(self, T_K: float, first: SampleBlock) -> None:
        """Set every temperature to ``T_K`` and take the first sample as the starting point."""
        self.motor.initialise(T_K)
        self.T_hyd = np.full(self.circuit.n, float(T_K))
        self.circuit.T_report = None
        self.time_s = float(first.t_s[-1])
        raw = np.array([first.p_a_Pa[-1], first.p_b_Pa[-1], first.p_acc_Pa[-1]])
        p = self._node_pressures(raw[:, None], np.zeros(1))
        self._last = (float(first.t_s[-1]), float(first.position_m[-1]), raw, p[:, -1].copy())

    def hold_from(self, sample: SampleBlock) -> None:
        """
        Take the last values of ``sample`` as the last sample taken; keep the state and time.

        A copy that then steps a made-up duty (the estimator's limits hold the
        recent one) starts it without the jump from the real last sample: the
        pressure work of that jump would heat the oil once, a transient of the
        copy, not of the duty.
        """
        raw = np.array([sample.p_a_Pa[-1], sample.p_b_Pa[-1], sample.p_acc_Pa[-1]])
        p = self._node_pressures(raw[:, None], np.zeros(1))
        self._last = (self._last[0], float(sample.position_m[-1]), raw, p[:, -1].copy())

    @property
    def defer_refresh(self) -> bool:
        """Return whether motor re-discretisations wait for :meth:`prepare` or the next step."""
        return self.motor.net.hold_changes

    @defer_refresh.setter
    def defer_refresh(self, value: bool) -> None:
        self.motor.net.apply_changes()
        self.motor.net.hold_changes = bool(value)

    def prepare(self, dt_s: float) -> bool:
        """Do a deferred motor re-discretisation now, for a next step of ``dt_s``."""
        return self.motor.prepare(dt_s)

    @property
    def state(self) -> np.ndarray:
        """Return the state vector: motor states, then hydraulic node temperatures (K)."""
        return np.concatenate([self.motor.x, self.T_hyd])

    @property
    def last_position_m(self) -> float:
        """Return the actuator position (m) of the last sample the model took."""
        return self._last[1]

    @functools.cached_property
    def _motor_input_names(self) -> Tuple[str, ...]:
        """Return the motor transition's inputs: boundary temperatures, then each source."""
        mo = self.motor
        sources = [f'{group}_{k}' for group, idx in mo.sources.items()
                   for k in range(idx.stop - idx.start)]
        return tuple(mo.net.boundary_names) + tuple(sources)

    def linearize(self) -> Linearisation:
        """
        Return the last step as linear maps (:class:`Linearisation`), as a filter predicts with.

        The circuit must keep its transition (``circuit.keep_transition``).
        """
        mo, net = self.motor, self.motor.net
        disc = net.last_disc
        p_cu = mo.power_W[mo.src_copper]
        if mo.extra_power_W is not None:          # a learned heat does not follow R(T)
            p_cu = p_cu - mo.extra_power_W[mo.src_copper]
        # the DC part grows as R(T), the AC excess falls as 1 / R(T): dP/dT weighs their
        # difference
        p_cu = p_cu - 2.0 * mo.copper_ac_W
        Phi, g_acc, g_case, C = self.circuit.last_transition()
        return Linearisation(
            state_names=self.quantities.state_names,
            motor_input_names=self._motor_input_names,
            motor=MotorTransition(disc.Ad, disc.Bd, disc.Mx, disc.Mw, mo.last_substeps),
            circuit=CircuitTransition(Phi, g_acc, g_case),
            motor_capacity_J_K=net.coefficients_in_use()[2][net.dynamic],
            circuit_capacity_J_K=C, copper_K=mo.T[mo.idx_copper], copper_power_W=p_cu)

    def correct(self, delta_K: np.ndarray) -> None:
        """
        Add a correction ``delta_K`` to the state (K, in the order of :attr:`state`).

        The motor's algebraic nodes follow their states, the circuit's reported
        temperatures move with its nodes, and the case's previous temperature
        (the motor inlet's extrapolation) moves too, so the next step does not
        take the correction for a trend.
        """
        mo = self.motor
        m = mo.x.size
        dx = delta_K[:m]
        mo.x = mo.x + dx
        T = mo.T.copy()
        T[mo.net.dynamic] += dx
        a, out_x = mo.net.algebraic_map()
        if a.size:
            T[a] += out_x @ dx
        mo.T = T
        dh = delta_K[m:m + self.circuit.n]
        self.T_hyd = self.T_hyd + dh
        if self.circuit.T_report is not None:
            self.circuit.T_report = self.circuit.T_report + dh
        self._case_prev_K += float(dh[CASE])

    # ------------------------------------------------------------ the samples
    def _node_pressures(self, sensed: np.ndarray, flow_m3_s: np.ndarray) -> np.ndarray:
        """Return the pressure (Pa) of every oil node (8 x n) from sensed p_a, p_b, p_acc."""
        ln = self.cfg.hydraulics.lines
        P, re = node_pressures(sensed, flow_m3_s, 0.5 * (self.T_hyd[LINE_A] + self.T_hyd[LINE_B]),
                               ln.length_m, ln.bore_m, self.oil.laws)
        fp.check_line_pressure_drop(self.log, re)
        return P

    def step_flows(self, b: SampleBlock):
        """
        Derive the hydraulic flows, flow-pressure products and pump friction of a block.

        Returns (StepFlows without the motor terms, external leakage mean m^3/s,
        step length s, interval weights, the sub-steps' sums of
        :func:`~.eha_kernels.segment_sums`, the mean of the current squared A^2). Everything
        is evaluated per sample interval: the mean flow from the position
        difference, paired with the interval's mean pressures (pairing it with
        the end pressure would lag by half an interval and book spurious load
        work).
        """
        p0 = self._last[3]
        h = self.cfg.hydraulics
        (flow, work, P_end, vdp, x_mean, dx, fric_W, q_ext, dt, wgt, raw_end,
         re, re_gap, seg, i_sq) = step_flows_kernel(
            self._last, (b.t_s, b.position_m, b.p_a_Pa, b.p_b_Pa, b.p_acc_Pa, b.speed_rad_s,
                         b.current_A), 0.5 * (self.T_hyd[LINE_A] + self.T_hyd[LINE_B]),
            float(self.T_hyd[CASE]), self._flow_constants, self.oil_substep_s)
        fp.check_line_pressure_drop(self.log, re)
        if not within(re_gap, 0.0, fp.GAP_LAMINAR_RE):   # laminar, the usual case: no flag
            fp.check_gap_leakage(self.log, re_gap)
        act = h.actuator
        chambers = (act.dead_volume_m3 + self.area * (act.half_stroke_m + x_mean),
                    act.dead_volume_m3 + self.area * (act.half_stroke_m - x_mean))
        dv = self.area * dx
        sf = StepFlows(flow, work, p0, P_end, vdp, chambers, (dv, -dv), 0.0, 0.0, 0.0, 0.0,
                       fric_W)
        self._pending_last = (float(b.t_s[-1]), float(b.position_m[-1]), raw_end, P_end)
        return sf, q_ext, dt, wgt, seg, i_sq

    # ------------------------------------------------------------------ step
    def step(self, b: SampleBlock, ambient_K: float,
             max_substep_s: Optional[float] = None, exact_coefficients: bool = False) -> None:
        """
        Advance the coupled model over one block of samples.

        ``max_substep_s`` overrides the motor's sub-step limit for this block:
        a long block (the estimator crossing a silence of the sensors, its
        forecast) is then one exact motor step. A block longer than the case
        buffer's time constant refreshes the motor's coefficients exactly: the
        1 % tolerance on the motor's flow, integrated over minutes, would
        drain or flood the 40 mL of case oil; ``exact_coefficients`` does it
        for any block (a probe of the present state, past the filters).
        """
        if self._last is None:
            raise RuntimeError('initialise the model with a first sample before stepping')
        sf, q_ext, dt, wgt, seg, i_sq = self.step_flows(b)
        ci = self.circuit
        # the motor's inlet over the step: the case temperature extrapolated to mid-step
        # (the case moves with the leakage heat; a start-of-step value would lag), over
        # at most twice the previous step (a step much longer than the one before would
        # stretch a trend over far more time than it was seen in)
        T_now = float(self.T_hyd[CASE])
        T_case = T_now + 0.5 * (T_now - self._case_prev_K) * min(dt, 2.0 * self._dt_prev) \
            / self._dt_prev if self._dt_prev else T_now
        self._case_prev_K, self._dt_prev = T_now, dt
        p_case = float(sf.p_end_Pa[CASE])
        # the buffered oil drains through the motor: the motor's (filtered) flow follows
        # the leakage plus the buffer over buffer_time_s, or over the step when that is
        # longer (draining faster than in one step would overshoot and ring)
        q_drive = max(q_ext + self.case_buffer_m3 / max(self.buffer_time_s, dt), 0.0)
        u = MotorInputs(current_sq_mean_A2=i_sq, speed_rad_s=b.speed_rad_s, oil_inlet_K=T_case,
                        oil_flow_m3_s=q_drive, ambient_K=ambient_K, case_pressure_Pa=p_case,
                        current_A=b.current_A)
        self.motor.step(dt, u, max_substep_s=max_substep_s,
                        exact_coefficients=exact_coefficients or dt > self.buffer_time_s)
        m = self.motor
        # the enthalpy flow the motor network used decides the flow through the motor;
        # the rest of the leakage bypasses it, so the loop's mass balance is exact
        m_cp = float(m.net.coefficients_in_use()[1][m.adv[0]])
        rho_cp = float(ci.rho_cp(T_case, p_case))
        q_motor = m_cp / rho_cp
        buffer0 = self.case_buffer_m3
        sf.motor_flow_m3_s = q_motor
        sf.motor_outlet_K = float(m.T_mean[m.idx_oil[-1]])
        if wgt.size > 1:
            # the oil volumes sub-step by sub-step: their flows, volumes and pressure
            # work swing within a duty cycle
            self.T_hyd = ci.step_substeps(self.T_hyd, self._substeps(seg, q_motor), q_motor,
                                          sf.motor_outlet_K, ambient_K, rho_cp)
            dv_case = self.case_buffer_m3 - buffer0
            sf.case_volume_m3 = ci.oil_volumes[CASE] + buffer0 + 0.5 * dv_case
            sf.case_dV_m3 = dv_case
        else:
            # one sample interval (held inputs: a silence crossed in one block): flows
            # and volumes are constant over it, and one exact step holds for any length
            dv_case = self._case_change(q_ext, q_motor, dt)
            sf.case_volume_m3 = ci.oil_volumes[CASE] + buffer0 + 0.5 * dv_case
            sf.case_dV_m3 = dv_case
            self.case_buffer_m3 += dv_case
            self.T_hyd = ci.step(self.T_hyd, dt, sf, ambient_K, rho_cp)
        self.flows = sf
        self._last = self._pending_last
        self.time_s = self._last[0]
        self.heat_W = {
            'motor_losses': float(m.power_W.sum()),
            'motor_to_oil': float(m_cp * (sf.motor_outlet_K - T_case)),
            'pump_friction': sf.pump_friction_W,
            'hydraulic_sources': float(ci.last_sources.sum()),
            'motor_flow_L_min': q_motor * L_MIN_PER_M3_S,
            'case_buffer_mL': self.case_buffer_m3 * 1e6,
            'leakage_to_case_L_min': q_ext * L_MIN_PER_M3_S,
        }

    def _case_change(self, q_ext: float, q_motor: float, dt: float) -> float:
        """
        Return the change (m^3) of the case oil over ``dt``: leakage in, motor flow out.

        The motor's filtered flow lags a sudden fall of the leakage (the
        pressures dropping with hot, thin oil): the case never gives more oil
        than CASE_BUFFER_FLOOR allows, and each time this guard acts it is
        counted (the books then miss that volume's heat).
        """
        dv = (q_ext - q_motor) * dt
        floor = -CASE_BUFFER_FLOOR * self.circuit.oil_volumes[CASE]
        if self.case_buffer_m3 + dv < floor:
            dv = floor - self.case_buffer_m3
            self.case_floor_hits += 1
        return dv

    def _substeps(self, seg: tuple, q_motor: float) -> SubSteps:
        """Return the circuit's sub-steps from the flows kernel's sums; move the case buffer."""
        h, x_end, flow, work, vdp, p_mid, fric, q_ext = seg
        buffer = np.empty(h.size + 1)
        buffer[0] = self.case_buffer_m3
        for k, (q_k, h_k) in enumerate(zip(q_ext.tolist(), h.tolist())):
            self.case_buffer_m3 += self._case_change(q_k, q_motor, h_k)
            buffer[k + 1] = self.case_buffer_m3
        vol = substep_volumes(self._last[1], x_end, buffer, self.circuit.oil_volumes,
                              tuple(self._geometry))
        return SubSteps(h, flow, work, vdp, p_mid, fric, vol)

    # --------------------------------------------------------------- outputs
    def outputs(self) -> Dict[str, float]:
        """
        Return the outputs of :func:`~.quantities.coupled_outputs`, in K.

        The motor's are those of the present state; the hydraulic nodes' those
        the circuit reports (:attr:`HydraulicCircuit.T_report`: the last
        step's means when it was sub-stepped).
        """
        return self.quantities.values(self._output_values(), self._port_a_high())

    def outputs_and_states(self) -> Tuple[Dict[str, float], np.ndarray]:
        """Return :meth:`outputs` and the state each takes, in the map's order (-1: a mean)."""
        return self.quantities.values_and_states(self._output_values(), self._port_a_high())

    def _output_values(self) -> np.ndarray:
        """Return the temperatures the outputs are evaluated on: motor nodes, then circuit (K)."""
        ci = self.circuit
        return np.concatenate([self.motor.T, self.T_hyd if ci.T_report is None else ci.T_report])

    def _port_a_high(self) -> Optional[bool]:
        """Return whether port A is the pump's outlet (the higher pressure; None: no sample)."""
        if self._last is None:
            return None
        p = self._last[3]
        return bool(p[PORT_A] >= p[PORT_B])

    def energy(self) -> Dict[str, float]:
        """
        Return the energies (J) since the start: heat generated, stored, to ambient.

        ``coupling_mismatch`` is the enthalpy the motor reports giving the oil
        minus what the circuit received; it is not zero only because the motor
        takes the case temperature at the start of a step as its inlet.
        """
        me, he = self.motor.energy_J, self.circuit.energy_J
        return {'sources': me['losses'] + he['sources'],
                'stored': me['stored'] + he['stored'],
                'to_ambient': me['to_ambient'] + he['to_ambient'],
                'coupling_mismatch': me['to_oil'] - he['motor_loop']}
