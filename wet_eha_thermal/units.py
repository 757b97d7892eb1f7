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
#: Pa per MPa.
MPA = 1.0e6
