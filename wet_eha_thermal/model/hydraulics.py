"""
Control-node thermal model of the EHA hydraulic circuit (docs/model.md).

Oil volumes (pump ports A and B, pump case, the two lines, the two actuator
chambers, the accumulator) and solid shells (pump, lines, actuator,
accumulator). Each oil volume V at (T, p) obeys, for a fixed or a moving
boundary alike (the boundary work cancels in the enthalpy form),

    rho V c_p dT/dt = sum_in m_dot (h_in - h) + Q_heat + alpha_p T V dp/dt,
    h_in - h = c_p (T_in - T) + (1 - alpha_p T)(p_in - p) / rho.

Only inflows change a volume's temperature. Every flow is a directed link
whose mean volumetric flow over a step comes from the sensor samples; the
pressure part of h_in - h becomes a heat source in the receiving volume:
``(1 - alpha_p T) dp Q`` for a throttle or a leak (isenthalpic: about
0.45 K/MPa) and ``alpha_p T (p_d - p_u) Q`` for the pump's displacement flow
(isentropic compression: the pump adds dp/rho of work per kg), so that all
dissipated hydraulic power ends up as heat. Inside a model step the 13 nodes
take sub-steps of at most ``hydraulics.substep_s`` (Crank-Nicolson, with the
oil capacities following the volumes); each oil volume's energy is kept as
V e(T), e the oil's energy per volume, and every flow carries e, so that
energy is conserved exactly whatever the step, the volumes and the
temperatures do. The flows are incompressible, so the capacities and e take
the density at one pressure, the accumulator's. A step with the inputs held
is one exact matrix-exponential step.
"""

from dataclasses import dataclass
from typing import Dict, NamedTuple, Optional, Tuple

import numpy as np
import scipy.linalg
from scipy.linalg.lapack import dgesv

from . import correlations as corr
from .compiled import jit
from .oil import (conductivity, density, kinematic_viscosity, Oil, specific_heat,
                  temperature_of_energy, volumetric_energy)
from ..config import Hydraulics

OIL_NODES = ('port_a', 'port_b', 'case', 'line_a', 'line_b', 'chamber_a', 'chamber_b',
             'accumulator')
SOLID_NODES = ('pump_shell', 'line_a_shell', 'line_b_shell', 'actuator_shell',
               'accumulator_shell')
NODES = OIL_NODES + SOLID_NODES
_I = {name: i for i, name in enumerate(NODES)}
#: the rows the kernels index by name: of each node in the temperature vector, and of each
#: oil node in the pressure, volume and V dp vectors (the oil nodes come first)
PORT_A, PORT_B, CASE = _I['port_a'], _I['port_b'], _I['case']
LINE_A, LINE_B = _I['line_a'], _I['line_b']
CHAMBER_A, CHAMBER_B, ACCUMULATOR = _I['chamber_a'], _I['chamber_b'], _I['accumulator']
PUMP_SHELL = _I['pump_shell']
N_OIL = len(OIL_NODES)

# Directed flow links, name: (upstream, downstream); 'pump' is the displacement flow, the
# rest are throttles (leaks, line friction, check valves). A line section's forward link
# carries the flow into chamber A (out of chamber B), its '_back' link the reverse.
_LINKS: Dict[str, Tuple[str, str]] = {
    'pump_into_a': ('port_b', 'port_a'), 'pump_into_b': ('port_a', 'port_b'),
    'leak_a_to_b': ('port_a', 'port_b'), 'leak_b_to_a': ('port_b', 'port_a'),
    'leak_a_to_case': ('port_a', 'case'), 'leak_b_to_case': ('port_b', 'case'),
    'line_a_pump_end': ('port_a', 'line_a'), 'line_a_pump_end_back': ('line_a', 'port_a'),
    'line_a_actuator_end': ('line_a', 'chamber_a'),
    'line_a_actuator_end_back': ('chamber_a', 'line_a'),
    'line_b_actuator_end': ('chamber_b', 'line_b'),
    'line_b_actuator_end_back': ('line_b', 'chamber_b'),
    'line_b_pump_end': ('line_b', 'port_b'), 'line_b_pump_end_back': ('port_b', 'line_b'),
    'make_up_a': ('accumulator', 'port_a'), 'relief_a': ('port_a', 'accumulator'),
    'make_up_b': ('accumulator', 'port_b'), 'relief_b': ('port_b', 'accumulator'),
}
LINKS: Tuple[Tuple[str, str], ...] = tuple(_LINKS.values())
_L = {name: k for k, name in enumerate(_LINKS)}
#: the rows of LINKS the kernels index by name
PUMP_INTO_A, PUMP_INTO_B = _L['pump_into_a'], _L['pump_into_b']
LEAK_A_TO_B, LEAK_B_TO_A = _L['leak_a_to_b'], _L['leak_b_to_a']
LEAK_A_TO_CASE, LEAK_B_TO_CASE = _L['leak_a_to_case'], _L['leak_b_to_case']
LINE_A_PUMP_END, LINE_A_PUMP_END_BACK = _L['line_a_pump_end'], _L['line_a_pump_end_back']
LINE_A_ACTUATOR_END, LINE_A_ACTUATOR_END_BACK = (_L['line_a_actuator_end'],
                                                 _L['line_a_actuator_end_back'])
