"""
Hydraulic oil properties versus temperature and pressure.

Units are SI throughout: temperature ``T_K`` in kelvin, pressure ``p_Pa`` in
pascal *gauge* (above atmospheric; the property data are quoted at
atmospheric pressure), density in kg/m^3, kinematic viscosity in m^2/s,
dynamic viscosity in Pa s, specific heat in J/(kg K), conductivity in
W/(m K). Every function accepts floats or numpy arrays (broadcast together).

Models (docs/model.md, Oil properties):

- density: rho = rho_15 [1 - alpha_p (T - 288.15 K)] / (1 - p / K(T, p)),
  with K the isothermal *secant* bulk modulus from 0 to p (the one that
  gives the volume change from 0 to p in one step), linear in p (Hayward
  1967) and exponential in T: K(T, p) = K_40 exp(-lambda (T - 313.15 K)) + m p.
  The isothermal tangent modulus follows from it, and the isentropic
  tangent modulus (wave speed, compressibility flows; about 20 % higher)
  from the thermodynamic identities gamma = c_p / c_v = K_S / K_T and
  c_p - c_v = T alpha_p^2 K_T / rho.
- kinematic viscosity: ASTM D341 (Walther),
  log10 log10(nu_cSt + 0.7) = A - B log10(T_K), one line through the 40 and
  100 degC data for T >= 40 degC and a second line through the cold datum
  (-40 degC) and 40 degC below; the VI improver of a MIL-PRF-5606 fluid makes
  a single line miss the -40 degC value by a factor of about 2.5 (200 cSt
  instead of 495 cSt). Pressure: Barus, nu(p) = nu(0) exp(a_p p).
- specific heat and conductivity: linear laws in the Celsius temperature.
  For the petroleum grade they are Cragoe's petroleum-oil correlations
  (Cragoe, C. S., "Thermal properties of petroleum products", US Bureau of
  Standards Misc. Publ. 97, 1929; as reproduced in most heat-transfer data
  books): c_p = (1.685 + 0.003391 t_C) / sqrt(s) kJ/(kg K),
  k = 0.1172 (1 - 0.00054 t_C) / s W/(m K), s the specific gravity at
  15 degC (rho_15 / 999.1).

Values marked (est.) are engineering estimates, not measured data of a
particular batch; replace them with the data sheet of the fluid on the rig.
"""

from dataclasses import dataclass
import math
from typing import Dict, NamedTuple, Optional, Tuple

import numpy as np

from .compiled import interpreted, jit
from .validity import check, ValidityLog
from ..units import C_TO_K

#: Reference temperature of the density data (15 degC) in kelvin.
T15_K = C_TO_K + 15.0
#: Reference temperature of the bulk modulus law (40 degC) in kelvin.
T40_K = 313.15
#: Density of water at 15 degC (kg/m^3), the reference of the specific gravity.
RHO_WATER_15 = 999.1
#: Pressure range over which the bulk modulus law and the Barus factor are
#: accepted (gauge Pa): 0..35 MPa, the working range of aircraft hydraulics.
P_MIN_PA = 0.0
P_MAX_PA = 35.0e6


def walther_fit(T1_K: float, nu1_cSt: float, T2_K: float,
                nu2_cSt: float) -> Tuple[float, float]:
    """
    Fit the ASTM D341 (Walther) line through two viscosity data points.

    Source: ASTM D341, "Standard practice for viscosity-temperature
    equations and charts of liquid petroleum products":
    log10 log10(nu_cSt + 0.7) = A - B log10(T_K). The 0.7 offset is the
    D341 constant for nu >= 2 cSt (the correlation's validity range).

    :param T1_K: temperature of the first datum (K).
    :param nu1_cSt: kinematic viscosity at ``T1_K`` (cSt = mm^2/s).
    :param T2_K: temperature of the second datum (K), different from ``T1_K``.
    :param nu2_cSt: kinematic viscosity at ``T2_K`` (cSt).

    :return: ``(A, B)``, dimensionless, for ``log10 log10(nu_cSt + 0.7) = A - B log10(T_K)``.

    Examples
    --------
    Hand-checked, MIL-PRF-5606's 13.5 cSt at 40 degC and 5.1 cSt at 100 degC:
    z = log10 log10(nu + 0.7) = 0.061561 and -0.117232, B = 0.178793 /
    (log10 373.15 - log10 313.15) = 0.178793 / 0.076131 = 2.3485,
    A = 0.061561 + B log10 313.15 = 5.9228. Extrapolated to -40 degC the line
    reads 10^10^(A - B log10 233.15) - 0.7 = 201 cSt, against the 495 cSt of
    the fluid: the reason for the grade's second, cold line.

    >>> a, b = walther_fit(313.15, 13.5, 373.15, 5.1)
    >>> round(a, 4), round(b, 4)
    (5.9228, 2.3485)
    >>> round(10.0 ** 10.0 ** (a - b * math.log10(233.15)) - 0.7)
    201

    """
    z1 = math.log10(math.log10(nu1_cSt + 0.7))
    z2 = math.log10(math.log10(nu2_cSt + 0.7))
    b = (z1 - z2) / (math.log10(T2_K) - math.log10(T1_K))
    return z1 + b * math.log10(T1_K), b


