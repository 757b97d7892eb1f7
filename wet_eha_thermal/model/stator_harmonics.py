"""
The stator's current sheet harmonics: the winding's space harmonics and the inverter's PWM.

What the armature puts on the bore besides its fundamental, for the rotor's
eddy-current losses (:mod:`.rotor_losses`) and the copper's AC resistance:
the space harmonics of a concentrated winding's MMF (its winding factors by
order and their directions) and the time harmonics of the phase current
under sine-triangle PWM (the double Fourier series of Holmes and Lipo, the
ripple current each sideband drives through the machine's inductance, and
Dowell's AC factor over them). Sources are named where each is used.

SI units: speed in rad/s, current in A RMS, frequency in Hz or rad/s as named.
"""

from typing import Optional

import numpy as np
from scipy.special import jv

from .losses import copper_ac_factor
from .validity import check, ValidityLog
from .winding import winding_layout

#: PWM carrier groups kept (m = 1..PWM_CARRIER_GROUPS); the rotor loss of group m falls
#: about as 1/m^2 before skin effect and faster after it. On the reference rig, 8 groups
#: give the sleeve loss 1.1 to 1.5 % below 24 groups (magnets 0.4 to 0.6 %, core 0.2 %).
PWM_CARRIER_GROUPS = 8
#: Sidebands kept either side of each carrier multiple, beyond the Bessel argument.
PWM_SIDEBAND_MARGIN = 12


# --------------------------------------------------------------- winding
def winding_coefficients(slots: int, pole_pairs: int, orders, phases: int = 3):
    """
    Return the complex Fourier coefficients of each phase's conductors and its coil count.

    Double-layer tooth-coil winding: each tooth carries one coil, conductors in
    the two (narrow) slots beside it; coils go to phases by the star of slots
    (coil EMF angle = pole_pairs x tooth angle, phase belts of 180/phases
    degrees: A+, C-, B+, A-, C+, B- for three phases), the standard layout of
    fractional-slot concentrated windings (12 slots / 8 poles: A B C A B C ...).
    Returns ``(coeff, coils)``: coeff[phase, k] = sum over the phase's slots of
    turns x exp(-j order_k theta_slot) per turn of a coil, and coils the number
    of coils of each phase. The winding factor of order nu is
    |coeff| / (2 coils).

    >>> c, n = winding_coefficients(12, 4, [4, 8])
    >>> [round(float(abs(x) / (2 * n[0])), 3) for x in c[0]]     # k_w1 = k_w8 = 0.866
    [0.866, 0.866]
    """
    if phases % 2 == 0:
        raise ValueError('the star-of-slots layout here needs an odd number of phases')
    orders = np.asarray(orders, float)
    tooth = 2.0 * np.pi * (np.arange(slots) + 0.5) / slots
    belt = np.round(pole_pairs * tooth / (np.pi / phases)).astype(int) % (2 * phases)
    sign = np.where(belt % 2 == 0, 1.0, -1.0)
    phase = np.where(belt % 2 == 0, belt, (belt + phases) % (2 * phases)) // 2
    slot_angle = 2.0 * np.pi * np.arange(slots) / slots
    coeff = np.zeros((phases, orders.size), complex)
    for k in range(slots):
        for s, side in ((k, 1.0), ((k + 1) % slots, -1.0)):
            coeff[phase[k]] += sign[k] * side * np.exp(-1j * orders * slot_angle[s])
    return coeff, np.bincount(phase, minlength=phases)