LINE_B_ACTUATOR_END, LINE_B_ACTUATOR_END_BACK = (_L['line_b_actuator_end'],
                                                 _L['line_b_actuator_end_back'])
LINE_B_PUMP_END, LINE_B_PUMP_END_BACK = _L['line_b_pump_end'], _L['line_b_pump_end_back']
MAKE_UP_A, MAKE_UP_B = _L['make_up_a'], _L['make_up_b']
PUMP_LINKS = (PUMP_INTO_A, PUMP_INTO_B)


@dataclass
class StepFlows:
    """
    What the circuit needs from one step of samples (SI units, means over the step).

    ``flow_m3_s`` and ``work_W`` hold, per link of :data:`LINKS`, the mean flow
    and the mean of flow x (p_upstream - p_downstream); ``p_start_Pa`` and
    ``p_end_Pa`` the oil-node pressures at both ends of the step;
    ``volume_dp_m3Pa`` the integral of V dp of every oil node over the step,
    summed per sample interval (the compression heat; a chamber's volume
    moves with the pressure); ``chamber_volumes_m3`` the mean volumes of chambers A
    and B and ``chamber_dV_m3`` their changes over the step; ``case_volume_m3``
    and ``case_dV_m3`` the same for the pump case, whose oil buffers the
    difference between the pulsating leakage and the motor's smoothed flow
    (the accumulator's oil changes by the opposite amount);
    ``motor_flow_m3_s`` the oil flowing case -> motor -> accumulator and
    ``motor_outlet_K`` its mean temperature back from the motor;
    ``pump_friction_W`` the pump's friction loss.
    """

    flow_m3_s: np.ndarray
    work_W: np.ndarray
    p_start_Pa: np.ndarray
    p_end_Pa: np.ndarray
    volume_dp_m3Pa: np.ndarray
    chamber_volumes_m3: Tuple[float, float]
    chamber_dV_m3: Tuple[float, float]
    case_volume_m3: float
    case_dV_m3: float
    motor_flow_m3_s: float
    motor_outlet_K: float
    pump_friction_W: float


class SubSteps(NamedTuple):
    """
    The sub-steps of one model step, one row each (SI units, means over the sub-step).

    ``dt_s`` their lengths; ``flow_m3_s`` and ``work_W`` per link of
    :data:`LINKS` as in :class:`StepFlows`; ``volume_dp_m3Pa`` the integral of
    V dp of each oil node; ``p_mid_Pa`` the mean pressure of each oil node;
    ``pump_friction_W``; ``volumes_m3`` the oil volume of each oil node at the
    sub-step boundaries (one row more): the chambers move with the piston, the
    case holds the buffer the accumulator gives.
    """

    dt_s: np.ndarray
    flow_m3_s: np.ndarray
    work_W: np.ndarray
    volume_dp_m3Pa: np.ndarray
    p_mid_Pa: np.ndarray
    pump_friction_W: np.ndarray
    volumes_m3: np.ndarray


class LineGeometry(NamedTuple):
    """One hydraulic line's geometry (both lines are alike)."""

    bore_m: float
    flow_area_m2: float
    inner_area_m2: float        #: the oil-wetted wall


