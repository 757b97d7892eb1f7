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
"""

import math

#: 0 degC in kelvin: add it to a temperature in degC to get kelvin.
C_TO_K = 273.15
#: rad/s per r/min.
RPM = math.pi / 30.0
