"""Digital-twin thermal estimator for a wet electro-hydrostatic actuator (EHA)."""

__version__ = '0.1.0'
