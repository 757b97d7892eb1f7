"""
Control-node thermal model of the EHA hydraulic circuit (physics.md section 4).

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
dissipated hydraulic power ends up as heat. With the flows and sources held
over a step, the 13-node system is integrated exactly (one small matrix
exponential per step, which also gives the step-mean temperatures).
"""

from dataclasses import dataclass
from typing import Dict, Optional, Tuple

import numpy as np
import scipy.linalg
from scipy.linalg.lapack import dgesv

from . import correlations as corr
from .compiled import jit
from .oil import conductivity, density, kinematic_viscosity, Oil, specific_heat
from ..config import Hydraulics

OIL_NODES = ('port_a', 'port_b', 'case', 'line_a', 'line_b', 'chamber_a', 'chamber_b',
             'accumulator')
SOLID_NODES = ('pump_shell', 'line_a_shell', 'line_b_shell', 'actuator_shell',
               'accumulator_shell')
NODES = OIL_NODES + SOLID_NODES
_I = {name: i for i, name in enumerate(NODES)}
_CASE, _ACC, _PUMP_SHELL = _I['case'], _I['accumulator'], _I['pump_shell']
_CHAMBER_A, _CHAMBER_B = _I['chamber_a'], _I['chamber_b']
_LINE_A, _LINE_B = _I['line_a'], _I['line_b']

# Directed flow links (upstream, downstream); 'pump' is the displacement flow, the
# rest are throttles (leaks, line friction, check valves).
LINKS: Tuple[Tuple[str, str], ...] = (
    ('port_b', 'port_a'), ('port_a', 'port_b'),             # 0, 1 pump displacement
    ('port_a', 'port_b'), ('port_b', 'port_a'),             # 2, 3 internal leakage
    ('port_a', 'case'), ('port_b', 'case'),                 # 4, 5 external leakage
    ('port_a', 'line_a'), ('line_a', 'port_a'),             # 6, 7 line A, pump end
    ('line_a', 'chamber_a'), ('chamber_a', 'line_a'),       # 8, 9 line A, actuator end
    ('chamber_b', 'line_b'), ('line_b', 'chamber_b'),       # 10, 11 line B, actuator end
    ('line_b', 'port_b'), ('port_b', 'line_b'),             # 12, 13 line B, pump end
    ('accumulator', 'port_a'), ('port_a', 'accumulator'),   # 14, 15 make-up / relief A
    ('accumulator', 'port_b'), ('port_b', 'accumulator'),   # 16, 17 make-up / relief B
)
PUMP_LINKS = (0, 1)


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
        self._line_geometry = (ln.bore_m, 0.25 * np.pi * ln.bore_m ** 2, self.line_inner_area)
        self._capacities = np.concatenate([np.zeros(self.n_oil), self.solid_capacity])
        self._T_alpha: Optional[float] = None
        # energies (J): heat generated, stored (a moving chamber's oil included), to
        # ambient, and the net enthalpy the motor adds to the oil passing through it
        self.energy_J = {'sources': 0.0, 'stored': 0.0, 'to_ambient': 0.0, 'motor_loop': 0.0}
        self.T_mean = np.full(n, np.nan)
        self.last_step: Optional[tuple] = None

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
        K, M, C, s = circuit_matrices(
            T0, dt_s, sf.flow_m3_s, 0.5 * (sf.p_start_Pa + sf.p_end_Pa), sf.chamber_volumes_m3,
            sf.case_volume_m3, motor_rate, sf.motor_outlet_K, ambient_K, rho_cp_flow, heat,
            self.K_static, self._k_index, self.oil_volumes, self._capacities, self.G_amb,
            self._line_geometry, self.oil.laws)
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
            tm[_CHAMBER_A] * dV_a + tm[_CHAMBER_B] * dV_b
            + (tm[_CASE] - tm[_ACC]) * sf.case_dV_m3)
        e['to_ambient'] += float(np.dot(self.G_amb, Tm - ambient_K)) * dt_s
        e['motor_loop'] += motor_rate * (sf.motor_outlet_K - tm[_CASE]) * dt_s
        self.last_sources = heat
        # what a state estimator needs to propagate a covariance through this step: the
        # augmented transition (its last column holds the constant input), the exponent,
        # the heat capacities and the motor loop's capacity rate (W/K)
        self.last_step = (E, M, C, motor_rate)
        return T1

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
        T_oil = float(T0[:self.n_oil].sum() / self.n_oil)    # the mean, as np.mean forms it
        if self._T_alpha is None:
            self._T_alpha = T_oil
        else:
            self._T_alpha += -np.expm1(-dt_s / self.alpha_T_filter_s) * (T_oil - self._T_alpha)
        return node_sources(self.oil.alpha_p * self._T_alpha, dt_s, sf.work_W,
                            sf.volume_dp_m3Pa, sf.pump_friction_W, self.is_pump, self.d,
                            self.n, self.friction_to_case, self.extra_loss_W)

    def named(self, T: np.ndarray) -> Dict[str, float]:
        """Return the node temperatures (K) by name."""
        return dict(zip(NODES, T.tolist()))


