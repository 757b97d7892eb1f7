"""
The wet motor's compiled kernels and the named structures they take.

:class:`~.motor.WetMotor` builds each structure once (the motor's constants
do not change) and calls these kernels every step. A structure is a
``typing.NamedTuple`` whose fields carry their units; a kernel called from
Python takes it as the plain tuple of its fields (``tuple(s)``) and names
them again at its first line: numba types a plain tuple in C and a
NamedTuple in Python, three times slower, which counts on every step (the
precedent is :class:`~.oil.OilLaws`).
"""

from typing import NamedTuple

import numpy as np

from . import correlations as corr
from .compiled import jit
from .loss_table import COPPER_EXCESS, IRON, MAGNET, ROTOR_CORE, SLEEVE, table_values
from .losses import copper_resistance, electrical_frequency, steinmetz_loss_density
from .oil import conductivity as oil_conductivity, density as oil_density, \
    kinematic_viscosity as oil_nu, specific_heat as oil_cp

#: the kinds of surface the end-space oil washes (:func:`end_space_htc`): the rotor's end
#: face, the end cap (its part facing the rotor, and the rest), a stator surface in the
#: oil's swirl (end winding, stack faces, frame), the turning shaft end
END_ROTOR_FACE, END_CAP, END_STATOR, END_SHAFT = range(4)
#: how :func:`filter_coefficient_point` moves the filter: start at the input, the running
#: mean of the first time constant, or the two cascaded first-order stages
FILTER_START, FILTER_RUNNING_MEAN, FILTER_CASCADE = range(3)


class CopperLaw(NamedTuple):
    """The phase resistance R(T) of :func:`~.losses.copper_resistance`."""

    r_20C_ohm: float        #: phase resistance at 20 degC (ohm)
    tempco_1_K: float       #: its temperature coefficient (1/K)


class IronLaw(NamedTuple):
    """The stator iron's Steinmetz law (:func:`~.losses.steinmetz_loss_density`)."""

    pole_pairs: float
    hysteresis_coeff_W_kgHzT: float     #: k_h, W/(kg Hz T^alpha)
    steinmetz_exponent: float           #: alpha
    eddy_coeff_W_kgHz2T2: float         #: k_e, W/(kg Hz^2 T^2)
    yoke_flux_density_T: float
    teeth_flux_density_T: float


class GapFriction(NamedTuple):
    """
    One airgap section's factors of :func:`~.correlations.airgap_friction_kernel`.

    As :func:`~.correlations.airgap_friction_factors` forms them: the Couette
    power is 4 pi mu w^2 ``couette_m3``; Re_d = ``re_per_rho_w_m2`` rho w / mu;
    ``g03`` = g^0.3 and ``bb_rho_m5`` (r1^4 L) scale the Bilgen-Boulos power;
    Ta_m = ``ta_per_re2`` Re_d^2.
    """

    couette_m3: float
    re_per_rho_w_m2: float
    g03: float
    bb_rho_m5: float
    ta_per_re2: float


class EndDrag(NamedTuple):
    """The rotor's end faces (Daily and Nece's enclosed disc) and the bearings' friction."""

    disc_radius_m: float
    disc_laws: np.ndarray       #: :func:`~.correlations.daily_nece_laws` at the clearance
    bearing_mean_diameter_m: float
    bearing_f0: float           #: Palmgren's lubrication factor
    bearing_f1: float           #: Palmgren's load factor
    bearing_load_N: float
    bearing_factor: float       #: calibration factor on the bearing's friction


class EndGeometry(NamedTuple):
    """The end spaces' geometry in :func:`end_space_htc`."""

    disc_radius_m: float        #: the rotor's end face as a disc, its radius a
    disc_laws: np.ndarray       #: :func:`~.correlations.daily_nece_laws` at its clearance
    gap_ratio: float            #: G, the rotor-to-cap clearance over a
    cap_disc_share: float       #: the share of the cap's face that faces the disc
    depth_m: float              #: the end space's axial depth


class EndSurfaces(NamedTuple):
    """The surfaces the end-space oil washes, one row each (node indices, kinds END_*)."""

    surface: np.ndarray         #: the surface's node
    oil: np.ndarray             #: the end-space oil node that washes it
    kind: np.ndarray            #: END_ROTOR_FACE, END_CAP, END_STATOR or END_SHAFT
    radius_m: np.ndarray        #: its mean radius
    length_m: np.ndarray        #: its length as a plate in the swirl


