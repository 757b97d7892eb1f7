"""
Heat-transfer and friction correlations of the wet-EHA thermal model.

SI units throughout: temperatures in K, lengths in m, angular speed in rad/s,
volume flow in m^3/s, dynamic viscosity in Pa s, kinematic viscosity in
m^2/s, conductivity in W/(m K), heat-transfer coefficients in W/(m^2 K),
power in W. Every function accepts floats or numpy arrays (broadcast
together) and is vectorised (regimes by ``np.where``/``np.clip``, no Python
loops), so it can be evaluated per axial section in the time loop.

Every correlation takes an optional ``log``
(:class:`~wet_eha_thermal.model.validity.ValidityLog`) and flags the inputs
that fall outside the range its source validates; out-of-range inputs are
still evaluated (the correlation is extrapolated), never rejected.

Naming rule for a law, its kernel and its checker (here and in
:mod:`.fluid_power`):

- ``name(..., log=None)``: the documented law (source, range, example),
  range-checked into ``log``; what a reader or a script calls.
- ``name_kernel(...)``: the same arithmetic compiled by numba for the hot
  loops; never checks, and may take precomputed factors or return extra
  diagnostics (a regime, a Reynolds number) that the checks need.
- ``check_name(log, ...)``: flags the inputs of ``name`` outside its range,
  for a hot loop that calls ``name_kernel`` and checks apart.

A law with nothing to check, or whose range is checked by ``check_name``
only, is compiled under its own name (e.g. :func:`colburn_disc_nusselt`,
:func:`~.fluid_power.gap_leakage`).

Airgap notation: ``r_rotor`` = r1 (outer radius of the rotor, sleeve
included), ``r_bore`` = r2 (stator bore radius), gap delta = r2 - r1,
mean radius R_m = (r1 + r2) / 2.
"""

import functools
from typing import NamedTuple, Optional

import numpy as np
from scipy.constants import g as _GRAVITY
from scipy.constants import Stefan_Boltzmann as _SIGMA

from .compiled import jit
from .validity import check, ValidityLog
from ..units import RPM_PER_RAD_S

#: Specific gas constant of dry air, J/(kg K).
R_AIR = 287.05

#: Bilgen-Boulos: range of gap ratio delta/r1 flagged as outside the data
#: their correlation was fitted to. See :func:`bilgen_boulos_torque_coefficient`.
BILGEN_BOULOS_GAP_RATIO = (0.0068, 0.114)
#: Bilgen-Boulos: highest Couette Reynolds number Re_d of the data.
BILGEN_BOULOS_RE_MAX = 1.0e5
#: Modified Taylor number Ta_m at which Taylor vortices appear in a narrow gap with a
#: rotating inner cylinder (Taylor 1923; 1697.6 in the narrow-gap limit, as used by
#: Becker and Kaye 1962 for :func:`becker_kaye_geometric_factor`).
TAYLOR_ONSET = 1700.0
#: Ta_m / TAYLOR_ONSET where the airgap friction has become Bilgen-Boulos's: between
#: onset and there, the torque grows from the exact Couette value linearly in
#: Ta_m / TAYLOR_ONSET - 1, as the weakly nonlinear theory of the supercritical onset
#: gives (Davey 1962, J. Fluid Mech. 14, 336-368: the excess torque is proportional to
#: the excess Taylor number near onset); the width of the blend is a modelling choice.
TAYLOR_BLEND_END = 2.0
#: Airgap friction regime code of that blend (see :func:`airgap_friction`).
AIRGAP_ONSET_BLEND = 5
#: Reynolds number range of the reference paper's (Jiao et al. 2022) airgap
#: axial-flow correlation.
REFERENCE_AXIAL_RE = (380.0, 4220.0)

#: Laminar fully developed Nusselt numbers (Shah and London 1978).
NU_PARALLEL_PLATES_T = 7.54
NU_PIPE_T = 3.66
NU_PIPE_Q = 4.36

#: Pipe Reynolds numbers (hydraulic diameter) up to which the flow is taken as laminar and
#: from which as turbulent (a linear blend between): the Nusselt laws here, the friction
#: factor of :func:`~.fluid_power.line_pressure_drop`
PIPE_RE_LAMINAR = 2300.0
PIPE_RE_TURBULENT = 4000.0


def _scalar(x):
    """Return a 0-d array as a numpy scalar, anything else unchanged."""
    return x[()] if isinstance(x, np.ndarray) else x


def _positive_or_nan(x):
    """Return ``x`` with its non-positive entries replaced by NaN (never flagged)."""
    return np.where(np.greater(x, 0.0), x, np.nan)


# --------------------------------------------------------------------------- air


class AirProperties(NamedTuple):
    """
    Properties of dry air (SI units).

    :ivar rho: density, kg/m^3.
    :ivar mu: dynamic viscosity, Pa s.
    :ivar k: thermal conductivity, W/(m K).
    :ivar cp: isobaric specific heat, J/(kg K).
    :ivar Pr: Prandtl number mu cp / k.
    :ivar beta: isobaric expansion coefficient (ideal gas 1/T), 1/K.

    """

    rho: object
    mu: object
    k: object
    cp: object
    Pr: object
    beta: object


def air_properties(T_K, p_Pa=101325.0, log: Optional[ValidityLog] = None) -> AirProperties:
    """
    Return the properties of dry air near atmospheric pressure.

    - rho: ideal gas p / (R T), R = 287.05 J/(kg K).
    - mu: Sutherland's law, mu = 1.716e-5 (T/273)^1.5 (273 + 111)/(T + 111)
      Pa s (White, Viscous Fluid Flow, 3rd ed., table 1-2; +-2 % over
      170-1900 K).
    - k: Sutherland form, k = 0.0241 (T/273)^1.5 (273 + 194)/(T + 194)
      W/(m K) (White, table 1-3; +-2 % over 160-2000 K).
    - cp: quadratic fit cp = 1029.1 - 0.18584 T + 3.723e-4 T^2 J/(kg K) to
      Incropera's table A.4 (200-600 K), within 0.1 %.
    - beta = 1/T (ideal gas).

    Validity flagged: 200 K <= T <= 600 K (the cp fit's range) and
    50 kPa <= p <= 200 kPa (mu, k, cp taken pressure independent).

    :param T_K: temperature (K).
    :param p_Pa: absolute pressure (Pa).
    :param log: optional validity log.

    :return: :class:`AirProperties`.

    Examples
    --------
    Incropera, Fundamentals of Heat and Mass Transfer, Table A.4 at 300 K:
    mu 184.6e-7 Pa s, k 26.3e-3 W/(m K), cp 1007 J/(kg K), Pr 0.707.

    >>> air = air_properties(300.0)
    >>> round(float(air.mu) * 1e7, 1), round(float(air.k) * 1e3, 1), round(float(air.cp))
    (184.7, 26.2, 1007)
    >>> round(float(air.Pr), 3)
    0.709

    """
    if log is not None:
        check(log, 'air properties', 'T_K', T_K, 200.0, 600.0,
              'cp fit and property laws checked over 200-600 K only; extrapolated')
        check(log, 'air properties', 'p_Pa', p_Pa, 5.0e4, 2.0e5,
              'mu, k, cp taken at about 1 atm; ideal-gas density still applies')
    T = np.asarray(T_K, dtype=float)
    t_ratio = T / 273.0
    t_pow = t_ratio * np.sqrt(t_ratio)
    rho = np.divide(p_Pa, R_AIR * T)
    mu = 1.716e-5 * t_pow * (273.0 + 111.0) / (T + 111.0)
    k = 0.0241 * t_pow * (273.0 + 194.0) / (T + 194.0)
    cp = 1029.1 + T * (-0.18584 + 3.723e-4 * T)
    return AirProperties(_scalar(rho), _scalar(mu), _scalar(k), _scalar(cp),
                         _scalar(mu * cp / k), _scalar(1.0 / T))


# ------------------------------------------------------------ airgap friction


def couette_torque(mu, omega, L, r_rotor, r_bore):
    """
    Return the exact laminar Couette torque on the rotor, N m.

    Circular Couette flow between a rotating inner cylinder (radius r1,
    speed omega) and a fixed outer one (r2), length L, end effects
    neglected: M = 4 pi mu omega L r1^2 r2^2 / (r2^2 - r1^2) (e.g. Bird,
    Stewart and Lightfoot, Transport Phenomena, ex. 3.6-3). Valid while the
    flow is laminar and free of Taylor vortices (Ta below about 1700). The
    sign follows omega (the fluid resists the rotation).

    :param mu: dynamic viscosity (Pa s).
    :param omega: rotor angular speed (rad/s).
    :param L: wetted length (m).
    :param r_rotor: rotor outer radius r1 (m).
    :param r_bore: bore radius r2 > r1 (m).

    Examples
    --------
    Hand-checked: mu 0.01 Pa s, omega 100 rad/s, L 0.1 m, r1 10 mm, r2 20 mm:
    M = 4 pi 0.01 100 0.1 (1e-4 4e-4 / 3e-4) = 4 pi 1.3333e-5 = 1.6755e-4 N m.

    >>> round(float(couette_torque(0.01, 100.0, 0.1, 0.01, 0.02)) * 1e4, 4)
    1.6755

    """
    r1s = np.square(r_rotor)
    r2s = np.square(r_bore)
    return 4.0 * np.pi * np.multiply(mu, omega) * np.multiply(L, r1s * r2s / (r2s - r1s))