@jit
def node_sources(alpha_T, dt_s, work_W, volume_dp_m3Pa, pump_friction_W, is_pump, link_down,
                 n, friction_to_case, extra_loss_W):
    """Return the heat input (W) of each node, see :meth:`HydraulicCircuit.sources`."""
    # throttles: (1 - alpha T) dp Q; pump: alpha T (p_d - p_u) Q = -alpha T * work
    per_link = np.where(is_pump, -alpha_T * work_W, (1 - alpha_T) * work_W)
    heat = np.bincount(link_down, weights=per_link, minlength=n)
    heat[:volume_dp_m3Pa.size] += alpha_T * volume_dp_m3Pa / dt_s
    heat[_CASE] += friction_to_case * pump_friction_W + extra_loss_W
    heat[_PUMP_SHELL] += (1 - friction_to_case) * pump_friction_W
    return heat


@jit
def line_conductances(T_K, p_Pa, rho, cp, flows, line_geometry, laws):
    """
    Return the oil-to-wall conductances (W/K) of lines A and B at their mean flows.

    Fully developed pipe flow (laminar 3.66, Gnielinski above Re 4000).
    ``T_K``, ``p_Pa``, ``rho`` and ``cp`` are the two lines' oil values;
    ``flows`` the mean flow of every link; ``line_geometry`` the bore (m),
    flow section (m^2) and inner wall area (m^2) of a line.
    """
    bore, flow_area, inner_area = line_geometry
    mu = kinematic_viscosity(T_K, p_Pa, laws) * rho
    k = conductivity(T_K, laws)
    q = np.empty(2)
    q[0] = flows[6] + flows[7]          # links 6 + 7 (line A), 10 + 11 (line B)
    q[1] = flows[10] + flows[11]
    re = rho * q / flow_area * bore / mu
    nu = corr.laminar_turbulent_nusselt(re, mu * cp / k, corr.NU_PIPE_T)
    return nu * k / bore * inner_area


@jit
def circuit_matrices(T0, dt_s, flows, p_mid, chamber_volumes, case_volume, motor_rate,
                     motor_outlet_K, ambient_K, rho_cp_flow, heat, K_static, k_index,
                     oil_volumes, capacities, G_amb, line_geometry, laws):
    """
    Return (K, M, C, s) of one step of :meth:`HydraulicCircuit.step`.

    K (W/K) the conductance matrix with the step's advection and line
    convection, C (J/K) the heat capacities, s (W) the constant input and M
    the exponent of the augmented system (its last column holds s).
    """
    n = T0.size
    no = p_mid.size
    T_oil = T0[:no]
    rho, cp = density(T_oil, p_mid, laws), specific_heat(T_oil, laws)
    vol = oil_volumes.copy()
    vol[5], vol[6] = chamber_volumes
    vol[2] = case_volume
    C = capacities.copy()
    C[:no] = rho * cp * vol
    rate = rho_cp_flow * flows
    lines = slice(_LINE_A, _LINE_B + 1)       # adjacent nodes
    g_line = line_conductances(T0[lines], p_mid[lines], rho[lines], cp[lines], flows,
                               line_geometry, laws)
    weights = np.concatenate((rate, -rate, g_line, g_line, -g_line, -g_line,
                              np.full(1, motor_rate)))
    K = K_static + np.bincount(k_index, weights=weights, minlength=n * n).reshape(n, n)
    s = G_amb * ambient_K + heat
    s[_ACC] += motor_rate * motor_outlet_K
    M = np.zeros((n + 1, n + 1))
    M[:n, :n] = -K * (dt_s / C.reshape(n, 1))
    M[:n, n] = s * (dt_s / C)
    return K, M, C, s