class MotorLossConstants(NamedTuple):
    """
    The constants of :func:`motor_losses`: nodes, laws, masses, the loss table.

    ``copper_weight`` is phases x each copper source's share of the
    conductor length; ``iron_split`` shares a map's iron loss among the yoke
    and teeth slices; ``table``, ``grid`` and ``from_map`` the loss table of
    :mod:`.loss_table`; ``oil_laws`` the oil's :class:`~.oil.OilLaws`.
    """

    idx_copper: np.ndarray      #: the copper nodes in the temperature vector
    idx_gap: np.ndarray         #: the airgap oil sections
    idx_end_oil: np.ndarray     #: the two end spaces' oil (front, rear)
    copper_weight: np.ndarray
    copper: CopperLaw
    yoke_mass_kg: np.ndarray    #: per slice
    teeth_mass_kg: np.ndarray   #: per slice
    iron: IronLaw
    iron_split: np.ndarray
    gap: GapFriction
    ends: EndDrag
    table: np.ndarray
    grid: tuple
    from_map: bool
    oil_laws: tuple


class AmbientLedger(NamedTuple):
    """The links :func:`step_energies` books to ambient and the oil's inlet and outlet."""

    ids: np.ndarray             #: the links to ambient, the frame's first, then the caps'
    ends: np.ndarray            #: their ends, indices into [T; T_b]
    n_frame: int                #: how many of them are the frame's
    outlet: int                 #: the motor's outlet oil node


class CoefficientFilter(NamedTuple):
    """The coefficient filter's watched nodes and state (:func:`filter_coefficient_point`)."""

    idx_watch: np.ndarray       #: the nodes whose temperatures set coefficients
    stages: np.ndarray          #: 2 x (2 + watched): the two stages, moved in place
    T_refreshed_K: np.ndarray   #: the watched temperatures at the last refresh
    watch_scale: np.ndarray     #: their drift thresholds, in units of refresh_dT_K


@jit
def core_loss_density(speed_abs_rad_s, iron):
    """
    Return the Steinmetz loss per kg (W/kg) of the yoke and of the teeth at each speed (rad/s).

    ``iron``: the :class:`IronLaw`.
    """
    k_h, alpha, k_e = (iron.hysteresis_coeff_W_kgHzT, iron.steinmetz_exponent,
                       iron.eddy_coeff_W_kgHz2T2)
    f = electrical_frequency(speed_abs_rad_s, iron.pole_pairs)
    return (steinmetz_loss_density(f, iron.yoke_flux_density_T, k_h, alpha, k_e),
            steinmetz_loss_density(f, iron.teeth_flux_density_T, k_h, alpha, k_e))


@jit
def gap_friction(speed_abs_rad_s, T_gap_K, p_Pa, gap, laws):
    """
    Return the oil friction (W) of each airgap section at each speed (samples x sections).

    The oil at the sections' temperatures ``T_gap_K`` (K) and ``p_Pa``;
    ``gap``: the :class:`GapFriction` of one section; ``laws``: the oil's.
    Returns (power W, regime, Re_d) as :func:`~.correlations.airgap_friction_kernel`.
    """
    rho = oil_density(T_gap_K, p_Pa, laws)
    mu = oil_nu(T_gap_K, p_Pa, laws) * rho     # the dynamic viscosity
    return corr.airgap_friction_kernel(rho, mu, speed_abs_rad_s.reshape(-1, 1), gap.couette_m3,
                                       gap.re_per_rho_w_m2, gap.g03, gap.bb_rho_m5,
                                       gap.ta_per_re2)


@jit
def end_space_htc(T_K, surfaces, w, p_Pa, geometry, laws):
    """
    Return h (W/(m^2 K)) of each end-space surface, and the disc's and plates' Re and Pr.

    The :class:`EndSurfaces` at the temperatures ``T_K`` (K); ``w`` |speed|
    (rad/s); oil properties at the film temperature and ``p_Pa``;
    ``geometry`` the :class:`EndGeometry` (as plain tuples, see the module
    docstring). The rotor's end face, and the cap where it faces it:
    :func:`~.correlations.enclosed_disc_nusselt_kernel`; the stator surfaces and the shaft
    end: :func:`~.correlations.flat_plate_nusselt_kernel` in the swirl of
    :func:`~.correlations.end_space_swirl_speed` (relative to the shaft for
    the shaft), never below conduction through half the end space's depth.
    """
    s, geo = EndSurfaces(*surfaces), EndGeometry(*geometry)
    kind, radius_m, length_m = s.kind, s.radius_m, s.length_m
    a, disc_laws, g, cap_share, depth = (geo.disc_radius_m, geo.disc_laws, geo.gap_ratio,
                                         geo.cap_disc_share, geo.depth_m)
    T_film = 0.5 * (T_K[s.surface] + T_K[s.oil])
    rho = oil_density(T_film, p_Pa, laws)
    nu = oil_nu(T_film, p_Pa, laws)
    k = oil_conductivity(T_film, laws)
    pr = nu * rho * oil_cp(T_film, laws) / k
    v = corr.end_space_swirl_speed(w, a, radius_m, corr.CORE_SWIRL_RATIO)
    v = np.where(kind == END_SHAFT, w * radius_m - v, v)
    re_plate = v * length_m / nu
    h = np.maximum(corr.flat_plate_nusselt_kernel(re_plate, pr) * k / length_m, 2.0 * k / depth)
    re_disc = np.zeros(kind.size)
    for i in range(kind.size):
        if kind[i] <= END_CAP:
            re_disc[i] = w * a * a / nu[i]
            h_disc = corr.enclosed_disc_nusselt_kernel(re_disc[i], pr[i], disc_laws, g) * k[i] / a
            if kind[i] == END_ROTOR_FACE:
                h[i] = h_disc
            else:
                h[i] = cap_share * h_disc + (1.0 - cap_share) * h[i]
    return h, re_disc, re_plate, pr


