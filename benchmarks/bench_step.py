"""
Wall time of the estimator's model step, as the offline replay drives it, and a bitwise check.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_step.py
     [--seconds 300] [--stage 6] [--pressure ports|differential] [--no-noise]
     [--save FILE.npy] [--compare FILE.npy] [--profile [FILE.prof]] [--correction]
     [--uncertainty]

The inputs are the kinetic model's signals of a reference stage
(:class:`~wet_eha_thermal.model.kinetics.KineticModel`, oil at 40 degC) at
1 kHz, with the simulated rig's seeded sensor noise, stamped since the epoch
as a recorded bag is. They go to :class:`~wet_eha_thermal.estimator.core.Estimator`
as :func:`wet_eha_thermal.offline.replay.replay` feeds them: ``add_many`` per input
in blocks of 10 s of log, then ``advance()`` (no ambient readings, no
background work).

Printed: the wall time per model step all included (each block's
``add_many`` + ``advance`` over its steps), median and mean over the blocks,
and what that makes for one hour of log; ``Estimator._step`` alone (the
model step and the estimate), median and mean over the steps. ``--save``
writes every step's estimate (stamp, temperatures in K, heat flows) to a
.npy; ``--compare`` runs again and prints the largest difference from a
saved run (temperatures in K, heat flows relative).

``--correction`` times the live correction (``estimator.correction``) in the
same process: a run with it off (the figures above, and what ``--save`` and
``--compare`` use), then one with it on, fed a frame and a pump case
thermocouple at 10 Hz (the off run's estimates plus 1 K, with 0.2 K of seeded
noise, so that the filter corrects all along), and prints both medians and
their ratio.

``--uncertainty`` times the propagated uncertainty (``estimator/uncertainty.py``):
the run above has the configuration's ``uncertainty`` section, a second the
same without it (the constant sigma, no copies); it prints the copies' share
and both per-step figures.
"""

import argparse
import cProfile
import dataclasses
import math
import pstats
import time
from typing import Optional

import numpy as np

from wet_eha_thermal.config import load_config, with_values
from wet_eha_thermal.estimator.core import Estimator
from wet_eha_thermal.estimator.intake import sensor_inputs, sensor_signal
from wet_eha_thermal.interface import THERMOCOUPLES
from wet_eha_thermal.model.duty import stage_duty
from wet_eha_thermal.model.kinetics import KineticModel, ThermalFeedback
from wet_eha_thermal.model.oil import get_oil
from wet_eha_thermal.offline.simulated_rig import NOISE_SIGMA
from wet_eha_thermal.units import C_TO_K

RATE_HZ = 1000.0
BLOCK_S = 10.0
START_NS = 1_700_000_000 * 10**9     # stamps since the epoch, as in a recorded bag


def make_inputs(cfg, stage: int, seconds: float, noise: bool, seed: int = 1) -> tuple:
    """Return (stamps s since the epoch, {input: values}) of ``seconds`` of a stage at 1 kHz."""
    n = int(round(seconds * RATE_HZ))
    t = np.arange(1, n + 1) / RATE_HZ
    kin = KineticModel(cfg, get_oil(cfg.fluid.grade))
    s = kin.sample(stage_duty(cfg, stage), t, ThermalFeedback.uniform())
    values = {}
    for k, name in enumerate(sensor_inputs(cfg)):
        v = np.asarray(sensor_signal(s, name), dtype=float)
        if noise:
            # one generator per input: a shorter run gets the start of a longer one's noise
            rng = np.random.default_rng([seed, k])
            v = v + rng.normal(0.0, NOISE_SIGMA[name], v.size)
            if name == 'current_A':
                v = np.abs(v)        # an RMS reading is never negative
        values[name] = v
    stamps = (START_NS + np.round(t * 1e9)).astype(np.int64) * 1e-9
    return stamps, values