def bilgen_boulos_torque_coefficient(Re_d, gap_ratio, log: Optional[ValidityLog] = None):
    """
    Return the Bilgen-Boulos torque coefficient C_M and its regime (1-4).

    Source: Bilgen, E. and Boulos, R., "Functional dependence of torque
    coefficient of coaxial cylinders on gap width and Reynolds number",
    J. Fluids Eng. 95(1), 1973, 122-126. With C_M = 2 M / (pi rho omega^2
    r1^4 L), Re_d = rho omega r1 delta / mu and g = delta / r1:

    ======  =====================  ==============================
    regime  Re_d (published)       C_M
    ======  =====================  ==============================
    1       Re_d < 64              10 g^0.3 / Re_d
    2       64 <= Re_d < 500       2 g^0.3 / Re_d^0.6
    3       500 <= Re_d < 1e4      1.03 g^0.3 / Re_d^0.5
    4       Re_d >= 1e4            0.065 g^0.3 / Re_d^0.2
    ======  =====================  ==============================

    The published laws do not meet at the published edges (C_M would jump by
    +5.6 % at Re_d = 64, -4.1 % at 500 and +0.02 % at 1e4). Here each regime
    ends where its law meets the next one's, Re_d = (c_k / c_k+1)^(1 /
    (n_k - n_k+1)): 55.9, 762.0 and 9994 (``BILGEN_BOULOS_RE_EDGES``), so C_M
    is continuous; the laws themselves are the published ones. Between a
    published edge and the crossing the value differs from the published
    table by at most those jumps.

    Validity flagged: Re_d <= 1e5 and 0.0068 <= g <= 0.114. The gap-ratio
    range is the one usually quoted for the data Bilgen and Boulos fitted
    (their own cylinders and the literature data they pooled); it could not
    be checked against the paper itself (abstract only), so treat it as the
    chosen flagging range. The reference rig has g = 0.5/18 = 0.028.

    :param Re_d: Couette Reynolds number rho omega r1 delta / mu (>= 0).
    :param gap_ratio: delta / r1.
    :param log: optional validity log.

    :return: ``(C_M, regime)``; C_M is inf at Re_d = 0.

    Examples
    --------
    Hand-checked, regime 3 at Re_d 2000 and g 0.03:
    C_M = 1.03 0.03^0.3 / 2000^0.5 = 1.03 * 0.34925 / 44.721 = 0.008044.

    >>> cm, regime = bilgen_boulos_torque_coefficient(2000.0, 0.03)
    >>> round(float(cm), 6), int(regime)
    (0.008044, 3)

    """
    if log is not None:
        check(log, 'Bilgen-Boulos airgap friction', 'Re_d', Re_d, 0.0, BILGEN_BOULOS_RE_MAX,
              'Couette Reynolds number above the data of Bilgen and Boulos (1973)')
        check(log, 'Bilgen-Boulos airgap friction', 'delta/r1', gap_ratio,
              *BILGEN_BOULOS_GAP_RATIO, 'gap ratio outside the data of Bilgen and Boulos (1973)')
    re = np.asarray(Re_d, dtype=float)
    k = bilgen_boulos_regime_kernel(re)
    with np.errstate(divide='ignore'):
        cm = _BB_COEF[k] * np.power(gap_ratio, 0.3) * np.power(re, _BB_NEG_EXPO[k])
    return _scalar(cm), _scalar(k + 1)


#: Bilgen-Boulos constants c and n of C_M = c g^0.3 Re^-n, regimes 1-4 (table above).
_BB_COEF = np.array([10.0, 2.0, 1.03, 0.065])
_BB_EXPO = np.array([1.0, 0.6, 0.5, 0.2])
_BB_NEG_EXPO = -_BB_EXPO
#: Per regime index, for the friction power: 0.5 pi c and the exponent 3 - n of w.
_BB_POWER_COEF = 0.5 * np.pi * _BB_COEF
_BB_W_EXPO = 3.0 - _BB_EXPO


#: Re_d where the Bilgen-Boulos regimes 2, 3 and 4 start: where each law meets the next.
BILGEN_BOULOS_RE_EDGES = (_BB_COEF[:-1] / _BB_COEF[1:]) ** (1.0 / (_BB_EXPO[:-1] - _BB_EXPO[1:]))
_BB_RE_EDGES = BILGEN_BOULOS_RE_EDGES


@jit
def bilgen_boulos_regime_kernel(re):
    """Return the Bilgen-Boulos regime minus one (an index of the tables) at each Re_d."""
    # the count of edges at or below Re_d (NaN counts all three: its C_M is NaN either way)
    return np.searchsorted(_BB_RE_EDGES, re, side='right')


@functools.lru_cache(maxsize=16)
def airgap_friction_factors(r_rotor: float, r_bore: float, L: float) -> tuple:
    """
    Return the geometric factors of :func:`airgap_friction` for one airgap (cached).

    ``(couette, re_per_rho_w, gap_ratio, gap_in_data, g03, bb_rho,
    ta_per_re2)``: the Couette power is 4 pi mu w^2 couette; Re_d =
    re_per_rho_w rho w / mu; the Bilgen-Boulos power of regime index k is
    0.5 pi c g03 (Re_d / w)^(-n) w^(3 - n) rho bb_rho, g03 = g^0.3 (see
    ``_BB_POWER_COEF``); gap_in_data tells whether g is inside the data of
    Bilgen and Boulos; Ta_m = ta_per_re2 Re_d^2 (Ta = Re_d^2 R_m delta /
    r1^2, divided by the Becker-Kaye factor). Each factor is
    formed as the full expressions form it, so the powers agree with
    :func:`couette_torque` and :func:`bilgen_boulos_torque_coefficient` to
    rounding.
    """
    delta = np.subtract(r_bore, r_rotor)
    r1s = np.square(r_rotor)
    r2s = np.square(r_bore)
    gap_ratio = delta / np.asarray(r_rotor, dtype=float)
    low, high = BILGEN_BOULOS_GAP_RATIO
    gap_in_data = bool(np.all((gap_ratio >= low) & (gap_ratio <= high)))
    r_mean = 0.5 * np.add(r_rotor, r_bore)
    ta_per_re2 = r_mean * delta / r1s / becker_kaye_geometric_factor(r_rotor, r_bore)
    return (np.multiply(L, r1s * r2s / (r2s - r1s)), np.multiply(r_rotor, delta), gap_ratio,
            gap_in_data, np.power(gap_ratio, 0.3), np.multiply(np.square(r1s), L),
            _scalar(ta_per_re2))


def airgap_friction(rho, mu, omega, r_rotor, r_bore, L, log: Optional[ValidityLog] = None):
    """
    Return the viscous friction power of a flooded airgap and its regime.

    docs/model.md (Motor losses). Below the onset of Taylor vortices (modified Taylor
    number Ta_m < ``TAYLOR_ONSET``, 1700) the flow is laminar circular
    Couette flow and the torque is exactly :func:`couette_torque`'s. Above
    it, the torque grows linearly in eps = Ta_m / 1700 - 1 from the Couette
    value to Bilgen-Boulos's (:func:`bilgen_boulos_torque_coefficient`),
    reached at eps = 1 (``TAYLOR_BLEND_END``), and follows Bilgen-Boulos from
    there: P = P_C + s max(P_BB - P_C, 0), s = clip(eps, 0, 1). Vortices and
    turbulence only ever add torque to the laminar value, hence the max. The
    curve is continuous everywhere: at the onset, at the end of the blend and
    at the Bilgen-Boulos regime edges. (Bilgen-Boulos alone reads up to 50 %
    above the exact Couette torque below the onset.)
    Power P = 0.5 C_M pi rho |omega|^3 r1^4 L (= M |omega|). The pump is
    bidirectional, so |omega| is used; omega = 0 gives 0 W.

    :param rho: oil density (kg/m^3).
    :param mu: oil dynamic viscosity (Pa s).
    :param omega: rotor speed (rad/s), either sign.
    :param r_rotor: rotor outer radius r1 (m).
    :param r_bore: stator bore radius r2 (m).
    :param L: wetted length of the section (m).
    :param log: optional validity log (Re_d and delta/r1 of Bilgen-Boulos;
        only evaluations where Bilgen-Boulos sets the torque are flagged
        for Re_d).

    :return: ``(power_W, regime)``: power in W (>= 0) and an int regime: 0 =
        laminar Couette (exact torque), 1-4 = the Bilgen-Boulos regime that
        set the torque (edges ``BILGEN_BOULOS_RE_EDGES``), 5
        (``AIRGAP_ONSET_BLEND``) = the blend just above the vortex onset.

    Examples
    --------
    Hand-checked on the reference rig's airgap (r1 18 mm, r2 18.5 mm, L 55 mm).
    Cold oil (rho 850 kg/m^3, mu 0.5 Pa s) at 10 rad/s is far below the vortex
    onset (Ta about 7e-4), so P = M omega with the Couette torque
    M = 4 pi 0.5 10 0.055 (r1^2 r2^2 / (r2^2 - r1^2)) = 0.0209975 N m:

    >>> power, regime = airgap_friction(850.0, 0.5, 10.0, 0.018, 0.0185, 0.055)
    >>> round(float(power), 5), int(regime)
    (0.20998, 0)

    Oil at 40 degC (rho 848 kg/m^3, mu 0.0114 Pa s) at 20 000 rpm (2094.4 rad/s):
    Re_d = 848 2094.4 0.018 0.0005 / 0.0114 = 1402 (Bilgen-Boulos regime 3),
    C_M = 1.03 (0.5/18)^0.3 / 1402^0.5 = 0.009388 and
    P = 0.5 C_M pi rho omega^3 r1^4 L = 663 W:

    >>> power, regime = airgap_friction(848.0, 0.0114, 2094.4, 0.018, 0.0185, 0.055)
    >>> round(float(power)), int(regime)
    (663, 3)

    """
    w = np.abs(omega)
    try:      # a machine's dimensions come back every call: their factors are cached
        couette_geo, re_geo, gap_ratio, gap_in_data, g03, bb_rho, ta_per_re2 = \
            airgap_friction_factors(r_rotor, r_bore, L)
    except TypeError:           # array dimensions (not hashable)
        couette_geo, re_geo, gap_ratio, gap_in_data, g03, bb_rho, ta_per_re2 = \
            airgap_friction_factors.__wrapped__(r_rotor, r_bore, L)
    power, regime, re = airgap_friction_kernel(rho, mu, w, couette_geo, re_geo, g03, bb_rho,
                                               ta_per_re2)
    check_airgap_friction(log, regime, re, gap_ratio, gap_in_data)
    return _scalar(power), _scalar(regime)


def check_airgap_friction(log: Optional[ValidityLog], regime, re, gap_ratio,
                          gap_in_data: bool) -> None:
    """Flag in ``log`` what :func:`airgap_friction` evaluated outside the data it rests on."""
    if log is None:
        return
    # only where Bilgen-Boulos set the torque
    bb = np.not_equal(regime, 0)
    if bb.any():
        check(log, 'Bilgen-Boulos airgap friction', 'Re_d', np.asarray(re)[bb],
              0.0, BILGEN_BOULOS_RE_MAX,
              'Couette Reynolds number above the data of Bilgen and Boulos (1973)')
    if not gap_in_data:     # (a ratio inside the data is never flagged)
        check(log, 'Bilgen-Boulos airgap friction', 'delta/r1', gap_ratio,
              *BILGEN_BOULOS_GAP_RATIO,
              'gap ratio outside the data of Bilgen and Boulos (1973)')