@jit
def end_drag(speed_abs_rad_s, T_end_K, p_Pa, ends, laws):
    """
    Return the friction (W) of each end face and of each bearing at each |speed| (samples x 2).

    With the end spaces' oil at ``T_end_K`` (K, front and rear) and ``p_Pa``:
    the rotor's end face, :func:`~.correlations.enclosed_disc_friction`; the
    bearing, :func:`~.correlations.palmgren_bearing_torque` times the speed
    and the calibration factor. ``ends``: the :class:`EndDrag`.
    """
    a, disc, dm, f0, f1, load, factor = (
        ends.disc_radius_m, ends.disc_laws, ends.bearing_mean_diameter_m, ends.bearing_f0,
        ends.bearing_f1, ends.bearing_load_N, ends.bearing_factor)
    rho = oil_density(T_end_K, p_Pa, laws)
    nu = oil_nu(T_end_K, p_Pa, laws)
    n = speed_abs_rad_s.size
    face = np.empty((n, 2))
    bearing = np.empty((n, 2))
    for e in range(2):
        mu = nu[e] * rho[e]
        for k in range(n):
            w = speed_abs_rad_s[k]
            face[k, e] = corr.enclosed_disc_friction(rho[e], mu, w, a, disc)[0]
            torque = corr.palmgren_bearing_torque(nu[e], w, dm, f0, f1, load)
            bearing[k, e] = factor * w * torque
    return face, bearing


@jit
def motor_losses(current_sq_mean_A2, current_sq_A2, speed_rad_s, T_K, case_pressure_Pa,
                 constants):
    """
    Return the source powers (W), the largest Bilgen-Boulos Re_d, whether the table ran out.

    The powers of :meth:`WetMotor.losses`; whether the loss table was extrapolated; and
    the copper's AC excess (A^2 at 20 degC) the powers hold.

    ``constants``: the :class:`MotorLossConstants` (its plain tuple), whose
    nodes index ``T_K`` (K). The loss table at each speed sample (rad/s) and
    its current squared ``current_sq_A2`` (A^2). Copper: ``current_sq_mean_A2``
    (A^2) x R(T) of each copper node plus the table's AC excess (A^2 at 20 degC)
    x R_20^2 / R(T), x ``copper_weight``; iron: the yoke's and the teeth's masses (kg) x their
    Steinmetz loss per kg (:func:`core_loss_density`), or with ``from_map``
    the table's iron loss shared by ``iron_split``; friction
    (:func:`gap_friction`, :func:`end_drag`) at ``case_pressure_Pa``;
    magnet, sleeve and rotor core from the table, the same in every slice.
    Every loss but the DC copper is a mean over the samples. The Re_d returned is the largest
    where Bilgen-Boulos set the airgap friction (0 where it set none): what
    the validity log would flag.
    """
    c = MotorLossConstants(*constants)
    idx_copper, idx_gap, idx_end, laws = c.idx_copper, c.idx_gap, c.idx_end_oil, c.oil_laws
    w = np.abs(speed_rad_s)
    n_s = w.size
    n_cu, n = idx_copper.size, idx_gap.size
    power = np.empty(n_cu + 6 * n + 4)
    em, outside = table_values(c.table, c.grid, w, current_sq_A2)
    em_mean = em.sum(axis=0) / n_s
    # the AC excess is eddy currents, resistance limited: its loss goes as 1 / rho(T)
    r_cu = copper_resistance(c.copper.r_20C_ohm, c.copper.tempco_1_K, T_K[idx_copper])
    power[:n_cu] = (current_sq_mean_A2 * r_cu
                    + em_mean[COPPER_EXCESS] * c.copper.r_20C_ohm ** 2 / r_cu) * c.copper_weight
    k = n_cu
    if c.from_map:
        power[k:k + 2 * n] = em_mean[IRON] * c.iron_split
    else:
        d_yoke, d_teeth = core_loss_density(w, c.iron)
        power[k:k + n] = c.yoke_mass_kg * (d_yoke.sum() / n_s)
        power[k + n:k + 2 * n] = c.teeth_mass_kg * (d_teeth.sum() / n_s)
    k += 2 * n
    friction, regime, re = gap_friction(w, T_K[idx_gap], case_pressure_Pa, c.gap, laws)
    power[k:k + n] = friction.sum(axis=0) / n_s
    k += n
    for column in (MAGNET, SLEEVE, ROTOR_CORE):
        power[k:k + n] = em_mean[column] / n
        k += n
    face, bearing = end_drag(w, T_K[idx_end], case_pressure_Pa, c.ends, laws)
    power[k:k + 2] = face.sum(axis=0) / n_s
    power[k + 2:k + 4] = bearing.sum(axis=0) / n_s
    re_bb_max = 0.0
    for i in range(re.size):
        if regime.flat[i] != 0 and re.flat[i] > re_bb_max:
            re_bb_max = re.flat[i]
    return power, re_bb_max, outside, em_mean[COPPER_EXCESS]


