"""
The coupled model's compiled per-step kernels and the named structs they take.

The flows of a step from the sensors' samples (:func:`step_flows_kernel`),
their interval sums (:func:`segment_sums`), the pressures along the lines and
the oil volumes per substep, for :class:`~.eha.EHAModel`. A kernel called
from Python takes a struct as the plain tuple of its fields and names it
again on its first line (as :mod:`.motor_kernels` does): numba types a plain
tuple faster than a NamedTuple from Python, and this runs at every step.
"""

from typing import NamedTuple

import numpy as np

from . import fluid_power as fp
from .compiled import jit
from .hydraulics import (ACCUMULATOR, CASE, CHAMBER_A, CHAMBER_B, LEAK_A_TO_B,
                         LEAK_A_TO_CASE, LEAK_B_TO_A, LEAK_B_TO_CASE, LINE_A, LINE_A_ACTUATOR_END,
                         LINE_A_ACTUATOR_END_BACK, LINE_A_PUMP_END, LINE_A_PUMP_END_BACK, LINE_B,
                         LINE_B_ACTUATOR_END, LINE_B_ACTUATOR_END_BACK, LINE_B_PUMP_END,
                         LINE_B_PUMP_END_BACK, MAKE_UP_A, MAKE_UP_B, N_OIL, PORT_A, PORT_B,
                         PUMP_INTO_A, PUMP_INTO_B)
from .oil import density as oil_density, kinematic_viscosity as oil_nu


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
