"""A writer in a child process, killed with SIGKILL mid-run: what a crash leaves (tests)."""

import os
import signal
import subprocess
import sys
import time


def sigkill_after(script: str, target, seconds: float) -> int:
    """
    Run ``script`` (Python source) with ``target`` as its argument; SIGKILL it ``seconds`` later.

    The script prints ``ready`` when it starts writing. Returns the kill's time.time_ns().
    """
    child = subprocess.Popen([sys.executable, '-c', script, str(target)],
                             stdout=subprocess.PIPE, text=True,
                             env=dict(os.environ, OPENBLAS_NUM_THREADS='1'))
    try:
        assert child.stdout.readline().strip() == 'ready'
        time.sleep(seconds)
        kill_ns = time.time_ns()
        child.send_signal(signal.SIGKILL)
    finally:
        child.kill()
        child.wait()
    return kill_ns
