"""
The copies' oil sub-step: how far it moves the propagated sigmas, and what it saves.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/compare_copy_substep.py
     [--stage 6] [--seconds 2400] [--substeps 0.25,1.0]

The coverage run of ``benchmarks/uncertainty_coverage.py`` (three rigs drawn
with seeds 1-3, 1 s model steps, the copies every 10 s), once per value of
``uncertainty.copy_substep_s``. Printed per value: the CPU of the run, and
per checked quantity the share of the time the truths are inside the 2-sigma
band, the mean sigma over the RMS error and the final sigma; then, per
quantity, the largest difference of the sigma between the first value and
each other one over the whole run (docs/model.md, Uncertainty).
"""

import argparse
import time

import numpy as np
from wet_eha_thermal.config import load_config, with_values
from wet_eha_thermal.model.uncertainty import as_built
from wet_eha_thermal.offline.coverage import CHECKED, coarse, play


def main() -> None:
    """Run the coverage once per sub-step and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0].strip())
    ap.add_argument('--stage', type=int, default=6)
    ap.add_argument('--seconds', type=float, default=2400.0)
    ap.add_argument('--substeps', default='0.25,1.0',
                    help='comma-separated values of uncertainty.copy_substep_s (s)')
    opts = ap.parse_args()
    base = coarse(load_config(), 1.0, 10.0)
    truths = [as_built(base, seed) for seed in (1, 2, 3)]
    runs = {}
    for sub in (float(v) for v in opts.substeps.split(',')):
        cfg = with_values(base, {'uncertainty.copy_substep_s': sub})
        start = time.process_time()
        c = runs[sub] = play(cfg, truths, opts.stage, opts.seconds)
        print(f'copy_substep_s {sub}: CPU {time.process_time() - start:.1f} s', flush=True)
        inside, ratio = c.inside_pooled(2.0), c.sigma_over_rms()
        for q in CHECKED:
            print(f'  {q:20s} inside {inside[q]:.3f}  sigma/RMS {ratio[q]:.2f}  '
                  f'final sigma {c.sigma_K[q][-1]:.3f} K')
    first, *others = runs
    for sub in others:
        print(f'largest |sigma({sub}) - sigma({first})| over the run:')
        for q in CHECKED:
            diff = np.max(np.abs(runs[sub].sigma_K[q] - runs[first].sigma_K[q]))
            print(f'  {q:20s} {diff:.4f} K of {np.max(runs[first].sigma_K[q]):.2f} K')


if __name__ == '__main__':
    main()
