"""
``runtime.spin`` stops on SIGINT and SIGTERM even when the executor never runs out of work.

An EventsExecutor slice ends at its timeout only once its queue is empty, so
a node whose callbacks outlast their timers' periods (a loaded machine) never
returned to the loop that read the signal flag: it ignored Ctrl-C. Here a
timer's callback takes 60 ms of a 50 ms period, so the queue is never empty:
before the fix the child below never stopped (the deadline is for a fact,
the exit, never a pace).
"""

import os
import signal
import subprocess
import sys
import textwrap
import threading

from node_probe import PATIENCE
import pytest
from ros_domains import claim_domain

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

CHILD = textwrap.dedent("""
    import sys, time
    import rclpy
    from rclpy.signals import SignalHandlerOptions
    from wet_eha_thermal.ros import runtime

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('spin_test')

    def overrun():
        end = time.perf_counter() + 0.06
        while time.perf_counter() < end:
            pass
        print('tick', flush=True)

    node.create_timer(0.05, overrun)
    executor = runtime.make_executor(sys.argv[1])
    executor.add_node(node)
    runtime.spin(executor, node, started=lambda: print('spinning', flush=True))
    print('stopped', flush=True)
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown()
""")


@pytest.mark.parametrize('kind, signum', [('events', signal.SIGINT), ('single', signal.SIGTERM)],
                         ids=['events-SIGINT', 'single-SIGTERM'])
def test_a_signal_stops_an_executor_whose_timer_is_always_due(kind, signum):
    env = dict(os.environ, ROS_DOMAIN_ID=str(claim_domain()), PYTHONUNBUFFERED='1',
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    proc = subprocess.Popen([sys.executable, '-c', CHILD, kind], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines, ticked = [], threading.Event()

    def read():          # ticked: two overrunning callbacks ran, or the child's output ended
        for line in proc.stdout:
            lines.append(line)
            if line == 'tick\n' and lines.count(line) == 2:
                ticked.set()
        ticked.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        # a deadline for a fact, never a pace: the child's rclpy start takes seconds when busy
        assert ticked.wait(timeout=12.0 * PATIENCE), ''.join(lines)
        # signalled after two overrunning callbacks: by then the timer is due again at once
        proc.send_signal(signum)
        proc.wait(timeout=12.0 * PATIENCE)
    except subprocess.TimeoutExpired:
        pytest.fail(f'the {kind} executor ignored signal {signum.name}')
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        reader.join(timeout=10.0)
    text = ''.join(lines)
    assert proc.returncode == 0 and 'spinning' in text and 'stopped' in text, text
