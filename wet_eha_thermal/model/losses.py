"""
Electromagnetic losses of the motor: copper (with its AC resistance) and stator iron.

The rotor's eddy-current losses (magnets, sleeve, solid core) and the PWM
ripple current are in :mod:`.rotor_losses`; oil friction lives in
:mod:`.correlations`. The laws of the per-step kernel are compiled
(:func:`~.compiled.jit`): the motor's losses kernel calls them; they take
floats or arrays.
"""

from typing import Optional

import numpy as np

from scipy.special import jv

from .compiled import jit
from .validity import check, ValidityLog
from ..units import C_TO_K

T_REF_COPPER_K = C_TO_K + 20.0  # reference of the phase resistance


@jit
def copper_resistance(r_20C_ohm, tempco_1_K, T_K):
    """
    Return a copper resistance (ohm) at ``T_K``: R_20 [1 + a (T - 20 degC)].

    Linear law, accurate to about 1 % from -50 to 200 degC for annealed copper
    (a = 0.00393 1/K).

    >>> round(float(copper_resistance(0.060, 0.00393, 373.15)), 5)
    0.07886
    """
    return r_20C_ohm * (1.0 + tempco_1_K * (T_K - T_REF_COPPER_K))


@jit
def electrical_frequency(speed_rad_s, pole_pairs: int):
    """
    Return the electrical frequency (Hz) of a machine at mechanical speed ``speed_rad_s``.

    >>> round(float(electrical_frequency(2 * np.pi * 10000 / 60, 4)), 2)    # 10 000 r/min
    666.67
    """
    return pole_pairs * np.abs(speed_rad_s) / (2.0 * np.pi)


@jit
def steinmetz_loss_density(frequency_Hz, flux_density_T, hysteresis_coeff: float,
                           exponent: float, eddy_coeff: float):
    """
    Return iron loss per kg (W/kg): k_h f B^alpha + k_e f^2 B^2 (Steinmetz split).

    Coefficients are per kg and fitted on the lamination's loss curves; the
    split holds for sinusoidal flux without DC bias in the fitted range of f
    and B (the caller's data sheet states it).

    >>> round(float(steinmetz_loss_density(400.0, 1.5, 0.012, 2.0, 1.0e-5)), 2)
    14.4
    """
    return (hysteresis_coeff * frequency_Hz * flux_density_T ** exponent
            + eddy_coeff * frequency_Hz ** 2 * flux_density_T ** 2)


#: Resistivity of annealed copper at 20 degC (IEC 60028), ohm m.
COPPER_RESISTIVITY_20C_OHM_M = 1.7241e-8


#: Permeability of free space (H/m).
MU0_H_M = 4.0e-7 * np.pi


def copper_ac_factor(frequency_Hz, diameter_m: float, layers: int, porosity: float,
                     resistivity_ohm_m: float = COPPER_RESISTIVITY_20C_OHM_M,
                     log: Optional[ValidityLog] = None):
    """
    Return R_ac / R_dc of a coil side of ``layers`` rows of round wire in a slot.

    J. A. Ferreira, "Improved analytical modeling of conductive losses in
    magnetic components", IEEE Trans. Power Electron. 9(1), 1994: the skin and
    proximity losses of a round wire are orthogonal and each exact through
    Kelvin functions of gamma = d / (sqrt(2) delta), delta = sqrt(rho / (pi f
    mu0)) the skin depth:
    F_R = (gamma / 2) tau_1 - (pi^2 / 12) eta^2 (4 p^2 - 1) gamma tau_2,
    tau_1 = (ber bei' - bei ber') / (ber'^2 + bei'^2),
    tau_2 = (ber_2 ber' + bei_2 bei') / (ber^2 + bei^2) (all at gamma).
    The first term is the isolated wire's skin effect; the second the proximity
    loss of each wire in the slot's one-dimensional leakage field, which grows
    from the slot bottom by n I / b per row (n wires in a row across the slot's
    breadth b, eta = n d / b the porosity): row m sees (m - 1/2) n I / b at its
    wires' centres, and the mean of (m - 1/2)^2 over p rows is (4 p^2 - 1) / 12.
    Ferreira's own coefficient is 2 pi eta^2 (4 p^2 - 1) / 3, 4 / pi times this
    one: here it is taken from the slot field so that the low-frequency limit
    is the exact eddy loss of a round wire in a uniform field, pi sigma omega^2
    B^2 d^4 / 128 (test_rotor_losses checks both limits). Low frequency:
    F_R - 1 = (d / delta)^4 [1 + pi^2 eta^2 (4 p^2 - 1)] / 768, which scales as
    1 / rho^2: the excess loss, R_dc (F_R - 1) I^2, as 1 / rho (resistance
    limited). The field is one-dimensional and the currents of the slot's
    coil sides in phase (an upper bound where two phases share a slot); flagged
    past d / delta = 3. ``frequency_Hz`` may be an array.

    >>> # 0.8 mm wire, 14 rows, eta 0.38, 20 kHz: proximity dominates
    >>> round(float(copper_ac_factor(20e3, 0.8e-3, 14, 0.38)), 2)
    12.77
    >>> # 1333 Hz (20 000 r/min, 4 pole pairs)
    >>> round(float(copper_ac_factor(1333.0, 0.8e-3, 14, 0.38)), 4)
    1.0555
    """
    f = np.asarray(frequency_Hz, float)
    delta = np.sqrt(resistivity_ohm_m / (np.pi * np.maximum(f, 1e-300) * MU0_H_M))
    check(log, 'Ferreira copper AC resistance', 'd/delta', diameter_m / delta, 0.0, 3.0,
          'round wire past d/delta = 3: the one-dimensional slot field is a rough picture')
    g = np.minimum(diameter_m / (np.sqrt(2.0) * delta), 100.0)
    z0 = jv(0, g * np.exp(0.75j * np.pi))           # ber + j bei
    z1 = jv(1, g * np.exp(0.75j * np.pi))
    z2 = jv(2, g * np.exp(0.75j * np.pi))
    zp = -z1 * np.exp(0.75j * np.pi)                # ber' + j bei' (the chain rule on J_0)
    tau1 = (z0.real * zp.imag - z0.imag * zp.real) / (zp.real ** 2 + zp.imag ** 2)
    tau2 = (z2.real * zp.real + z2.imag * zp.imag) / (z0.real ** 2 + z0.imag ** 2)
    exact = 0.5 * g * tau1 - np.pi ** 2 / 12.0 * porosity ** 2 * (4.0 * layers ** 2 - 1.0) \
        * g * tau2
    # below gamma = 0.05 the Kelvin terms cancel to rounding: their series
    small = (diameter_m / delta) ** 4 / 768.0 * (
        1.0 + np.pi ** 2 * porosity ** 2 * (4.0 * layers ** 2 - 1.0))
    return np.where(g < 0.05, 1.0 + small, exact)