def winding_harmonics(slots: int, pole_pairs: int, phases: int = 3, max_order: int = 200):
    """
    Return the travelling waves of the current sheet of a tooth-coil winding.

    Balanced sinusoidal phase currents of positive sequence (phase k lagging
    by 2 pi k / phases) in the winding of :func:`winding_coefficients` make,
    for each order nu (cycles per turn), a wave forward (direction +1, with
    the fundamental) of amplitude |sum_k coeff_k(nu) exp(j 2 pi k / phases)|
    and one backward (-1) with exp(-j ...). Returns ``(order, direction,
    amplitude)`` of the waves present, amplitude relative to the fundamental
    (order pole_pairs, forward): for narrow slots, the ratio of the
    harmonic's winding factor to the fundamental's.

    >>> nu, d, k = winding_harmonics(12, 4, max_order=20)
    >>> [(int(n), int(s), round(float(a), 3)) for n, s, a in zip(nu, d, k)]
    [(4, 1, 1.0), (8, -1, 1.0), (16, 1, 1.0), (20, -1, 1.0)]
    """
    orders = np.arange(1, max_order + 1)
    coeff, _ = winding_coefficients(slots, pole_pairs, orders, phases)
    lag = 2.0 * np.pi * np.arange(phases) / phases
    fwd = np.abs(np.sum(coeff * np.exp(1j * lag)[:, None], axis=0))
    bwd = np.abs(np.sum(coeff * np.exp(-1j * lag)[:, None], axis=0))
    if fwd[pole_pairs - 1] < bwd[pole_pairs - 1]:
        fwd, bwd = bwd, fwd
    ref = fwd[pole_pairs - 1]
    nu = np.concatenate([orders, orders])
    direction = np.concatenate([np.ones(orders.size), -np.ones(orders.size)])
    amp = np.concatenate([fwd, bwd]) / ref
    keep = amp > 1e-9
    order = np.lexsort((-direction[keep], nu[keep]))
    return nu[keep][order], direction[keep][order].astype(int), amp[keep][order]


# --------------------------------------------------------------- PWM
def modulation_index(motor, speed_rad_s, current_A):
    """
    Return the sine-PWM modulation index at an operating point (peak phase voltage / (V_dc/2)).

    Current in phase with the back-EMF (i_d = 0, surface PM): back-EMF
    E = k_t |omega_m| / phases (RMS; phases x E x I = torque x speed), phase
    voltage V = |E + (R_20 + j omega_1 L) I| (R at 20 degC), M = sqrt(2) V /
    (V_dc / 2). Broadcasts speed against current.

    >>> from wet_eha_thermal.config import load_config
    >>> m = load_config().motor
    >>> round(float(modulation_index(m, 2 * np.pi * 20000 / 60, 15.0)), 3)
    0.925
    """
    em, wdg = motor.electromagnetic, motor.winding
    speed = np.abs(np.asarray(speed_rad_s, float))
    current = np.asarray(current_A, float)
    emf = motor.torque_constant_Nm_A * speed / wdg.phases
    w1 = motor.pole_pairs * speed
    volt = np.hypot(emf + wdg.phase_resistance_20C_ohm * current,
                    w1 * em.phase_inductance_H * current)
    return np.sqrt(2.0) * volt / (em.dc_link_voltage_V / 2.0)


def pwm_sidebands(max_modulation: float, groups: int = PWM_CARRIER_GROUPS):
    """
    Return the (m, n) harmonics of a two-level sine-PWM inverter's phase voltage.

    Naturally sampled sine-triangle PWM of one leg (H. S. Black, "Modulation
    theory", 1953; D. G. Holmes and T. A. Lipo, "Pulse width modulation for
    power converters", IEEE Press / Wiley, 2003, ch. 3): harmonics at
    m omega_c + n omega_1 with amplitude (2 V_dc / (m pi)) J_n(m pi M / 2)
    sin((m + n) pi / 2), i.e. m + n odd. Into a star load with floating
    neutral the zero-sequence ones (n a multiple of 3) cancel; n = 1 mod 3 is
    of positive sequence, n = 2 mod 3 of negative. Kept: m = 1..groups,
    |n| up to the Bessel argument plus a margin. Returns (m, n, sequence).

    >>> m, n, s = pwm_sidebands(0.9, groups=1)
    >>> sorted(int(k) for k in n if abs(k) <= 4)
    [-4, -2, 2, 4]
    """
    out = []
    for m in range(1, groups + 1):
        top = int(np.ceil(m * np.pi * max(max_modulation, 1e-3) / 2.0)) + PWM_SIDEBAND_MARGIN
        for n in range(-top, top + 1):
            if (m + n) % 2 == 1 and n % 3 != 0:
                out.append((m, n, 1 if n % 3 == 1 else -1))
    arr = np.array(out, dtype=int)
    return arr[:, 0], arr[:, 1], arr[:, 2]