@jit
def airgap_friction_kernel(rho, mu, w, couette_geo, re_geo, g03, bb_rho, ta_per_re2):
    """
    Return the ``(power W, regime, Re_d)`` of :func:`airgap_friction`; no checks.

    ``w`` is |omega| (rad/s); the geometric factors are those of
    :func:`airgap_friction_factors`. Arrays broadcast as in numpy.
    """
    p_couette = 4.0 * np.pi * (mu * (w * w)) * couette_geo
    # Re_d = w * re_per_w; write w^3 Re^-n = w^(3-n) re_per_w^-n (no 0 ** negative).
    re_per_w = rho * re_geo / mu
    re = w * re_per_w
    k = bilgen_boulos_regime_kernel(re)
    p_bb = (np.take(_BB_POWER_COEF, k) * g03 * np.power(re_per_w, np.take(_BB_NEG_EXPO, k))
            * np.power(w, np.take(_BB_W_EXPO, k)) * (rho * bb_rho))
    blend = np.minimum(np.maximum((ta_per_re2 * (re * re) / TAYLOR_ONSET - 1.0)
                                  / (TAYLOR_BLEND_END - 1.0), 0.0), 1.0)
    excess = np.maximum(p_bb - p_couette, 0.0)
    couette = (blend == 0.0) | (excess == 0.0)
    regime = np.where(couette, 0, np.where(blend < 1.0, AIRGAP_ONSET_BLEND, k + 1))
    return p_couette + blend * excess, regime, re


# ------------------------------------------------------ airgap heat transfer


def becker_kaye_geometric_factor(r_rotor, r_bore):
    """
    Return the Becker-Kaye geometric factor F_g of an annulus (dimensionless).

    Source: Becker, K. M. and Kaye, J., "Measurements of diabatic flow in an
    annulus with an inner rotating cylinder", J. Heat Transfer 84, 1962,
    97-105 (after Taylor's stability analysis):
    F_g = pi^4 / [1697 P (1 - delta / (2 R_m))], P = 0.0571 X + 0.00056 / X,
    X = 1 - 0.652 (delta/r1) / (1 - delta/r1). As delta -> 0, X -> 1 and
    F_g -> pi^4 / (1697 * 0.05766) = 0.9955. Meant for narrow gaps
    (delta/r1 well below 1).

    :param r_rotor: rotor outer radius r1 (m).
    :param r_bore: bore radius r2 (m).

    Examples
    --------
    Becker and Kaye's narrow-gap limit 0.9955, and, hand-checked, the
    reference rig's airgap (delta/r1 = 0.5/18): X = 1 - 0.652 * 0.028571 =
    0.98137, P = 0.056036 + 0.000571 = 0.056607, F_g = 97.409 / (1697 P
    (1 - 0.0005/0.0365)) = 1.0281.

    >>> round(float(becker_kaye_geometric_factor(1.0, 1.0 + 1e-6)), 4)
    0.9955
    >>> round(float(becker_kaye_geometric_factor(0.018, 0.0185)), 4)
    1.0281

    """
    r1 = np.asarray(r_rotor, dtype=float)
    delta = np.subtract(r_bore, r1)
    g = delta / r1
    x = 1.0 - 0.652 * g / (1.0 - g)
    p = 0.0571 * x + 0.00056 / x
    r_mean = 0.5 * (r1 + r_bore)
    return _scalar(np.pi ** 4 / (1697.0 * p * (1.0 - delta / (2.0 * r_mean))))


def taylor_number(omega, r_rotor, r_bore, nu):
    """
    Return the Taylor number Ta = omega^2 R_m delta^3 / nu^2 (dimensionless).

    Definition of Becker and Kaye (1962); R_m the mean radius, delta the gap,
    nu the kinematic viscosity (m^2/s), omega in rad/s (either sign).

    Examples
    --------
    Hand-checked, the reference rig's airgap at 1000 rad/s, nu 1.3e-5 m^2/s:
    Ta = 1e6 0.01825 (5e-4)^3 / (1.3e-5)^2 = 13 499.

    >>> round(float(taylor_number(1000.0, 0.018, 0.0185, 1.3e-5)))
    13499

    """
    delta = np.subtract(r_bore, r_rotor)
    r_mean = 0.5 * np.add(r_rotor, r_bore)
    return np.square(omega) * r_mean * delta ** 3 / np.square(nu)


def modified_taylor_number(omega, r_rotor, r_bore, nu):
    """
    Return the modified Taylor number Ta_m = Ta / F_g (dimensionless).

    :func:`taylor_number` divided by :func:`becker_kaye_geometric_factor`;
    Taylor vortices appear at Ta_m of about 1700.

    Examples
    --------
    Hand-checked, the case of :func:`taylor_number` and
    :func:`becker_kaye_geometric_factor`: Ta_m = 13 499 / 1.0281 = 13 129.

    >>> round(float(modified_taylor_number(1000.0, 0.018, 0.0185, 1.3e-5)))
    13129

    """
    return _scalar(taylor_number(omega, r_rotor, r_bore, nu)
                   / becker_kaye_geometric_factor(r_rotor, r_bore))


def taylor_couette_nusselt(Ta_m, Pr=None, gap_ratio=None, log: Optional[ValidityLog] = None):
    """
    Return the wall-to-wall Nusselt number of a rotating annulus (Becker-Kaye).

    Source: Becker and Kaye (1962), Nu = h 2 delta / k, h the coefficient
    between the two walls (rotor and stator) of the annulus:

    - Ta_m < 1700: Nu = 2 (laminar, pure conduction across the gap);
    - 1700 <= Ta_m < 1e4: Nu = 0.128 Ta_m^0.367 (vortices);
    - 1e4 <= Ta_m <= 1e7: Nu = 0.409 Ta_m^0.241 (turbulent vortices).

    The vortex law gives 1.96 at Ta_m = 1700 (1.9 % below conduction); it is
    clipped to 2 so that the vortices never lower the conductive value and
    the curve is continuous there. At 1e4 the two laws agree within 0.1 %.
    Validity flagged: Ta_m > 1e7.

    :param Ta_m: modified Taylor number (:func:`modified_taylor_number`).
    :param Pr: not used (the law depends on Ta_m alone); in the signature
        every law of ``AIRGAP_NUSSELT`` shares.
    :param gap_ratio: not used, as ``Pr``.
    :param log: optional validity log.

    Examples
    --------
    Hand-checked, one value per range: conduction 2 below the onset,
    0.128 5000^0.367 = 0.128 * 22.778 = 2.916, 0.409 1e6^0.241 = 0.409 *
    27.925 = 11.422.

    >>> [round(float(taylor_couette_nusselt(ta)), 3) for ta in (1000.0, 5000.0, 1.0e6)]
    [2.0, 2.916, 11.422]

    """
    if log is not None:
        check(log, 'Becker-Kaye Taylor-Couette Nusselt', 'Ta_m', Ta_m, 0.0, 1.0e7,
              'modified Taylor number above the Becker-Kaye data; extrapolated')
    ta = np.asarray(Ta_m, dtype=float)
    nu = np.where(ta < 1.0e4, np.maximum(2.0, 0.128 * np.power(ta, 0.367)),
                  0.409 * np.power(ta, 0.241))
    return _scalar(np.where(ta < 1700.0, 2.0, nu))


def tachibana_fukui_nusselt(Ta_m, Pr, gap_ratio, log: Optional[ValidityLog] = None):
    """
    Return the wall-to-wall Nusselt number of a rotating annulus (Tachibana et al.).

    Source: F. Tachibana, S. Fukui and H. Mitsumura, "Heat transfer in an
    annulus with an inner rotating cylinder", Bull. JSME 3(9), 1960, 119-123,
    as quoted by the review of M. Fenot, Y. Bertin, E. Dorignac and G.
    Lalizel, Int. J. Thermal Sci. 50, 2011, 1138-1155:
    Nu = 0.21 (Ta^2 Pr)^(1/4) (delta/r1)^(1/4), Nu = h 2 delta / k, with their
    Taylor number Ta = (omega r1 delta / nu) (delta / r1)^(1/2), so that
    Ta^2 = omega^2 r1 delta^3 / nu^2 = Ta_m F_g r1 / R_m (F_g of
    :func:`becker_kaye_geometric_factor`, r1 / R_m = 2 / (2 + delta/r1)).
    Unlike Becker-Kaye's it grows with the Prandtl number, which for oil
    (Pr 100-1000) gives several times Becker-Kaye's value. Below the vortex
    onset (Ta_m < ``TAYLOR_ONSET``) and wherever the law falls below it, the
    conduction value 2 is used, as in :func:`taylor_couette_nusselt`.

    Not checked: the coefficients and the definition of Ta are the review's
    as recalled here; the paper itself (and the range of Ta, Pr and gap of
    its data, air and water) could not be read. Validity flagged: Pr above
    1000 (an assumption, not the paper's range). Use it as the alternative
    it is, to see the spread between published laws.

    :param Ta_m: modified Taylor number (:func:`modified_taylor_number`).
    :param Pr: Prandtl number of the oil.
    :param gap_ratio: delta / r1.
    :param log: optional validity log.

    Examples
    --------
    Hand-checked at Ta_m = 1e4, Pr = 1 and delta/r1 = 0.5/18 (F_g = 1.0281,
    r1 / R_m = 0.98630): Ta^2 = 1e4 * 1.0281 * 0.98630 = 10 140,
    Nu = 0.21 (10 140)^0.25 (0.027778)^0.25 = 0.21 * 10.035 * 0.40825 = 0.860,
    below conduction, so 2; at Pr = 200: 0.86034 * 200^0.25 = 3.235.

    >>> [round(float(tachibana_fukui_nusselt(1.0e4, pr, 0.5 / 18)), 2) for pr in (1.0, 200.0)]
    [2.0, 3.24]

    """
    if log is not None:
        check(log, 'Tachibana-Fukui Taylor-Couette Nusselt', 'Pr', Pr, 0.0, 1000.0,
              'Prandtl number above the assumed range of Tachibana et al.; extrapolated')
    ta = np.asarray(Ta_m, dtype=float)
    g = np.asarray(gap_ratio, dtype=float)
    ta2 = ta * becker_kaye_geometric_factor(1.0, 1.0 + g) * 2.0 / (2.0 + g)
    nu = np.maximum(2.0, 0.21 * np.power(ta2 * Pr * g, 0.25))
    return _scalar(np.where(ta < TAYLOR_ONSET, 2.0, nu))