def cragoe_laws(specific_gravity_15: float) -> Tuple[Tuple[float, float], Tuple[float, float]]:
    """
    Return Cragoe's linear c_p and k laws of a petroleum oil.

    Source: Cragoe (1929), US Bureau of Standards Misc. Publ. 97, converted
    to SI: c_p = (1.685 + 0.003391 t_C) / sqrt(s) kJ/(kg K) and
    k = 0.1172 (1 - 0.00054 t_C) / s W/(m K), with s the specific gravity at
    15 degC (60 degF). Stated for petroleum oils (s about 0.75-0.96) from
    about 0 to 400 degC (c_p) and 0 to 200 degC (k); accuracy a few percent.

    :param specific_gravity_15: specific gravity at 15 degC (rho_15 / 999.1).

    :return: ``((c0, c1), (k0, k1))`` with c_p = c0 + c1 t_C in J/(kg K) and
        k = k0 + k1 t_C in W/(m K), t_C the temperature in degC.

    Examples
    --------
    At s = 1 the laws are Cragoe's constants themselves (k1 = -0.1172 *
    0.00054 = -6.3288e-5):

    >>> cragoe_laws(1.0)
    ((1685.0, 3.391), (0.1172, -6.3288e-05))

    """
    root_s = math.sqrt(specific_gravity_15)
    cp = (1685.0 / root_s, 3.391 / root_s)
    k = (0.1172 / specific_gravity_15, -0.1172 * 0.00054 / specific_gravity_15)
    return cp, k


class OilLaws(NamedTuple):
    """
    The constants of one grade's property laws, as compiled kernels take them.

    rho = rho15 [1 - alpha (T - 288.15)] / (1 - p / K), the secant bulk modulus
    K = k40 exp(-k_lambda (T - 313.15)) + k_slope p (Pa); Walther lines
    ``(a_hot, b_hot)`` for T >= 40 degC and ``(a_cold, b_cold)`` below, Barus
    coefficient ``barus`` (1/Pa); c_p = c0 + c1 t_C; k = k0 + k1 t_C.
    """

    rho15: float
    alpha: float
    k40: float
    k_lambda: float
    k_slope: float
    a_hot: float
    b_hot: float
    a_cold: float
    b_cold: float
    barus: float
    c0: float
    c1: float
    k0: float
    k1: float


# The property laws take ``laws`` as a plain tuple in OilLaws order: numba types a plain
# tuple three times faster than a NamedTuple, which counts on every call from Python.

@jit
def secant_bulk_modulus(T_K, p_Pa, laws):
    """Return K (Pa) of :meth:`Oil.secant_bulk_modulus` (floats or arrays, no checks)."""
    return laws[2] * np.exp(-laws[3] * (T_K - T40_K)) + laws[4] * p_Pa


@jit
def density(T_K, p_Pa, laws):
    """Return rho (kg/m^3) as :meth:`Oil.density` does (floats or arrays, no checks)."""
    return laws[0] * (1.0 - laws[1] * (T_K - T15_K)) / (
        1.0 - p_Pa / secant_bulk_modulus(T_K, p_Pa, laws))


@jit
def kinematic_viscosity(T_K, p_Pa, laws):
    """Return nu (m^2/s) of :meth:`Oil.kinematic_viscosity` (floats or arrays, no checks)."""
    log_t = np.log10(T_K)
    z = np.where(T_K >= C_TO_K + 40.0, laws[5] - laws[6] * log_t, laws[7] - laws[8] * log_t)
    nu_cst = np.power(10.0, np.power(10.0, z)) - 0.7
    return 1.0e-6 * nu_cst * np.exp(laws[9] * p_Pa)


@jit
def specific_heat(T_K, laws):
    """Return c_p (J/(kg K)) of :meth:`Oil.specific_heat` (floats or arrays, no checks)."""
    return laws[10] + laws[11] * (T_K - C_TO_K)


#: terms of the compression factor's series in e(T) (see :func:`volumetric_energy`)
ENERGY_SERIES_TERMS = 4


