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
from .correlations import DAILY_NECE_CORE_SWIRL as DAILY_NECE_K0
from .loss_table import COPPER_EXCESS, IRON, MAGNET, ROTOR_CORE, SLEEVE, table_values
from .losses import copper_resistance, electrical_frequency, steinmetz_loss_density
from .oil import conductivity as oil_conductivity, density as oil_density, \
    kinematic_viscosity as oil_nu, specific_heat as oil_cp

#: the kinds of surface the end-space oil washes (:func:`end_space_htc`): an annulus of the
#: rotor's end face, an annulus of the stationary wall facing it (the end cap's hub), a
#: stationary surface in the oil's swirl (end winding, stack faces, frame, cap), the turning
#: shaft end
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


class EndSurfaces(NamedTuple):
    """
    The surfaces the end-space oil washes, one row each (node indices, kinds END_*).

    An annulus of the disc or of the wall facing it (END_ROTOR_FACE,
    END_CAP) spans ``radius_m`` -+ ``length_m`` / 2; a surface in the swirl
    (END_STATOR, END_SHAFT) is a plate of ``length_m`` along the flow at
    ``radius_m``.
    """

    surface: np.ndarray         #: the surface's node
    oil: np.ndarray             #: the end-space oil node that washes it
    side: np.ndarray            #: its end space: 0 front, 1 rear
    kind: np.ndarray            #: END_ROTOR_FACE, END_CAP, END_STATOR or END_SHAFT
    radius_m: np.ndarray        #: its mean radius
    length_m: np.ndarray        #: its radial width (an annulus) or its length as a plate
    area_m2: np.ndarray         #: its wetted area


class EndGeometry(NamedTuple):
    """The end spaces' geometry in :func:`end_space_htc` and :func:`end_space_swirl`."""

    disc_radius_m: float        #: the rotor's end face as a disc, its radius a
    disc_laws: np.ndarray       #: :func:`~.correlations.daily_nece_laws` at its clearance
    gap_ratio: float            #: G, the rotor-to-hub clearance over a
    depth_m: float              #: the end space's axial depth
    oil: np.ndarray             #: the two end spaces' oil nodes (front, rear)


class EndDrag(NamedTuple):
    """
    The end spaces' friction (their rotating surfaces) and the bearings'.

    ``swirl`` holds each end space's core swirl ratio K (front, rear) from
    the last coefficient refresh (:func:`end_space_htc`), moved in place.
    """

    disc_radius_m: float        #: the rotor's end face as a disc, its radius a
    disc_laws: np.ndarray       #: :func:`~.correlations.daily_nece_laws` at the clearance
    rotating: np.ndarray        #: rotating surfaces, a row each: side, kind, radius, length, area
    swirl: np.ndarray           #: K of each end space, front and rear
    bearing_mean_diameter_m: float
    bearing_f0: float           #: Palmgren's lubrication factor
    bearing_f1: float           #: Palmgren's load factor
    bearing_load_N: float
    bearing_factor: float       #: calibration factor on the bearing's friction


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
def surface_torque(kind, radius_m, length_m, area_m2, swirl, w, rho, nu, a, m, regime, face_Nm):
    """
    Return the torque (N m) one end-space surface puts on the oil (floats; compiled).

    Positive from a rotating surface, negative on a stationary one, with the
    end space's core at K = ``swirl`` and |speed| ``w`` (rad/s), the oil's
    ``rho`` (kg/m^3) and ``nu`` (m^2/s). The surface: its ``kind``
    (END_*), mean radius, length and area as in :class:`EndSurfaces`. An
    annulus of the disc or of the wall facing it: its
    :func:`~.correlations.disc_annulus_share` (shear exponent ``m``) of the
    one-face torque ``face_Nm`` of Daily and Nece's cavity
    (:func:`~.correlations.enclosed_disc_friction` over w, disc radius ``a``) times
    :func:`~.correlations.disc_shear_factor` of the ``regime``; a surface in
    the swirl: :func:`~.correlations.flat_plate_shear` at its speed relative
    to the swirl (:func:`~.correlations.end_space_swirl_speed`) times its
    area and radius.
    """
    if kind == END_ROTOR_FACE or kind == END_CAP:
        share = corr.disc_annulus_share(radius_m - 0.5 * length_m, radius_m + 0.5 * length_m, a, m)
        rotating = kind == END_ROTOR_FACE
        torque = face_Nm * share * corr.disc_shear_factor(swirl, regime, rotating)
        return torque if rotating else -torque
    v = corr.end_space_swirl_speed(w, a, radius_m, swirl)
    if kind == END_SHAFT:
        return corr.flat_plate_shear(rho, nu, w * radius_m - v, length_m) * area_m2 * radius_m
    return -corr.flat_plate_shear(rho, nu, v, length_m) * area_m2 * radius_m