class Correlation(NamedTuple):
    """
    One published law of a registry such as ``AIRGAP_NUSSELT``.

    :ivar function: the law, a function of this file.
    :ivar source: its authors, year and journal.
    :ivar validity: the range it was fitted to, as text.

    """

    function: object
    source: str
    validity: str


#: The wall-to-wall Nusselt laws of a rotating annulus, selectable by name as
#: ``motor.airgap_nusselt`` (each called as ``function(Ta_m, Pr, gap_ratio, log)``);
#: ``becker_kaye`` is the default.
AIRGAP_NUSSELT = {
    'becker_kaye': Correlation(
        taylor_couette_nusselt, 'Becker and Kaye, J. Heat Transfer 84, 1962, 97-105',
        'Ta_m up to 1e7; narrow gaps'),
    'tachibana_fukui': Correlation(
        tachibana_fukui_nusselt,
        'Tachibana, Fukui and Mitsumura, Bull. JSME 3(9), 1960, 119-123 (via Fenot et al. 2011)',
        'range of the data not checked; Pr above 1000 flagged'),
}


def laminar_turbulent_nusselt(Re, Pr, nu_laminar, correlation, log):
    """
    Return the laminar value / Gnielinski Nusselt number, blended in 2300-4000.

    Gnielinski, V., Int. Chem. Eng. 16, 1976, 359-368, with the Petukhov
    friction factor f = (0.790 ln Re - 1.64)^-2:
    Nu = (f/8)(Re - 1000) Pr / [1 + 12.7 (f/8)^0.5 (Pr^(2/3) - 1)], for
    3000 <= Re <= 5e6 and 0.5 <= Pr <= 2000. Below Re = 2300 the laminar
    fully developed value ``nu_laminar`` is used; between 2300 and 4000 the
    Nusselt number is interpolated linearly in Re from ``nu_laminar`` to
    Gnielinski's value at Re = 4000 (transition; no correlation is accurate
    there). Flags Re > 5e6, and Pr outside 0.5-2000 where Re > 2300.
    """
    re = np.asarray(Re, dtype=float)
    if log is not None:
        check(log, correlation, 'Re', re, 0.0, 5.0e6,
              'Reynolds number above the Gnielinski range; extrapolated')
        check(log, correlation, 'Pr', np.where(re > PIPE_RE_LAMINAR, Pr, np.nan), 0.5, 2000.0,
              'Prandtl number outside the Gnielinski range; extrapolated')
    re_b, pr_b = np.broadcast_arrays(re, np.asarray(Pr, dtype=float))
    nu = laminar_turbulent_nusselt_kernel(re_b.ravel(), pr_b.ravel(), float(nu_laminar))
    return _scalar(nu.reshape(re_b.shape))


@jit
def laminar_turbulent_nusselt_kernel(re, pr, nu_laminar):
    """Return the Nusselt number of :func:`laminar_turbulent_nusselt` (1-D arrays, no checks)."""
    if (re <= PIPE_RE_LAMINAR).all() and ((pr >= 0.0) & (pr < 1e300)).all():
        # laminar throughout, the usual case: the blend weight is zero, and the blend
        # below gives exactly the laminar value (for any physical Prandtl number)
        return np.full(re.shape, nu_laminar)
    re_t = np.maximum(re, PIPE_RE_TURBULENT)
    f8 = 0.125 / np.square(0.790 * np.log(re_t) - 1.64)
    denominator = 1.0 + 12.7 * np.sqrt(f8) * (np.power(pr, 2.0 / 3.0) - 1.0)
    nu_gn = f8 * (re_t - 1000.0) * pr / denominator
    weight = np.minimum(np.maximum((re - PIPE_RE_LAMINAR)
                                   / (PIPE_RE_TURBULENT - PIPE_RE_LAMINAR), 0.0), 1.0)
    return nu_laminar + weight * (nu_gn - nu_laminar)


def annulus_axial_nusselt(Re, Pr, log: Optional[ValidityLog] = None):
    """
    Return the Nusselt number of axial flow in a narrow annulus (plates).

    Hydraulic diameter 2 delta (Nu = h 2 delta / k, Re = rho u 2 delta / mu).
    Laminar fully developed flow between parallel plates at uniform wall
    temperature: Nu = 7.54 (Shah and London 1978) for Re <= 2300; Gnielinski
    with the Petukhov friction factor for Re >= 4000; linear blend between
    (see :func:`pipe_internal_nusselt`). Entrance effects are neglected (a
    conservative, lower value). Validity flagged: Re > 5e6; Pr outside
    0.5-2000 in the transitional and turbulent range.

    :param Re: axial Reynolds number on 2 delta.
    :param Pr: Prandtl number.
    :param log: optional validity log.

    Examples
    --------
    Shah and London's laminar parallel-plate value, and the hand-checked
    Gnielinski value of :func:`pipe_internal_nusselt` at Re 1e4, Pr 0.7.

    >>> float(annulus_axial_nusselt(1000.0, 170.0))
    7.54
    >>> round(float(annulus_axial_nusselt(1.0e4, 0.7)), 1)
    29.8

    """
    return laminar_turbulent_nusselt(Re, Pr, NU_PARALLEL_PLATES_T,
                                     'annulus axial flow (plates / Gnielinski)', log)


def pipe_internal_nusselt(Re, Pr, thermal_bc='T', log: Optional[ValidityLog] = None):
    """
    Return the Nusselt number of fully developed flow in a round pipe.

    Laminar (Re <= 2300): 3.66 at uniform wall temperature (``thermal_bc``
    ``'T'``) or 4.36 at uniform heat flux (``'q'``) (Shah and London 1978).
    Turbulent (Re >= 4000): Gnielinski (1976) with the Petukhov friction
    factor, valid 3000 <= Re <= 5e6 and 0.5 <= Pr <= 2000. Between 2300 and
    4000 the value is interpolated linearly in Re (docs/model.md, Heat paths of the circuit).
    Entrance effects are neglected. Validity flagged: Re > 5e6; Pr outside
    0.5-2000 in the transitional and turbulent range.

    :param Re: Reynolds number on the pipe diameter.
    :param Pr: Prandtl number.
    :param thermal_bc: ``'T'`` (uniform wall temperature) or ``'q'`` (uniform
        heat flux).
    :param log: optional validity log.

    :raises ValueError: ``thermal_bc`` is neither ``'T'`` nor ``'q'``.

    Examples
    --------
    Shah and London's laminar values 3.66 and 4.36; Gnielinski hand-checked at
    Re 1e4, Pr 0.7: f = (0.790 ln 1e4 - 1.64)^-2 = 0.03148, Nu = (f/8) 9000 0.7
    / [1 + 12.7 (f/8)^0.5 (0.7^(2/3) - 1)] = 24.79 / 0.8314 = 29.8
    (Dittus-Boelter, 0.023 Re^0.8 Pr^0.4, gives 31.6).

    >>> float(pipe_internal_nusselt(1000.0, 5.0)), float(pipe_internal_nusselt(1000.0, 5.0, 'q'))
    (3.66, 4.36)
    >>> round(float(pipe_internal_nusselt(1.0e4, 0.7)), 1)
    29.8

    """
    if thermal_bc == 'T':
        nu_lam = NU_PIPE_T
    elif thermal_bc == 'q':
        nu_lam = NU_PIPE_Q
    else:
        raise ValueError(f"thermal_bc must be 'T' or 'q', not {thermal_bc!r}")
    return laminar_turbulent_nusselt(Re, Pr, nu_lam, 'pipe flow (laminar / Gnielinski)', log)


class AirgapHTC(NamedTuple):
    """
    Wall-to-bulk heat transfer of an airgap section and its diagnostics.

    :ivar h: wall-to-bulk heat-transfer coefficient, W/(m^2 K) (same for rotor
        and stator wall).
    :ivar Ta_m: modified Taylor number.
    :ivar Re_axial: axial Reynolds number on 2 delta.
    :ivar Nu: wall-to-bulk Nusselt number h 2 delta / k.

    """

    h: object
    Ta_m: object
    Re_axial: object
    Nu: object


