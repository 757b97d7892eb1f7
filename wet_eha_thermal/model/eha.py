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
from typing import Dict, NamedTuple, Optional, Tuple

import numpy as np

from . import fluid_power as fp
from .compiled import jit
from .hydraulics import (ACCUMULATOR, CASE, CHAMBER_A, CHAMBER_B, HydraulicCircuit, LEAK_A_TO_B,
                         LEAK_A_TO_CASE, LEAK_B_TO_A, LEAK_B_TO_CASE, LINE_A, LINE_A_ACTUATOR_END,
                         LINE_A_ACTUATOR_END_BACK, LINE_A_PUMP_END, LINE_A_PUMP_END_BACK, LINE_B,
                         LINE_B_ACTUATOR_END, LINE_B_ACTUATOR_END_BACK, LINE_B_PUMP_END,
                         LINE_B_PUMP_END_BACK, MAKE_UP_A, MAKE_UP_B, N_OIL, NODES, PORT_A, PORT_B,
                         PUMP_INTO_A, PUMP_INTO_B, StepFlows, SubSteps)
from .motor import MotorInputs, WetMotor
from .oil import density as oil_density, get_oil, kinematic_viscosity as oil_nu, Oil
from .quantities import coupled_outputs, QuantityMap
from .validity import ValidityLog, within
from ..config import Config

#: the case oil may fall this far below its nominal volume (a fraction), never further
CASE_BUFFER_FLOOR = 0.75


class ActuatorGeometry(NamedTuple):
    """The actuator's, the pump's and the lines' geometry in the flows kernels."""

    area_m2: float              #: the actuator's piston area
    displacement_m3_rad: float  #: the pump's displacement per radian
    line_length_m: float
    line_bore_m: float
    dead_volume_m3: float       #: a chamber's oil at the end of its stroke
    half_stroke_m: float


class FlowConstants(NamedTuple):
    """
    The constants of :func:`step_flows_kernel`.

    ``leak_coeffs_m3`` the laminar coefficients of the internal and external
    leakage (2 x 1); the gap's height, length and discharge coefficient of
    :func:`~.fluid_power.gap_leakage`; the pump's friction coefficients of
    :func:`~.fluid_power.pump_friction_torque`; ``link_up``/``link_down`` the
    oil nodes of each link of LINKS; ``oil_volumes_m3`` the nominal volumes.
    As :class:`~.hydraulics.CircuitConstants`, a kernel called from Python
    takes it as a plain tuple and names it again.
    """

    geometry: ActuatorGeometry
    leak_coeffs_m3: np.ndarray
    leak_gap_height_m: float
    leak_gap_length_m: float
    leak_discharge_coeff: float
    viscous_friction_coeff: float
    pressure_friction_coeff: float
    coulomb_torque_Nm: float
    oil_laws: tuple
    link_up: np.ndarray
    link_down: np.ndarray
    oil_volumes_m3: np.ndarray


class LastSample(NamedTuple):
    """The last sample of the previous block, where the next block's intervals start."""

    t_s: float
    position_m: float
    sensed_Pa: np.ndarray       #: p_a, p_b, p_acc as sensed
    node_Pa: np.ndarray         #: the oil nodes' pressures


class BlockSamples(NamedTuple):
    """A :class:`SampleBlock`'s arrays in :func:`step_flows_kernel` (units as there)."""

    t_s: np.ndarray
    position_m: np.ndarray
    p_a_Pa: np.ndarray
    p_b_Pa: np.ndarray
    p_acc_Pa: np.ndarray
    speed_rad_s: np.ndarray
    current_A: np.ndarray