class CircuitConstants(NamedTuple):
    """
    The circuit's constants, as its kernels take them (as a plain tuple, see below).

    ``K_static_W_K`` the constant conductances (shells to oil and to
    ambient) as a matrix; ``k_index`` the flat indices into it of the
    step's conductances (advection (d, d), (d, u); each line's convection
    (i, i), (j, j), (i, j), (j, i); the motor's inflow into the
    accumulator); ``capacities_J_K`` the heat capacities, the solids' filled
    in (the oil's change every step); ``G_amb_W_K`` each node's conductance
    to ambient; ``p_ref_Pa`` the pressure of the oil's density law in the
    capacities and energies; ``is_pump``, ``link_up`` and ``link_down`` per
    link of :data:`LINKS`; ``friction_to_case`` the share of the pump's
    friction heat that goes to the case oil.

    A kernel called from Python takes these as ``tuple(constants)`` and
    names them again at its first line: numba types a plain tuple in C and
    a NamedTuple in Python, three times slower (as :class:`~.oil.OilLaws`).
    """

    K_static_W_K: np.ndarray
    k_index: np.ndarray
    capacities_J_K: np.ndarray
    G_amb_W_K: np.ndarray
    line: LineGeometry
    oil_laws: tuple
    p_ref_Pa: float
    is_pump: np.ndarray
    link_up: np.ndarray
    link_down: np.ndarray
    friction_to_case: float


class LoopInputs(NamedTuple):
    """A step's inputs besides the flows: the motor's oil, its return, ambient, case heat."""

    rho_cp_flow_J_m3K: float    #: the one rho c_p of every enthalpy flow of the loop
    motor_rate_W_K: float       #: rho c_p times the oil flowing case -> motor -> accumulator
    motor_outlet_K: float       #: its temperature back from the motor
    ambient_K: float
    extra_loss_W: float         #: heat into the case oil besides the pump's friction