def airgap_wall_to_bulk_htc(omega, r_rotor, r_bore, axial_flow_m3_s, rho, mu, k, cp,
                            log: Optional[ValidityLog] = None,
                            nusselt: str = 'becker_kaye') -> AirgapHTC:
    """
    Return the wall-to-bulk heat-transfer coefficient of a flooded airgap section.

    The model has one well-mixed oil node per section between rotor and
    stator, so what is needed is h between either wall and that bulk node.
    docs/model.md (Frame and end caps to ambient) combines a rotational (Taylor vortex) part and an
    axial-flow part; conduction must be counted once:

    - Becker-Kaye's Nu_TC (:func:`taylor_couette_nusselt`) is wall-to-wall,
      h_ww = Nu_TC k / (2 delta). With the bulk node halfway, the wall-to-wall
      resistance is two equal wall-to-bulk resistances in series, so
      h_wb = 2 h_ww, i.e. Nu_wb,rot = 2 Nu_TC >= 4, the pure-conduction
      value (conduction from a wall to the mid-plane, h = k / (delta/2)).
    - The laminar plate value Nu_axial = 7.54 (:func:`annulus_axial_nusselt`)
      is already a wall-to-bulk value that contains that conduction (4); only
      its excess over conduction is added.

    Hence Nu_wb = 2 Nu_TC + max(Nu_axial - 4, 0) and h = Nu_wb k / (2 delta):
    Nu_wb = 4 for a stagnant, still gap; 7.54 with laminar axial flow and no
    rotation. With exactly zero axial flow there is no axial part (the bulk
    node is then the mid-gap fluid, not a mixed-mean stream), so Nu_wb steps
    from 4 to 7.54 as soon as any flow exists: the fully developed laminar
    value does not depend on the flow rate. The addition of the two
    enhancements is the model's approximation (docs/model.md; no interaction term);
    7.54 is the symmetric-wall value, used although rotor and stator run at
    different temperatures, and thermal-entrance effects (which raise Nu in
    short, slow sections) are neglected.

    Validity: Ta_m > 1e7 flagged by Becker-Kaye; Gnielinski limits; and the
    axial Reynolds number is flagged against the reference paper's axial
    correlation range 380-4220 (zero flow is not flagged): wet-motor leakage
    flows are usually laminar far below it, where the laminar plate value is
    used instead of extrapolating that correlation.

    :param omega: rotor speed (rad/s), either sign.
    :param r_rotor: rotor outer radius r1 (m).
    :param r_bore: stator bore radius r2 (m).
    :param axial_flow_m3_s: axial volume flow through the gap (m^3/s), either sign.
    :param rho: oil density (kg/m^3).
    :param mu: oil dynamic viscosity (Pa s).
    :param k: oil conductivity (W/(m K)).
    :param cp: oil specific heat (J/(kg K)).
    :param log: optional validity log.
    :param nusselt: the rotational law Nu_TC, a name of ``AIRGAP_NUSSELT``
        (default Becker-Kaye's, as above).

    :return: :class:`AirgapHTC` ``(h, Ta_m, Re_axial, Nu)``.

    Examples
    --------
    Hand-checked on the reference rig's airgap (delta 0.5 mm) with oil of
    k 0.132 W/(m K): a still, stagnant gap conducts, Nu_wb = 4 and
    h = 4 0.132 / 0.001 = 528 W/(m^2 K); a laminar leakage flow without
    rotation gives 7.54 and h = 7.54 0.132 / 0.001 = 995.3 W/(m^2 K).

    >>> still = airgap_wall_to_bulk_htc(0.0, 0.018, 0.0185, 0.0, 848.0, 0.0114, 0.132, 1957.0)
    >>> round(float(still.Nu), 2), round(float(still.h), 1)
    (4.0, 528.0)
    >>> leak = airgap_wall_to_bulk_htc(0.0, 0.018, 0.0185, 1e-5, 848.0, 0.0114, 0.132, 1957.0)
    >>> round(float(leak.Nu), 2), round(float(leak.h), 1)
    (7.54, 995.3)

    """
    delta = np.subtract(r_bore, r_rotor)
    ta_m = modified_taylor_number(omega, r_rotor, r_bore, np.divide(mu, rho))
    pr = np.multiply(mu, cp) / k
    nu_tc = AIRGAP_NUSSELT[nusselt].function(ta_m, pr, delta / np.asarray(r_rotor), log=log)
    area = np.pi * (np.square(r_bore) - np.square(r_rotor))
    re_ax = np.multiply(rho, np.abs(axial_flow_m3_s)) * 2.0 * delta / np.multiply(mu, area)
    nu_ax = annulus_axial_nusselt(re_ax, pr, log)
    if log is not None:
        check(log, 'airgap axial flow (reference paper correlation)', 'Re_axial',
              _positive_or_nan(re_ax), *REFERENCE_AXIAL_RE,
              "outside the reference paper's axial correlation range (Re 380-4220): "
              'wet-motor leakage flows are laminar here; laminar parallel-plate value '
              'used (Gnielinski above 4000)')
    nu_wb = 2.0 * nu_tc + np.where(re_ax > 0.0, np.maximum(nu_ax - 4.0, 0.0), 0.0)
    h = nu_wb * np.asarray(k) / (2.0 * delta)
    return AirgapHTC(_scalar(h), ta_m, _scalar(re_ax), _scalar(nu_wb))


# ------------------------------------------------------------- outer surfaces


def churchill_chu_horizontal_cylinder(Ra, Pr, log: Optional[ValidityLog] = None):
    """
    Return the mean Nusselt number of free convection from a horizontal cylinder.

    Source: Churchill, S. W. and Chu, H. H. S., "Correlating equations for
    laminar and turbulent free convection from a horizontal cylinder",
    Int. J. Heat Mass Transfer 18, 1975, 1049-1053 (Incropera eq. 9.34):
    Nu_D = {0.60 + 0.387 Ra_D^(1/6) / [1 + (0.559/Pr)^(9/16)]^(8/27)}^2,
    isothermal cylinder, all Pr, 1e-5 <= Ra_D <= 1e12 (flagged; Ra = 0, the
    equal-temperature limit Nu = 0.36, is not flagged). Ra uses |dT|.

    :param Ra: Rayleigh number on the diameter.
    :param Pr: Prandtl number.
    :param log: optional validity log.

    Examples
    --------
    Cengel and Ghajar, Heat and Mass Transfer, the hot-water pipe of their
    natural-convection chapter: Ra_D = 1.867e6, Pr = 0.7241, Nu_D = 17.40.

    >>> round(float(churchill_chu_horizontal_cylinder(1.867e6, 0.7241)), 1)
    17.4

    """
    if log is not None:
        check(log, 'Churchill-Chu horizontal cylinder', 'Ra', _positive_or_nan(Ra),
              1.0e-5, 1.0e12, 'Rayleigh number outside the correlated range')
    shape = np.power(1.0 + np.power(np.divide(0.559, Pr), 9.0 / 16.0), 8.0 / 27.0)
    return np.square(0.60 + 0.387 * np.power(np.abs(Ra), 1.0 / 6.0) / shape)


def churchill_chu_vertical_plate(Ra, Pr, log: Optional[ValidityLog] = None):
    """
    Return the mean Nusselt number of free convection on a vertical plate.

    Source: Churchill, S. W. and Chu, H. H. S., "Correlating equations for
    laminar and turbulent free convection from a vertical plate", Int. J.
    Heat Mass Transfer 18, 1975, 1323-1329 (Incropera eq. 9.26):
    Nu_L = {0.825 + 0.387 Ra_L^(1/6) / [1 + (0.492/Pr)^(9/16)]^(8/27)}^2,
    isothermal plate (also vertical cylinders whose diameter is not small
    against the height), all Pr, 0.1 <= Ra_L <= 1e12 (flagged; Ra = 0 is not
    flagged and gives 0.68).

    :param Ra: Rayleigh number on the height.
    :param Pr: Prandtl number.
    :param log: optional validity log.

    Examples
    --------
    Incropera, Fundamentals of Heat and Mass Transfer, Example 9.2 (glass
    fireplace screen): Ra_L = 1.813e9, Pr = 0.690, Nu_L = 147.

    >>> round(float(churchill_chu_vertical_plate(1.813e9, 0.690)))
    147

    """
    if log is not None:
        check(log, 'Churchill-Chu vertical plate', 'Ra', _positive_or_nan(Ra),
              0.1, 1.0e12, 'Rayleigh number outside the correlated range')
    shape = np.power(1.0 + np.power(np.divide(0.492, Pr), 9.0 / 16.0), 8.0 / 27.0)
    return np.square(0.825 + 0.387 * np.power(np.abs(Ra), 1.0 / 6.0) / shape)


#: Morgan's horizontal-cylinder law, Nu_D = C Ra_D^n: (lowest Ra, C, n) per range, the last
#: range up to Ra 1e12 (Incropera, Table 9.1).
_MORGAN = ((1.0e-10, 0.675, 0.058), (1.0e-2, 1.02, 0.148), (1.0e2, 0.850, 0.188),
           (1.0e4, 0.480, 0.250), (1.0e7, 0.125, 0.333))


def morgan_horizontal_cylinder(Ra, log: Optional[ValidityLog] = None):
    """
    Return the mean Nusselt number of free convection from a horizontal cylinder.

    Source: Morgan, V. T., "The overall convective heat transfer from smooth
    circular cylinders", Advances in Heat Transfer 11, 1975, 199-264
    (Incropera Table 9.1, eq. 9.33): Nu_D = C Ra_D^n, piecewise in five
    ranges from 1e-10 to 1e12 (flagged outside), isothermal cylinder, in air
    (no Prandtl number dependence); the pieces join within 0.8 %. The
    literature's other choice beside :func:`churchill_chu_horizontal_cylinder`:
    21 % above it at Ra 1e2, 10 % at 1e4, 4 % at 1e6 (air, Pr 0.71).

    :param Ra: Rayleigh number on the diameter.
    :param log: optional validity log.

    Examples
    --------
    Hand-checked with Incropera's constants for Ra 1e4-1e7:
    0.480 (1e6)^0.25 = 0.480 * 31.623 = 15.18.

    >>> round(float(morgan_horizontal_cylinder(1.0e6)), 2)
    15.18

    """
    if log is not None:
        check(log, 'Morgan horizontal cylinder', 'Ra', _positive_or_nan(Ra), 1.0e-10, 1.0e12,
              'Rayleigh number outside the correlated range')
    ra = np.abs(np.asarray(Ra, dtype=float))
    piece = np.clip(np.searchsorted([r for r, _, _ in _MORGAN], ra, side='right') - 1,
                    0, len(_MORGAN) - 1)
    c = np.array([c for _, c, _ in _MORGAN])[piece]
    n = np.array([n for _, _, n in _MORGAN])[piece]
    return _scalar(c * np.power(ra, n))


def mcadams_vertical_plate(Ra, log: Optional[ValidityLog] = None):
    """
    Return the mean Nusselt number of free convection on a vertical plate.

    Source: McAdams, W. H., Heat Transmission, 3rd ed., McGraw-Hill, 1954
    (Incropera eq. 9.24): Nu_L = 0.59 Ra_L^(1/4) for 1e4 <= Ra_L <= 1e9
    (laminar), 0.10 Ra_L^(1/3) for 1e9 < Ra_L <= 1e13 (turbulent), a step
    of 5 % at 1e9; flagged outside 1e4-1e13. The simple power laws beside
    :func:`churchill_chu_vertical_plate`: 9 % above it at Ra 1e4, 3 % below
    at 1e8, 15 % below at 1e10 (air, Pr 0.71).

    :param Ra: Rayleigh number on the height.
    :param log: optional validity log.

    Examples
    --------
    Hand-checked, one value per law: 0.59 (1e8)^(1/4) = 0.59 * 100 = 59.0
    and 0.10 (1e10)^(1/3) = 0.10 * 2154.4 = 215.4.

    >>> [round(float(mcadams_vertical_plate(ra)), 1) for ra in (1.0e8, 1.0e10)]
    [59.0, 215.4]

    """
    if log is not None:
        check(log, 'McAdams vertical plate', 'Ra', _positive_or_nan(Ra), 1.0e4, 1.0e13,
              'Rayleigh number outside the correlated range')
    ra = np.abs(np.asarray(Ra, dtype=float))
    return _scalar(np.where(ra <= 1.0e9, 0.59 * np.power(ra, 0.25),
                            0.10 * np.power(ra, 1.0 / 3.0)))


class FreeConvection(NamedTuple):
    """One free-convection law in air: Nusselt numbers called as ``(Ra, Pr, log)``."""

    cylinder: object        # Nu_D of a horizontal cylinder
    plate: object           # Nu_L of a vertical plate
    source: str