@jit
def _rho_cp_series(p_Pa, laws):
    """
    Return the constants of rho(T, p) c_p(T) as :func:`volumetric_energy` integrates it.

    rho c_p = (a + b T + c T^2) (1 + sum_n s_n E^n), n = 1.. ENERGY_SERIES_TERMS,
    E = exp(lambda (T - 313.15 K)): rho_0(T) c_p(T) is quadratic in T (J/(m^3 K))
    and the compression factor 1 / (1 - p / K) = 1 + p / (K_40 / E + (m - 1) p)
    is the geometric series in E of ratio -(m - 1) p E / K_40. Returns
    (a, b, c, s, lambda).
    """
    r1 = -laws[0] * laws[1]                              # rho_0 = r0 + r1 T
    r0 = laws[0] - r1 * T15_K
    d0 = laws[10] - laws[11] * C_TO_K                       # c_p = d0 + d1 T
    s = np.empty(ENERGY_SERIES_TERMS)
    s[0] = p_Pa / laws[2]
    ratio = -(laws[4] - 1.0) * p_Pa / laws[2]
    for n in range(1, ENERGY_SERIES_TERMS):
        s[n] = s[n - 1] * ratio
    return r0 * d0, r0 * laws[11] + r1 * d0, r1 * laws[11], s, laws[3]


@jit
def volumetric_energy(T_K, p_Pa, laws):
    """
    Return e(T), an antiderivative of rho(T, p) c_p(T) in T (J/m^3), T in K, at a fixed p.

    The energy of a unit volume of oil filled at pressure ``p_Pa``: what a
    volume holds and what a flow carries, so that books kept in ``e`` close
    exactly whatever the temperatures (rho c_p moves by about 0.1 %/K).
    Only differences mean anything. Closed form: the quadratic
    P(T) = rho_0 c_p integrates to a cubic, and each term P(T) s_n E^n of the
    compression factor's series (:func:`_rho_cp_series`) to
    s_n E^n (P / k - P' / k^2 + P'' / k^3), k = n lambda (lambda > 0). The
    series is cut after ENERGY_SERIES_TERMS terms, an error of the order of
    ((m - 1) p / K_0)^4 p / K_0: against a quadrature of rho c_p, within
    1e-13 at the accumulator's 0.6 MPa, where the model uses it, 2e-8 at
    8 MPa and 2e-6 at 21 MPa (from 40 to 135 degC, test_oil.py).

    Examples
    --------
    Hand-checked, MIL-PRF-5606 from 40 to 41 degC at 0 Pa: rho c_p at
    40.5 degC is 865 (1 - 8e-4 * 25.5) (1685 + 3.391 * 40.5) / 0.93047 =
    847.35 * 1958.5 = 1.6595e6 J/(m^3 K) (rho c_p is near enough linear over
    1 K that the midpoint value is the integral).

    >>> laws = get_oil('MIL-PRF-5606').laws
    >>> e = volumetric_energy(np.array([313.15, 314.15]), 0.0, laws)
    >>> round(float(e[1] - e[0]) / 1e6, 4)
    1.6595

    """
    a, b, c, s, lam = _rho_cp_series(p_Pa, laws)
    e = T_K * (a + T_K * (0.5 * b + T_K * (c / 3.0)))
    p0 = a + T_K * (b + T_K * c)
    p1 = b + 2.0 * c * T_K
    E = np.exp(lam * (T_K - T40_K))
    En = np.ones_like(E)
    for n in range(ENERGY_SERIES_TERMS):
        k = (n + 1) * lam
        En = En * E
        e = e + s[n] * En * (p0 / k - p1 / k ** 2 + 2.0 * c / k ** 3)
    return e


@jit
def temperature_of_energy(e, T_guess_K, p_Pa, laws):
    """
    Return T (K) with :func:`volumetric_energy` (T) = ``e``, by Newton from ``T_guess_K``.

    Examples
    --------
    The inverse of :func:`volumetric_energy`: from a guess 5 K off, back to
    the temperatures whose energies were given (at 8 MPa).

    >>> laws = get_oil('MIL-PRF-5606').laws
    >>> T = np.array([253.15, 313.15, 393.15])
    >>> back = temperature_of_energy(volumetric_energy(T, 8.0e6, laws), T + 5.0, 8.0e6, laws)
    >>> [round(float(t), 6) for t in back]
    [253.15, 313.15, 393.15]

    """
    a, b, c, s, lam = _rho_cp_series(p_Pa, laws)
    T = T_guess_K.copy()
    for _ in range(3):       # from a guess within a few K: converged to rounding in two
        E = np.exp(lam * (T - T40_K))
        factor = np.ones_like(E)
        En = np.ones_like(E)
        for n in range(ENERGY_SERIES_TERMS):
            En = En * E
            factor = factor + s[n] * En
        T -= (volumetric_energy(T, p_Pa, laws) - e) / ((a + T * (b + T * c)) * factor)
    return T


