"""
Throughput benchmark of the recorder: messages written against messages sent, and its CPU.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_recorder.py
     [--rate 10000] [--topics 10] [--seconds 30] [--depth 1000] [--dir DIR] [--keep]

Two processes on a private ROS domain (picked as ``wet-eha-thermal live``
picks its own, or ``$WET_EHA_LIVE_DOMAIN_ID``):

- the recorder (``python -m wet_eha_thermal.ros.recorder_node``; the command
  is printed) with the benchmark topics as ``extra_topics``, so it takes
  their type and QoS from the publisher;
- this process, the publisher: ``--topics`` std_msgs/Float64 topics
  ``/bench/f<k>``, reliable, keep-last ``--depth``, at ``--rate`` messages
  per second in total (one message per topic per tick, paced to the wall
  clock), message k of each topic carrying k. It starts once the recorder
  has matched every topic, so that nothing is lost to discovery, stops
  after ``--seconds``, and then the recorder gets SIGINT.

Figures: messages sent and written (read back with
:func:`~wet_eha_thermal.bag.reader.read_columns`; every topic must hold
0, 1, 2, ... in order: lost = sent - written), the rate reached, and CPU in %
of one core (utime + stime from ``/proc/<pid>/stat`` over the publishing
window) of the recorder and of the publisher.
"""

import argparse
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time

from bench_estimator import reliable
import numpy as np
from procfs import cpu_seconds
import rclpy
from std_msgs.msg import Float64
from wet_eha_thermal.bag.reader import read_columns
from wet_eha_thermal.interface import FLOAT64
from wet_eha_thermal.ros.live_monitor import domain_from_env, open_domain

#: Longest wait for the recorder to match every topic (s).
MATCH_TIMEOUT_S = 30.0
#: Time left for the last messages to arrive before the recorder is stopped (s).
SETTLE_S = 1.0


def _parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0].strip())
    parser.add_argument('--rate', type=float, default=10000.0,
                        help='messages per second, all topics together (default: %(default)g)')
    parser.add_argument('--topics', type=int, default=10, help='topics (default: %(default)d)')
    parser.add_argument('--seconds', type=float, default=30.0,
                        help='publishing time, s (default: %(default)g)')
    parser.add_argument('--depth', type=int, default=1000,
                        help='history depth of publisher and recorder (default: %(default)d)')
    parser.add_argument('--dir', type=Path, default=None,
                        help='folder of the bag (default: a temporary folder)')
    parser.add_argument('--keep', action='store_true', help='keep the bag and the log')
    return parser.parse_args()


def _publish(pubs, rate_per_topic_Hz: float, count: int) -> None:
    """Publish ``count`` messages on every publisher, one per topic per tick, paced."""
    msg = Float64()
    t0 = time.perf_counter()
    k = 0
    while k < count:
        due = min(count, int((time.perf_counter() - t0) * rate_per_topic_Hz) + 1)
        while k < due:
            msg.data = float(k)
            for pub in pubs:
                pub.publish(msg)
            k += 1
        time.sleep(max(0.0, k / rate_per_topic_Hz - (time.perf_counter() - t0)))


def main() -> int:
    """Run the benchmark; print the figures; return 0 when nothing was lost."""
    args = _parse_args()
    folder = args.dir or Path(tempfile.mkdtemp(prefix='bench-recorder-'))
    folder.mkdir(parents=True, exist_ok=True)
    bag = folder / f'bench_recorder_{time.strftime("%Y%m%dT%H%M%S")}.mcap'
    names = [f'/bench/f{k}' for k in range(args.topics)]
    rate_per_topic_Hz = args.rate / args.topics
    count = int(round(rate_per_topic_Hz * args.seconds))

    context, domain = open_domain(domain_from_env())
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', OPENBLAS_NUM_THREADS='1')
    cmd = [sys.executable, '-m', 'wet_eha_thermal.ros.recorder_node', '--ros-args',
           '-p', f'output:={bag}', '-p', f'qos_depth:={args.depth}',
           '-p', f'extra_topics:=[{",".join(names)}]']
    print(f'recorder: ROS_DOMAIN_ID={domain} {" ".join(cmd)}')
    print(f'publisher: {args.topics} x std_msgs/Float64 reliable depth {args.depth} at '
          f'{rate_per_topic_Hz:g} Hz each ({args.rate:g} msg/s) for {args.seconds:g} s')
    log_path = folder / 'bench_recorder.log'
    with open(log_path, 'wb') as log:
        rec = subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)
    node = rclpy.create_node('bench_recorder_publisher', context=context)
    pubs = [node.create_publisher(Float64, name, reliable(args.depth)) for name in names]
    try:
        end = time.monotonic() + MATCH_TIMEOUT_S
        while any(p.get_subscription_count() == 0 for p in pubs):
            if time.monotonic() > end or rec.poll() is not None:
                print(f'error: the recorder did not subscribe; see {log_path}', file=sys.stderr)
                return 1
            time.sleep(0.05)
        rec_cpu0, pub_cpu0, t0 = cpu_seconds(rec.pid), time.process_time(), time.perf_counter()
        _publish(pubs, rate_per_topic_Hz, count)
        wall_s = time.perf_counter() - t0
        rec_cpu_s, pub_cpu_s = cpu_seconds(rec.pid) - rec_cpu0, time.process_time() - pub_cpu0
        time.sleep(SETTLE_S)
    finally:
        rec.send_signal(signal.SIGINT)
        rec.wait(timeout=30)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    data = read_columns(bag, dict.fromkeys(names, FLOAT64))
    written = sum(len(c) for c in data.topics.values())
    in_order = all(np.array_equal(c.values['data'], np.arange(len(c)))
                   for c in data.topics.values())
    sent = count * len(names)
    print(f'sent {sent} messages in {wall_s:.2f} s ({sent / wall_s:.0f} msg/s); written {written}'
          f'; lost {sent - written}; every topic 0, 1, 2, ... in order: {in_order}')
    print(f'CPU over the publishing window: recorder {100 * rec_cpu_s / wall_s:.1f} % of one '
          f'core, publisher {100 * pub_cpu_s / wall_s:.1f} %; recorder exit status '
          f'{rec.returncode}; bag {bag.stat().st_size / 2 ** 20:.1f} MiB')
    print(log_path.read_text().strip().splitlines()[-1][:300])
    if not args.keep and args.dir is None:
        bag.unlink()
        log_path.unlink()
        folder.rmdir()
    return 0 if written == sent and in_order and rec.returncode == 0 else 1


if __name__ == '__main__':
    sys.exit(main())