@jit
def end_space_swirl(side, w, rho, nu, surfaces, geometry):
    """
    Return the core swirl ratio K of end space ``side`` (0 front, 1 rear), regime, face torque.

    The torque balance of the oil's core: what the rotating surfaces put in
    equals what the stationary ones take out (:func:`surface_torque`, each
    falls or rises monotonically with K), solved for K in [0, 1] by the
    Illinois method to 1e-12; at rest, K = 0. ``w`` |speed| (rad/s), the
    oil's ``rho`` and ``nu`` at its temperature; ``surfaces`` and
    ``geometry`` the :class:`EndSurfaces` and :class:`EndGeometry` (plain
    tuples). Returns (K, Daily and Nece's regime, the one-face torque N m
    of their cavity).
    """
    s, geo = EndSurfaces(*surfaces), EndGeometry(*geometry)
    a = geo.disc_radius_m
    power, regime, re = corr.enclosed_disc_friction(rho, rho * nu, w, a, geo.disc_laws)
    if w <= 0.0:
        return 0.0, regime, 0.0
    face = power / w
    m = corr.DAILY_NECE_SHEAR_EXPONENT[regime - 1]
    # the annuli of the disc and of the wall facing it share one factor of K: their torques
    # at Daily and Nece's K0 are summed once; the plates are evaluated at each K
    kind, radius, length, area = s.kind, s.radius_m, s.length_m, s.area_m2
    disc = 0.0
    wall = 0.0
    plates = np.flatnonzero((s.side == side) & (kind != END_ROTOR_FACE) & (kind != END_CAP))
    for i in np.flatnonzero(s.side == side):
        if kind[i] == END_ROTOR_FACE:
            disc += surface_torque(kind[i], radius[i], length[i], area[i],
                                   DAILY_NECE_K0[regime - 1], w, rho, nu, a, m, regime, face)
        elif kind[i] == END_CAP:
            wall -= surface_torque(kind[i], radius[i], length[i], area[i],
                                   DAILY_NECE_K0[regime - 1], w, rho, nu, a, m, regime, face)

    def balance(k):
        total = (disc * corr.disc_shear_factor(k, regime, True)
                 - wall * corr.disc_shear_factor(k, regime, False))
        for i in plates:
            total += surface_torque(kind[i], radius[i], length[i], area[i], k, w, rho, nu, a,
                                    m, regime, face)
        return total
    lo, hi = 0.0, 1.0
    f_lo, f_hi = balance(lo), balance(hi)
    if f_lo <= 0.0:
        return 0.0, regime, face
    if f_hi >= 0.0:
        return 1.0, regime, face
    last = 0
    k = 0.5
    for _ in range(200):
        k = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        f = balance(k)
        if f > 0.0:
            lo, f_lo = k, f
            if last > 0:
                f_hi *= 0.5
            last = 1
        elif f < 0.0:
            hi, f_hi = k, f
            if last < 0:
                f_lo *= 0.5
            last = -1
        else:
            break
        if hi - lo < 1e-12:
            break
    return k, regime, face


@jit
def end_space_htc(T_K, surfaces, w, p_Pa, geometry, laws, swirl):
    """
    Return h (W/(m^2 K)) of each end-space surface, and the disc's and plates' Re and Pr.

    The :class:`EndSurfaces` at the temperatures ``T_K`` (K); ``w`` |speed|
    (rad/s); ``geometry`` the :class:`EndGeometry` (as plain tuples, see the
    module docstring). First each end space's core swirl K,
    :func:`end_space_swirl` with the oil at its node's temperature, written
    into ``swirl`` (front, rear). Then, with the oil's properties at each
    surface's film temperature and ``p_Pa``, at its velocity relative to
    the core: an annulus of the rotor's end face, or of the wall facing it,
    :func:`~.correlations.enclosed_disc_nusselt_kernel`; the stator surfaces
    and the shaft end, :func:`~.correlations.flat_plate_nusselt_kernel` in
    the swirl of :func:`~.correlations.end_space_swirl_speed` (relative to
    the shaft for the shaft), never below conduction through half the end
    space's depth.
    """
    s, geo = EndSurfaces(*surfaces), EndGeometry(*geometry)
    kind, radius_m, length_m = s.kind, s.radius_m, s.length_m
    a, disc_laws, g, depth = geo.disc_radius_m, geo.disc_laws, geo.gap_ratio, geo.depth_m
    T_oil = T_K[geo.oil]
    rho_oil = oil_density(T_oil, p_Pa, laws)
    nu_oil = oil_nu(T_oil, p_Pa, laws)
    for e in range(2):
        swirl[e] = end_space_swirl(e, w, rho_oil[e], nu_oil[e], surfaces, geometry)[0]
    T_film = 0.5 * (T_K[s.surface] + T_K[s.oil])
    rho = oil_density(T_film, p_Pa, laws)
    nu = oil_nu(T_film, p_Pa, laws)
    k = oil_conductivity(T_film, laws)
    pr = nu * rho * oil_cp(T_film, laws) / k
    n = kind.size
    h = np.empty(n)
    re_disc = np.zeros(n)
    re_plate = np.zeros(n)
    for i in range(n):
        K = swirl[s.side[i]]
        if kind[i] <= END_CAP:
            re_disc[i] = w * a * a / nu[i]
            h[i] = corr.enclosed_disc_nusselt_kernel(re_disc[i], pr[i], disc_laws, g, K,
                                                     kind[i] == END_ROTOR_FACE) * k[i] / a
        else:
            v = corr.end_space_swirl_speed(w, a, radius_m[i], K)
            if kind[i] == END_SHAFT:
                v = w * radius_m[i] - v
            re_plate[i] = v * length_m[i] / nu[i]
            h[i] = max(corr.flat_plate_nusselt_kernel(re_plate[i:i + 1], pr[i:i + 1])[0]
                       * k[i] / length_m[i], 2.0 * k[i] / depth)
    return h, re_disc, re_plate, pr


