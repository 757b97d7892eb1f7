"""
Unit conversions used across the package, each defined once.

The package works in SI units (kelvin inside the model, degC at its edges:
configuration, estimates, thermocouples); these are the few factors between
them and the units people read. A leaf module: it imports nothing from the
package, so any layer may use it.

>>> 20.0 + C_TO_K
293.15
>>> round(3000.0 * RPM, 3)
314.159
>>> round(6.0 * L_MIN * L_MIN_PER_M3_S, 12)
6.0
"""

import math

#: 0 degC in kelvin: add it to a temperature in degC to get kelvin.
C_TO_K = 273.15
#: rad/s per r/min.
RPM = math.pi / 30.0
#: r/min per rad/s (the inverse of :data:`RPM`).
RPM_PER_RAD_S = 30.0 / math.pi
#: m^3/s per L/min.
L_MIN = 1.0e-3 / 60.0
#: L/min per m^3/s (the inverse of :data:`L_MIN`, exact: 60 s/min times 1000 L/m^3).
L_MIN_PER_M3_S = 60000.0
#: rad/s per deg/s.
DEG_S = math.pi / 180.0
#: Pa per bar.
BAR = 1e5
#: Pa per kPa.
KPA = 1e3
#: Pa per MPa.
MPA = 1.0e6
#: Pa per psi (NIST SP 811: 1 lbf/in^2 = 6.894 757 293 168 kPa).
PSI = 6894.757293168
#: m per mm.
MM = 1e-3
#: A RMS per A of peak (amplitude) of a sinusoidal phase current: 1/sqrt(2).
A_PEAK = 1.0 / math.sqrt(2.0)

#: Units an input may be declared in, by name: (the SI unit it converts to, SI per unit).
#: ``A`` is RMS, as the estimator takes it; ``A_peak`` the amplitude of a sinusoidal phase
#: current (ros2_control drives often report it, or the q-axis current of a
#: amplitude-invariant Park transform, which is the same number).
BY_NAME = {
    'A': ('A', 1.0), 'A_rms': ('A', 1.0), 'A_peak': ('A', A_PEAK), 'mA': ('A', 1e-3),
    'rad/s': ('rad/s', 1.0), 'r/min': ('rad/s', RPM), 'rpm': ('rad/s', RPM),
    'deg/s': ('rad/s', DEG_S),
    'Pa': ('Pa', 1.0), 'kPa': ('Pa', KPA), 'MPa': ('Pa', MPA), 'bar': ('Pa', BAR),
    'psi': ('Pa', PSI),
    'm': ('m', 1.0), 'mm': ('m', MM),
    'K': ('K', 1.0), 'degC': ('K', 1.0), 'degF': ('K', 5.0 / 9.0),
}
#: The units whose zero is not the SI zero: the value of absolute zero in the unit, negated
#: (a reading ``x`` in the unit is ``(x + ZERO[unit]) * factor`` in SI: 20 degC is 293.15 K,
#: 68 degF is (68 + 459.67) * 5/9 = 293.15 K).
ZERO = {'degC': C_TO_K, 'degF': 459.67}
