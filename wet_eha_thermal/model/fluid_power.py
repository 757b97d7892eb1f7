"""
Fluid-power relations of the EHA: pump flow, leakage, pump friction, line losses.

Shared by the kinetic simulator (which makes sensor-like signals from a duty)
and the thermal model (which derives flows and losses from those signals, as
the live estimator does from the rig's sensors), so both use one physics.
Signs: a positive speed makes the pump deliver into port A.
"""

from typing import Optional

import numpy as np

from .compiled import jit
from .correlations import PIPE_RE_LAMINAR, PIPE_RE_TURBULENT
from .validity import check, ValidityLog


def displacement_per_rad(displacement_m3_rev: float) -> float:
    """Return the pump displacement per radian (m^3/rad)."""
    return displacement_m3_rev / (2.0 * np.pi)


#: Churchill-Usagi exponent of the blend of the laminar gap law and the orifice law
GAP_BLEND_EXPONENT = 8.0
#: Gap Reynolds number (hydraulic diameter 2 h) up to which the laminar gap law holds
GAP_LAMINAR_RE = 2000.0
#: Line Reynolds number up to which Blasius's smooth-tube friction factor holds
BLASIUS_RE_MAX = 1.0e5


@jit
def gap_leakage(coeff_m3, dp_Pa, mu_Pa_s, rho, height_m, length_m, discharge_coeff):
    """
    Return a gap leakage flow (m^3/s, signed like ``dp``) and its gap Reynolds number.

    Laminar, the flow through a gap of width b, height h and length l is
    Q_L = C dp / mu with C = b h^3 / (12 l) (or fitted); at high Reynolds
    numbers it tends to the orifice law Q_T = C_d A sqrt(2 |dp| / rho) of its
    section A = b h (docs/model.md, Flows and pressures). The two are
    blended as S. W. Churchill and R. Usagi, "A general expression for the
    correlation of rates of transfer and other phenomena", AIChE J. 18(6),
    1972, 1121-1128, propose: Q = Q_L (1 + (Q_L / Q_T)^n)^(-1/n), n =
    GAP_BLEND_EXPONENT (8, a modelling choice: the laminar law within 1.2 %
    up to Re_gap 2000 with the reference gap), continuous and monotonic in dp,
    the laminar law as dp -> 0 and the orifice law as dp grows.

    The gap's width follows from C: b = 12 C l / h^3, so that the Reynolds
    number of the mean velocity on the hydraulic diameter 2 h,
    Re_gap = 2 rho |Q| / (mu b), is rho h^3 |dp| / (6 l mu^2) while laminar,
    and (Q_L / Q_T)^2 = Re_L / Re_x with Re_x = 48 C_d^2 l / h, where the two
    laws cross: neither depends on C. Valid (laminar law) for Re_gap below
    about 2000 (GAP_LAMINAR_RE; :func:`check_gap_leakage` flags the rest);
    the orifice law's C_d is an estimate for a gap.

    :param coeff_m3: laminar coefficient C (m^3).
    :param dp_Pa: pressure difference across the gap (Pa).
    :param mu_Pa_s: dynamic viscosity (Pa s).
    :param rho: density (kg/m^3).
    :param height_m: gap height h (m).
    :param length_m: gap length l along the flow (m).
    :param discharge_coeff: C_d of the orifice law.
    :return: ``(Q m^3/s, Re_gap)``.

    Examples
    --------
    Hand-checked, the reference pump's external path (C 9e-15 m^3, h 10 um,
    l 2 mm, C_d 0.61) at 21 MPa, with rho 861.3 kg/m^3 and mu 11.59 mPa s
    (MIL-PRF-5606 near 40 degC): Q_L = 9e-15 * 21e6 /
    0.01159 = 1.6307e-5 m^3/s (0.978 L/min), Re_L = 861.3 * 1e-15 * 21e6 /
    (6 * 2e-3 * 0.01159^2) = 11.22, Re_x = 48 * 0.61^2 * 200 = 3572.2, the
    blend factor (1 + (11.22 / 3572.2)^4)^(-1/8) = 1 - 1.2e-11: laminar.

    >>> q, re = gap_leakage(9e-15, 21e6, 0.01159, 861.3, 1e-5, 2e-3, 0.61)
    >>> round(q * 6e4, 3), round(re, 2)
    (0.978, 11.22)

    At 21 MPa and 1000 times less viscous oil (Re_L 1.12e7) the flow is the
    orifice law's: A = 12 * 9e-15 * 2e-3 / 1e-10 = 2.16e-6 m^2,
    Q_T = 0.61 * 2.16e-6 * sqrt(2 * 21e6 / 861.3) = 2.9096e-4 m^3/s.

    >>> q, _ = gap_leakage(9e-15, 21e6, 1.159e-5, 861.3, 1e-5, 2e-3, 0.61)
    >>> round(q * 1e4, 4)
    2.9096

    """
    re_lam = rho * height_m ** 3 * np.abs(dp_Pa) / (6.0 * length_m * mu_Pa_s ** 2)
    re_cross = 48.0 * discharge_coeff ** 2 * length_m / height_m
    blend = (1.0 + (re_lam / re_cross) ** (0.5 * GAP_BLEND_EXPONENT)) ** (
        -1.0 / GAP_BLEND_EXPONENT)
    return coeff_m3 * dp_Pa / mu_Pa_s * blend, re_lam * blend


