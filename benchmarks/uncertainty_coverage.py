"""
Does the 2-sigma band hold rigs drawn from the stated sigmas? Coverage, sigma, cost.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/uncertainty_coverage.py
     [--stages 2,6] [--draws 3] [--first-seed 1] [--seconds 2400] [--figure PNG]

For each stage, from ambient: the simulated rig's kinetics, one truth model per
draw (``model/uncertainty.py`` ``as_built``: every uncertain parameter drawn,
lognormal or Gaussian at its stated sigma, cut at 2.5 sigma, and each
structural alternative with probability one half) stepped on the rig's
samples, and the open-loop estimator on the nominal configuration beside them
(``offline/coverage.py``; 1 s model steps for everyone, the copies every
10 s). Printed per stage: the share of the time each truth is inside
estimate +- 2 sigma, per draw and pooled, the mean sigma over the RMS error
(pooled), the largest sigma of the first minute and the sigma at the end,
and the CPU the copies took against the estimator's own steps. With
``--figure``, the first stage's first draw: estimate, band and truth of the
hot spot, the magnets and the pump case (docs/model.md, Uncertainty).
"""

import argparse
from pathlib import Path
import sys
import time

from wet_eha_thermal.config import load_config
from wet_eha_thermal.estimator import core
from wet_eha_thermal.model.quantity_table import label
from wet_eha_thermal.model.uncertainty import as_built
from wet_eha_thermal.offline.coverage import coarse, play
from wet_eha_thermal.output_files import save_figure

FIGURE = ('winding_hotspot', 'magnet', 'pump_case')


def plot(c, stage: int, seed: int, path: Path) -> None:
    """Plot the first truth against the estimate and its 2-sigma band."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(FIGURE), 1, figsize=(9, 8), sharex=True)
    t = c.t_s / 60.0
    for ax, q in zip(axes, FIGURE):
        est, s = c.estimate_C[q], c.sigma_K[q]
        ax.fill_between(t, est - 2 * s, est + 2 * s, color='tab:blue', alpha=0.25,
                        label='estimate +- 2 sigma')
        ax.plot(t, est, color='tab:blue', lw=1.0, label='estimate (nominal configuration)')
        ax.plot(t, c.truth_C[0][q], color='k', lw=1.0, ls='--', label=f'truth (rig draw {seed})')
        ax.set_ylabel(f'{label(q)} (degC)')
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel('time (min)')
    fig.suptitle(f'Stage {stage} from ambient: the open-loop estimate, its 2-sigma band\n'
                 'and a rig drawn from the stated sigmas')
    save_figure(fig, path)


def main() -> None:
    """Run the stages against the draws; print the figures."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--stages', default='2,6')
    p.add_argument('--draws', type=int, default=3)
    p.add_argument('--first-seed', type=int, default=1)
    p.add_argument('--seconds', type=float, default=2400.0)
    p.add_argument('--figure', type=Path, default=None)
    args = p.parse_args()
    print('command: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/uncertainty_coverage.py '
          + ' '.join(sys.argv[1:]), flush=True)
    cfg = coarse(load_config(), 1.0, 10.0)
    seeds = list(range(args.first_seed, args.first_seed + args.draws))
    truths = [as_built(cfg, s) for s in seeds]
    # the copies' share of the estimator's CPU: their wall time from the propagation
    made = []
    original = core.Estimator.__init__

    def keep(self, *a, **k):
        original(self, *a, **k)
        made.append(self)
    core.Estimator.__init__ = keep
    for n, stage in enumerate(int(s) for s in args.stages.split(',')):
        t0 = time.process_time()
        c = play(cfg, truths, stage, args.seconds)
        cpu = time.process_time() - t0
        prop = made[-1].propagation
        print(f'\nstage {stage}, {args.seconds:g} s from ambient, draws {seeds}: {cpu:.0f} s '
              f'CPU in all, of which the {prop.copies} copies {prop.work_s:.0f} s '
              f'({prop.periods} periods; the rest the estimator, the truths and the rig)')
        print(f'  {"quantity":<18} {"inside 2 sigma per draw":<26} {"pooled":>7} '
              f'{"sigma/rms":>9} {"sigma 1 min":>11} {"sigma end":>9} {"rise end":>8}')
        per_draw = c.inside(2.0)
        pooled, ratio, first = c.inside_pooled(2.0), c.sigma_over_rms(), c.sigma_at(60.0)
        for q in pooled:
            draws = ' '.join(f'{d[q]:.2f}' for d in per_draw)
            print(f'  {q:<18} {draws:<26} {pooled[q]:7.2f} {ratio[q]:9.2f} {first[q]:11.2f} '
                  f'{c.sigma_K[q][-1]:9.2f} {c.estimate_C[q][-1] - 20.0:8.1f}')
        if n == 0 and args.figure is not None:
            plot(c, stage, seeds[0], args.figure)
            print(f'  wrote {args.figure}')


if __name__ == '__main__':
    main()
