"""
The drive's current limits against the model itself: where each limit takes the winding.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/limits_check.py [--seconds 600]

Two states: test/test_limits.py's steady loaded duty (15 A, 800 rad/s, 3 MPa) after 60 s,
and ``--seconds`` of reference stage 2 (8 MPa; benchmarks/bench_step.py's signals). At
each, every horizon's limit (:func:`~wet_eha_thermal.estimator.limits.limit_steps`,
the winding limit set so that it binds) is checked by stepping the full model on the
same held duty at that current for that horizon: printed, the limit and how far above
(+) or below (-) its limit less 2 sigma the worst quantity ends (K).
"""

import argparse
from pathlib import Path
import pickle
import sys

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))
from bench_step import make_inputs  # noqa: E402 - the benchmarks' stage signals
from test_limits import feed, peak_excess, run  # noqa: E402 - the tests' duty, check, runner
from wet_eha_thermal.config import load_config  # noqa: E402
from wet_eha_thermal.estimator.core import Estimator  # noqa: E402
from wet_eha_thermal.estimator.limits import limit_steps, probing  # noqa: E402

CASES = {'steady duty after 60 s': ((40.0, (10.0, 60.0)), (80.0, (600.0,))),
         'stage 2': ((60.0, (10.0, 60.0, 600.0)), (75.0, (600.0,)))}


def check(est: Estimator, winding_C: float, horizons) -> list:
    """Return (horizon, limit A, binds, end excess K) for each horizon at ``winding_C``."""
    limits_C = dict(est.limits_C, winding_hotspot=winding_C)
    k = est.cfg.estimator.limits.k_sigma
    got = run(limit_steps(pickle.dumps(est.model), est.model.state,
                          probing(est.model, list(limits_C)), est._outlook.held_duty(),
                          est.ambient_K, est.latest.uncertainty_K, limits_C, k, horizons,
                          est.cfg.estimator.limits.period_s, est.cfg.motor.peak_current_A))
    return [(h, amps, binds, peak_excess(est, limits_C, amps, h, k))
            for h, (amps, binds) in zip(horizons, got)]


def main() -> None:
    """Build both states, check their limits, print them."""
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument('--seconds', type=float, default=600.0, help='of stage 2')
    args = ap.parse_args()
    cfg = load_config()
    steady = Estimator(cfg)
    feed(steady, 0.0, 60.0)
    stage2 = Estimator(cfg)
    t, signals = make_inputs(cfg, 2, args.seconds, True)
    for name, values in signals.items():
        stage2.add_many(name, t, values)
    stage2.advance_all()
    for (label, cases), est in zip(CASES.items(), (steady, stage2)):
        if label == 'stage 2':
            label = f'stage 2 after {args.seconds:g} s'
        for winding_C, horizons in cases:
            for h, amps, binds, worst in check(est, winding_C, horizons):
                print(f'{label}, winding limit {winding_C:g} degC: {h:g} s limit '
                      f'{amps:.2f} A ({binds}), ends {worst:+.2f} K from its limit less 2 sigma')


if __name__ == '__main__':
    main()
