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
from .validity import check, ValidityLog


def displacement_per_rad(displacement_m3_rev: float) -> float:
    """Return the pump displacement per radian (m^3/rad)."""
    return displacement_m3_rev / (2.0 * np.pi)


@jit
def laminar_leakage(coeff_m3, dp_Pa, mu_Pa_s):
    """
    Return a laminar gap leakage flow (m^3/s), Q = C dp / mu, signed like ``dp``.

    C = b h^3 / (12 l) for a gap of width b, height h and length l, or a
    fitted value; valid while the gap flow stays laminar (Re_gap < ~2000).
    """
    return coeff_m3 * dp_Pa / mu_Pa_s


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

    Darcy friction factor: 64/Re laminar (Re <= 2300), Blasius 0.316 Re^-0.25
    turbulent (Re >= 4000, smooth tube, valid to Re = 1e5), linear blend
    between. Fittings and bends are not included.
    """
    q = np.asarray(flow_m3_s, dtype=float)
    dp, re = line_drop_and_reynolds(q.reshape(-1), length_m, bore_m, rho, mu)
    check_line_reynolds(log, re)
    return dp.reshape(q.shape)


def check_line_reynolds(log: Optional[ValidityLog], re) -> None:
    """Flag line Reynolds numbers outside the validity of :func:`line_pressure_drop`."""
    check(log, 'line friction (Blasius)', 'Re', re, 0.0, 1e5, 'above the smooth-tube range')


@jit
def line_drop_and_reynolds(flow_m3_s, length_m, bore_m, rho, mu):
    """Return the (dp Pa, Re) of :func:`line_pressure_drop` for a 1-D array of flows; no checks."""
    area = 0.25 * np.pi * bore_m ** 2
    v = np.abs(flow_m3_s) / area
    re = rho * v * bore_m / mu
    re_safe = np.maximum(re, 1e-12)
    f = 64.0 / re_safe
    if not (re <= 2300.0).all():        # laminar throughout is the usual case
        f_turb = 0.316 * np.maximum(re_safe, 2300.0) ** -0.25
        blend = np.minimum(np.maximum((re - 2300.0) / 1700.0, 0.0), 1.0)
        f = np.where(re <= 2300.0, f, (1.0 - blend) * 64.0 / 2300.0 + blend * f_turb)
        f = np.where(re >= 4000.0, f_turb, f)
    return np.sign(flow_m3_s) * f * (length_m / bore_m) * 0.5 * rho * v ** 2, re
