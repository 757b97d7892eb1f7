"""A writer in a child process, killed with SIGKILL mid-run: what a crash leaves (tests)."""

import contextlib
import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

#: A bag writer at about 1 kHz until killed: ``/f`` (std_msgs/Float64) = i and, when argv[3]
#: is 'pressure', ``/p`` (sensor_msgs/FluidPressure, 1e5 + i Pa, stamped at its log time);
#: argv[1] the bag, argv[2] the BagWriter options as JSON. Prints ``ready`` first, then the
#: log time (ns) of each message written: what it had written when it died is a fact.
WRITER = """
import json, sys, time
import numpy as np
from wet_eha_thermal.bag import cdr
from wet_eha_thermal.bag.writer import BagWriter
bag = BagWriter(sys.argv[1], **json.loads(sys.argv[2]))
bag.add_topic('/f', 'std_msgs/msg/Float64')
pressure = sys.argv[3] == 'pressure'
if pressure:
    bag.add_topic('/p', 'sensor_msgs/msg/FluidPressure')
print('ready', flush=True)
start, i = time.monotonic(), 0
while True:
    now_ns = time.time_ns()
    bag.write('/f', cdr.encode_float64(float(i)), now_ns)
    if pressure:
        bag.write('/p', cdr.encode_stamped(np.array([now_ns]), 'port_a', [[1e5 + i, 0.0]])[0],
                  now_ns)
    print(now_ns, flush=True)
    i += 1
    time.sleep(max(0.0, start + i / 1000 - time.monotonic()))
"""


class Killed:
    """What :func:`killed_at_exit` leaves: the child and when it was killed (time.time_ns())."""

    def __init__(self, child: subprocess.Popen) -> None:
        self.child = child
        self.kill_ns = None


@contextlib.contextmanager
def killed_at_exit(argv, **popen):
    """
    Run ``argv`` as a child (OPENBLAS_NUM_THREADS=1); SIGKILL it when the block ends.

    Yields a :class:`Killed`; its ``kill_ns`` is set once the signal is sent.
    The child is reaped even when the block fails.
    """
    child = subprocess.Popen(argv, env=dict(os.environ, OPENBLAS_NUM_THREADS='1'), **popen)
    killed = Killed(child)
    try:
        yield killed
        killed.kill_ns = time.time_ns()
        child.send_signal(signal.SIGKILL)
    finally:
        child.kill()
        child.wait()


def kill_writer(target, messages: int, pressure: bool = False, **options):
    """
    Run :data:`WRITER` on ``target`` with BagWriter ``options``; SIGKILL it mid-run.

    It is killed once it has written ``messages`` (however long the machine
    takes to let it). Returns ``(written, last_ns)``: the messages (of ``/f``)
    it had written when it died and the log time of the last, in ns.
    """
    argv = [sys.executable, '-c', WRITER, str(target), json.dumps(options),
            'pressure' if pressure else 'float']
    stamps = []
    with killed_at_exit(argv, stdout=subprocess.PIPE, text=True) as killed:
        out = killed.child.stdout
        assert out.readline().strip() == 'ready'
        while len(stamps) < messages:
            stamps.append(int(out.readline()))
    # what it printed before it died, each line after its write (a cut last line is not one)
    stamps += [int(line) for line in out.read().splitlines(keepends=True)
               if line.endswith('\n')]
    return len(stamps), stamps[-1]


def in_a_fresh_process(module: str, function: str, *args: str, forks: bool = True,
                       timeout_s: float = 600.0):
    """
    Call ``module.function(*args)`` (a test module's; string arguments) in a fresh interpreter.

    What a command (one thread) gets, where the package forks its children: not
    this test process, whose ROS tests' objects and DDS threads a forked child
    would inherit (children forked so died in their GC). Asserts that the child
    forks (unless ``forks`` is false) and that the call returns within
    ``timeout_s``; the child's output is the failure's message.
    """
    fork_check = ('assert processes.child_context().get_start_method() == "fork", '
                  'processes.thread_count(); ') if forks else ''
    script = ('import sys; from wet_eha_thermal import processes; '
              f'import {module} as t; {fork_check}'
              f't.{function}(*sys.argv[1:])')
    done = subprocess.run([sys.executable, '-c', script, *args], cwd=Path(__file__).parent,
                          capture_output=True, text=True, timeout=timeout_s)
    assert done.returncode == 0, done.stdout + done.stderr
