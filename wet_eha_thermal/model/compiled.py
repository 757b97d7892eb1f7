"""
Compile the model's per-step numerics with numba when it is installed.

A model step is a few hundred small numpy operations on arrays of one step's
samples (tens of values); called from Python each costs about a microsecond
of overhead, which is most of the step. The functions marked :func:`jit` are
written in numpy array style that numba's nopython mode also compiles, so the
same source runs compiled (cached on disk after the first run) or, where
numba is missing, as the plain numpy code it is, slower, with the same
results to rounding. numba is in requirements.txt; on a ROS install it is
optional because rosdep has no key for it on Ubuntu Noble (``apt install
python3-numba`` or ``pip install numba`` brings the speed).
"""

try:
    import numba
except ImportError:         # pragma: no cover - the pip path installs numba
    numba = None

#: True when the :func:`jit` functions run compiled.
COMPILED = numba is not None and not numba.config.DISABLE_JIT


def jit(func):
    """Compile ``func`` in nopython mode, cached on disk; without numba, return it as it is."""
    if numba is None:       # pragma: no cover
        return func
    return numba.njit(cache=True)(func)


def interpreted(func):
    """Return the Python source function of a :func:`jit` function (cheaper on a few floats)."""
    return getattr(func, 'py_func', func)
