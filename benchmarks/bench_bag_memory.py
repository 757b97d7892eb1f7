"""
Memory of the bag writer over a long recording: what it keeps per file when it splits.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_bag_memory.py
     [--minutes 30] [--split-s 60] [--tracemalloc] [--dir DIR]

Writes ``--minutes`` of log time of the recorder's traffic, as fast as it
goes, through :class:`~wet_eha_thermal.bag.writer.BagWriter` in the
recorder's mode (bag directory, ``on_error='suspend'``, zstd, chunks closed
every second of log time) with ``--split-s`` (0: one file). The traffic:
33 topics, 7 000 messages and about 250 kB a second, of synthetic CDR
bytes (random, so that compression does not shrink them): three Float64
inputs and two FluidPressure at 1 kHz, 8 thermocouples and 12 estimates
(Temperature) at 100 Hz, the state (Float64MultiArray of 57 values) at
100 Hz, /diagnostics at 1 Hz and six String topics at 1 Hz.
:meth:`~wet_eha_thermal.bag.writer.BagWriter.health` is asked once a
second of log time, as the recorder does.

Figures, every minute of log time and at the end: the files so far, the
process's RSS (``/proc/self/statm``) and with ``--tracemalloc`` the Python
heap traced since the writer was made (tracemalloc slows the writing about
threefold). The growth per minute (per split with ``--split-s 60``) is the
slope from the second minute to the last (the first carries the one-time
allocations: the topics' definitions, mcap's and zstd's buffers).
"""

import argparse
import os
from pathlib import Path
import shutil
import tempfile
import time
import tracemalloc

import numpy as np
from wet_eha_thermal.bag.writer import BagWriter

RATE_S = 1.0
T0_NS = 1_700_000_000_000_000_000
TICK_NS = 1_000_000                         # 1 kHz
PAGE = os.sysconf('SC_PAGE_SIZE')
# topic -> (type, messages per second, CDR bytes)
TOPICS = {
    **{f'/eha/{name}': ('std_msgs/msg/Float64', 1000, 12)
       for name in ('current', 'speed', 'position')},
    **{f'/eha/pressure_{port}': ('sensor_msgs/msg/FluidPressure', 1000, 44)
       for port in ('a', 'b')},
    **{f'/eha/measured/tc{k}': ('sensor_msgs/msg/Temperature', 100, 40) for k in range(8)},
    **{f'/eha/estimate/e{k}': ('sensor_msgs/msg/Temperature', 100, 40) for k in range(12)},
    '/eha/state': ('std_msgs/msg/Float64MultiArray', 100, 4 + 40 + 8 * 57),
    '/diagnostics': ('diagnostic_msgs/msg/DiagnosticArray', 1, 600),
    **{f'/eha/text{k}': ('std_msgs/msg/String', 1, 120) for k in range(6)},
}


def rss_bytes() -> int:
    with open('/proc/self/statm') as f:
        return int(f.read().split()[1]) * PAGE


def schedule():
    """Return, per 1 ms tick of a second, the topics due and a pool of payloads per topic."""
    rng = np.random.default_rng(1)
    pools = {t: [b'\x00\x01\x00\x00' + rng.bytes(n - 4) for _ in range(64)]
             for t, (_, _, n) in TOPICS.items()}
    ticks = [[] for _ in range(1000)]
    for topic, (_, rate, _) in TOPICS.items():
        for k in range(rate):
            ticks[k * 1000 // rate].append(topic)
    return ticks, pools


def run(bag: Path, minutes: float, split_s: float, trace: bool) -> list:
    ticks, pools = schedule()
    if trace:
        tracemalloc.start()
    base_traced = tracemalloc.get_traced_memory()[0] if trace else 0
    writer = BagWriter(bag, directory=True, on_error='suspend', split_duration_s=split_s or None)
    for topic, (type_name, _, _) in TOPICS.items():
        writer.add_topic(topic, type_name)
    rows = []
    started = time.perf_counter()
    for second in range(int(minutes * 60)):
        health = writer.health()
        if second % 60 == 0:
            traced = tracemalloc.get_traced_memory()[0] - base_traced if trace else 0
            rows.append((len(health.files), second, rss_bytes(), traced,
                         health.messages_written, time.perf_counter() - started))
        t0 = T0_NS + second * 1_000_000_000
        j = second
        for tick, due in enumerate(ticks):
            t = t0 + tick * TICK_NS
            for topic in due:
                writer.write(topic, pools[topic][j & 63], t)
                j += 1
    health = writer.close()
    traced = tracemalloc.get_traced_memory()[0] - base_traced if trace else 0
    rows.append((len(health.files), int(minutes * 60), rss_bytes(), traced,
                 health.messages_written, time.perf_counter() - started))
    assert health.errors == 0 and health.messages_dropped == 0
    print(f'{health.messages_written} messages, {health.bytes_written / 2 ** 20:.0f} MiB in '
          f'{len(health.files)} files, {rows[-1][5]:.0f} s')
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0].strip())
    parser.add_argument('--minutes', type=float, default=30.0)
    parser.add_argument('--split-s', type=float, default=60.0, help='0: no splitting')
    parser.add_argument('--tracemalloc', action='store_true')
    parser.add_argument('--dir', type=Path, default=None)
    args = parser.parse_args()
    per_s = sum(rate for _, rate, _ in TOPICS.values())
    per_s_bytes = sum(rate * n for _, rate, n in TOPICS.values())
    print(f'{len(TOPICS)} topics, {per_s} msg/s, {per_s_bytes / 1e3:.0f} kB/s of CDR, '
          f'{args.minutes:g} min, split every {args.split_s:g} s')
    folder = Path(tempfile.mkdtemp(dir=args.dir))
    try:
        rows = run(folder / 'bag', args.minutes, args.split_s, args.tracemalloc)
    finally:
        shutil.rmtree(folder)
    print('files  log s   RSS MiB  traced MiB  messages  wall s')
    for files, second, rss, traced, messages, wall in rows:
        print(f'{files:5d} {second:6d} {rss / 2 ** 20:9.1f} {traced / 2 ** 20:11.2f} '
              f'{messages:9d} {wall:7.0f}')
    if len(rows) > 3:
        (_, s0, r0, m0, _, _), (_, s1, r1, m1, _, _) = rows[1], rows[-2]
        minutes = (s1 - s0) / 60
        print(f'growth per minute from minute {s0 // 60} to {s1 // 60}: RSS '
              f'{(r1 - r0) / minutes / 1024:.1f} KiB, traced {(m1 - m0) / minutes / 1024:.1f} KiB')
    first, last = rows[0], rows[-1]
    print(f'whole run: RSS {first[2] / 2 ** 20:.1f} -> {last[2] / 2 ** 20:.1f} MiB, traced '
          f'{first[3] / 2 ** 20:.2f} -> {last[3] / 2 ** 20:.2f} MiB')


if __name__ == '__main__':
    main()