#: The free-convection laws of the barrel and the end caps, selectable by name as
#: ``frame.natural_convection``; ``churchill_chu`` is the default. Morgan's and
#: McAdams' power laws have no Prandtl number: theirs is dropped.
NATURAL_CONVECTION = {
    'churchill_chu': FreeConvection(
        churchill_chu_horizontal_cylinder, churchill_chu_vertical_plate,
        'Churchill and Chu, Int. J. Heat Mass Transfer 18, 1975'),
    'morgan_mcadams': FreeConvection(
        lambda Ra, Pr, log=None: morgan_horizontal_cylinder(Ra, log),
        lambda Ra, Pr, log=None: mcadams_vertical_plate(Ra, log),
        'Morgan, Adv. Heat Transfer 11, 1975 (cylinder); McAdams, Heat Transmission, 1954 '
        '(plate)'),
}


def _rayleigh_air(T_surface_K, T_ambient_K, length_m, log):
    """Return ``(Ra, air)`` of air at the film temperature for a length scale."""
    t_film = 0.5 * np.add(T_surface_K, T_ambient_K)
    air = air_properties(t_film, log=log)
    # Ra = g beta |dT| L^3 / (nu alpha), nu alpha = mu k / (rho^2 cp).
    ra = (_GRAVITY * air.beta * np.abs(np.subtract(T_surface_K, T_ambient_K))
          * np.power(length_m, 3) * air.rho * air.rho * air.cp / (air.mu * air.k))
    return ra, air


def natural_convection_htc_horizontal_cylinder(T_surface_K, T_ambient_K, D_m,
                                               log: Optional[ValidityLog] = None,
                                               law: str = 'churchill_chu'):
    """
    Return h (W/(m^2 K)) of free convection in air from a horizontal cylinder.

    :func:`churchill_chu_horizontal_cylinder` (``law`` 'churchill_chu') or
    :func:`morgan_horizontal_cylinder` ('morgan_mcadams') with dry-air
    properties at the film temperature (T_s + T_inf)/2 and beta = 1/T_film
    (ideal gas), 1 atm. T_s == T_inf gives Churchill-Chu's Ra -> 0 limit
    h = 0.36 k / D (no division by zero), Morgan's 0.

    :param T_surface_K: surface temperature (K).
    :param T_ambient_K: ambient air temperature (K).
    :param D_m: outer diameter (m).
    :param log: optional validity log.

    Examples
    --------
    The hot-water pipe of Cengel and Ghajar (see
    :func:`churchill_chu_horizontal_cylinder`; D 80 mm, 70 degC in 20 degC
    air): Nu_D = 17.40 with their table's air properties; with the air laws
    here h = 5.96 W/(m^2 K), Nu_D = h D / k = 17.2.

    >>> h = natural_convection_htc_horizontal_cylinder(343.15, 293.15, 0.08)
    >>> round(float(h), 2), round(float(h * 0.08 / air_properties(318.15).k), 1)
    (5.96, 17.2)

    """
    ra, air = _rayleigh_air(T_surface_K, T_ambient_K, D_m, log)
    return NATURAL_CONVECTION[law].cylinder(ra, air.Pr, log) * air.k / D_m


def natural_convection_htc_vertical_plate(T_surface_K, T_ambient_K, height_m,
                                          log: Optional[ValidityLog] = None,
                                          law: str = 'churchill_chu'):
    """
    Return h (W/(m^2 K)) of free convection in air on a vertical plate.

    :func:`churchill_chu_vertical_plate` (``law`` 'churchill_chu') or
    :func:`mcadams_vertical_plate` ('morgan_mcadams') with dry-air properties
    at the film temperature and beta = 1/T_film, 1 atm. T_s == T_inf gives
    Churchill-Chu's Ra -> 0 limit h = 0.68 k / H, McAdams' 0.

    :param T_surface_K: surface temperature (K).
    :param T_ambient_K: ambient air temperature (K).
    :param height_m: plate height (m).
    :param log: optional validity log.

    Examples
    --------
    Incropera's Example 9.2 (see :func:`churchill_chu_vertical_plate`; 0.71 m
    high, 232 degC in 23 degC air): Nu_L = 147 with the table's air
    properties at 400 K; with the air laws here h = 7.04 W/(m^2 K),
    Nu_L = h L / k = 149.

    >>> h = natural_convection_htc_vertical_plate(505.15, 296.15, 0.71)
    >>> round(float(h), 2), round(float(h * 0.71 / air_properties(400.65).k))
    (7.04, 149)

    """
    ra, air = _rayleigh_air(T_surface_K, T_ambient_K, height_m, log)
    return NATURAL_CONVECTION[law].plate(ra, air.Pr, log) * air.k / height_m


def radiation_htc(T_surface_K, T_ambient_K, emissivity):
    """
    Return the linearised radiation coefficient h_r (W/(m^2 K)).

    Small grey surface in large isothermal surroundings (Incropera eq.
    1.9): q = eps sigma (T_s^4 - T_sur^4) = h_r (T_s - T_sur) with
    h_r = eps sigma (T_s^2 + T_sur^2)(T_s + T_sur), exact for any pair of
    temperatures (K). sigma from scipy.constants.

    Examples
    --------
    Hand-checked: a black surface at 300 K in 300 K surroundings,
    h_r = 4 sigma T^3 = 4 * 5.6704e-8 * 2.7e7 = 6.124 W/(m^2 K).

    >>> round(float(radiation_htc(300.0, 300.0, 1.0)), 3)
    6.124

    """
    ts = np.asarray(T_surface_K, dtype=float)
    return _scalar(np.multiply(emissivity, _SIGMA) * (ts * ts + np.square(T_ambient_K))
                   * (ts + T_ambient_K))


# ------------------------------------------- the rotor's end faces in the end spaces

#: Daily and Nece (1960): range of their torque data, disc Reynolds number omega a^2 / nu
#: and axial clearance ratio G = s / a. See :func:`daily_nece_moment_coefficient`.
DAILY_NECE_RE = (1.0e3, 1.0e7)
DAILY_NECE_GAP_RATIO = (0.0127, 0.217)
# Their four laws C_M = c G^e Re^-n (both faces), regimes I to IV.
_DN_COEF = np.array([2.0 * np.pi, 3.70, 0.080, 0.102])
_DN_G_EXPO = np.array([-1.0, 0.1, -1.0 / 6.0, 0.1])
_DN_RE_EXPO = (1.0, 0.5, 0.25, 0.2)     # tuples: compile-time constants in the kernels
#: Wall shear tau ~ r^m of each regime (laminar: m = 1, exact for the free disc and for
#: Couette flow; turbulent: 8/5, the 1/7-power-law boundary layer of von Karman), as
#: :func:`enclosed_disc_nusselt` integrates it.
DAILY_NECE_SHEAR_EXPONENT = (1.0, 1.0, 1.6, 1.6)
#: Core swirl ratio K0 of Daily and Nece's cavity, one disc face and the wall facing it,
#: in regimes I-IV: 0.5 where the boundary layers merge (the mid-gap speed of plane Couette
#: flow, laminar or turbulent, by its symmetry); 0.4 where they are separate (Daily and
#: Nece measured about 0.4-0.45 in turbulent flow; the laminar similarity solution,
#: Batchelor flow, gives 0.31, Poncet, Chauve and Schiestel, Phys. Fluids 17, 075110,
#: 2005, 0.44 in turbulent flow; one value for both keeps K continuous where the regimes
#: meet). Their C_M is the disc's torque with the core at K0. See :func:`disc_shear_factor`.
DAILY_NECE_CORE_SWIRL = (0.5, 0.4, 0.5, 0.4)
#: Laminar-turbulent transition of a flat plate's boundary layer (Incropera, 7th ed., 7.2).
PLATE_RE_CRITICAL = 5.0e5


def daily_nece_laws(gap_ratio: float) -> np.ndarray:
    """Return the four laws' log constants at ``gap_ratio`` G: ln(c G^e) of C_M = c G^e Re^-n."""
    return np.log(_DN_COEF) + _DN_G_EXPO * np.log(float(gap_ratio))


@jit
def daily_nece_moment_coefficient_kernel(log_re, laws):
    """
    Return the regime (1-4) of :func:`daily_nece_moment_coefficient` and its C_M.

    The regime whose law gives the largest C_M, at ln Re = ``log_re``;
    ``laws``: :func:`daily_nece_laws`. Compiled, scalar, no checks.
    """
    best, regime = -np.inf, 1
    for k in range(4):
        log_cm = laws[k] - _DN_RE_EXPO[k] * log_re
        if log_cm > best:
            best, regime = log_cm, k + 1
    return regime, np.exp(best)


def daily_nece_moment_coefficient(Re, gap_ratio, log: Optional[ValidityLog] = None):
    """
    Return the moment coefficient C_M of a disc in a closed housing, and its regime (1-4).

    Source: J. W. Daily and R. E. Nece, "Chamber dimension effects on induced
    flow and frictional resistance of enclosed rotating disks", J. Basic Eng.
    82(1), 1960, 217-232. A smooth disc of radius a turns at omega in a
    cylindrical housing with the axial clearance s on either side;
    Re = omega a^2 / nu, G = s / a and C_M = 2 M / (rho omega^2 a^5), M the
    torque on BOTH faces (regime I is the laminar Couette flow of the two
    clearances, M = pi mu omega a^4 / s, which is C_M = 2 pi / (G Re): the
    constants belong to both faces; one face takes half):

    ======  ==========================  ==============================
    regime  flow in the clearance       C_M
    ======  ==========================  ==============================
    I       laminar, merged layers      2 pi / (G Re)
    II      laminar, separate layers    3.70 G^0.1 / Re^0.5
    III     turbulent, merged layers    0.080 / (G^(1/6) Re^0.25)
    IV      turbulent, separate layers  0.102 G^0.1 / Re^0.2
    ======  ==========================  ==============================

    The regime is the one whose law gives the largest C_M: each law is the
    resistance of one flow structure, the curve is continuous, and the
    laminar-turbulent crossing of the separate-layer laws falls at
    Re = 1.6e5 for every G (Daily and Nece saw transition near 1e5-2e5).
    Validity flagged: Re 1e3-1e7 and G 0.0127-0.217, the range of their data.

    :param Re: disc Reynolds number omega a^2 / nu (> 0).
    :param gap_ratio: G = s / a.
    :param log: optional validity log.

    :return: ``(C_M, regime)``.

    Examples
    --------
    Hand-checked, one point per regime: regime I at G = 0.0127, Re = 1e3:
    2 pi / 12.7 = 0.4947; II at G = 0.217, Re = 2.5e4: 3.70 * 0.85831 / 158.114
    = 0.020085; III at G = 0.0127, Re = 1e6: 0.080 / (0.4831 * 31.623) =
    0.005237; IV at G = 0.217, Re = 1e6: 0.102 * 0.85831 / 15.849 = 0.005524.

    >>> [(round(float(c), 6), int(k)) for c, k in (daily_nece_moment_coefficient(r, g)
    ...  for r, g in ((1e3, 0.0127), (2.5e4, 0.217), (1e6, 0.0127), (1e6, 0.217)))]
    [(0.494739, 1), (0.020085, 2), (0.005237, 3), (0.005524, 4)]

    """
    if log is not None:
        check(log, 'Daily-Nece enclosed disc', 'Re', Re, *DAILY_NECE_RE,
              'disc Reynolds number outside the data of Daily and Nece (1960); extrapolated')
        check(log, 'Daily-Nece enclosed disc', 's/a', gap_ratio, *DAILY_NECE_GAP_RATIO,
              'clearance ratio outside the data of Daily and Nece (1960); extrapolated')
    re, g = np.broadcast_arrays(np.asarray(Re, dtype=float), np.asarray(gap_ratio, dtype=float))
    out = [daily_nece_moment_coefficient_kernel(np.log(r), daily_nece_laws(s))
           for r, s in zip(re.ravel(), g.ravel())]
    regime = np.array([k for k, _ in out], dtype=int).reshape(re.shape)
    cm = np.array([c for _, c in out]).reshape(re.shape)
    return _scalar(cm), _scalar(regime)