@jit
def end_space_torques(T_K, surfaces, w, p_Pa, geometry, laws, swirl):
    """
    Return the torque (N m) each end-space surface puts on its oil (:func:`surface_torque`).

    At the core swirl ``swirl`` (front, rear), |speed| ``w`` (rad/s) and the
    oil at its nodes' temperatures in ``T_K`` (K) and ``p_Pa``.
    """
    s, geo = EndSurfaces(*surfaces), EndGeometry(*geometry)
    a = geo.disc_radius_m
    T_oil = T_K[geo.oil]
    rho = oil_density(T_oil, p_Pa, laws)
    nu = oil_nu(T_oil, p_Pa, laws)
    out = np.zeros(s.kind.size)
    if w <= 0.0:
        return out
    for e in range(2):
        power, regime, re = corr.enclosed_disc_friction(rho[e], rho[e] * nu[e], w, a,
                                                        geo.disc_laws)
        m = corr.DAILY_NECE_SHEAR_EXPONENT[regime - 1]
        for i in np.flatnonzero(s.side == e):
            out[i] = surface_torque(s.kind[i], s.radius_m[i], s.length_m[i], s.area_m2[i],
                                    swirl[e], w, rho[e], nu[e], a, m, regime, power / w)
    return out


@jit
def end_drag(speed_abs_rad_s, T_end_K, p_Pa, ends, laws):
    """
    Return the friction (W) of each end space and of each bearing at each |speed| (samples x 2).

    With the end spaces' oil at ``T_end_K`` (K, front and rear) and ``p_Pa``:
    the rotating surfaces' torques (:func:`surface_torque`: the rotor's end
    face and the shaft end) at each end space's core swirl ``ends.swirl``,
    times the speed; the bearing, :func:`~.correlations.palmgren_bearing_torque`
    times the speed and the calibration factor. ``ends``: the :class:`EndDrag` (a plain
    tuple).
    """
    ends = EndDrag(*ends)
    a, laws_disc, rows = ends.disc_radius_m, ends.disc_laws, ends.rotating
    dm, f0, f1, load, factor = (ends.bearing_mean_diameter_m, ends.bearing_f0,
                                ends.bearing_f1, ends.bearing_load_N, ends.bearing_factor)
    rho = oil_density(T_end_K, p_Pa, laws)
    nu = oil_nu(T_end_K, p_Pa, laws)
    n = speed_abs_rad_s.size
    face = np.zeros((n, 2))
    bearing = np.empty((n, 2))
    for e in range(2):
        mu = nu[e] * rho[e]
        for k in range(n):
            w = speed_abs_rad_s[k]
            if w > 0.0:
                power, regime, re = corr.enclosed_disc_friction(rho[e], mu, w, a, laws_disc)
                m = corr.DAILY_NECE_SHEAR_EXPONENT[regime - 1]
                torque = 0.0
                for j in range(rows.shape[0]):
                    if rows[j, 0] == e:
                        torque += surface_torque(int(rows[j, 1]), rows[j, 2], rows[j, 3],
                                                 rows[j, 4], ends.swirl[e], w, rho[e], nu[e], a,
                                                 m, regime, power / w)
                face[k, e] = torque * w
            bearing[k, e] = factor * w * corr.palmgren_bearing_torque(nu[e], w, dm, f0, f1, load)
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
