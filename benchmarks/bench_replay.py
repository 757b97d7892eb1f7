"""
Offline replay of a rig log through the estimator: rate, ratio to the plain reader loop, memory.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_replay.py
     [--minutes 60] [--bag EXISTING.mcap] [--keep] [--dir DIR] [--rounds N]

Without ``--bag`` it first writes a log of the simulated rig on stage 6
(:func:`~wet_eha_thermal.offline.simulated_rig.write_rig_bag`: current, speed, one
differential pressure and position at 1 kHz, thermocouples at 10 Hz, ambient
at 1 Hz), ``--minutes`` long. Then, each in its own process so that its peak
RSS is its own:

- ``plain``: the reference loop, ``mcap.reader.make_reader``
  ``iter_messages()`` with a struct unpack of every message's double
  (``read_plain`` of ``bench_replay_read.py``);
- ``open-loop``: :func:`wet_eha_thermal.offline.replay.replay` of the whole log (read,
  decode, estimator in sample time at its 20 ms step) plus the CSV and MCAP
  outputs, as ``wet-eha-thermal replay --no-report --open-loop --no-outlook``
  does: the work of a rig log: four sensor topics and no thermocouple;
- ``replay``: the same with the live correction on (the shipped default for
  a log with thermocouples, as this one has);
- ``outlook``: the same with the outlook too (the current limits every
  0.5 s, the forecast every minute: the shipped default of
  ``wet-eha-thermal replay --no-report``) and its ``limits.csv``.

Printed: messages per second of each, the replays' ratios to the plain loop,
multiples of real time, and peak RSS (the replay's reading process, which
decodes the next block on the other core, on its own). With ``--rounds N``
the phases run N times in turn, and the medians close the output: each phase's
time, and each replay's ratio to the plain loop of its own round (a virtual
machine whose speed drifts by 10-30 % within minutes makes one round's ratio
a sample, not a figure).
"""

import argparse
import json
from pathlib import Path
import resource
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_replay_read import read_plain  # noqa: E402,I100 - the same reference loop


def peak_rss_MB(who: int = resource.RUSAGE_SELF) -> float:
    """Return the peak resident memory (MB) of this process (or of its largest child)."""
    return resource.getrusage(who).ru_maxrss / 1024


def run_phase(phase: str, path: Path) -> None:
    """Child process: one pass over the log, its figures as JSON on stdout."""
    from wet_eha_thermal.offline import replay as rp
    from wet_eha_thermal.config import with_values

    before = peak_rss_MB()
    t = time.perf_counter()
    if phase == 'plain':
        messages = read_plain(path)
        extra = {}
    else:
        plan = rp.plan_replay(path)
        if phase == 'open-loop':
            plan.cfg = with_values(plan.cfg, {'estimator.correction.enabled': False})
        with tempfile.TemporaryDirectory() as out:
            result = rp.replay(plan, outlook=phase == 'outlook')
            rp.write_outputs(result, Path(out), report=False)
        messages = result.messages
        extra = {'steps': result.steps, 'sample_time_s': result.sample_time_s}
    seconds = time.perf_counter() - t
    print(json.dumps({'messages': messages, 'seconds': seconds, 'rss_before_MB': before,
                      'peak_rss_MB': peak_rss_MB(),
                      'reader_rss_MB': peak_rss_MB(resource.RUSAGE_CHILDREN), **extra}))


def write_log(path: Path, minutes: float) -> None:
    """Write ``minutes`` of the simulated rig on stage 6 to ``path``, with progress."""
    from wet_eha_thermal.config import load_config
    from wet_eha_thermal.model.duty import stage_duty
    from wet_eha_thermal.offline.simulated_rig import SimulatedRig, write_rig_bag

    cfg = load_config(overrides={'estimator.pressure_inputs': 'differential'})
    t = time.perf_counter()
    count = write_rig_bag(path, SimulatedRig(cfg, stage_duty(cfg, 6)), minutes * 60.0,
                          on_progress=lambda f: print(f'\rwriting {100 * f:5.1f} %', end='',
                                                      file=sys.stderr, flush=True))
    print(f'\rwrote {count} messages ({minutes:g} min) in {time.perf_counter() - t:.0f} s, '
          f'{path.stat().st_size / 1e6:.0f} MB -> {path}')


PHASES = ('plain', 'open-loop', 'replay', 'outlook')


def ratio(r: dict, phase: str) -> float:
    """Return a replay's rate over the plain loop's, both of the round ``r``."""
    return (r[phase]['messages'] / r[phase]['seconds']) / (
        r['plain']['messages'] / r['plain']['seconds'])


def run_round(path: Path) -> dict:
    """Run the phases once, each in its own process; print and return their figures."""
    r = {}
    for phase in PHASES:
        out = subprocess.run([sys.executable, __file__, '--phase', phase, '--bag', str(path)],
                             check=True, capture_output=True, text=True)
        r[phase] = json.loads(out.stdout)
        rate = r[phase]['messages'] / r[phase]['seconds']
        print(f'{phase:9s}: {r[phase]["messages"]} messages in {r[phase]["seconds"]:.1f} s '
              f'= {rate:.0f} msg/s, peak RSS {r[phase]["peak_rss_MB"]:.0f} MB (after '
              f'imports {r[phase]["rss_before_MB"]:.0f} MB)'
              + (f', reading process {r[phase]["reader_rss_MB"]:.0f} MB'
                 if r[phase]['reader_rss_MB'] else ''), flush=True)
    for phase in PHASES[1:]:
        rp = r[phase]
        print(f'{phase:9s} / plain loop: {ratio(r, phase):.2f}x; '
              f'{rp["steps"]} model steps, {rp["sample_time_s"]:.0f} s of sample time in '
              f'{rp["seconds"]:.1f} s = {rp["sample_time_s"] / rp["seconds"]:.1f}x real time',
              flush=True)
    return r


def main() -> None:
    """Run the benchmark and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--minutes', type=float, default=60.0)
    parser.add_argument('--bag', type=Path, help='replay this log instead of writing one')
    parser.add_argument('--dir', type=Path, help='where to write the log (default: temp dir)')
    parser.add_argument('--keep', action='store_true', help='keep the log written')
    parser.add_argument('--rounds', type=int, default=1,
                        help='run the phases this many times in turn; print medians')
    parser.add_argument('--phase', choices=PHASES, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.phase:
        run_phase(args.phase, args.bag)
        return
    print('command: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_replay.py '
          + ' '.join(sys.argv[1:]), flush=True)
    path = args.bag
    if path is None:
        path = (args.dir or Path(tempfile.gettempdir())) / (
            f'bench_replay_stage6_{args.minutes:g}min_{time.strftime("%Y%m%d_%H%M%S")}.mcap')
        write_log(path, args.minutes)
    try:
        rounds = [run_round(path) for _ in range(args.rounds)]
        if args.rounds > 1:
            print(f'medians of {args.rounds} rounds:')
            for phase in PHASES:
                print(f'{phase:9s}: '
                      f'{statistics.median(r[phase]["seconds"] for r in rounds):.1f} s')
            for phase in PHASES[1:]:
                ratios = [ratio(r, phase) for r in rounds]
                print(f'{phase:9s} / plain loop: {statistics.median(ratios):.2f}x (rounds: '
                      + ', '.join(f'{x:.2f}x' for x in ratios) + ')')
    finally:
        if args.bag is None and not args.keep:
            path.unlink()


if __name__ == '__main__':
    main()