@jit
def enclosed_disc_friction(rho, mu, w, radius_m, laws):
    """
    Return the friction power (W) of ONE face of an enclosed disc, its regime and Re.

    :func:`daily_nece_moment_coefficient` at Re = rho w a^2 / mu (``w`` =
    |omega| in rad/s, a the radius, floats; ``laws``: :func:`daily_nece_laws`
    at the clearance ratio): P = M_face w = C_M rho w^3 a^5 / 4. Compiled, no
    checks; w = 0 gives 0 W (regime I). The disc's hub (the shaft) is taken
    as part of the face.
    """
    a2 = radius_m * radius_m
    re = rho * w * a2 / mu
    if re <= 0.0:
        return 0.0, 1, 0.0
    regime, cm = daily_nece_moment_coefficient_kernel(np.log(re), laws)
    return 0.25 * cm * rho * w * w * w * a2 * a2 * radius_m, regime, re


@jit
def disc_shear_factor(swirl_ratio, regime, rotating):
    """
    Return an enclosed disc's wall shear, or the facing wall's, over Daily and Nece's.

    The oil's core between the two boundary layers turns at K omega
    (``swirl_ratio`` K); each wall's shear follows its speed relative to the
    core, the disc's (1 - K) omega r and the facing stationary wall's
    K omega r, as the regime's law follows the disc speed (C_M ~ Re^-n, so
    tau ~ V^(2 - n)), and is Daily and Nece's where K is their cavity's
    K0 (:data:`DAILY_NECE_CORE_SWIRL`): their C_M is the disc's torque there,
    and the facing wall, alone, takes the same. The disc ((1 - K) / (1 - K0))^(2 - n),
    the facing wall (K / K0)^(2 - n). Compiled; ``regime`` 1-4.

    Examples
    --------
    Hand-checked: regime II (n = 0.5, K0 = 0.4) with the core at K = 0.2: the
    disc (0.8 / 0.6)^1.5 = 1.5396, the facing wall (0.2 / 0.4)^1.5 = 0.35355.

    >>> [round(float(disc_shear_factor(0.2, 2, r)), 5) for r in (True, False)]
    [1.5396, 0.35355]

    """
    k0 = DAILY_NECE_CORE_SWIRL[regime - 1]
    p = 2.0 - _DN_RE_EXPO[regime - 1]
    if rotating:
        return ((1.0 - swirl_ratio) / (1.0 - k0)) ** p
    return (swirl_ratio / k0) ** p


@jit
def disc_annulus_share(r_in_m, r_out_m, disc_radius_m, shear_exponent):
    """
    Return the share of a disc face's torque that the annulus r_in..r_out takes.

    With the wall shear tau ~ r^m (``shear_exponent``, :data:`DAILY_NECE_SHEAR_EXPONENT`)
    over a face of radius a: (r_out^(m+3) - r_in^(m+3)) / a^(m+3). Compiled.

    Examples
    --------
    Hand-checked: the outer half of a laminar face (m = 1), 1 - 0.5^4 = 0.9375.

    >>> float(disc_annulus_share(0.5, 1.0, 1.0, 1.0))
    0.9375

    """
    e = shear_exponent + 3.0
    return (r_out_m ** e - r_in_m ** e) / disc_radius_m ** e


@jit
def colburn_disc_nusselt(C_M, Re, Pr, shear_exponent):
    """
    Return the face-mean Nusselt number h a / k of a disc from its moment coefficient.

    The Reynolds-Colburn analogy (St Pr^(2/3) = C_f / 2; A. P. Colburn,
    Trans. AIChE 29, 1933, 174-210) applied locally with the disc's own speed
    omega r as the reference velocity, h(r) = tau(r) c_p Pr^(-2/3) / (omega r),
    for a wall shear tau = c r^m whose torque on one face is C_M rho omega^2
    a^5 / 4 (C_M of both faces, as Daily and Nece give it). The mean over the
    face is Nu_a = C_M Re Pr^(1/3) (m + 3) / (4 pi (m + 1)), a the radius,
    Re = omega a^2 / nu; m = 1 for a laminar boundary layer (exact for the
    free disc and for Couette flow), 8/5 for a turbulent one (the 1/7 power
    law). Checked against an exact result: for the laminar free disc
    (C_M = 3.87 Re^-0.5 on both faces; Cochran, Proc. Camb. Phil. Soc. 30,
    1934) it gives 0.616 Re^0.5 Pr^(1/3), where the exact solution at large
    Prandtl numbers is 0.620 Re^0.5 Pr^(1/3) (the rotating disc of Levich,
    1942; Sparrow and Gregg, J. Heat Transfer 81, 1959): the analogy holds
    for oil, Pr 100-1000.

    :param C_M: moment coefficient (both faces).
    :param Re: disc Reynolds number omega a^2 / nu.
    :param Pr: Prandtl number.
    :param shear_exponent: m.

    Examples
    --------
    The laminar free disc at Re = 1e4, Pr = 200: C_M = 3.87 / 100 = 0.0387,
    Nu = 0.0387 * 1e4 * 5.848 / (2 pi) = 360.2 (Levich: 0.620 * 100 * 5.848
    = 362.6).

    >>> round(float(colburn_disc_nusselt(0.0387, 1.0e4, 200.0, 1.0)), 1)
    360.2

    """
    return C_M * Re * np.cbrt(Pr) * (shear_exponent + 3.0) / (4.0 * np.pi * (shear_exponent + 1.0))


def enclosed_disc_nusselt(Re, Pr, gap_ratio, swirl_ratio=None, rotating=True,
                          log: Optional[ValidityLog] = None):
    """
    Return the face-mean Nusselt number h a / k of an enclosed disc, or of the wall facing it.

    :func:`colburn_disc_nusselt` with the boundary-layer laws of Daily and
    Nece (:func:`daily_nece_moment_coefficient`'s regimes II, III and IV with
    their shear exponents; the largest of the three values, so that the
    curve is continuous and rises with speed), each with the wall's shear and
    velocity relative to the oil's core turning at K omega (``swirl_ratio``):
    h(r) = tau(r) c_p Pr^(-2/3) / V, V = (1 - K) omega r on the disc
    (``rotating``), K omega r on the facing stationary wall, tau scaled by
    :func:`disc_shear_factor`; so the disc's Nu is the ``colburn_disc_nusselt``
    value times ((1 - K) / (1 - K0))^(2 - n) / (1 - K), the wall's times
    (K / K0)^(2 - n) / K. Never below conduction across the clearance to
    the well-mixed oil at its middle, Nu_a = 2 / G (h = 2 k / s, as for the
    airgap): in regime I (merged laminar layers, Couette flow) no fluid
    crosses the gap, so conduction is the physics there; the boundary-layer
    value grows from it as omega^0.5, and the curve is continuous. Without
    ``swirl_ratio``, each law's own K0 (:data:`DAILY_NECE_CORE_SWIRL`, Daily
    and Nece's cavity). Validity flagged as Daily and Nece's data.

    :param Re: disc Reynolds number omega a^2 / nu (>= 0).
    :param Pr: Prandtl number of the oil (film temperature).
    :param gap_ratio: G = s / a.
    :param swirl_ratio: K, the core's speed over the disc's (0-1); None: K0.
    :param rotating: the disc (True) or the stationary wall facing it.
    :param log: optional validity log.

    Examples
    --------
    The reference rig's rotor face at 10 000 r/min, oil at 40 degC (Re =
    1047 * 0.018^2 / 13.5e-6 = 25 128, Pr = 170, G = 0.222): regime II,
    C_M = 3.70 * 0.8603 / 158.52 = 0.020079, colburn_disc_nusselt = C_M Re
    5.540 / (2 pi) = 444.9; with the core at K0 = 0.4 the disc takes
    444.9 / 0.6 = 741.5 (h = Nu k / a = 5360 W/(m^2 K) with k = 0.13); with
    the core at K = 0.2, 444.9 (0.8 / 0.6)^1.5 / 0.8 = 856.2; at rest,
    conduction: 2 / G = 9.0.

    >>> [round(float(enclosed_disc_nusselt(re, 170.0, 0.004 / 0.018, k)), 1)
    ...  for re, k in ((25128.0, None), (25128.0, 0.2), (0.0, 0.2))]
    [741.5, 856.2, 9.0]

    """
    check_enclosed_disc_nusselt(log, Re, gap_ratio)
    re, g, pr, k = np.broadcast_arrays(np.asarray(Re, dtype=float),
                                       np.asarray(gap_ratio, dtype=float),
                                       np.asarray(Pr, dtype=float),
                                       np.asarray(np.nan if swirl_ratio is None else swirl_ratio,
                                                  dtype=float))
    nu = np.array([enclosed_disc_nusselt_kernel(r, p, daily_nece_laws(x), x, s, rotating)
                   for r, p, x, s in zip(re.ravel(), pr.ravel(), g.ravel(), k.ravel())])
    return _scalar(nu.reshape(re.shape))