def check_gap_leakage(log: Optional[ValidityLog], re) -> None:
    """Flag gap Reynolds numbers where :func:`gap_leakage` leaves the laminar gap law."""
    check(log, 'pump leakage gap (laminar gap law)', 'Re_gap', re, 0.0, GAP_LAMINAR_RE,
          'beyond laminar: blended toward the orifice law Q = C_d A sqrt(2 dp / rho) (C_d est.)')


@jit
def pump_friction_torque(speed_rad_s, dp_Pa, mu_Pa_s, displacement_m3_rad: float,
                         viscous_coeff: float, pressure_coeff: float, coulomb_Nm: float):
    """
    Return the pump friction torque magnitude (N m): C_v mu D |w| + C_f D |dp| + T_c.

    Lumped loss model of docs/model.md (hydraulic control volumes) (viscous, pressure-proportional
    and Coulomb parts, D per radian); it always opposes the motion, so the
    loss power is this torque times |w|.
    """
    return (viscous_coeff * mu_Pa_s * displacement_m3_rad * np.abs(speed_rad_s)
            + pressure_coeff * displacement_m3_rad * np.abs(dp_Pa) + coulomb_Nm)


def line_pressure_drop(flow_m3_s, length_m: float, bore_m: float, rho, mu,
                       log: Optional[ValidityLog] = None):
    """
    Return the pressure drop (Pa) of a straight line, signed like the flow.

    Darcy friction factor: 64/Re laminar (Re <= PIPE_RE_LAMINAR, 2300), Blasius
    0.316 Re^-0.25 turbulent (Re >= PIPE_RE_TURBULENT, 4000; smooth tube, valid to
    BLASIUS_RE_MAX, 1e5), linear blend between. Fittings and bends are not included.
    """
    q = np.asarray(flow_m3_s, dtype=float)
    dp, re = line_pressure_drop_kernel(q.reshape(-1), length_m, bore_m, rho, mu)
    check_line_pressure_drop(log, re)
    return dp.reshape(q.shape)


def check_line_pressure_drop(log: Optional[ValidityLog], re) -> None:
    """Flag line Reynolds numbers outside the validity of :func:`line_pressure_drop`."""
    check(log, 'line friction (Blasius)', 'Re', re, 0.0, BLASIUS_RE_MAX,
          'above the smooth-tube range')


@jit
def line_pressure_drop_kernel(flow_m3_s, length_m, bore_m, rho, mu):
    """Return the (dp Pa, Re) of :func:`line_pressure_drop` for a 1-D array of flows; no checks."""
    area = 0.25 * np.pi * bore_m ** 2
    v = np.abs(flow_m3_s) / area
    re = rho * v * bore_m / mu
    re_safe = np.maximum(re, 1e-12)
    f = 64.0 / re_safe
    if not (re <= PIPE_RE_LAMINAR).all():        # laminar throughout is the usual case
        f_turb = 0.316 * np.maximum(re_safe, PIPE_RE_LAMINAR) ** -0.25
        blend = np.minimum(np.maximum((re - PIPE_RE_LAMINAR)
                                      / (PIPE_RE_TURBULENT - PIPE_RE_LAMINAR), 0.0), 1.0)
        f = np.where(re <= PIPE_RE_LAMINAR, f,
                     (1.0 - blend) * 64.0 / PIPE_RE_LAMINAR + blend * f_turb)
        f = np.where(re >= PIPE_RE_TURBULENT, f_turb, f)
    return np.sign(flow_m3_s) * f * (length_m / bore_m) * 0.5 * rho * v ** 2, re