class HydraulicCircuit:
    """Thermal control nodes of the pump, lines, actuator and accumulator."""

    def __init__(self, cfg: Hydraulics, oil: Oil) -> None:
        self.cfg, self.oil = cfg, oil
        n = len(NODES)
        self.n, self.n_oil = n, len(OIL_NODES)
        pump, act, acc, ln = cfg.pump, cfg.actuator, cfg.accumulator, cfg.lines
        line_vol = 0.25 * np.pi * ln.bore_m ** 2 * ln.length_m
        self.oil_volumes = np.array([pump.port_volume_m3, pump.port_volume_m3,
                                     pump.case_volume_m3, line_vol, line_vol, np.nan, np.nan,
                                     acc.oil_volume_m3])
        wall = np.pi * ((0.5 * ln.bore_m + ln.wall_m) ** 2 - (0.5 * ln.bore_m) ** 2) * ln.length_m
        line_shell_C = wall * ln.wall_density_kg_m3 * ln.wall_specific_heat_J_kgK
        self.solid_capacity = np.array([pump.shell.capacity_J_K, line_shell_C, line_shell_C,
                                        act.shell.capacity_J_K, acc.shell.capacity_J_K])
        # constant conductances (W/K): shells to oil and to ambient
        g = np.zeros((n, n))
        g_amb = np.zeros(n)

        def link(a, b, G):
            i, j = _I[a], _I[b]
            g[i, j] += G
            g[j, i] += G

        # the pump body is wetted by the case oil and by both ports: (est.) 60/20/20 %
        g_pump = pump.shell.oil_htc_W_m2K * pump.shell.oil_area_m2
        for node, share in (('case', 0.6), ('port_a', 0.2), ('port_b', 0.2)):
            link('pump_shell', node, share * g_pump)
        for ch in ('chamber_a', 'chamber_b'):
            link('actuator_shell', ch, act.shell.oil_htc_W_m2K * act.shell.oil_area_m2)
        link('accumulator_shell', 'accumulator', acc.shell.oil_htc_W_m2K * acc.shell.oil_area_m2)
        outer = np.pi * (ln.bore_m + 2 * ln.wall_m) * ln.length_m
        for name, shell in (('pump_shell', pump.shell), ('actuator_shell', act.shell),
                            ('accumulator_shell', acc.shell)):
            g_amb[_I[name]] = shell.air_htc_W_m2K * shell.air_area_m2
        g_amb[_I['line_a_shell']] = g_amb[_I['line_b_shell']] = ln.air_htc_W_m2K * outer
        self.G = g
        self.G_amb = g_amb
        # the pressure of the oil's density law in the heat capacities and energies: one
        # for every volume, as the flows are incompressible (the accumulator's)
        self.p_ref_Pa = acc.pressure_Pa
        self.K_static = np.diag(g.sum(axis=1) + g_amb) - g
        self.line_inner_area = np.pi * ln.bore_m * ln.length_m
        self.u = np.array([_I[a] for a, _ in LINKS])
        self.d = np.array([_I[b] for _, b in LINKS])
        # flat indices of K for: advection (d,d), (d,u); line convection (i,i), (j,j), (i,j),
        # (j,i) for lines A and B; the motor's inflow into the accumulator
        li = np.array([_I['line_a'], _I['line_b']])
        lj = np.array([_I['line_a_shell'], _I['line_b_shell']])
        acc = _I['accumulator']
        self._k_index = np.concatenate([self.d * n + self.d, self.d * n + self.u, li * n + li,
                                        lj * n + lj, li * n + lj, lj * n + li, [acc * n + acc]])
        self.is_pump = np.zeros(len(LINKS), dtype=bool)
        self.is_pump[list(PUMP_LINKS)] = True
        self.friction_to_case = pump.friction_to_case_fraction
        self.extra_loss_W = pump.extra_loss_W
        self.alpha_T_filter_s = 30.0
        # per-step constants: a line's bore (m), flow section (m^2) and inner wall area
        # (m^2), and the heat capacities with the solids' filled in (the oil's change
        # every step)
        self._line_geometry = LineGeometry(ln.bore_m, 0.25 * np.pi * ln.bore_m ** 2,
                                           self.line_inner_area)
        self._capacities = np.concatenate([np.zeros(self.n_oil), self.solid_capacity])
        self._constants = tuple(CircuitConstants(
            self.K_static, self._k_index, self._capacities, self.G_amb, self._line_geometry,
            oil.laws, self.p_ref_Pa, self.is_pump, self.u, self.d, self.friction_to_case))
        self._T_alpha: Optional[float] = None
        # energies (J): heat generated, stored (a moving chamber's oil included), to
        # ambient, and the net enthalpy the motor adds to the oil passing through it
        self.energy_J = {'sources': 0.0, 'stored': 0.0, 'to_ambient': 0.0, 'motor_loop': 0.0}
        self.T_mean = np.full(n, np.nan)
        # what the model reports: after sub-steps the step means (the oil swings within a
        # duty cycle, and a step-end value is a sample of that swing at one phase: a fit at
        # 1 s steps against 10 Hz thermocouples then saw 0.28 K of structured misfit, 0.19
        # with the means); after one exact step (held inputs, no swing) the end values
        self.T_report: Optional[np.ndarray] = None
        self._last_exact: Optional[tuple] = None
        self._last_transition: Optional[tuple] = None
        # a state estimator sets this: the sub-steps then also compose their transition
        # (a 13 x 16 solve and a 13 x 13 product each), which nothing else needs
        self.keep_transition = False

    def index(self, name: str) -> int:
        """Return the index of a node in the temperature vector."""
        return _I[name]

    def rho_cp(self, T_K, p_Pa) -> float:
        """Return the volumetric heat capacity rho c_p (J/(m^3 K)) of the oil."""
        return self.oil.density(T_K, p_Pa) * self.oil.specific_heat(T_K)

    def step(self, T0: np.ndarray, dt_s: float, sf: StepFlows, ambient_K: float,
             rho_cp_flow: float) -> np.ndarray:
        """
        Advance the node temperatures (K) by ``dt_s`` with the step's flows; return them.

        ``rho_cp_flow`` is the one volumetric heat capacity used for every
        enthalpy flow of the loop (the motor's too), which keeps the loop's
        advection exactly conservative. The step is exact for flows and
        sources held over it: one matrix exponential of the 13 nodes plus the
        constant input; the step mean follows from one solve, since
        K int(T) = s dt - C (T1 - T0).
        """
        n = self.n
        heat = self.sources(T0, dt_s, sf)
        motor_rate = rho_cp_flow * sf.motor_flow_m3_s
        volumes = self.oil_volumes.copy()
        volumes[CHAMBER_A], volumes[CHAMBER_B] = sf.chamber_volumes_m3
        volumes[CASE] = sf.case_volume_m3
        K, M, C, s = circuit_matrices(
            T0, dt_s, sf.flow_m3_s, 0.5 * (sf.p_start_Pa + sf.p_end_Pa), volumes, heat,
            (rho_cp_flow, motor_rate, sf.motor_outlet_K, ambient_K, self.extra_loss_W),
            self._constants)
        T0_1 = np.empty(n + 1)         # the start temperatures and the constant input's 1
        T0_1[:n] = T0
        T0_1[n] = 1.0
        E = scipy.linalg.expm(M)
        T1 = E[:n] @ T0_1
        dT = T1 - T0
        # LAPACK's gesv directly: np.linalg.solve's wrapper costs more than this 13 x 13 solve
        _, _, Tm_dt, info = dgesv(K, s * dt_s - C * dT)
        if info:
            raise np.linalg.LinAlgError(f'singular circuit matrix (gesv info {info})')
        self.T_mean = Tm = Tm_dt / dt_s
        # the ledger in Python floats: a few scalars, where numpy scalars cost more
        e = self.energy_J
        tm = Tm.tolist()
        dV_a, dV_b = sf.chamber_dV_m3
        e['sources'] += float(heat.sum()) * dt_s
        e['stored'] += float(np.dot(C, dT)) + rho_cp_flow * (
            tm[CHAMBER_A] * dV_a + tm[CHAMBER_B] * dV_b
            + (tm[CASE] - tm[ACCUMULATOR]) * sf.case_dV_m3)
        e['to_ambient'] += float(np.dot(self.G_amb, Tm - ambient_K)) * dt_s
        e['motor_loop'] += motor_rate * (sf.motor_outlet_K - tm[CASE]) * dt_s
        self.last_sources = heat
        self.T_report = T1
        self._last_exact = (E, M, C, motor_rate, dt_s)
        self._last_transition = None
        return T1

    def step_substeps(self, T0: np.ndarray, sub: SubSteps, motor_flow_m3_s: float,
                      motor_outlet_K: float, ambient_K: float, rho_cp_flow: float) -> np.ndarray:
        """
        Advance the node temperatures (K) over the sub-steps of ``sub``; return them.

        Each sub-step is one Crank-Nicolson step of C dT/dt = -K T + s with
        the oil capacities at the mean of their values at its ends, and the
        inflows (and the motor's outflow from the case) changing the volumes
        in between. That scheme conserves energy exactly: summed over the
        nodes, C_mid dT + T_mid dC of a sub-step equals its heat in, minus the
        heat to ambient, plus what the motor adds to the oil it carries,
        whatever the step and the volumes do, since a capacity changes by the
        loop's rho c_p times the oil that came or went, as the flows carry it.
        ``motor_flow_m3_s`` leaves the case for the motor and comes back to
        the accumulator at ``motor_outlet_K``.
        """
        dt = float(sub.dt_s.sum())
        alpha_T = self._alpha_T(T0, dt)
        motor_rate = rho_cp_flow * motor_flow_m3_s
        (T1, Tm, Phi, g_acc, g_case, C, heat, ledger) = cn_substeps(
            T0, alpha_T, tuple(sub),
            (rho_cp_flow, motor_rate, motor_outlet_K, ambient_K, self.extra_loss_W),
            self._constants, self.keep_transition)
        self.T_mean = self.T_report = Tm
        e = self.energy_J
        e['sources'] += ledger[0]
        e['stored'] += ledger[1]
        e['to_ambient'] += ledger[2]
        e['motor_loop'] += ledger[3]
        self.last_sources = heat
        self._last_exact = None
        self._last_transition = (Phi, g_acc, g_case, C) if self.keep_transition else None
        return T1

    def last_transition(self) -> tuple:
        """
        Return how the last step maps its start onto its end, for a state estimator.

        ``(Phi, g_acc, g_case, C)``: T_end = Phi T_start + g_acc * (motor
        outlet K) + g_case * (extra heat into the case, W) + the rest of the
        inputs; ``C`` the heat capacities (J/K). After sub-steps only with
        ``keep_transition`` set.
        """
        if self._last_transition is None:
            if self._last_exact is None:
                raise RuntimeError('the sub-steps kept no transition: set keep_transition')
            E, M, C, motor_rate, dt = self._last_exact
            n = self.n
            # int_0^dt exp(A t) dt b = A^-1 (E - I) b for a constant input b (W / C)
            rhs = E[:n, [ACCUMULATOR, CASE]].copy()
            rhs[[ACCUMULATOR, CASE], [0, 1]] -= 1.0
            gam = np.linalg.solve(M[:n, :n], rhs)
            # in C order, as the sub-steps' transition: the filter's kernel takes either
            self._last_transition = (np.ascontiguousarray(E[:n, :n]),
                                     gam[:, 0] * (motor_rate * dt / C[ACCUMULATOR]),
                                     gam[:, 1] * (dt / C[CASE]), C)
        return self._last_transition

    def sources(self, T0: np.ndarray, dt_s: float, sf: StepFlows) -> np.ndarray:
        """
        Return the heat input (W) of each node over a step: pressure work, compression, friction.

        The alpha_p T factor of the pressure terms takes one temperature, the
        mean oil temperature of the circuit low-passed over ``alpha_T_filter_s``:
        the isentropic part (at the pump, and in compression) and the
        isenthalpic part (at the throttles) then add up to exactly the
        dissipated dp Q, and the reversible compression heat cancels over a
        duty cycle (a factor that swung within the cycle would pump heat that
        no pump work pays for). The few kelvin between volumes would change a
        throttle rise by < 0.5 %.
        """
        return node_sources(self._alpha_T(T0, dt_s), dt_s, sf.work_W, sf.volume_dp_m3Pa,
                            sf.pump_friction_W, self.extra_loss_W, self._constants)

    def _alpha_T(self, T0: np.ndarray, dt_s: float) -> float:
        """Advance the filtered oil temperature by ``dt_s``; return alpha_p times it."""
        T_oil = float(T0[:self.n_oil].sum() / self.n_oil)    # the mean, as np.mean forms it
        if self._T_alpha is None:
            self._T_alpha = T_oil
        else:
            self._T_alpha += -np.expm1(-dt_s / self.alpha_T_filter_s) * (T_oil - self._T_alpha)
        return self.oil.alpha_p * self._T_alpha