def check_enclosed_disc_nusselt(log: Optional[ValidityLog], Re, gap_ratio) -> None:
    """Flag in ``log`` the Re and G outside the data of Daily and Nece (Re = 0 never)."""
    if log is not None:
        check(log, 'Daily-Nece enclosed disc', 'Re', _positive_or_nan(Re), *DAILY_NECE_RE,
              'disc Reynolds number outside the data of Daily and Nece (1960); extrapolated')
        check(log, 'Daily-Nece enclosed disc', 's/a', gap_ratio, *DAILY_NECE_GAP_RATIO,
              'clearance ratio outside the data of Daily and Nece (1960); extrapolated')


@jit
def enclosed_disc_nusselt_kernel(re, pr, laws, gap_ratio, swirl_ratio, rotating):
    """
    Return :func:`enclosed_disc_nusselt` at one point (floats); compiled, no checks.

    ``laws``: :func:`daily_nece_laws` at ``gap_ratio``; ``swirl_ratio`` NaN: each law's K0.
    """
    best = 2.0 / gap_ratio
    if re > 0.0:
        log_re = np.log(re)
        for k in range(1, 4):
            cm = np.exp(laws[k] - _DN_RE_EXPO[k] * log_re)
            swirl = DAILY_NECE_CORE_SWIRL[k] if np.isnan(swirl_ratio) else swirl_ratio
            relative = (1.0 - swirl) if rotating else swirl
            if relative > 0.0:
                nu = colburn_disc_nusselt(cm, re, pr, DAILY_NECE_SHEAR_EXPONENT[k]) \
                    * disc_shear_factor(swirl, k + 1, rotating) / relative
                best = max(best, nu)
    return best


def flat_plate_nusselt(Re_L, Pr, log: Optional[ValidityLog] = None):
    """
    Return the mean Nusselt number h L / k of a plate of length L in a parallel stream.

    Isothermal plate, Incropera, Fundamentals of Heat and Mass Transfer, 7th
    ed.: laminar (Pohlhausen) Nu_L = 0.664 Re_L^0.5 Pr^(1/3) up to Re_L =
    5e5 (eq. 7.30, Pr >= 0.6), mixed laminar-turbulent
    Nu_L = (0.037 Re_L^0.8 - 871) Pr^(1/3) above (eq. 7.38, transition at
    5e5, 0.6 <= Pr <= 60, Re_L up to 1e8). The two meet at 5e5 within
    0.1 %. Validity flagged: Re_L above 1e8; Pr above 60 where the boundary
    layer is turbulent (the laminar law holds for any Pr >= 0.6).

    :param Re_L: Reynolds number U L / nu.
    :param Pr: Prandtl number.
    :param log: optional validity log.

    Examples
    --------
    Hand-checked: Re_L = 1e4, Pr = 1: 0.664 * 100 = 66.4; Re_L = 1e6, Pr = 1:
    0.037 * 63 095.7 - 871 = 1463.5.

    >>> [round(float(flat_plate_nusselt(re, 1.0)), 1) for re in (1.0e4, 1.0e6)]
    [66.4, 1463.5]

    """
    re = np.asarray(Re_L, dtype=float)
    check_flat_plate_nusselt(log, re, Pr)
    re_b, pr_b = np.broadcast_arrays(re, np.asarray(Pr, dtype=float))
    return _scalar(flat_plate_nusselt_kernel(re_b.ravel(), pr_b.ravel()).reshape(re_b.shape))


def check_flat_plate_nusselt(log: Optional[ValidityLog], Re_L, Pr) -> None:
    """Flag in ``log`` what :func:`flat_plate_nusselt` evaluates outside its laws' ranges."""
    if log is not None:
        check(log, 'flat plate', 'Re_L', Re_L, 0.0, 1.0e8,
              'plate Reynolds number above the correlated range; extrapolated')
        check(log, 'flat plate', 'Pr', np.where(np.greater(Re_L, PLATE_RE_CRITICAL), Pr, np.nan),
              0.6, 60.0, 'Prandtl number outside the turbulent plate law; extrapolated')


@jit
def flat_plate_nusselt_kernel(re, pr):
    """Return :func:`flat_plate_nusselt` for 1-D arrays; compiled, no checks."""
    laminar = 0.664 * np.sqrt(re)
    mixed = 0.037 * np.power(re, 0.8) - 871.0
    return np.where(re <= PLATE_RE_CRITICAL, laminar, mixed) * np.cbrt(pr)


@jit
def flat_plate_shear(rho, nu, speed_m_s, length_m):
    """
    Return the mean wall shear (Pa) of a plate of length L in a parallel stream of speed V.

    tau = rho V^2 C_f / 2 with Incropera's mean friction coefficients (7th ed.,
    section 7.2): laminar (Blasius) C_f = 1.328 Re_L^-0.5 up to Re_L = 5e5,
    mixed laminar-turbulent C_f = 0.074 Re_L^-0.2 - 1742 / Re_L above (meeting
    within 0.1 %). The Reynolds-Colburn analogy (St Pr^(2/3) = C_f / 2) of
    these is :func:`flat_plate_nusselt`. Floats, compiled; V = 0 gives 0.

    Examples
    --------
    Hand-checked: oil (850 kg/m^3, 1e-5 m^2/s) at 2 m/s along 0.1 m: Re_L =
    2e4, tau = 0.5 * 850 * 4 * 1.328 / 141.42 = 15.96 Pa.

    >>> round(float(flat_plate_shear(850.0, 1e-5, 2.0, 0.1)), 2)
    15.96

    """
    re = abs(speed_m_s) * length_m / nu
    if re <= 0.0:
        return 0.0
    if re <= PLATE_RE_CRITICAL:
        cf = 1.328 / np.sqrt(re)
    else:
        cf = 0.074 * re ** -0.2 - 1742.0 / re
    return 0.5 * rho * speed_m_s * speed_m_s * cf


@jit
def end_space_swirl_speed(omega, disc_radius_m, r_m, swirl_ratio):
    """
    Return the speed (m/s) of the end space's swirling oil at radius ``r_m``.

    Inside the disc's radius a the core turns as a solid body at K omega (K,
    ``swirl_ratio``, from the end space's torque balance); past it nothing
    drives the oil and its angular momentum is conserved (a free vortex), so
    v = K omega a^2 / r. Approximate: an estimate of the oil's speed past the
    end windings, the stack faces and the housing, for a plate law; the end
    space's calibration multiplier absorbs its error. Floats, compiled.

    Examples
    --------
    Hand-checked: 1000 rad/s, a = 18 mm, K = 0.4: at r = 9 mm 0.4 * 1000 *
    0.009 = 3.6 m/s; at r = 36 mm 0.4 * 1000 * 0.018^2 / 0.036 = 3.6 m/s.

    >>> [round(float(end_space_swirl_speed(1000.0, 0.018, r, 0.4)), 3) for r in (0.009, 0.036)]
    [3.6, 3.6]

    """
    if r_m <= disc_radius_m:
        return swirl_ratio * abs(omega) * r_m
    return swirl_ratio * abs(omega) * disc_radius_m * disc_radius_m / r_m


# ----------------------------------------------------------------- rolling bearings

@jit
def palmgren_bearing_torque(nu_m2_s, speed_rad_s, mean_diameter_m, f0, f1, load_N):
    """
    Return the friction torque (N m) of a rolling bearing: Palmgren's M0 + M1.

    Source: A. Palmgren, Ball and Roller Bearing Engineering, 3rd ed., SKF
    Industries, 1959; as given by T. A. Harris and M. N. Kotzalas, Rolling
    Bearing Analysis, 5th ed., 2007, ch. 12 (SI units converted here):

    - load-independent (viscous) part, nu in mm^2/s, n in r/min, d_m in mm:
      M0 = 1e-7 f0 (nu n)^(2/3) d_m^3 N mm for nu n >= 2000, else
      160e-7 f0 d_m^3 N mm (the two meet within 1 % at 2000; the larger of
      the two is taken, which keeps the torque continuous there);
    - load part M1 = f1 P1 d_m N mm, P1 the load that sets the friction
      (radial bearings: the radial load).

    f0 depends on the bearing type and its lubrication (larger in an oil
    bath or running flooded than in oil mist); f1 on the type and load
    (:func:`deep_groove_ball_f1`). Valid for a bearing at its operating
    temperature, without seal friction. Compiled; floats or arrays.

    :param nu_m2_s: kinematic viscosity of the oil at the bearing (m^2/s).
    :param speed_rad_s: shaft speed (rad/s), either sign.
    :param mean_diameter_m: pitch diameter d_m = (bore + outside) / 2 (m).
    :param f0: Palmgren's lubrication factor.
    :param f1: Palmgren's load factor.
    :param load_N: P1 (N).

    Examples
    --------
    Hand-checked: 13.5 mm^2/s at 10 000 r/min (1047.2 rad/s), d_m 16 mm,
    f0 = 4, f1 = 1.4e-4, 50 N: nu n = 135 000, (nu n)^(2/3) = 2631.6,
    M0 = 1e-7 * 4 * 2631.6 * 4096 = 4.312 N mm, M1 = 1.4e-4 * 50 * 16 =
    0.112 N mm, M = 4.424e-3 N m.

    >>> round(float(palmgren_bearing_torque(13.5e-6, 1047.2, 0.016, 4.0, 1.4e-4, 50.0)), 6)
    0.004424

    """
    nu_n = (nu_m2_s * 1.0e6) * (np.abs(speed_rad_s) * RPM_PER_RAD_S)
    dm3 = (mean_diameter_m * 1.0e3) ** 3
    m0 = f0 * dm3 * np.maximum(1.0e-7 * np.square(np.cbrt(nu_n)), 160.0e-7)
    return 1.0e-3 * (m0 + f1 * load_N * mean_diameter_m * 1.0e3)


def deep_groove_ball_f1(load_N, static_rating_N):
    """
    Return Palmgren's load factor f1 of a deep-groove ball bearing.

    f1 = 0.0007 (P0 / C0)^0.5, P0 the static equivalent load and C0 the
    static load rating (Harris and Kotzalas, Rolling Bearing Analysis, 5th
    ed., 2007, ch. 12, after Palmgren 1959).

    Examples
    --------
    Hand-checked: 50 N on C0 = 1270 N: 0.0007 * (0.03937)^0.5 = 1.389e-4.

    >>> round(float(deep_groove_ball_f1(50.0, 1270.0)), 7)
    0.0001389

    """
    return 0.0007 * np.sqrt(np.divide(load_N, static_rating_N))
