"""Child processes: forked only from a process with one thread, else from the fork server."""

import threading

from wet_eha_thermal import processes


def test_a_process_that_runs_a_thread_does_not_fork():
    alone = processes.thread_count()
    stop = threading.Event()
    thread = threading.Thread(target=stop.wait)
    thread.start()
    try:
        assert processes.thread_count() == alone + 1
        assert not processes.can_fork()
        assert processes.child_context().get_start_method() in ('forkserver', 'spawn')
    finally:
        stop.set()
        thread.join()
