"""
Write a synthetic run with BagWriter, then read it back two ways and compare.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_replay_read.py
     [--minutes 60] [--dir DIR] [--keep] [--bag EXISTING.mcap] [--block-s 10]

The run is four 1 kHz sensor topics (current, speed and position as
std_msgs/Float64, pressure A as sensor_msgs/FluidPressure with a frame_id and
a header stamp 0.2 ms before the log time), written message by message
through :class:`~wet_eha_thermal.bag.writer.BagWriter` (figure: write msg/s,
including building and serializing the messages).

Each read runs in its own process so that its peak RSS is its own:

- ``plain``: ``mcap.reader.make_reader(f).iter_messages()`` and
  ``struct.unpack_from`` of the double of every message (the reference loop);
- ``columns``: :func:`~wet_eha_thermal.bag.reader.read_columns`, whole arrays;
- ``blocks``: :func:`~wet_eha_thermal.bag.reader.iter_column_blocks`,
  ``--block-s`` of log time at a time, as the estimator consumes a replay.

``columns`` and ``blocks`` check every decoded value and time against the
values written (regenerated from the message index), outside the timing.
Printed: msg/s of each read, the speed-up over the plain loop, peak RSS up to
the end of the read (before the check), and that of the process before
reading (imports only).
"""

import argparse
import json
from pathlib import Path
import resource
import struct
import subprocess
import sys
import tempfile
import time

from mcap.reader import make_reader
import numpy as np
from rclpy.serialization import serialize_message
from sensor_msgs.msg import FluidPressure
from std_msgs.msg import Float64
from wet_eha_thermal.bag.reader import iter_column_blocks, read_columns
from wet_eha_thermal.bag.writer import BagWriter, qos_profiles
from wet_eha_thermal.interface import FLOAT64, FLUID_PRESSURE, INPUT_TOPICS
from wet_eha_thermal.ros.topics import input_qos

RATE_HZ = 1000
T0_NS = 1_750_000_000_000_000_000   # log time of the first sample
PERIOD_NS = 1_000_000_000 // RATE_HZ
STAMP_LEAD_NS = 200_000              # pressure stamps precede their log time by this
FRAME_ID = 'port_a'                  # 7 bytes with the NUL: exercises the alignment
TOPICS = {                           # topic -> (type, field of the value)
    INPUT_TOPICS['current_A']: (FLOAT64, 'data'),
    INPUT_TOPICS['speed_rad_s']: (FLOAT64, 'data'),
    INPUT_TOPICS['p_a_Pa']: (FLUID_PRESSURE, 'fluid_pressure'),
    INPUT_TOPICS['position_m']: (FLOAT64, 'data'),
}
WRITE_BLOCK = 10 * RATE_HZ          # samples generated at once while writing


def expected(k: int, first: int, stop: int) -> np.ndarray:
    """Return the values of topic number ``k`` for samples ``first`` to ``stop - 1``."""
    i = np.arange(first, stop, dtype=np.int64)
    t_s = i / RATE_HZ
    return (k + 1) * 100.0 * np.sin(2 * np.pi * (0.05 + 0.3 * k) * t_s) + i * 1e-7


def log_times(first: int, stop: int) -> np.ndarray:
    return T0_NS + np.arange(first, stop, dtype=np.int64) * PERIOD_NS


def write_bag(path: Path, minutes: float) -> dict:
    samples = int(minutes * 60 * RATE_HZ)
    qos = qos_profiles(input_qos('sensor_data'))
    float_msg, pressure_msg = Float64(), FluidPressure()
    pressure_msg.header.frame_id = FRAME_ID
    pressure_msg.variance = 25.0
    t = time.perf_counter()
    with BagWriter(path, metadata={'benchmark': {'minutes': str(minutes)}}) as bag:
        for topic, (type_name, _) in TOPICS.items():
            bag.add_topic(topic, type_name, qos)
        for first in range(0, samples, WRITE_BLOCK):
            stop = min(first + WRITE_BLOCK, samples)
            values = [expected(k, first, stop).tolist() for k in range(len(TOPICS))]
            for j, log_ns in enumerate(log_times(first, stop).tolist()):
                for k, (topic, (type_name, _)) in enumerate(TOPICS.items()):
                    if type_name == FLOAT64:
                        float_msg.data = values[k][j]
                        bag.write(topic, serialize_message(float_msg), log_ns)
                    else:
                        stamp_ns = log_ns - STAMP_LEAD_NS
                        pressure_msg.header.stamp.sec = stamp_ns // 1_000_000_000
                        pressure_msg.header.stamp.nanosec = stamp_ns % 1_000_000_000
                        pressure_msg.fluid_pressure = values[k][j]
                        bag.write(topic, serialize_message(pressure_msg), log_ns)
    elapsed_s = time.perf_counter() - t
    messages = samples * len(TOPICS)
    return {'messages': messages, 'seconds': elapsed_s, 'msg_per_s': messages / elapsed_s,
            'bytes': path.stat().st_size}