class IntervalSeries(NamedTuple):
    """A block's series per sample interval, summed into sub-steps by :func:`segment_sums`."""

    t_s: np.ndarray             #: the sample times, the previous block's last in front
    position_m: np.ndarray      #: the positions at those times
    dt_s: np.ndarray            #: the intervals
    flow_m3_s: np.ndarray       #: each link's flow (links x intervals)
    work_W: np.ndarray          #: each link's flow x pressure drop
    volume_dp_m3Pa: np.ndarray  #: V dp of each oil node
    p_Pa: np.ndarray            #: each oil node's interval-mean pressure
    pump_friction_W: np.ndarray
    external_leak_m3_s: np.ndarray


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
    copper losses depend on their temperatures (R(T)): ``copper_K`` and
    ``copper_power_W`` give the operating point of that feedback, without a
    heat the caller added (:attr:`WetMotor.extra_power_W`).
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
        Phi, g_acc, g_case, C = self.circuit.last_transition()
        sources = [f'{group}_{k}' for group, idx in mo.sources.items()
                   for k in range(idx.stop - idx.start)]
        return Linearisation(
            state_names=tuple(self.quantities.state_names),
            motor_input_names=tuple(net.boundary_names) + tuple(sources),
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
        :func:`segment_sums`, the mean of the current squared A^2). Everything
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
             max_substep_s: Optional[float] = None) -> None:
        """
        Advance the coupled model over one block of samples.

        ``max_substep_s`` overrides the motor's sub-step limit for this block:
        a long block (the estimator crossing a silence of the sensors, its
        forecast) is then one exact motor step. A block longer than the case
        buffer's time constant refreshes the motor's coefficients exactly: the
        1 % tolerance on the motor's flow, integrated over minutes, would
        drain or flood the 40 mL of case oil.
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
                        exact_coefficients=dt > self.buffer_time_s)
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
            'motor_flow_L_min': q_motor * 60000.0,
            'case_buffer_mL': self.case_buffer_m3 * 1e6,
            'leakage_to_case_L_min': q_ext * 60000.0,
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


@jit
def node_pressures(sensed, flow_m3_s, T_line_K, length_m, bore_m, laws):
    """
    Return the pressures (Pa) of the oil nodes (8 x n) and the lines' Reynolds numbers.

    From the sensed p_a, p_b, p_acc (3 x n) and the line flow into chamber A
    (n): both lines at their mean temperature ``T_line_K`` and the low-side
    pressure, as the kinetics. Rows in OIL_NODES order: pump ports A and B
    (line ends), case (at the accumulator's pressure), lines A and B
    (mid-line), chambers A and B, accumulator.
    """
    pa, pb, pacc = sensed[0], sensed[1], sensed[2]
    p_l = pacc[-1]
    rho = oil_density(T_line_K, p_l, laws)
    mu = oil_nu(T_line_K, p_l, laws) * rho     # the dynamic viscosity
    dp, re = fp.line_pressure_drop_kernel(flow_m3_s, length_m, bore_m, rho, mu)
    half = 0.5 * dp
    P = np.empty((N_OIL, pa.size))
    P[PORT_A] = pa + dp
    P[PORT_B] = pb - dp
    P[CASE] = pacc
    P[LINE_A] = pa + half
    P[LINE_B] = pb - half
    P[CHAMBER_A] = pa
    P[CHAMBER_B] = pb
    P[ACCUMULATOR] = pacc
    return P, re


@jit
def step_flows_kernel(last, samples, T_line_K, T_case_K, constants, substep_s):
    """
    Return the flows of one block of samples, as :meth:`EHAModel.step_flows` uses them.

    ``last``: the :class:`LastSample` of the previous block; ``samples``: the
    block's :class:`BlockSamples`; the lines' oil at ``T_line_K`` and the
    leakage gaps' at ``T_case_K`` (K); ``constants``: the
    :class:`FlowConstants` (all three as plain tuples). Returns (mean flow of each link m^3/s, mean
    flow x pressure drop W, end node pressures Pa, integral of V dp per oil
    node m^3 Pa, mean position m, position change m, pump friction W, mean
    external leakage m^3/s, step length s, interval weights, end sensed
    pressures Pa, line Reynolds numbers, gap Reynolds numbers of both leakage
    paths, the sub-steps: see :func:`segment_sums`, and the mean of the
    ``current`` (A) squared).
    """
    c, smp = FlowConstants(*constants), BlockSamples(*samples)
    t0, x0, raw0, p0 = LastSample(*last)
    t_s, speed, current = smp.t_s, smp.speed_rad_s, smp.current_A
    link_up, link_down, laws = c.link_up, c.link_down, c.oil_laws
    geo = c.geometry
    area, dead_volume, half_stroke = geo.area_m2, geo.dead_volume_m3, geo.half_stroke_m
    n = t_s.size
    # times, positions and pressures with the last sample of the previous step in front
    t = np.empty(n + 1)
    t[0] = t0
    t[1:] = t_s
    dts = t[1:] - t[:-1]
    if (dts <= 0.0).any():
        raise ValueError('sample times must increase strictly')
    dt = t[-1] - t0
    wgt = dts / dt
    x = np.empty(n + 1)
    x[0] = x0
    x[1:] = smp.position_m
    q = area * (x[1:] - x[:-1]) / dts          # into chamber A
    raw = np.empty((3, n + 1))
    raw[:, 0] = raw0
    raw[0, 1:] = smp.p_a_Pa
    raw[1, 1:] = smp.p_b_Pa
    raw[2, 1:] = smp.p_acc_Pa
    P, re = node_pressures(0.5 * (raw[:, 1:] + raw[:, :-1]), q, T_line_K, geo.line_length_m,
                           geo.line_bore_m, laws)
    # the two leakage gaps, in one evaluation: port to port (internal) and high port
    # to case (external), each with the viscosity and density at its mean pressure
    p_high = np.maximum(P[PORT_A], P[PORT_B])
    gap_dp = np.empty((2, n))
    gap_dp[0] = P[PORT_A] - P[PORT_B]
    gap_dp[1] = p_high - P[CASE]
    gap_p = np.empty((2, n))
    gap_p[0] = P[PORT_A] + P[PORT_B]
    gap_p[1] = p_high + P[CASE]
    gap_p *= 0.5
    gap_rho = oil_density(T_case_K, gap_p, laws)
    gap_mu = oil_nu(T_case_K, gap_p, laws) * gap_rho
    leak, re_gap = fp.gap_leakage(c.leak_coeffs_m3, gap_dp, gap_mu, gap_rho, c.leak_gap_height_m,
                                  c.leak_gap_length_m, c.leak_discharge_coeff)
    q_int = leak[0]
    high_a = P[PORT_A] >= P[PORT_B]
    q_ext = np.maximum(leak[1], 0.0)
    q_ext_a = np.where(high_a, q_ext, 0.0)
    q_ext_b = q_ext - q_ext_a
    # The pump's transfer into the high port closes that port's balance (line flow,
    # internal and external leakage); only the low port exchanges with the
    # accumulator (check valves), by the external leakage. Measured speed and
    # position never agree exactly (sampling, noise): closing the balance through
    # the high port would pass that mismatch across the full load pressure.
    q_line_int = q + q_int
    q_pump = np.where(high_a, q_line_int + q_ext_a, q_line_int - q_ext_b)   # into port A
    make_up_a = np.where(high_a, 0.0, q_ext)
    # flow of every link of LINKS per interval: a signed flow splits into its two
    # directed links (forward part, reverse part); no make-up flows back
    F = np.zeros((link_up.size, n))
    F[PUMP_INTO_A] = np.maximum(q_pump, 0.0)
    F[PUMP_INTO_B] = np.maximum(-q_pump, 0.0)
    F[LEAK_A_TO_B] = np.maximum(q_int, 0.0)
    F[LEAK_B_TO_A] = np.maximum(-q_int, 0.0)
    F[LEAK_A_TO_CASE] = q_ext_a
    F[LEAK_B_TO_CASE] = q_ext_b
    q_fwd = np.maximum(q, 0.0)          # the four line sections carry q
    q_rev = np.maximum(-q, 0.0)
    F[LINE_A_PUMP_END] = q_fwd
    F[LINE_A_PUMP_END_BACK] = q_rev
    F[LINE_A_ACTUATOR_END] = q_fwd
    F[LINE_A_ACTUATOR_END_BACK] = q_rev
    F[LINE_B_ACTUATOR_END] = q_fwd
    F[LINE_B_ACTUATOR_END_BACK] = q_rev
    F[LINE_B_PUMP_END] = q_fwd
    F[LINE_B_PUMP_END_BACK] = q_rev
    F[MAKE_UP_A] = make_up_a
    F[MAKE_UP_B] = q_ext - make_up_a
    flow = F @ wgt
    work = (F * (P[link_up] - P[link_down])) @ wgt
    fric = fp.pump_friction_torque(speed, gap_dp[0], gap_mu[0], geo.displacement_m3_rad,
                                   c.viscous_friction_coeff, c.pressure_friction_coeff,
                                   c.coulomb_torque_Nm)
    x_mean = np.dot(0.5 * (x[1:] + x[:-1]), wgt)
    # integral of V dp per oil node: P holds interval-mean pressures, so between two
    # of them the chamber volume is the one at the sample instant in between
    dP = np.empty((N_OIL, n))
    dP[:, 0] = P[:, 0] - p0
    dP[:, 1:] = P[:, 1:] - P[:, :-1]
    vdp_int = c.oil_volumes_m3.reshape(-1, 1) * dP
    va = dead_volume + area * (half_stroke + x[:-1])
    vb = 2 * dead_volume + 2 * area * half_stroke - va
    vdp_int[CHAMBER_A] = va * dP[CHAMBER_A]
    vdp_int[CHAMBER_B] = vb * dP[CHAMBER_B]
    vdp = vdp_int.sum(axis=1)
    fric_W = fric * np.abs(speed)
    seg = segment_sums(IntervalSeries(t, x, dts, F, F * (P[link_up] - P[link_down]), vdp_int, P,
                                      fric_W, q_ext), substep_s)
    return (flow, work, P[:, -1].copy(), vdp, x_mean, x[-1] - x[0],
            np.dot(fric_W, wgt), np.dot(q_ext, wgt), dt, wgt, raw[:, -1].copy(), re,
            re_gap.ravel(), seg, np.dot(current * current, wgt))


@jit
def segment_sums(series, substep_s):
    """
    Split a step's sample intervals into sub-steps of at most ``substep_s`` (s); sum each.

    An interval belongs to the sub-step its end falls in (a sub-step holds
    at least one interval: one longer than ``substep_s`` is a sub-step of its
    own). Returns, per sub-step: length (s), actuator position at its end (m),
    mean flow and mean flow x pressure drop of each link, integral of V dp
    of each oil node (m^3 Pa), mean node pressures (Pa), mean pump friction
    (W) and mean external leakage (m^3/s). ``series``: the :class:`IntervalSeries`.
    """
    t, x, dts, F, FdP = series.t_s, series.position_m, series.dt_s, series.flow_m3_s, \
        series.work_W
    vdp_int, P, fric_W, q_ext = series.volume_dp_m3Pa, series.p_Pa, series.pump_friction_W, \
        series.external_leak_m3_s
    n = dts.size
    ids = np.empty(n, dtype=np.int64)
    cut = 0
    for k in range(n):
        if k > 0 and t[k + 1] - t[cut] > substep_s * (1.0 + 1e-9):
            cut = k
        ids[k] = cut
    starts = np.flatnonzero(np.diff(ids) != 0) + 1
    first = np.empty(starts.size + 1, dtype=np.int64)
    first[0] = 0
    first[1:] = starts
    m = first.size
    last = np.empty(m, dtype=np.int64)
    last[:-1] = first[1:]
    last[-1] = n
    h = np.empty(m)
    x_end = np.empty(m)
    flow = np.empty((m, F.shape[0]))
    work = np.empty((m, F.shape[0]))
    vdp = np.empty((m, vdp_int.shape[0]))
    p_mid = np.empty((m, P.shape[0]))
    fric = np.empty(m)
    q = np.empty(m)
    for j in range(m):
        a, b = first[j], last[j]
        w = dts[a:b]
        h[j] = w.sum()
        x_end[j] = x[b]
        # contiguous copies: numba's matrix product wants them
        flow[j] = np.ascontiguousarray(F[:, a:b]) @ w / h[j]
        work[j] = np.ascontiguousarray(FdP[:, a:b]) @ w / h[j]
        vdp[j] = vdp_int[:, a:b].sum(axis=1)
        p_mid[j] = np.ascontiguousarray(P[:, a:b]) @ w / h[j]
        fric[j] = np.dot(fric_W[a:b], w) / h[j]
        q[j] = np.dot(q_ext[a:b], w) / h[j]
    return h, x_end, flow, work, vdp, p_mid, fric, q


@jit
def substep_volumes(x0, x_end, case_buffer, oil_volumes, geometry):
    """
    Return the volume (m^3) of every oil node at the sub-step boundaries (one row each).

    ``x0`` the actuator position (m) at the start and ``x_end`` at the end of
    each sub-step; ``case_buffer`` the case oil above its nominal volume
    (m^3) at each boundary, which the accumulator gives; ``oil_volumes`` the
    nominal volumes; ``geometry`` the :class:`ActuatorGeometry` (a plain tuple).
    """
    geo = ActuatorGeometry(*geometry)
    area, dead_volume, half_stroke = geo.area_m2, geo.dead_volume_m3, geo.half_stroke_m
    x = np.empty(x_end.size + 1)
    x[0] = x0
    x[1:] = x_end
    vol = np.empty((x.size, oil_volumes.size))
    vol[:] = oil_volumes
    vol[:, CHAMBER_A] = dead_volume + area * (half_stroke + x)
    vol[:, CHAMBER_B] = dead_volume + area * (half_stroke - x)
    vol[:, CASE] += case_buffer          # the case holds what the accumulator gives
    vol[:, ACCUMULATOR] -= case_buffer
    return vol