@jit
def node_sources(alpha_T, dt_s, work_W, volume_dp_m3Pa, pump_friction_W, extra_loss_W,
                 constants):
    """
    Return the heat input (W) of each node, see :meth:`HydraulicCircuit.sources`.

    ``constants``: the :class:`CircuitConstants`.
    """
    c = CircuitConstants(*constants)
    is_pump, link_down, friction_to_case = c.is_pump, c.link_down, c.friction_to_case
    n = c.K_static_W_K.shape[0]
    # throttles: (1 - alpha T) dp Q; pump: alpha T (p_d - p_u) Q = -alpha T * work
    per_link = np.where(is_pump, -alpha_T * work_W, (1 - alpha_T) * work_W)
    heat = np.bincount(link_down, weights=per_link, minlength=n)
    heat[:volume_dp_m3Pa.size] += alpha_T * volume_dp_m3Pa / dt_s
    heat[CASE] += friction_to_case * pump_friction_W + extra_loss_W
    heat[PUMP_SHELL] += (1 - friction_to_case) * pump_friction_W
    return heat


@jit
def line_conductances(T_K, p_Pa, rho, cp, flows, line, laws):
    """
    Return the oil-to-wall conductances (W/K) of lines A and B at their mean flows.

    Fully developed pipe flow (laminar 3.66, Gnielinski above Re 4000).
    ``T_K``, ``p_Pa``, ``rho`` and ``cp`` are the two lines' oil values;
    ``flows`` the mean flow of every link; ``line`` the :class:`LineGeometry`.
    """
    bore, flow_area, inner_area = line.bore_m, line.flow_area_m2, line.inner_area_m2
    mu = kinematic_viscosity(T_K, p_Pa, laws) * rho
    k = conductivity(T_K, laws)
    q = np.empty(2)
    # each line's flow, taken at one of its sections (both carry it)
    q[0] = flows[LINE_A_PUMP_END] + flows[LINE_A_PUMP_END_BACK]
    q[1] = flows[LINE_B_ACTUATOR_END] + flows[LINE_B_ACTUATOR_END_BACK]
    re = rho * q / flow_area * bore / mu
    nu = corr.laminar_turbulent_nusselt_kernel(re, mu * cp / k, corr.NU_PIPE_T)
    return nu * k / bore * inner_area


