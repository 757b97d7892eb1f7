"""
Wall time of one tick of the drive's current limits, against what a tick's horizons cost alone.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_limits.py [--repeat 15]
     [--seconds 60] [--winding-limit-C 80]

An estimator is fed ``--seconds`` of a steady duty (15 A, 800 rad/s, 3 MPa:
test/test_limits.py's); then ``--repeat`` ticks, each after 0.5 s more of
the duty (so that, as live, no tick's state is the last one's), time the job
of one limit tick (:func:`~wet_eha_thermal.estimator.limits.limit_steps`, the
model saved as the outlook does at a tick, the searches starting at the last
tick's answers and a tick close to the last linearised one taking its
linearisations, as the outlook's do), for the default horizons and, on a new
estimator, for the ones up to a minute alone (no linearisation half-way),
with the winding limit at ``--winding-limit-C`` so that the horizons bind.
Printed: median and minimum per tick (ms), what that makes at 2 Hz in % of
a core, the first tick's limits and how many ticks were linearised.
"""

import argparse
from pathlib import Path
import sys
import time

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))
from test_limits import feed, run  # noqa: E402 - the tests' duty and generator runner
from wet_eha_thermal.config import load_config  # noqa: E402
from wet_eha_thermal.estimator.core import Estimator  # noqa: E402
from wet_eha_thermal.estimator.limits import (ceilings_K, limit_steps, Linearised,  # noqa: E402
                                              probing)
from wet_eha_thermal.model import snapshot  # noqa: E402


def main() -> None:
    """Time the ticks and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument('--repeat', type=int, default=15)
    ap.add_argument('--seconds', type=float, default=60.0)
    ap.add_argument('--winding-limit-C', type=float, default=80.0)
    args = ap.parse_args()
    cfg = load_config()
    lim = cfg.estimator.limits
    print(f'a tick of the limits every {lim.period_s:g} s of the steady duty after '
          f'{args.seconds:g} s, winding limit {args.winding_limit_C:g} degC, {args.repeat} '
          f'ticks each')
    for horizons in (lim.horizons_s, tuple(h for h in lim.horizons_s if h <= 60.0)):
        est = Estimator(cfg)
        t = feed(est, 0.0, args.seconds)
        limits_C = dict(est.limits_C, winding_hotspot=args.winding_limit_C)
        setup = probing(est.model, list(limits_C))
        guesses = {}    # the last tick's answers, where the searches start (as in the outlook)
        kept = []       # the linearised ticks (the outlook's: a tick close to the last takes it)

        def tick():
            saved = snapshot.save(est.model)       # as the outlook saves it
            x0, held, sigma = est.model.state, est._outlook.held_duty(), est.latest.uncertainty_K
            kept.append(Linearised.for_tick(kept[-1] if kept else None, saved, x0, held,
                                            est.ambient_K, ceilings_K(limits_C, sigma,
                                                                      lim.k_sigma, None,
                                                                      est.ambient_K)))
            return run(limit_steps(saved, x0, setup, held, est.ambient_K, sigma, limits_C,
                                   lim.k_sigma, horizons, lim.period_s,
                                   cfg.motor.peak_current_A, guesses=guesses, kept=kept[-1]))

        got = tick()            # the first: caches, loss-table bins
        times = []
        for _ in range(args.repeat):
            # the state moves between ticks, as live: nothing is the last tick's to the bit
            t = feed(est, t, lim.period_s)
            start = time.perf_counter()
            tick()
            times.append(time.perf_counter() - start)
        med = float(np.median(times))
        print(f'  horizons {", ".join(f"{h:g} s" for h in horizons)}: median '
              f'{med * 1e3:.1f} ms, min {min(times) * 1e3:.1f} ms per tick; '
              f'{med / lim.period_s * 100:.1f} % of a core at one tick per '
              f'{lim.period_s:g} s; first limits {", ".join(f"{a:.1f} A ({b})" for a, b in got)}'
              f'; {sum(a is not b for a, b in zip(kept, kept[1:]))} of {args.repeat} ticks '
              "linearised, the others took the last one's")


if __name__ == '__main__':
    main()