def run(cfg, stamps: np.ndarray, values: dict, thermocouples: Optional[dict] = None) -> dict:
    """
    Feed the inputs block by block; return the estimates and the timings.

    ``thermocouples`` maps a thermocouple to (stamps s, degC), fed with
    ``add_measured`` block by block before ``advance``, as the replay does.
    """
    est = Estimator(cfg)
    step_times = []
    inner = est._step

    def timed_step(*args):
        t0 = time.perf_counter()
        out = inner(*args)
        step_times.append(time.perf_counter() - t0)
        return out

    est._step = timed_step          # advance() looks the method up on the instance
    rows, block_per_step = [], []
    temp_names = heat_names = None
    per_block = int(round(BLOCK_S * RATE_HZ))
    blocks_s = 0.0
    for lo in range(0, stamps.size, per_block):
        hi = min(lo + per_block, stamps.size)
        t0 = time.perf_counter()
        for name, v in values.items():
            est.add_many(name, stamps[lo:hi], v[lo:hi])
        for name, (ts, vs) in (thermocouples or {}).items():
            a, b = np.searchsorted(ts, [stamps[lo], stamps[hi - 1]], side='right')
            for t_tc, v_tc in zip(ts[a:b].tolist(), vs[a:b].tolist()):
                est.add_measured(name, t_tc, v_tc)
        estimates = est.advance_all()
        wall = time.perf_counter() - t0
        blocks_s += wall
        if estimates:
            block_per_step.append(wall / len(estimates))
        for e in estimates:
            if temp_names is None:
                temp_names, heat_names = sorted(e.temperatures_C), sorted(e.heat_W)
            rows.append([e.stamp_s] + [e.temperatures_C[k] + C_TO_K for k in temp_names]
                        + [e.heat_W[k] for k in heat_names])
    return {'table': np.array(rows), 'temps': temp_names, 'heats': heat_names,
            'step_times': np.array(step_times), 'block_per_step': np.array(block_per_step),
            'total': blocks_s, 'energy': est.model.energy(), 'estimator': est}


def thermocouple_readings(result: dict, names=('frame', 'pump_case'), rate_Hz: float = 10.0,
                          offset_K: float = 1.0, seed: int = 2) -> dict:
    """Return readings (stamps s, degC) of thermocouples from a run's estimates, offset, noisy."""
    table = result['table']
    every = max(1, int(round(1.0 / (rate_Hz * (table[1, 0] - table[0, 0])))))
    rng = np.random.default_rng(seed)
    out = {}
    for name in names:
        col = 1 + result['temps'].index(THERMOCOUPLES[name])
        v = table[::every, col] - C_TO_K + offset_K
        out[name] = (table[::every, 0], v + rng.normal(0.0, 0.2, v.size))
    return out


def compare(result: dict, path: str) -> None:
    """Print the largest differences of this run from the one saved in ``path``."""
    ref = np.load(path)
    new = result['table']
    if ref.shape[1] != new.shape[1] or ref.shape[0] < new.shape[0]:
        print(f'compare: shapes differ: saved {ref.shape}, now {new.shape}')
        return
    if ref.shape[0] > new.shape[0]:      # a shorter run: the steps are causal
        print(f'compare: the first {new.shape[0]} of {ref.shape[0]} saved steps')
        ref = ref[:new.shape[0]]
    nt = len(result['temps'])
    d_stamp = float(np.max(np.abs(new[:, 0] - ref[:, 0])))
    d_temp = np.abs(new[:, 1:1 + nt] - ref[:, 1:1 + nt])
    heat_new, heat_ref = new[:, 1 + nt:], ref[:, 1 + nt:]
    d_heat = np.abs(heat_new - heat_ref) / np.maximum(np.abs(heat_ref), 1e-12)
    worst = np.unravel_index(np.argmax(d_temp), d_temp.shape)
    print(f'compare with {path}: max |dT| = {d_temp.max():.3e} K '
          f'({result["temps"][worst[1]]}, step {worst[0] + 1}); temperatures identical in '
          f'{np.mean(d_temp == 0.0) * 100:.1f} % of values; max stamp difference '
          f'{d_stamp:.3e} s; max relative heat-flow difference {d_heat.max():.3e}')