def pwm_current_harmonics(motor, speed_rad_s, current_A, log: Optional[ValidityLog] = None):
    """
    Return the PWM harmonics of the phase current at operating points.

    Voltage harmonics of :func:`pwm_sidebands` at the modulation index of
    :func:`modulation_index`, each driving its current through the phase's
    R + j omega L (the back-EMF has no harmonic at those frequencies; R at
    20 degC). Returns a dict: 'm', 'n', 'sequence' (H,), 'omega_rad_s'
    (signed m omega_c + n omega_1, shape (..., H)), 'current_A' (peak, shape
    (..., H)) and 'modulation_index'. Flags M past 1: the series holds for the
    linear range of sine PWM only (overmodulation changes the spectrum).
    """
    em = motor.electromagnetic
    mod = modulation_index(motor, speed_rad_s, current_A)
    check(log, 'sine-PWM ripple', 'modulation index', mod, 0.0, 1.0,
          'overmodulation: the linear-range double Fourier series is extrapolated')
    m, n, seq = pwm_sidebands(float(np.max(mod)))
    w1 = motor.pole_pairs * np.abs(np.asarray(speed_rad_s, float))
    wc = 2.0 * np.pi * em.pwm_frequency_Hz
    omega = m * wc + n * np.asarray(w1)[..., None]
    arg = m * np.pi * mod[..., None] / 2.0
    volt = (2.0 * em.dc_link_voltage_V / (m * np.pi)) * np.abs(jv(n, arg))
    imp = np.hypot(motor.winding.phase_resistance_20C_ohm, omega * em.phase_inductance_H)
    omega = np.broadcast_to(omega, volt.shape)
    return {'m': m, 'n': n, 'sequence': seq, 'omega_rad_s': omega, 'current_A': volt / imp,
            'modulation_index': mod}


def pwm_ripple_current_rms_A(motor, speed_rad_s, current_A, log: Optional[ValidityLog] = None):
    """
    Return the RMS of the phase current's PWM ripple (A) at operating points.

    sqrt(sum I_h^2 / 2) over :func:`pwm_current_harmonics` (peak amplitudes).
    Checked against a time-domain simulation of the switched inverter in
    ``test/test_rotor_losses.py``.

    >>> from wet_eha_thermal.config import load_config
    >>> m = load_config().motor
    >>> float(pwm_ripple_current_rms_A(m, 0.0, 0.0))    # M = 0: the legs switch alike
    0.0
    >>> # 10 000 r/min, 15 A: the switched simulation gives 1.11 A too (within 2 %)
    >>> round(float(pwm_ripple_current_rms_A(m, 2 * np.pi * 10000 / 60, 15.0)), 2)
    1.11
    """
    h = pwm_current_harmonics(motor, speed_rad_s, current_A, log)
    return np.sqrt(np.sum(h['current_A'] ** 2, axis=-1) / 2.0)


def pwm_ripple_ac_factor(motor, speed_rad_s, current_A, log: Optional[ValidityLog] = None):
    """
    Return the copper AC factor of the ripple: sum F_R(f_h) I_h^2 / sum I_h^2.

    F_R of :func:`~.losses.copper_ac_factor` at each harmonic's frequency, so
    that the ripple's copper loss is phases R I_ripple^2 times this factor
    (F_R at the switching frequency alone misses the sidebands of 2 f_sw).
    """
    h = pwm_current_harmonics(motor, speed_rad_s, current_A, log)
    wdg, lay = motor.winding, winding_layout(motor)
    fr = copper_ac_factor(np.abs(h['omega_rad_s']) / (2.0 * np.pi), wdg.conductor_diameter_m,
                          lay.rows, lay.porosity, log=log)
    sq = h['current_A'] ** 2
    total = np.sum(sq, axis=-1)
    return np.where(total > 0, np.sum(fr * sq, axis=-1) / np.where(total > 0, total, 1.0), 1.0)
