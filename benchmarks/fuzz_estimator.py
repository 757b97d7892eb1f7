"""
Ten minutes of fuzz against the estimator core: nothing raised, memory flat, recovery.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/fuzz_estimator.py
     [--minutes 10] [--seed 20261123]

The fuzz of ``test/test_estimator_time.py`` (NaN, inf, huge and negative
values; stamps backwards, NaN, negative and far ahead; silences of seconds to
hours and clock jumps back; inputs in any order), for ``--minutes`` instead of
a few seconds, in slices of 30 s. Printed after each slice: the rounds fed,
the process's RSS now and its peak, the slowest ``advance`` call so far, and
what the core counted (rejected samples, gaps, clock jumps, held blocks).
Then one second of good data: the estimate must be finite, current and on no
fallback. The issue's bound: RSS under 400 MB throughout.
"""

import argparse
import math
from pathlib import Path
import resource
import sys
import time

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))
from test_estimator_time import fuzz, good_data  # noqa: E402 (the test's fuzz, reused)
from wet_eha_thermal.config import load_config  # noqa: E402
from wet_eha_thermal.estimator.core import Estimator  # noqa: E402


def rss_MB() -> float:
    """Return the resident set size of this process now (MB)."""
    with open('/proc/self/statm') as f:
        return int(f.read().split()[1]) * resource.getpagesize() / 2 ** 20


def main() -> None:
    """Fuzz for the given minutes and print the figures."""
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--minutes', type=float, default=10.0)
    p.add_argument('--seed', type=int, default=20261123)
    args = p.parse_args()
    print('command: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/fuzz_estimator.py '
          + ' '.join(sys.argv[1:]), flush=True)
    est = Estimator(load_config())
    rng = np.random.default_rng(args.seed)
    start = time.monotonic()
    end = start + args.minutes * 60.0
    slowest = 0.0
    print(f'RSS at the start {rss_MB():.0f} MB')
    while time.monotonic() < end:
        clock, slow = fuzz(est, rng, seconds=min(30.0, end - time.monotonic()))
        slowest = max(slowest, slow)
        h = est.health.values()
        print(f'{(time.monotonic() - start) / 60:5.1f} min: RSS {rss_MB():.0f} MB (peak '
              f'{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB), slowest '
              f'advance {slowest * 1e3:.1f} ms, model steps {est.steps}, held blocks '
              f'{est.held_blocks}, data gaps {est.gaps.count}, clock jumps {est.clock_jumps}, '
              f'rejected {sum(x.rejected for x in h)} (future {sum(x.future for x in h)}), '
              f'discarded {sum(x.discarded for x in h)}', flush=True)
    t = good_data(est, clock, 1.0)
    last = est.latest
    finite = all(math.isfinite(v) for v in last.temperatures_C.values())
    print(f'good data again: estimate at {last.stamp_s - t:+.3f} s of the clock, finite '
          f'{finite}, inputs on fallback {last.stale or "none"}, winding hot-spot '
          f'{last.temperatures_C["winding_hotspot"]:.1f} degC')
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f'peak RSS {peak:.0f} MB (bound 400 MB): {"ok" if peak < 400 else "OVER"}')


if __name__ == '__main__':
    main()