@jit
def conductivity(T_K, laws):
    """Return k (W/(m K)) of :meth:`Oil.conductivity` (floats or arrays, no checks)."""
    return laws[12] + laws[13] * (T_K - C_TO_K)


# a few operators: as Python arithmetic on a float, cheaper than a compiled call
_density_interpreted = interpreted(density)
_specific_heat_interpreted = interpreted(specific_heat)
_conductivity_interpreted = interpreted(conductivity)


@dataclass(frozen=True)
class OilGrade:
    """
    Data of one hydraulic oil grade (all SI unless the name says otherwise).

    :ivar name: grade name, e.g. ``'MIL-PRF-5606'``.
    :ivar rho15_kg_m3: density at 15 degC and atmospheric pressure (kg/m^3).
    :ivar alpha_p_1_K: isobaric volumetric expansion coefficient (1/K).
    :ivar bulk_modulus_40_Pa: isothermal secant bulk modulus K_40 (Pa) at 40 degC
        in the limit of zero pressure.
    :ivar bulk_modulus_lambda_1_K: its temperature coefficient lambda (1/K):
        K_0(T) = K_40 exp(-lambda (T - 313.15 K)).
    :ivar bulk_modulus_slope: Hayward's slope m (dimensionless) of the secant
        modulus against pressure: K(T, p) = K_0(T) + m p.
    :ivar nu_cold_cSt: kinematic viscosity at ``T_cold_K`` (cSt).
    :ivar nu_40_cSt: kinematic viscosity at 40 degC (cSt).
    :ivar nu_100_cSt: kinematic viscosity at 100 degC (cSt).
    :ivar T_cold_K: temperature of the cold viscosity datum (K), -40 degC.
    :ivar barus_1_Pa: pressure-viscosity (Barus) coefficient a_p (1/Pa).
    :ivar cp_J_kgK: ``(c0, c1)``: c_p = c0 + c1 t_C (J/(kg K), t_C in degC).
    :ivar k_W_mK: ``(k0, k1)``: k = k0 + k1 t_C (W/(m K), t_C in degC).
    :ivar T_min_K: lowest temperature the data are valid for (K).
    :ivar T_max_K: highest temperature the data are valid for (K).
    :ivar source_notes: where each value comes from; (est.) marks estimates.

    """

    name: str
    rho15_kg_m3: float
    alpha_p_1_K: float
    bulk_modulus_40_Pa: float
    bulk_modulus_lambda_1_K: float
    bulk_modulus_slope: float
    nu_cold_cSt: float
    nu_40_cSt: float
    nu_100_cSt: float
    T_cold_K: float
    barus_1_Pa: float
    cp_J_kgK: Tuple[float, float]
    k_W_mK: Tuple[float, float]
    T_min_K: float
    T_max_K: float
    source_notes: str = ''

    @property
    def specific_gravity_15(self) -> float:
        """
        Return the specific gravity at 15 degC (rho_15 / rho_water,15).

        Examples
        --------
        Hand-checked, MIL-PRF-5606: 865 / 999.1 = 0.8658.

        >>> round(OIL_GRADES['MIL-PRF-5606'].specific_gravity_15, 4)
        0.8658

        """
        return self.rho15_kg_m3 / RHO_WATER_15

    @property
    def walther_hot(self) -> Tuple[float, float]:
        """Return the Walther ``(A, B)`` through 40 and 100 degC (used for T >= 40 degC)."""
        return walther_fit(C_TO_K + 40.0, self.nu_40_cSt, C_TO_K + 100.0, self.nu_100_cSt)

    @property
    def walther_cold(self) -> Tuple[float, float]:
        """Return the Walther ``(A, B)`` through the cold datum and 40 degC (T < 40 degC)."""
        return walther_fit(self.T_cold_K, self.nu_cold_cSt, C_TO_K + 40.0, self.nu_40_cSt)