def main() -> None:
    """Run the benchmark and print the figures."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--seconds', type=float, default=300.0, help='log length (default 300)')
    p.add_argument('--stage', type=int, default=6, help='reference stage of the signals')
    p.add_argument('--pressure', choices=('ports', 'differential'), default='ports',
                   help='estimator.pressure_inputs (default: ports, the shipped setting)')
    p.add_argument('--no-noise', action='store_true', help='noise-free signals')
    p.add_argument('--save', metavar='FILE', help='write every estimate to FILE (.npy)')
    p.add_argument('--compare', metavar='FILE', help='compare the estimates with a saved run')
    p.add_argument('--profile', nargs='?', const='', metavar='FILE',
                   help='run under cProfile; print the top functions (and dump to FILE)')
    p.add_argument('--thermocouples', nargs='+', default=['frame', 'pump_case'],
                   choices=sorted(THERMOCOUPLES), metavar='TC',
                   help='thermocouples fed to the correction (default: frame pump_case)')
    p.add_argument('--correction', action='store_true',
                   help='also time the live correction (frame and pump case thermocouples at '
                   '10 Hz) against the run without it')
    p.add_argument('--uncertainty', action='store_true',
                   help='also time the run without the uncertainty section (the constant '
                   'sigma, no copies) against the one with it')
    args = p.parse_args()
    cfg = load_config(overrides={'estimator.pressure_inputs': args.pressure,
                                 'estimator.correction.enabled': False})
    stamps, values = make_inputs(cfg, args.stage, args.seconds, not args.no_noise)
    print(f'stage {args.stage}, {args.seconds:g} s at {RATE_HZ:g} Hz, inputs '
          f'{", ".join(values)}, noise {"off" if args.no_noise else "on"}')
    if args.profile is not None:
        prof = cProfile.Profile()
        result = prof.runcall(run, cfg, stamps, values)
        if args.profile:
            prof.dump_stats(args.profile)
        pstats.Stats(prof).sort_stats('tottime').print_stats(30)
    else:
        result = run(cfg, stamps, values)
    st = result['step_times'] * 1e3
    steps = st.size
    blocks = result['block_per_step'] * 1e3
    mean = result['total'] / max(steps, 1) * 1e3
    hour = mean * 1e-3 * 3600.0 / cfg.estimator.step_s
    print(f'{steps} steps in {blocks.size} blocks of {BLOCK_S:g} s; per step, all included '
          f'(add_many + advance): median {np.median(blocks):.4f} ms over the blocks, mean '
          f'{mean:.4f} ms')
    print(f'total {result["total"]:.2f} s for {args.seconds:g} s of log '
          f'({args.seconds / result["total"]:.1f} x real time); one hour of log: about '
          f'{hour:.0f} s')
    print(f'Estimator._step alone (model step and estimate): median {np.median(st):.4f} ms, '
          f'mean {st.mean():.4f} ms')
    e = result['energy']
    print('energy (J): ' + ', '.join(f'{k} {v:.6g}' for k, v in e.items())
          + f'; imbalance {e["sources"] - e["stored"] - e["to_ambient"]:.3g} J')
    table = result['table']
    nt = len(result['temps'])
    hot = table[-1, 1:1 + nt]
    print('last step (degC): ' + ', '.join(
        f'{k} {v - C_TO_K:.3f}' for k, v in zip(result['temps'], hot)
        if k in ('winding_hotspot', 'magnet', 'oil', 'pump_case')))
    if not math.isfinite(float(table[:, 1:].sum())):
        print('warning: non-finite estimates')
    if args.save:
        np.save(args.save, table)
        print(f'saved {table.shape[0]} estimates x {table.shape[1]} columns (stamp, '
              f'{nt} temperatures K, {len(result["heats"])} heat flows) -> {args.save}')
    if args.compare:
        compare(result, args.compare)
    if args.correction:
        readings = thermocouple_readings(result, args.thermocouples)
        on = run(with_values(cfg, {'estimator.correction.enabled': True}), stamps, values,
                 readings)
        st_on = on['step_times'] * 1e3
        blocks_on = on['block_per_step'] * 1e3
        c = on['estimator']._correction
        ratio_all = np.median(blocks_on) / np.median(blocks)
        print(f'correction on ({", ".join(args.thermocouples)} at 10 Hz, {c.updates} scalar '
              'updates, '
              f'{on["estimator"].latest.correction["thermocouples"]}): per step, all '
              f'included: median {np.median(blocks_on):.4f} ms ({ratio_all:.2f}x off), mean '
              f'{np.mean(blocks_on):.4f} ms ({np.mean(blocks_on) / np.mean(blocks):.2f}x off); '
              f'Estimator._step alone: median {np.median(st_on):.4f} ms '
              f'({np.median(st_on) / np.median(st):.2f}x off)')
    if args.uncertainty:
        prop = result['estimator'].propagation
        off = run(dataclasses.replace(cfg, uncertainty=None), stamps, values)
        blocks_off = off['block_per_step'] * 1e3
        st_off = off['step_times'] * 1e3
        ratio = np.median(blocks) / np.median(blocks_off)
        print(f'uncertainty: {prop.copies} copies, {prop.periods} periods; their steps '
              f'{prop.work_s:.2f} s of the {result["total"]:.2f} s (at the ends of the periods, '
              'as a replay makes them). Without the section: per step, all included: median '
              f'{np.median(blocks_off):.4f} ms (with it {ratio:.2f}x), mean '
              f'{np.mean(blocks_off):.4f} ms (with it {np.mean(blocks) / np.mean(blocks_off):.2f}'
              f'x); Estimator._step alone: median {np.median(st_off):.4f} ms (with it '
              f'{np.median(st) / np.median(st_off):.2f}x)')


if __name__ == '__main__':
    main()
