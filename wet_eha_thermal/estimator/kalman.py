"""
The Kalman filter's numerics on the coupled model: transition, prediction, scalar updates.

Compiled kernels over plain arrays and named tuples (the model's
:class:`~..model.eha.MotorTransition` and :class:`~..model.eha.CircuitTransition`,
and :class:`FilterLayout`); :mod:`.correction` holds the filter's state, its
thermocouple guards and the glue to the model.
"""

from typing import NamedTuple

import numpy as np

from ..model.compiled import jit
from ..units import C_TO_K


class FilterLayout(NamedTuple):
    """Where the filter's couplings sit in the model's states and inputs and in its own state."""

    s_copper: np.ndarray     # the copper states (in the order of their sources)
    col_copper: np.ndarray   # the copper sources' columns of the motor's Bd
    col_inlet: int           # the oil inlet's column of Bd (the pump case temperature)
    w_copper: np.ndarray     # the winding disturbance's split over the copper sources
    s_outlet: int            # the motor outlet's state
    i_case: int              # the pump case's hydraulic node
    i_case_d: int            # the case disturbance's filter state (-1: none)
    i_wind_d: int            # the winding disturbance's filter state (-1: none)


@jit
def coupled_transition(motor, circuit, copper_gain, layout, n):
    """
    Return the transition (n x n) of the filter's state over one step of the coupled model.

    Motor (a :class:`~..model.eha.MotorTransition`): the step's zero-order-hold
    matrices ``Ad``, ``Bd`` (``substeps`` equal sub-steps of them) and its
    mean ``Mx``, ``Mw``, the copper sources' columns of ``Bd`` fed back
    through ``copper_gain`` (dP/dT, W/K) into the copper states, the oil
    inlet's column (the pump case temperature). Hydraulics (a
    :class:`~..model.eha.CircuitTransition`): the circuit's transition
    ``Phi`` and its responses ``g_acc`` (to the motor outlet's step mean) and
    ``g_case`` (to heat into the case, W). ``layout``: a
    :class:`FilterLayout`; the disturbances walk, their rows are the identity.
    """
    Ad, Bd, Mx, Mw, substeps = motor
    Eh, g_acc, g_case = circuit
    s_copper, col_copper, col_inlet, w_copper, s_outlet, i_case, i_case_d, i_wind_d = layout
    m, nh = Ad.shape[0], Eh.shape[0]
    Phi = np.zeros((n, n))
    B_cu = np.ascontiguousarray(Bd[:, col_copper])
    A = Ad.copy()
    for j in range(s_copper.size):
        A[:, s_copper[j]] += B_cu[:, j] * copper_gain[j]
    b_in = Bd[:, col_inlet].copy()
    b_wind = B_cu @ w_copper
    if substeps > 1:                      # not with the estimator's steps (<= 1 s)
        acc = np.zeros_like(A)
        for j in range(substeps):
            acc += np.linalg.matrix_power(A, j)
        A = np.linalg.matrix_power(A, substeps)
        b_in, b_wind = acc @ b_in, acc @ b_wind
    Phi[:m, :m] = A
    Phi[:m, m + i_case] = b_in
    if i_wind_d >= 0:
        Phi[:m, i_wind_d] = b_wind
    out_x = Mx[s_outlet].copy()
    for j in range(s_copper.size):
        out_x[s_copper[j]] += Mw[s_outlet, col_copper[j]] * copper_gain[j]
    Phi[m:m + nh, :m] = np.outer(g_acc, out_x)
    Phi[m:m + nh, m:m + nh] = Eh
    Phi[m:m + nh, m + i_case] += g_acc * Mw[s_outlet, col_inlet]
    if i_case_d >= 0:
        Phi[m:m + nh, i_case_d] = g_case
    if i_wind_d >= 0:
        Phi[m:m + nh, i_wind_d] = g_acc * np.dot(Mw[s_outlet][col_copper], w_copper)
    for i in range(m + nh, n):
        Phi[i, i] = 1.0
    return Phi


@jit
def copper_gain(T_copper, p_copper, alpha_copper):
    """
    Return dP/dT (W/K) of each copper source: its loss ``p_copper`` (W) scales with R(T).

    R(T) is 1 + ``alpha_copper`` (T - 20 degC), ``T_copper`` in K.
    """
    return p_copper * alpha_copper / (1.0 + alpha_copper * (T_copper - (C_TO_K + 20.0)))