class Oil:
    """
    Temperature- and pressure-dependent properties of one oil grade.

    Every method takes ``T_K`` (K) and, where pressure matters, ``p_Pa``
    (gauge Pa), as floats or numpy arrays, plus an optional
    :class:`~wet_eha_thermal.model.validity.ValidityLog` that records
    temperatures outside the grade's range and pressures outside 0..35 MPa.
    Out-of-range inputs are evaluated (extrapolated) and flagged, never
    rejected.
    """

    def __init__(self, grade: OilGrade) -> None:
        """Precompute the property laws of ``grade`` (Walther lines, constants)."""
        self.grade = grade
        #: the constants of the property laws, a plain tuple in :class:`OilLaws` order
        self.laws = tuple(OilLaws(grade.rho15_kg_m3, grade.alpha_p_1_K,
                                  grade.bulk_modulus_40_Pa, grade.bulk_modulus_lambda_1_K,
                                  grade.bulk_modulus_slope, *grade.walther_hot,
                                  *grade.walther_cold, grade.barus_1_Pa, *grade.cp_J_kgK,
                                  *grade.k_W_mK))
        self._alpha = grade.alpha_p_1_K
        self._t_lo = grade.T_min_K
        self._t_hi = grade.T_max_K
        self._t_note = (f'{grade.name} property data valid for '
                        f'{grade.T_min_K - C_TO_K:.0f}..{grade.T_max_K - C_TO_K:.0f} degC; '
                        'value extrapolated')
        self._p_note = ('bulk modulus law and Barus viscosity factor accepted over '
                        '0..35 MPa gauge; value extrapolated')

    def __repr__(self) -> str:
        """Return a short description naming the grade."""
        return f'Oil({self.grade.name!r})'

    @property
    def name(self) -> str:
        """Return the grade name."""
        return self.grade.name

    @property
    def alpha_p(self) -> float:
        """Return the isobaric volumetric expansion coefficient (1/K)."""
        return self._alpha

    def _check_T(self, log: Optional[ValidityLog], what: str, T_K) -> None:
        check(log, f'{self.grade.name} {what}', 'T_K', T_K, self._t_lo, self._t_hi,
              self._t_note)

    def _check_p(self, log: Optional[ValidityLog], what: str, p_Pa) -> None:
        check(log, f'{self.grade.name} {what}', 'p_Pa', p_Pa, P_MIN_PA, P_MAX_PA,
              self._p_note)

    def secant_bulk_modulus(self, T_K, p_Pa=0.0, log: Optional[ValidityLog] = None):
        """
        Return the isothermal secant bulk modulus K(T, p) from 0 to p gauge, in Pa.

        K = p V_0 / (V_0 - V), the volume change from 0 to p in one step: what
        the density law needs. Linear in p, after A. T. J. Hayward,
        "Compressibility equations for liquids: a comparative study", Brit.
        J. Appl. Phys. 18, 1967, 965-977 (Tait's original equation rearranged,
        the most accurate two-constant equation of those compared), and exponential
        in T: K(T, p) = K_40 exp(-lambda (T - 313.15 K)) + m p. The grade's
        K_40, lambda and m are estimates (see its ``source_notes``): no
        public table of these grades' moduli over T and p was found.
        Validity: the grade's temperature range and 0..35 MPa.

        Examples
        --------
        Hand-checked, MIL-PRF-5606 at 40 degC and 35 MPa: 1.21e9 + 5.5 *
        35e6 = 1.4025e9 Pa, the 1.4 GPa of the former constant (0..35 MPa at
        about 40 degC); at 135 degC and 0 Pa, 1.21e9 exp(-4.4e-3 * 95) =
        1.21e9 * 0.65838 = 0.7966e9 Pa.

        >>> oil = get_oil('MIL-PRF-5606')
        >>> round(float(oil.secant_bulk_modulus(313.15, 35.0e6)) / 1e9, 4)
        1.4025
        >>> round(float(oil.secant_bulk_modulus(408.15, 0.0)) / 1e9, 4)
        0.7966

        """
        if log is not None:
            self._check_T(log, 'bulk modulus', T_K)
            self._check_p(log, 'bulk modulus', p_Pa)
        return secant_bulk_modulus(T_K, p_Pa, self.laws)

    def tangent_bulk_modulus(self, T_K, p_Pa=0.0, log: Optional[ValidityLog] = None):
        """
        Return the isothermal tangent bulk modulus K_T = -V (dp/dV)_T in Pa.

        From the secant law V / V_0 = 1 - p / K, K = K_0 + m p:
        K_T = K (K - p) / K_0, K_0 the secant modulus at zero pressure. Its
        pressure derivative at p = 0 is 2 m - 1. Same validity as
        :meth:`secant_bulk_modulus`.

        Examples
        --------
        Hand-checked, MIL-PRF-5606 at 40 degC and 21 MPa: K = 1.21e9 + 5.5 *
        21e6 = 1.3255e9, K_T = 1.3255e9 * 1.3045e9 / 1.21e9 = 1.4290e9 Pa.

        >>> round(float(get_oil('MIL-PRF-5606').tangent_bulk_modulus(313.15, 21.0e6)) / 1e9, 4)
        1.429

        """
        k = self.secant_bulk_modulus(T_K, p_Pa, log)
        k0 = secant_bulk_modulus(T_K, 0.0, self.laws)
        return k * (k - p_Pa) / k0

    def isentropic_bulk_modulus(self, T_K, p_Pa=0.0, log: Optional[ValidityLog] = None):
        """
        Return the isentropic tangent bulk modulus K_S = -V (dp/dV)_s in Pa.

        The one of wave speeds (c = sqrt(K_S / rho)) and of the compression of
        a volume faster than it exchanges heat (a chamber within a duty
        cycle): K_S = gamma K_T, with the exact thermodynamic identities
        gamma = c_p / c_v and c_p - c_v = T alpha_p^2 K_T / rho, so
        K_S = K_T / (1 - alpha_p^2 T K_T / (rho c_p)), from the grade's alpha_p,
        rho and c_p. Same validity as :meth:`secant_bulk_modulus`.

        Examples
        --------
        Hand-checked, MIL-PRF-5606 at 40 degC and 21 MPa: K_T = 1.4290e9 Pa,
        rho c_p = 861.35 * 1956.7 = 1.68538e6 J/(m^3 K), alpha_p^2 T K_T /
        (rho c_p) = (8e-4)^2 * 313.15 * 1.42902e9 / 1.68538e6 = 0.169933,
        K_S = 1.42902e9 / 0.830067 = 1.7216e9 Pa (20 % above K_T).

        >>> round(float(get_oil('MIL-PRF-5606').isentropic_bulk_modulus(313.15, 21.0e6)) / 1e9, 4)
        1.7216

        """
        k_t = self.tangent_bulk_modulus(T_K, p_Pa, log)
        rho_cp = self.density(T_K, p_Pa, log) * self.specific_heat(T_K, log)
        return k_t / (1.0 - self._alpha ** 2 * np.asarray(T_K) * k_t / rho_cp)

    def density(self, T_K, p_Pa=0.0, log: Optional[ValidityLog] = None):
        """
        Return the density rho(T, p) in kg/m^3.

        rho = rho_15 [1 - alpha_p (T - 288.15 K)] / (1 - p / K(T, p)),
        docs/model.md (Oil properties), with K the isothermal secant bulk
        modulus of :meth:`secant_bulk_modulus` and alpha_p constant (a
        first-order expansion about 15 degC). Validity: the grade's
        temperature range and 0..35 MPa.

        Examples
        --------
        MIL-PRF-5606: its datum 865 kg/m^3 at 15 degC and, hand-checked, at
        40 degC and 21 MPa 865 (1 - 8e-4 * 25) / (1 - 21e6 / 1.3255e9) =
        847.7 / 0.984157 = 861.35 kg/m^3 (860.4 with the former constant
        1.4 GPa in the first-order law rho_0 (1 + p / K)).

        >>> oil = get_oil('MIL-PRF-5606')
        >>> round(float(oil.density(288.15)), 6), round(float(oil.density(313.15, 21.0e6)), 2)
        (865.0, 861.35)

        """
        if log is not None:
            self._check_T(log, 'density', T_K)
            self._check_p(log, 'density', p_Pa)
        return _density_interpreted(T_K, p_Pa, self.laws)

    def kinematic_viscosity(self, T_K, p_Pa=0.0, log: Optional[ValidityLog] = None):
        """
        Return the kinematic viscosity nu(T, p) in m^2/s.

        ASTM D341 (Walther): log10 log10(nu_cSt + 0.7) = A - B log10(T_K),
        piecewise: the line through the 40 and 100 degC data for
        T >= 40 degC, the line through the cold (-40 degC) and 40 degC data
        below (continuous at 40 degC). Pressure by Barus:
        nu(p) = nu(0) exp(a_p p) (density change under pressure neglected in
        nu, i.e. the Barus factor is applied to nu; it is an estimate anyway).
        Validity: the grade's temperature range (below the cold datum the
        cold line is extrapolated) and 0..35 MPa.

        Examples
        --------
        MIL-PRF-5606's data (typical of qualified fluids, see the grade's
        ``source_notes``): 13.5 cSt at 40 degC, 5.1 cSt at 100 degC and
        495 cSt at -40 degC; and, hand-checked, the Barus factor at 20 MPa,
        exp(1.5e-8 * 2e7) = exp(0.3) = 1.3499.

        >>> oil = get_oil('MIL-PRF-5606')
        >>> [round(float(oil.kinematic_viscosity(T)) * 1e6, 6) for T in (313.15, 373.15, 233.15)]
        [13.5, 5.1, 495.0]
        >>> ratio = oil.kinematic_viscosity(323.15, 20.0e6) / oil.kinematic_viscosity(323.15)
        >>> round(float(ratio), 4)
        1.3499

        """
        if log is not None:
            self._check_T(log, 'viscosity', T_K)
            self._check_p(log, 'viscosity', p_Pa)
        return kinematic_viscosity(T_K, p_Pa, self.laws)

    def dynamic_viscosity(self, T_K, p_Pa=0.0, log: Optional[ValidityLog] = None):
        """
        Return the dynamic viscosity mu = rho nu in Pa s (same models and validity).

        Examples
        --------
        Hand-checked, MIL-PRF-5606 at 40 degC: 13.5e-6 m^2/s * 847.7 kg/m^3
        (865 * 0.98) = 11.44 mPa s.

        >>> round(float(get_oil('MIL-PRF-5606').dynamic_viscosity(313.15)) * 1e3, 2)
        11.44

        """
        return self.kinematic_viscosity(T_K, p_Pa, log) * self.density(T_K, p_Pa, log)

    def specific_heat(self, T_K, log: Optional[ValidityLog] = None):
        """
        Return the isobaric specific heat c_p(T) in J/(kg K).

        Linear law c_p = c0 + c1 t_C of the grade (Cragoe for the petroleum
        grade, see :func:`cragoe_laws`). Validity: the grade's temperature
        range.

        Examples
        --------
        Hand-checked, Cragoe for MIL-PRF-5606 (s = 0.86578) at 40 degC:
        (1685 + 3.391 * 40) / sqrt(0.86578) = 1820.64 / 0.93047 = 1956.7 J/(kg K).

        >>> round(float(get_oil('MIL-PRF-5606').specific_heat(313.15)), 1)
        1956.7

        """
        if log is not None:
            self._check_T(log, 'specific heat', T_K)
        return _specific_heat_interpreted(T_K, self.laws)

    def conductivity(self, T_K, log: Optional[ValidityLog] = None):
        """
        Return the thermal conductivity k(T) in W/(m K).

        Linear law k = k0 + k1 t_C of the grade (Cragoe for the petroleum
        grade). Validity: the grade's temperature range.

        Examples
        --------
        Hand-checked, Cragoe for MIL-PRF-5606 (s = 0.86578) at 40 degC:
        0.1172 (1 - 0.00054 * 40) / 0.86578 = 0.11467 / 0.86578 = 0.1324 W/(m K).

        >>> round(float(get_oil('MIL-PRF-5606').conductivity(313.15)), 4)
        0.1324

        """
        if log is not None:
            self._check_T(log, 'conductivity', T_K)
        return _conductivity_interpreted(T_K, self.laws)

    def prandtl(self, T_K, p_Pa=0.0, log: Optional[ValidityLog] = None):
        """
        Return the Prandtl number Pr = mu c_p / k (dimensionless).

        Examples
        --------
        Hand-checked from the three examples above, MIL-PRF-5606 at 40 degC:
        0.011444 * 1956.7 / 0.13245 = 169.1.

        >>> round(float(get_oil('MIL-PRF-5606').prandtl(313.15)), 1)
        169.1

        """
        return (self.dynamic_viscosity(T_K, p_Pa, log) * self.specific_heat(T_K, log)
                / self.conductivity(T_K, log))