@jit
def conductances_and_input(T, p_mid, rho, cp, flows, heat, loop, c):
    """
    Return K (W/K) and s (W) of C dT/dt = -K T + s for the given flows and heat sources.

    K holds the constant conductances, each link's advection into its
    downstream node (only inflows change a temperature), the lines' forced
    convection and the motor's return into the accumulator; s the ambient's
    and the sources' input and the motor outlet's enthalpy. ``loop``: the
    :class:`LoopInputs`; ``c``: the :class:`CircuitConstants` (both named).
    """
    n = T.size
    motor_rate = loop.motor_rate_W_K
    rate = loop.rho_cp_flow_J_m3K * flows
    lines = slice(LINE_A, LINE_B + 1)       # adjacent nodes
    g_line = line_conductances(T[lines], p_mid[lines], rho[lines], cp[lines], flows, c.line,
                               c.oil_laws)
    weights = np.concatenate((rate, -rate, g_line, g_line, -g_line, -g_line,
                              np.full(1, motor_rate)))
    K = c.K_static_W_K + np.bincount(c.k_index, weights=weights, minlength=n * n).reshape(n, n)
    s = c.G_amb_W_K * loop.ambient_K + heat
    s[ACCUMULATOR] += motor_rate * loop.motor_outlet_K
    return K, s


