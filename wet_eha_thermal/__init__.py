"""Digital-twin thermal estimator for a wet electro-hydrostatic actuator (EHA)."""

import os

__version__ = '0.1.0'

# The model's matrices are small (13 to 70 rows): OpenBLAS's threads cost more than they
# save there (the estimator's step took 2.2 ms with the default threads and 0.6 ms with
# one: benchmarks/bench_step.py with and without OPENBLAS_NUM_THREADS=1). Effective when
# this package is imported before numpy (every program of the package), and only where the
# user has not chosen otherwise.
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