def _grade_5606() -> OilGrade:
    rho15 = 865.0
    cp, k = cragoe_laws(rho15 / RHO_WATER_15)
    return OilGrade(
        name='MIL-PRF-5606',
        rho15_kg_m3=rho15,
        alpha_p_1_K=8.0e-4,
        bulk_modulus_40_Pa=1.21e9,
        bulk_modulus_lambda_1_K=4.4e-3,
        bulk_modulus_slope=5.5,
        nu_cold_cSt=495.0,
        nu_40_cSt=13.5,
        nu_100_cSt=5.1,
        T_cold_K=C_TO_K - 40.0,
        barus_1_Pa=1.5e-8,
        cp_J_kgK=cp,
        k_W_mK=k,
        T_min_K=C_TO_K - 54.0,
        T_max_K=C_TO_K + 135.0,
        source_notes=(
            'Petroleum base, VI-improved (NATO H-515). Viscosity: typical values of '
            'qualified fluids: 13.5 cSt at 40 degC, 5.1 cSt at 100 degC, '
            '495 cSt at -40 degC (spec limits: >= 10.0, >= 4.90, <= 600 cSt). '
            'rho_15 865 kg/m^3 (typical data sheets 0.86-0.87). alpha_p 8e-4 1/K (est.). '
            'Bulk modulus (est.; no public table of the grade over T and p found): '
            'isothermal secant K = K_40 exp(-lambda (T - 40 degC)) + m p (Hayward 1967), '
            'K_40 1.21 GPa so that K is 1.40 GPa from 0 to 35 MPa at 40 degC (the former '
            'constant), m 5.5 (a tangent-modulus slope 2 m - 1 = 10 at low pressure, '
            'typical of liquids), lambda 4.4e-3 1/K (the temperature factor of the Lee '
            'Company bulk-modulus chart, 1.10 at 60 degF and 0.86 at 160 degF). '
            'Barus a_p 1.5e-8 1/Pa (est., typical of '
            'light mineral hydraulic oils). c_p and k: Cragoe petroleum-oil '
            'correlations with s = rho_15/999.1. Temperature range -54..135 degC '
            '(spec service range; 135 degC is the oil limit of the reference rig); '
            'viscosity below -40 degC is extrapolated along the cold Walther line.'),
    )