@jit
def predict_covariance(P, motor, circuit, T_copper, p_copper, alpha_copper, layout, C_motor,
                       C_hyd, heat_var, walk_var, prior):
    """
    Return the covariance after a step of the coupled model, from the step's matrices.

    The copper losses are linear in their temperatures ``T_copper`` (K)
    (:func:`copper_gain`). The transition is
    :func:`coupled_transition`'s. Process noise, added at the start of the
    step: ``heat_var`` (W^2 s, the heat-rate noise q^2 times the step) over
    the square of each state's heat capacity (``C_motor``, ``C_hyd``, J/K),
    and ``walk_var`` for the disturbances (:func:`propagate_covariance`).
    """
    Phi = coupled_transition(motor, circuit, copper_gain(T_copper, p_copper, alpha_copper),
                             layout, P.shape[0])
    cap = np.concatenate((C_motor, C_hyd))
    noise = np.concatenate((heat_var / (cap * cap), walk_var))
    P = propagate_covariance(P, Phi, noise, prior)
    if not np.isfinite(P).all():
        raise FloatingPointError('the covariance is no longer finite')
    return P


@jit
def propagate_covariance(P, Phi, noise, prior):
    """
    Return the covariance after a step: Phi (P + diag(noise)) Phi^T, symmetrised, capped.

    ``noise`` the variance added to each state at the start of the step;
    the last ``prior.size`` states are the disturbances, whose variance never
    exceeds their ``prior`` (their rows and columns are scaled down to it).
    """
    n = P.shape[0]
    Q = P.copy()
    for i in range(n):
        Q[i, i] += noise[i]
    Q = Phi @ Q @ Phi.T
    Q = (Q + Q.T) * 0.5           # (not in place: Q.T is a view of Q)
    for j in range(prior.size):       # a disturbance never exceeds its prior
        i = n - prior.size + j
        if Q[i, i] > prior[j]:
            f = np.sqrt(prior[j] / Q[i, i])
            Q[i, :] *= f
            Q[:, i] *= f
    return Q


@jit
def output_variances(P, taken, H_mean, mean_of_output):
    """
    Return the variance of every output from the covariance ``P``, never below zero.

    ``taken[k]``: the state output ``k`` takes (-1: none); else it is the
    weighted mean of row ``mean_of_output[k]`` of ``H_mean``. An output that
    is neither now (a port before the first sample) gets 0.
    """
    HP = H_mean @ P
    out = np.empty(taken.size)
    for k in range(taken.size):
        if taken[k] >= 0:
            v = P[taken[k], taken[k]]
        elif mean_of_output[k] >= 0:
            v = np.dot(HP[mean_of_output[k]], H_mean[mean_of_output[k]])
        else:
            v = np.nan
        out[k] = v if v > 0.0 else 0.0
    return out


@jit
def scalar_update(P, row, y, prior, r, gate2, use, delta):
    """
    Gate a reading ``y`` of ``row`` . state; if it passes, update ``P`` and ``delta`` in place.

    ``prior``: its estimate before the step's earlier updates, ``delta`` (of
    the state), which add their part; ``r`` the reading's variance. Returns
    (innovation, its variance, inside the gate: innovation^2 <= ``gate2``
    variance); the update is made when inside and ``use``.
    """
    innovation = y - (prior + np.dot(row, delta))
    Ph = P @ row
    var = np.dot(row, Ph) + r
    inside = innovation * innovation <= gate2 * var
    if inside and use and np.isfinite(innovation) and np.isfinite(var) and var > 0.0:
        k = Ph / var
        delta += k * innovation
        joseph_update(P, k, Ph, var)          # Joseph form, in place
    return innovation, var, inside


@jit
def symmetrise(P):
    """Replace ``P`` in place by (P + P^T) / 2: the scalar updates leave rounding asymmetries."""
    n = P.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            v = (P[i, j] + P[j, i]) * 0.5
            P[i, j] = v
            P[j, i] = v


@jit
def joseph_update(P, k, Ph, var):
    """
    Update the covariance ``P`` in place for one scalar measurement, in Joseph form.

    (I - k h) P (I - k h)^T + k r k^T written as rank-one terms: ``Ph`` is
    P h^T, ``var`` = h P h^T + r the innovation's variance and ``k`` = Ph / var
    the gain.
    """
    n = k.size
    for i in range(n):
        for j in range(n):
            P[i, j] = P[i, j] - k[i] * Ph[j] - Ph[i] * k[j] + var * (k[i] * k[j])