@jit
def step_energies(dt_s, power_W, dx, capacity, dynamic, T_mean, boundary_K, conductance,
                  ledger, inlet_rate_W_K, inlet_K):
    """
    Return a step's energies (J): generated, stored, to ambient, carried off by the oil.

    Over ``dt_s`` (s): the sources' ``power_W`` (W); the states' change ``dx``
    (K) times their heat capacities (``capacity`` J/K of every node, the
    states at ``dynamic``); the heat through the links to ambient of the
    :class:`AmbientLedger` ``ledger`` (its plain tuple) of ``conductance``
    (W/K) at the step-mean temperatures ``T_mean`` (K) and ``boundary_K``; the
    enthalpy flow ``inlet_rate_W_K`` (m c_p, W/K) from ``inlet_K`` (K) to the
    mean of the outlet node.
    """
    books = AmbientLedger(*ledger)
    ambient_ids, ambient_ends, n_frame = books.ids, books.ends, books.n_frame
    n = T_mean.size
    to_frame = 0.0
    to_caps = 0.0
    for k in range(ambient_ids.size):
        a, b = ambient_ends[k, 0], ambient_ends[k, 1]
        dT = ((T_mean[a] if a < n else boundary_K[a - n])
              - (T_mean[b] if b < n else boundary_K[b - n]))
        if k < n_frame:
            to_frame += conductance[ambient_ids[k]] * dT
        else:
            to_caps += conductance[ambient_ids[k]] * dT
    return (power_W.sum() * dt_s, np.dot(capacity[dynamic], dx), (to_frame + to_caps) * dt_s,
            inlet_rate_W_K * (T_mean[books.outlet] - inlet_K) * dt_s)


@jit
def filter_coefficient_point(speed_rad_s, oil_flow_m3_s, T_K, mode, weight, state):
    """
    Move the coefficient filter by one step, in place; return (speed, flow, drift).

    The filter's input is [mean |speed| (rad/s), ``oil_flow_m3_s``, the
    temperatures (K) of the watched nodes of ``T_K``]; ``state`` the
    :class:`CoefficientFilter` (its plain tuple), whose ``stages`` move.
    ``mode`` FILTER_START sets both to the input;
    FILTER_RUNNING_MEAN moves the first by ``weight`` (dt / age) towards the
    input and the second with it; FILTER_CASCADE moves the first by
    ``weight`` (1 - exp(-dt / tau)) towards the input and the second by the
    same weight towards the first. Returns the second stage's speed and flow, and
    the largest move of its temperatures from ``T_refreshed_K`` in units of
    ``watch_scale``.
    """
    s = CoefficientFilter(*state)
    idx_watch, stages = s.idx_watch, s.stages
    raw = np.empty(idx_watch.size + 2)
    raw[0] = np.abs(speed_rad_s).sum() / speed_rad_s.size
    raw[1] = oil_flow_m3_s
    raw[2:] = T_K[idx_watch]
    f1, f2 = stages[0], stages[1]
    if mode == FILTER_START:
        f1[:] = raw
        f2[:] = raw
    elif mode == FILTER_RUNNING_MEAN:
        f1 += (raw - f1) * weight
        f2[:] = f1
    else:
        f1 += weight * (raw - f1)
        f2 += weight * (f1 - f2)
    drift = (np.abs(f2[2:] - s.T_refreshed_K) / s.watch_scale).max()
    return f2[0], f2[1], drift
