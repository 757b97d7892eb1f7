"""
Child processes started safely from any process: a CLI, a notebook, a ROS node, a test worker.

``fork`` copies only the thread that calls it. A lock that another thread
holds at that moment (a DDS middleware's, an allocator's, a queue's) stays
held in the child for ever, and the child, or the parent waiting on it,
hangs. So a process forks only while it has one thread; otherwise its
children come from the fork server, a process started for that purpose
with no other thread: a child's arguments are then pickled instead of
inherited, and its modules imported, unless the server preloaded them.
"""

from concurrent.futures import ProcessPoolExecutor
import multiprocessing
from multiprocessing.context import BaseContext
import os
import threading
from typing import Iterable, Set

# what the fork server imports once, for every child (only before it starts)
_PRELOAD: Set[str] = set()


def thread_count() -> int:
    """Threads of this process, native ones included (a DDS middleware's); Python's if unknown."""
    try:
        return len(os.listdir('/proc/self/task'))
    except OSError:            # no procfs: the threads Python knows of
        return threading.active_count()


def can_fork() -> bool:
    """Whether a forked child would start in a known state: fork exists and one thread runs."""
    return 'fork' in multiprocessing.get_all_start_methods() and thread_count() == 1


def fork_server(preload: Iterable[str] = ()) -> BaseContext:
    """
    Return the fork server's start method, ``preload`` among the modules it imports once.

    The modules of every caller are kept (the server is one per process); a
    module named after the server started is imported by each child instead.
    """
    methods = multiprocessing.get_all_start_methods()
    if 'forkserver' not in methods:
        return multiprocessing.get_context('spawn')
    ctx = multiprocessing.get_context('forkserver')
    _PRELOAD.update(preload)
    ctx.set_forkserver_preload(sorted(_PRELOAD))
    return ctx


def child_context(preload: Iterable[str] = ()) -> BaseContext:
    """Return the start method for a child process now: fork if safe, else the fork server."""
    return multiprocessing.get_context('fork') if can_fork() else fork_server(preload)


def stop_pool(pool: ProcessPoolExecutor) -> None:
    """Shut ``pool`` down now, its workers killed mid-task (a running task is not waited for)."""
    if hasattr(pool, 'terminate_workers'):          # Python 3.14
        pool.terminate_workers()
    else:
        # before 3.14 the executor keeps them in a private mapping (None once shut down)
        for process in list((getattr(pool, '_processes', None) or {}).values()):
            process.terminate()
    pool.shutdown(wait=True, cancel_futures=True)
