"""
Wall time of one tick of the drive's current limits, against what a tick's horizons cost alone.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_limits.py [--repeat 15]
     [--seconds 60] [--winding-limit-C 80]

An estimator is fed ``--seconds`` of a steady duty (15 A, 800 rad/s, 3 MPa:
test/test_limits.py's); then the job of one limit tick
(:func:`~wet_eha_thermal.estimator.limits.limit_steps`, the model saved as
the outlook does at a tick) runs ``--repeat`` times for the default horizons
and for the ones up to a minute alone (no linearisation half-way), with the
winding limit at ``--winding-limit-C`` so that the horizons bind. The
searches start at the last run's answers, as the outlook's do from tick to
tick (the first run, untimed, finds them). Printed: median and minimum per
tick (ms), and what that makes at 2 Hz in % of a core.
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
from wet_eha_thermal.estimator.limits import limit_steps, probing  # noqa: E402
from wet_eha_thermal.model import snapshot  # noqa: E402


def main() -> None:
    """Time the ticks and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument('--repeat', type=int, default=15)
    ap.add_argument('--seconds', type=float, default=60.0)
    ap.add_argument('--winding-limit-C', type=float, default=80.0)
    args = ap.parse_args()
    cfg = load_config()
    est = Estimator(cfg)
    feed(est, 0.0, args.seconds)
    lim = cfg.estimator.limits
    limits_C = dict(est.limits_C, winding_hotspot=args.winding_limit_C)
    setup = probing(est.model, list(limits_C))
    held = est._outlook.held_duty()

    guesses = {}        # the last answers, where the searches start (as the outlook keeps them)

    def tick(horizons):
        saved = snapshot.save(est.model)       # as the outlook saves it
        return run(limit_steps(saved, est.model.state, setup, held, est.ambient_K,
                               est.latest.uncertainty_K, limits_C, lim.k_sigma, horizons,
                               lim.period_s, cfg.motor.peak_current_A, guesses=guesses))

    print(f'one tick of the limits after {args.seconds:g} s of the steady duty, winding limit '
          f'{args.winding_limit_C:g} degC, {args.repeat} runs each')
    for horizons in (lim.horizons_s, tuple(h for h in lim.horizons_s if h <= 60.0)):
        got = tick(horizons)            # the first: caches, loss-table bins
        times = []
        for _ in range(args.repeat):
            start = time.perf_counter()
            tick(horizons)
            times.append(time.perf_counter() - start)
        med = float(np.median(times))
        print(f'  horizons {", ".join(f"{h:g} s" for h in horizons)}: median '
              f'{med * 1e3:.1f} ms, min {min(times) * 1e3:.1f} ms per tick; '
              f'{med / lim.period_s * 100:.1f} % of a core at one tick per '
              f'{lim.period_s:g} s; limits {", ".join(f"{a:.1f} A ({b})" for a, b in got)}')


if __name__ == '__main__':
    main()
