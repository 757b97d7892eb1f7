"""
ROS domains for the test modules that start nodes: one each, claimed with a lock file.

A domain picked from the process id alone is shared, once in so many runs,
by two test sessions on one machine (two clones, two developers, CI beside a
live run), and their nodes then see each other's messages. A claimed domain
is held by an exclusive ``flock`` on a file per domain until the process
ends, however it ends.
"""

import fcntl
import os
from pathlib import Path
import tempfile

FIRST, LAST = 150, 229      # Fast DDS takes domains 0..232 (live probes 100..232 for an idle one)
_held = []                  # the open lock files: closing one would release its domain


def claim_domain() -> int:
    """Return a ROS domain no other process on this machine has claimed; hold it until exit."""
    span = LAST - FIRST + 1
    start = os.getpid() % span
    for k in range(span):
        domain = FIRST + (start + k) % span
        path = Path(tempfile.gettempdir()) / f'wet_eha_thermal_test_domain_{domain}.lock'
        lock = open(path, 'a')
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            lock.close()
            continue
        _held.append(lock)
        return domain
    raise RuntimeError(f'every ROS domain {FIRST}..{LAST} is claimed by another test process')
