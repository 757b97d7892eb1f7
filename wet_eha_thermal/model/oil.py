"""
Hydraulic oil properties versus temperature and pressure.

Units are SI throughout: temperature ``T_K`` in kelvin, pressure ``p_Pa`` in
pascal *gauge* (above atmospheric; the property data are quoted at
atmospheric pressure), density in kg/m^3, kinematic viscosity in m^2/s,
dynamic viscosity in Pa s, specific heat in J/(kg K), conductivity in
W/(m K). Every function accepts floats or numpy arrays (broadcast together).

Models (docs/model.md, Oil properties):

- density: rho = rho_15 [1 - alpha_p (T - 288.15 K)] (1 + p / K), with K the
  isothermal *secant* bulk modulus (the one that gives the density change
  from 0 to p in one step; the isentropic tangent modulus is about 10 %
  higher and belongs in wave-speed calculations, not here).
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

#: 0 degC in kelvin.
T0_K = 273.15
#: Reference temperature of the density data (15 degC) in kelvin.
T15_K = 288.15
#: Density of water at 15 degC (kg/m^3), the reference of the specific gravity.
RHO_WATER_15 = 999.1
#: Pressure range over which the linear density law and the Barus factor are
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

    rho = rho15 [1 - alpha (T - 288.15)] (1 + p inv_k); Walther lines
    ``(a_hot, b_hot)`` for T >= 40 degC and ``(a_cold, b_cold)`` below, Barus
    coefficient ``barus`` (1/Pa); c_p = c0 + c1 t_C; k = k0 + k1 t_C.
    """

    rho15: float
    alpha: float
    inv_k: float
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
def density(T_K, p_Pa, laws):
    """Return rho (kg/m^3) as :meth:`Oil.density` does (floats or arrays, no checks)."""
    return laws[0] * (1.0 - laws[1] * (T_K - T15_K)) * (1.0 + p_Pa * laws[2])


@jit
def kinematic_viscosity(T_K, p_Pa, laws):
    """Return nu (m^2/s) of :meth:`Oil.kinematic_viscosity` (floats or arrays, no checks)."""
    log_t = np.log10(T_K)
    z = np.where(T_K >= T0_K + 40.0, laws[3] - laws[4] * log_t, laws[5] - laws[6] * log_t)
    nu_cst = np.power(10.0, np.power(10.0, z)) - 0.7
    return 1.0e-6 * nu_cst * np.exp(laws[7] * p_Pa)


@jit
def specific_heat(T_K, laws):
    """Return c_p (J/(kg K)) of :meth:`Oil.specific_heat` (floats or arrays, no checks)."""
    return laws[8] + laws[9] * (T_K - T0_K)


@jit
def _rho_cp_coefficients(p_Pa, laws):
    """Return (a, b, c) of rho(T, p) c_p(T) = a + b T + c T^2, T in K (J/(m^3 K))."""
    r1 = -laws[0] * laws[1] * (1.0 + p_Pa * laws[2])        # rho = r0 + r1 T
    r0 = laws[0] * (1.0 + p_Pa * laws[2]) - r1 * T15_K
    d0 = laws[8] - laws[9] * T0_K                              # c_p = d0 + d1 T
    return r0 * d0, r0 * laws[9] + r1 * d0, r1 * laws[9]


