"""
An hour of silence caught up: held blocks against stepping step by step, cost and accuracy.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_silence.py [--gap-s 3600]

Three cases, each 10 minutes of load (15 A at 800 rad/s, 3 MPa on port A) at
50 Hz, then 1 s of the held values, a silence of ``--gap-s`` with no sample,
then 1 s of data again:

- ``rig stopped``: the held values are at rest (no current, no speed, the
  accumulator's pressure on both ports): the lunch break;
- ``sensors dead, running``: the held values are the load's;
- ``sensors dead, hot``: 22 A and 5 MPa held, past the limits within the hour.

Each is run twice from the same start: with the estimator as it is (the
silence crossed in held blocks, ``estimator.core.HOLD_*``) and step by step
(``HOLD_AFTER_STEPS`` out of reach: 180 000 steps for an hour, minutes of CPU).
Printed: the held blocks; the CPU of crossing the silence (the calls of
``advance`` from the first sample after it until no step is left: the first 50
silent steps and the held blocks) and of the second of data after it (50
ordinary steps); and the differences of the estimates after that second (K)
between the two ways.
"""

import argparse
import sys
import time

import numpy as np
from wet_eha_thermal.config import load_config
from wet_eha_thermal.estimator import core
from wet_eha_thermal.estimator.core import Estimator
from wet_eha_thermal.offline.simulation import compile_model

LOAD = {'current_A': 15.0, 'speed_rad_s': 800.0, 'p_a_Pa': 3e6, 'p_b_Pa': 1e6,
        'p_acc_Pa': 1e6, 'position_m': 0.0}
REST = {'current_A': 0.0, 'speed_rad_s': 0.0, 'p_a_Pa': 1e6, 'p_b_Pa': 1e6, 'p_acc_Pa': 1e6,
        'position_m': 0.0}
HOT = dict(LOAD, current_A=22.0, p_a_Pa=5e6)
CASES = {'rig stopped': (LOAD, REST), 'sensors dead, running': (LOAD, LOAD),
         'sensors dead, hot': (HOT, HOT)}


def feed(est, t0, t1, values, dt):
    """Feed every input from t0 to t1 (s) every dt."""
    t = np.arange(t0 + dt, t1 + dt / 2, dt)
    for ch, v in values.items():
        est.add_many(ch, t, np.full(t.size, v))


def catch_up(est) -> None:
    """Advance until no complete step is left, as the live node's calls would."""
    while est.advance():
        pass


def run(cfg, before, held, gap_s: float, hold: bool):
    """
    Run one case; return the estimator and the figures of its catch-up.

    The figures: the CPU (s) of crossing the silence, that of the second after
    it, and the model steps of both.
    """
    core.HOLD_AFTER_STEPS = 50 if hold else 10 ** 12
    est = Estimator(cfg)
    feed(est, 0.0, 600.0, before, 0.02)
    feed(est, 600.0, 601.0, held, 0.001)
    catch_up(est)
    # the first sample of each input after the silence: the catch-up then crosses the
    # silence alone; the second of data after it is stepped as usual, timed apart
    first = 601.0 + gap_s + 0.001
    for ch, v in held.items():
        est.add(ch, first, v)
    steps0, cpu0 = est.steps, time.process_time()
    catch_up(est)
    cpu1 = time.process_time()
    feed(est, first, 602.0 + gap_s, held, 0.001)
    catch_up(est)
    return est, cpu1 - cpu0, time.process_time() - cpu1, est.steps - steps0


def main() -> None:
    """Run the three cases both ways and print the figures."""
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--gap-s', type=float, default=3600.0, help='length of the silence (s)')
    args = p.parse_args()
    print('command: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_silence.py '
          + ' '.join(sys.argv[1:]), flush=True)
    cfg = load_config()
    compile_model(cfg)
    for name, (before, held) in CASES.items():
        fast, fast_cpu, fast_after, _ = run(cfg, before, held, args.gap_s, True)
        slow, slow_cpu, _, slow_steps = run(cfg, before, held, args.gap_s, False)
        ref, got = slow.latest.temperatures_C, fast.latest.temperatures_C
        worst = max(ref, key=lambda k: abs(got[k] - ref[k]))
        print(f'{name}: {fast.held_blocks} held blocks, silence crossed in '
              f'{fast_cpu * 1e3:.0f} ms of CPU, the second after it {fast_after * 1e3:.0f} ms '
              f'(step by step {slow_cpu:.1f} s for the silence, {slow_steps} steps in all); '
              f'then winding hot-spot {ref["winding_hotspot"]:.1f} degC step by step, held '
              f'{got["winding_hotspot"] - ref["winding_hotspot"]:+.2f} K; largest difference '
              f'{got[worst] - ref[worst]:+.2f} K ({worst})', flush=True)


if __name__ == '__main__':
    main()
