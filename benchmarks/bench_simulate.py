"""
Wall time and step-size accuracy of the coupled wet-EHA model on a duty cycle.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_simulate.py
     [--stage 6] [--hours 1] [--dt 1.0] [--repeat 3] [--reference-dt 0.0005]
     [--reference-s 120]

1. Times ``--repeat`` runs of ``--hours`` of the stage at the default step and
   prints the median and the speed-up over real time.
2. Runs the first ``--reference-s`` seconds at ``--dt`` and at the reference
   step (one sample per reference step) and prints the largest difference of
   the cycle-mean temperatures over the last 10 s.
"""

import argparse
import statistics
import time

import numpy as np

from wet_eha_thermal.config import load_config
from wet_eha_thermal.model.duty import stage_duty
from wet_eha_thermal.offline.simulation import simulate
from wet_eha_thermal.units import C_TO_K


def cycle_means(res, window_s: float):
    """Return each temperature's mean over the last ``window_s`` of a run (K)."""
    t = np.array(res.time_s)
    sel = t > t[-1] - window_s
    return {k: float(np.mean(np.array(v)[sel])) for k, v in res.temperatures_K.items()
            if k != 'pump_outlet'}   # pump_outlet switches port with the flow direction


def main() -> None:
    """Run the timing and the step-size comparison and print the figures."""
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument('--stage', type=int, default=6)
    p.add_argument('--hours', type=float, default=1.0)
    p.add_argument('--dt', type=float, default=1.0)
    p.add_argument('--sample-rate-Hz', type=float, default=200.0)
    p.add_argument('--repeat', type=int, default=3)
    p.add_argument('--reference-dt', type=float, default=0.0005)
    p.add_argument('--reference-s', type=float, default=120.0)
    a = p.parse_args()
    cfg = load_config()
    duty = stage_duty(cfg, a.stage)
    walls = []
    for _ in range(a.repeat):
        t0 = time.perf_counter()
        res = simulate(cfg, duty, a.hours * 3600, dt_s=a.dt, sample_rate_Hz=a.sample_rate_Hz,
                       record_every_s=10.0)
        walls.append(time.perf_counter() - t0)
    med = statistics.median(walls)
    end = {k: v[-1] - C_TO_K for k, v in res.temperatures_K.items()}
    print(f'stage {a.stage}, {a.hours:g} h at dt {a.dt:g} s, {a.sample_rate_Hz:g} Hz samples: '
          f'median {med:.2f} s wall over {a.repeat} runs ({", ".join(f"{w:.2f}" for w in walls)})'
          f', {a.hours * 3600 / med:.0f}x real time; motor refreshes '
          f'{res.model.motor.refresh_count}')
    print('  end temperatures (degC): ' + ', '.join(f'{k} {v:.2f}' for k, v in end.items()))
    if a.reference_s > 0:
        fine = simulate(cfg, duty, a.reference_s, dt_s=a.reference_dt,
                        sample_rate_Hz=1.0 / a.reference_dt, record_every_s=a.reference_dt * 20)
        coarse = simulate(cfg, duty, a.reference_s, dt_s=a.dt, sample_rate_Hz=a.sample_rate_Hz,
                          record_every_s=a.dt)
        ref, got = cycle_means(fine, 10.0), cycle_means(coarse, 10.0)
        worst = max(ref, key=lambda k: abs(got[k] - ref[k]))
        print(f'  first {a.reference_s:g} s, dt {a.dt:g} s against dt {a.reference_dt:g} s: '
              f'largest difference of the last-10-s means {abs(got[worst] - ref[worst]):.3f} K '
              f'({worst})')


if __name__ == '__main__':
    main()