def _grade_83282() -> OilGrade:
    rho15 = 845.0
    cp, k = cragoe_laws(rho15 / RHO_WATER_15)
    return OilGrade(
        name='MIL-PRF-83282',
        rho15_kg_m3=rho15,
        alpha_p_1_K=7.8e-4,
        bulk_modulus_40_Pa=1.26e9,
        bulk_modulus_lambda_1_K=4.4e-3,
        bulk_modulus_slope=5.5,
        nu_cold_cSt=2050.0,
        nu_40_cSt=14.2,
        nu_100_cSt=3.6,
        T_cold_K=C_TO_K - 40.0,
        barus_1_Pa=1.3e-8,
        cp_J_kgK=cp,
        k_W_mK=k,
        T_min_K=C_TO_K - 40.0,
        T_max_K=C_TO_K + 205.0,
        source_notes=(
            'Synthetic hydrocarbon (PAO) base, fire resistant (NATO H-537). Viscosity '
            '(est.): 14.2 cSt at 40 degC, 3.6 cSt at 100 degC, 2050 cSt at -40 degC, '
            'chosen a little inside the spec limits (>= 14.0, >= 3.45, <= 2200 cSt) as '
            'typical of qualified products; replace with the batch data sheet. '
            'rho_15 845 kg/m^3, alpha_p 7.8e-4 1/K, '
            'bulk modulus law as for MIL-PRF-5606 with K_40 1.26 GPa (1.45 GPa from 0 to '
            '35 MPa at 40 degC, the former constant), '
            'Barus a_p 1.3e-8 1/Pa (all est.). c_p and k (est.): Cragoe petroleum-oil '
            'correlations applied with s = rho_15/999.1 for want of PAO data: Cragoe '
            'is a petroleum correlation, and PAO data in the literature tend to be '
            'somewhat higher in c_p (of order 5-10 %); treat as an estimate. '
            'Temperature range -40..205 degC (spec service range).'),
    )