@jit
def circuit_matrices(T0, dt_s, flows, p_mid, volumes, heat, loop, constants):
    """
    Return (K, M, C, s) of one step of :meth:`HydraulicCircuit.step`.

    K (W/K) the conductance matrix with the step's advection and line
    convection, C (J/K) the heat capacities, s (W) the constant input and M
    the exponent of the augmented system (its last column holds s).
    ``volumes`` (m^3) of the oil nodes; ``loop`` the :class:`LoopInputs` and
    ``constants`` the :class:`CircuitConstants`, as plain tuples.
    """
    c, loop = CircuitConstants(*constants), LoopInputs(*loop)
    laws = c.oil_laws
    n = T0.size
    no = p_mid.size
    T_oil = T0[:no]
    rho, cp = density(T_oil, p_mid, laws), specific_heat(T_oil, laws)
    C = c.capacities_J_K.copy()
    C[:no] = density(T_oil, c.p_ref_Pa, laws) * cp * volumes
    K, s = conductances_and_input(T0, p_mid, rho, cp, flows, heat, loop, c)
    M = np.zeros((n + 1, n + 1))
    M[:n, :n] = -K * (dt_s / C.reshape(n, 1))
    M[:n, n] = s * (dt_s / C)
    return K, M, C, s


@jit
def cn_substeps(T0, alpha_T, sub, loop, constants, with_transition):
    """
    Crank-Nicolson sub-steps of :meth:`HydraulicCircuit.step_substeps`.

    ``sub`` the :class:`SubSteps`, ``loop`` the :class:`LoopInputs` and
    ``constants`` the :class:`CircuitConstants`, as plain tuples.

    Returns (end temperatures K, step-mean temperatures K, transition,
    response to the motor outlet, response to case heat, end capacities J/K,
    step-mean heat sources W, ledger: sources, stored, to ambient, motor loop J).
    The three responses are composed only ``with_transition`` (else identity
    and zeros); they are those of the linear step, before the energy
    correction below.

    Each oil volume's energy is V e(T), with e the oil's energy per volume at
    ``p_ref`` (:func:`~.oil.volumetric_energy`; the flows are incompressible,
    so one density law keeps the oil's mass), and every flow carries e of its
    upstream volume's mid-step temperature. The linear step carries rho c_p
    of the loop instead; its end temperatures are then corrected so that each
    volume's energy is exactly what came in and went: the books close in e
    whatever the step, the volumes and the temperatures do.
    """
    c, loop = CircuitConstants(*constants), LoopInputs(*loop)
    sub = SubSteps(*sub)
    dts, flows, volumes, p_mids, laws = sub.dt_s, sub.flow_m3_s, sub.volumes_m3, sub.p_mid_Pa, \
        c.oil_laws
    capacities, p_ref, rho_cp_flow = c.capacities_J_K, c.p_ref_Pa, loop.rho_cp_flow_J_m3K
    motor_rate, motor_outlet_K = loop.motor_rate_W_K, loop.motor_outlet_K
    link_up, link_down = c.link_up, c.link_down
    n = T0.size
    no = volumes.shape[1]
    T = T0.copy()
    T_sum = np.zeros(n)
    heat_sum = np.zeros(n)
    Phi = np.eye(n)
    g_acc = np.zeros(n)
    g_case = np.zeros(n)
    ledger = np.zeros(4)
    rhs = np.empty((n, n + 2))
    C1 = capacities.copy()
    q_motor = motor_rate / rho_cp_flow                       # m^3/s
    for k in range(dts.size):
        h = dts[k]
        heat = node_sources(alpha_T, h, sub.work_W[k], sub.volume_dp_m3Pa[k],
                            sub.pump_friction_W[k], loop.extra_loss_W, c)
        T_oil = T[:no]
        rho = density(T_oil, p_mids[k], laws)
        cp = specific_heat(T_oil, laws)
        C0 = capacities.copy()
        C0[:no] = density(T_oil, p_ref, laws) * cp * volumes[k]
        # the oil that comes and goes carries the loop's rho c_p: so do the capacity changes
        C1 = C0.copy()
        C1[:no] += rho_cp_flow * (volumes[k + 1] - volumes[k])
        Cm = 0.5 * (C0 + C1)
        K, s = conductances_and_input(T, p_mids[k], rho, cp, flows[k], heat, loop, c)
        A = 0.5 * K
        B = -0.5 * K
        for i in range(n):
            A[i, i] += Cm[i] / h
            B[i, i] += Cm[i] / h
        # the temperatures by a solve of their own, so that they are the same bits
        # whether the transition is composed or not
        T1 = np.linalg.solve(A, B @ T + s)
        if with_transition:
            rhs[:, :n] = B
            rhs[:, n] = 0.0
            rhs[ACCUMULATOR, n] = motor_rate
            rhs[:, n + 1] = 0.0
            rhs[CASE, n + 1] = 1.0
            X = np.linalg.solve(A, rhs)
            if k == 0:              # composed with the identity and zeros: the same bits
                Phi = X[:, :n].copy()
                g_acc = X[:, n].copy()
                g_case = X[:, n + 1].copy()
            else:
                step_phi = X[:, :n].copy()
                Phi = step_phi @ Phi
                g_acc = step_phi @ g_acc + X[:, n]
                g_case = step_phi @ g_case + X[:, n + 1]
        Tm = 0.5 * (T + T1)
        # what the flows carry beyond the loop's rho c_p: g = e - rho c_p T of the upstream
        # volume, into the downstream one and out of the upstream one
        g = volumetric_energy(Tm[:no], p_ref, laws) - rho_cp_flow * Tm[:no]
        extra = np.zeros(no)
        for link in range(link_up.size):
            carried = flows[k, link] * h * g[link_up[link]]
            extra[link_down[link]] += carried
            extra[link_up[link]] -= carried
        # the motor's oil leaves the case and comes back to the accumulator with the heat
        # the motor books for it (its enthalpy rise at the loop's rho c_p, in K and s)
        carried = q_motor * h * g[CASE]
        extra[CASE] -= carried
        extra[ACCUMULATOR] += carried
        E0 = volumes[k] * volumetric_energy(T_oil, p_ref, laws)
        E1 = E0 + Cm[:no] * (T1[:no] - T_oil) + Tm[:no] * (C1[:no] - C0[:no]) + extra
        T1[:no] = temperature_of_energy(E1 / volumes[k + 1], T1[:no], p_ref, laws)
        T_sum += Tm * h
        heat_sum += heat * h
        ledger[0] += heat.sum() * h
        ledger[1] += (E1 - E0).sum() + np.dot(Cm[no:], T1[no:] - T[no:])
        ledger[2] += np.dot(c.G_amb_W_K, Tm - loop.ambient_K) * h
        ledger[3] += motor_rate * (motor_outlet_K - Tm[CASE]) * h
        T = T1
    dt = dts.sum()
    return T, T_sum / dt, Phi, g_acc, g_case, C1, heat_sum / dt, ledger