def check(topic: str, first: int, columns) -> None:
    """Compare decoded columns against what was written, from sample ``first`` on."""
    k = list(TOPICS).index(topic)
    type_name, field = TOPICS[topic]
    stop = first + len(columns)
    log_ns = log_times(first, stop)
    ok = (np.array_equal(columns.values[field], expected(k, first, stop))
          and np.array_equal(columns.log_time_ns, log_ns))
    if type_name == FLUID_PRESSURE:
        ok = ok and np.array_equal(columns.time_ns, log_ns - STAMP_LEAD_NS)
        ok = ok and bool((columns.values['variance'] == 25.0).all())
    if not ok:
        raise SystemExit(f'{topic}: decoded values differ from those written '
                         f'(samples {first}..{stop})')


def read_plain(path: Path) -> int:
    count = 0
    total = 0.0
    unpack = struct.unpack_from
    with open(path, 'rb') as f:
        for schema, _, message in make_reader(f).iter_messages():
            data = message.data
            if schema.name == FLOAT64:
                total += unpack('<d', data, 4)[0]
            else:  # FluidPressure: the float64 after the frame_id, aligned to 8
                frame_id_bytes = unpack('<I', data, 12)[0]
                total += unpack('<d', data, 4 + ((12 + frame_id_bytes + 7) & ~7))[0]
            count += 1
    return count


def read_with_columns(path: Path):
    """Return (messages, seconds, peak RSS), all taken before checking the values."""
    t = time.perf_counter()
    data = read_columns(path, {topic: type_name for topic, (type_name, _) in TOPICS.items()})
    elapsed_s = time.perf_counter() - t
    rss_MB = peak_rss_MB()
    for topic, columns in data.topics.items():
        check(topic, 0, columns)
    return data.message_count, elapsed_s, rss_MB


def read_with_blocks(path: Path, block_s: float):
    """Return (messages, seconds, peak RSS), the time spent checking each block taken out."""
    t = time.perf_counter()
    checking_s = 0.0
    blocks = iter_column_blocks(path, {t: type_name for t, (type_name, _) in TOPICS.items()},
                                max_block_s=block_s)
    done = dict.fromkeys(TOPICS, 0)
    for block in blocks:
        t_check = time.perf_counter()
        for topic, columns in block.items():
            check(topic, done[topic], columns)
            done[topic] += len(columns)
        checking_s += time.perf_counter() - t_check
    return blocks.message_count, time.perf_counter() - t - checking_s, peak_rss_MB()


def peak_rss_MB() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def run_phase(phase: str, path: Path, block_s: float) -> None:
    """Child process: one read, its figures as JSON on stdout."""
    rss_before_MB = peak_rss_MB()
    if phase == 'plain':
        t = time.perf_counter()
        count = read_plain(path)
        elapsed_s = time.perf_counter() - t
        rss_MB = peak_rss_MB()
    elif phase == 'columns':
        count, elapsed_s, rss_MB = read_with_columns(path)
    else:
        count, elapsed_s, rss_MB = read_with_blocks(path, block_s)
    print(json.dumps({'messages': count, 'seconds': elapsed_s, 'msg_per_s': count / elapsed_s,
                      'rss_before_MB': rss_before_MB, 'peak_rss_MB': rss_MB}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--minutes', type=float, default=60.0)
    parser.add_argument('--dir', type=Path, help='where to write the bag (default: the temp dir)')
    parser.add_argument('--bag', type=Path, help='read this bag (written by this script) instead')
    parser.add_argument('--keep', action='store_true', help='keep the bag written')
    parser.add_argument('--block-s', type=float, default=10.0)
    parser.add_argument('--phase', choices=('plain', 'columns', 'blocks'),
                        help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.phase:
        run_phase(args.phase, args.bag, args.block_s)
        return
    path = args.bag
    if path is None:
        path = (args.dir or Path(tempfile.gettempdir())) / (
            f'bench_replay_{args.minutes:g}min_{time.strftime("%Y%m%d_%H%M%S")}.mcap')
        w = write_bag(path, args.minutes)
        print(f'write   : {w["messages"]} messages in {w["seconds"]:.1f} s = '
              f'{w["msg_per_s"]:.0f} msg/s, {w["bytes"] / 1e6:.1f} MB -> {path}')
    try:
        results = {}
        for phase in ('plain', 'columns', 'blocks'):
            out = subprocess.run([sys.executable, __file__, '--phase', phase, '--bag', str(path),
                                  '--block-s', str(args.block_s)],
                                 check=True, capture_output=True, text=True)
            r = results[phase] = json.loads(out.stdout)
            print(f'{phase:8s}: {r["messages"]} messages in {r["seconds"]:.2f} s = '
                  f'{r["msg_per_s"]:.0f} msg/s, peak RSS {r["peak_rss_MB"]:.0f} MB '
                  f'(after imports {r["rss_before_MB"]:.0f} MB)')
        for phase in ('columns', 'blocks'):
            ratio = results[phase]['msg_per_s'] / results['plain']['msg_per_s']
            print(f'{phase} / plain: {ratio:.1f}x (values and times checked against those '
                  'written)')
    finally:
        if args.bag is None and not args.keep:
            path.unlink()


if __name__ == '__main__':
    main()