#: Known oil grades by name.
OIL_GRADES: Dict[str, OilGrade] = {
    g.name: g for g in (_grade_5606(), _grade_83282())
}

#: Name of the default grade.
DEFAULT_GRADE = 'MIL-PRF-5606'


def get_oil(name: str = DEFAULT_GRADE) -> Oil:
    """
    Return the :class:`Oil` of a named grade.

    :raises ValueError: the grade is unknown; the message names it and lists the
        known grades.

    """
    try:
        grade = OIL_GRADES[name]
    except (KeyError, TypeError):
        known = ', '.join(sorted(OIL_GRADES))
        raise ValueError(f'unknown oil grade {name!r}; known grades: {known}') from None
    return Oil(grade)


def isenthalpic_throttle_temperature_rise(dp_Pa, T_K, oil: Oil, p_Pa=0.0,
                                          log: Optional[ValidityLog] = None):
    """
    Return the temperature rise (K) of oil throttled isenthalpically across dp_Pa.

    From dh = c_p dT + (1 - alpha_p T) dp / rho = 0 (docs/model.md, Oil properties):
    dT = (1 - alpha_p T) dp / (rho c_p), about 0.45 K/MPa for MIL-PRF-5606 at
    40 degC. ``dp_Pa`` is the pressure drop (positive for a drop, giving a
    rise); ``T_K`` and ``p_Pa`` (gauge) are the state at which rho and c_p
    are evaluated (use the mean of the two sides for large drops). Valid
    where the oil properties are (flags through ``log``).

    Examples
    --------
    Hand-checked, MIL-PRF-5606 throttled by 1 MPa at 40 degC:
    (1 - 8e-4 * 313.15) 1e6 / (847.7 * 1956.7) = 0.74948e6 / 1.6587e6 = 0.452 K.

    >>> round(float(isenthalpic_throttle_temperature_rise(1.0e6, 313.15, get_oil())), 3)
    0.452

    """
    rho = oil.density(T_K, p_Pa, log)
    cp = oil.specific_heat(T_K, log)
    return (1.0 - oil.alpha_p * np.asarray(T_K)) * np.multiply(dp_Pa, 1.0 / (rho * cp))