@jit
def volumetric_energy(T_K, p_Pa, laws):
    """
    Return e(T) = int_0^T rho(T', p) c_p(T') dT' (J/m^3), T in K, at a fixed pressure.

    The energy of a unit volume of oil filled at pressure ``p_Pa``: what a
    volume holds and what a flow carries, so that books kept in ``e`` close
    exactly whatever the temperatures (rho c_p moves by about 0.1 %/K).
    Only differences mean anything.

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
    a, b, c = _rho_cp_coefficients(p_Pa, laws)
    return T_K * (a + T_K * (0.5 * b + T_K * (c / 3.0)))


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
    a, b, c = _rho_cp_coefficients(p_Pa, laws)
    T = T_guess_K.copy()
    for _ in range(3):       # from a guess within a few K: converged to rounding in two
        T -= (T * (a + T * (0.5 * b + T * (c / 3.0))) - e) / (a + T * (b + T * c))
    return T


@jit
def conductivity(T_K, laws):
    """Return k (W/(m K)) of :meth:`Oil.conductivity` (floats or arrays, no checks)."""
    return laws[10] + laws[11] * (T_K - T0_K)


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
    :ivar bulk_modulus_Pa: isothermal secant bulk modulus (Pa) over 0..35 MPa.
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
    bulk_modulus_Pa: float
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
        return walther_fit(T0_K + 40.0, self.nu_40_cSt, T0_K + 100.0, self.nu_100_cSt)

    @property
    def walther_cold(self) -> Tuple[float, float]:
        """Return the Walther ``(A, B)`` through the cold datum and 40 degC (T < 40 degC)."""
        return walther_fit(self.T_cold_K, self.nu_cold_cSt, T0_K + 40.0, self.nu_40_cSt)


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
                                  1.0 / grade.bulk_modulus_Pa, *grade.walther_hot,
                                  *grade.walther_cold, grade.barus_1_Pa, *grade.cp_J_kgK,
                                  *grade.k_W_mK))
        self._alpha = grade.alpha_p_1_K
        self._t_lo = grade.T_min_K
        self._t_hi = grade.T_max_K
        self._t_note = (f'{grade.name} property data valid for '
                        f'{grade.T_min_K - T0_K:.0f}..{grade.T_max_K - T0_K:.0f} degC; '
                        'value extrapolated')
        self._p_note = ('linear density law and Barus viscosity factor accepted over '
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

    @property
    def bulk_modulus(self) -> float:
        """Return the isothermal secant bulk modulus K (Pa)."""
        return self.grade.bulk_modulus_Pa

    def _check_T(self, log: Optional[ValidityLog], what: str, T_K) -> None:
        check(log, f'{self.grade.name} {what}', 'T_K', T_K, self._t_lo, self._t_hi,
              self._t_note)

    def _check_p(self, log: Optional[ValidityLog], what: str, p_Pa) -> None:
        check(log, f'{self.grade.name} {what}', 'p_Pa', p_Pa, P_MIN_PA, P_MAX_PA,
              self._p_note)

    def density(self, T_K, p_Pa=0.0, log: Optional[ValidityLog] = None):
        """
        Return the density rho(T, p) in kg/m^3.

        rho = rho_15 [1 - alpha_p (T - 288.15 K)] (1 + p / K), docs/model.md
        (Oil properties); alpha_p and K constant (first-order expansion about
        15 degC and 0 Pa gauge). Validity: the grade's temperature range and
        0..35 MPa.

        Examples
        --------
        MIL-PRF-5606: its datum 865 kg/m^3 at 15 degC and, hand-checked, at
        40 degC and 21 MPa 865 (1 - 8e-4 * 25) (1 + 21e6 / 1.4e9) = 865 *
        0.98 * 1.015 = 860.4 kg/m^3.

        >>> oil = get_oil('MIL-PRF-5606')
        >>> round(float(oil.density(288.15)), 6), round(float(oil.density(313.15, 21.0e6)), 1)
        (865.0, 860.4)

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
        bulk_modulus_Pa=1.4e9,
        nu_cold_cSt=495.0,
        nu_40_cSt=13.5,
        nu_100_cSt=5.1,
        T_cold_K=T0_K - 40.0,
        barus_1_Pa=1.5e-8,
        cp_J_kgK=cp,
        k_W_mK=k,
        T_min_K=T0_K - 54.0,
        T_max_K=T0_K + 135.0,
        source_notes=(
            'Petroleum base, VI-improved (NATO H-515). Viscosity: typical values of '
            'qualified fluids: 13.5 cSt at 40 degC, 5.1 cSt at 100 degC, '
            '495 cSt at -40 degC (spec limits: >= 10.0, >= 4.90, <= 600 cSt). '
            'rho_15 865 kg/m^3 (typical data sheets 0.86-0.87). alpha_p 8e-4 1/K (est.). '
            'Bulk modulus: isothermal secant, 0..35 MPa at about 40 degC, 1.4 GPa (est.; '
            'isentropic tangent about 1.5 GPa). Barus a_p 1.5e-8 1/Pa (est., typical of '
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
        bulk_modulus_Pa=1.45e9,
        nu_cold_cSt=2050.0,
        nu_40_cSt=14.2,
        nu_100_cSt=3.6,
        T_cold_K=T0_K - 40.0,
        barus_1_Pa=1.3e-8,
        cp_J_kgK=cp,
        k_W_mK=k,
        T_min_K=T0_K - 40.0,
        T_max_K=T0_K + 205.0,
        source_notes=(
            'Synthetic hydrocarbon (PAO) base, fire resistant (NATO H-537). Viscosity '
            '(est.): 14.2 cSt at 40 degC, 3.6 cSt at 100 degC, 2050 cSt at -40 degC, '
            'chosen a little inside the spec limits (>= 14.0, >= 3.45, <= 2200 cSt) as '
            'typical of qualified products; replace with the batch data sheet. '
            'rho_15 845 kg/m^3, alpha_p 7.8e-4 1/K, secant bulk modulus 1.45 GPa, '
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
