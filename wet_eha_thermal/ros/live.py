"""
The live digital twin in one command: simulated rig, estimator and a status line.

:func:`run` starts three child processes together, the recorder
(:mod:`.recorder_node`, unless ``record`` is off), the estimator
(:mod:`.estimator_node`) and the simulated rig (:mod:`.sim_rig_node`), on a
private ROS domain (``WET_EHA_LIVE_DOMAIN_ID``, or the first domain with no
ROS node on this machine from one picked by the process id; discovery
limited to this machine), and a small node in this process that follows the
ready topic, the estimates, the alerts, the drive's current limits and
/diagnostics and prints one status line about twice a second (updated in
place on a terminal, one line every few seconds otherwise). The estimator
also serves the Foxglove view (:mod:`wet_eha_thermal.live_view`) at ``foxglove`` (127.0.0.1:8765 by
default); :func:`run` prints the address to open. An address already in use
is one line on stderr, and the run goes on without the view: the twin
matters more than its display.

First it compiles the model's and the estimator's numba kernels (or loads
them from numba's cache: about a second), so that the children load them
instead of compiling them side by side. The rig starts its duty only once
the estimator and the recorder have said on ``/eha/ready`` that they are
ready (model loaded and warmed, every input matched), so no sample is
published before they listen, however long the start-up takes on this
machine; ``duration_s`` counts from that start. A
start-up longer than ``START_TIMEOUT_S`` ends the run with a message naming
who was not ready. After ``duration_s``, or on Ctrl-C / SIGTERM, it stops the
children (SIGINT, then SIGTERM, then SIGKILL, each after a timeout; the
recorder last, so that it keeps everything the others sent), prints a summary
(samples the rig published and the estimator received, from the reports
they print at shutdown; the recording's path and message count) and returns the exit
status: 0 when every child ran to the end, shut down cleanly and estimates
came, 1 otherwise (with the last lines a failed child printed). The recording
(the rosbag2 bag directory ``runs/live_<UTC time>`` by default) holds the
configuration and the estimator's parameters file, so the run can be
replayed from it alone.

With ``closed_loop`` the rig's simulated drive honours the current limit the
estimator publishes for it (the rig's ``honour_limit``; the load yields where
the duty asks for more current): the status line shows the limit and how
much of the time it clamped, the summary when it first did, the largest cut
and the rig truth's peak hot-spot.

The jobs live beside this module: the child processes in
:mod:`.live_children`, the private domain and the monitor node in
:mod:`.live_monitor`, the status line and the summary in :mod:`.live_text`.
"""

from dataclasses import replace
import math
import os
from pathlib import Path
import shutil
import signal
import socket
import sys
import tempfile
import time
from typing import Dict, List, Optional, TextIO, Tuple

import rclpy
from rclpy.executors import SingleThreadedExecutor
from wet_eha_thermal.config import load_config
from wet_eha_thermal.estimator.warmup import compile_estimator
from wet_eha_thermal.live_view import address_text
from wet_eha_thermal.ros.live_children import (Child, LiveOptions, start_children,
                                               START_TIMEOUT_S, stop_children, waited_nodes)
from wet_eha_thermal.ros.live_monitor import monitor_node, open_domain, TwinState
from wet_eha_thermal.ros.live_text import (duty_text, foxglove_lines, starting_line,
                                           status_line, StatusPrinter, summary)
from wet_eha_thermal.ros.recorder_node import default_output


def address_taken(host: str, port: int) -> Optional[str]:
    """Return why ``host:port`` cannot be listened on now, or None when it can."""
    family = socket.AF_INET6 if ':' in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as sock:
        # as the server binds: a port a finished run left in TIME_WAIT is free
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((host, port))
        except OSError as exc:
            return exc.strerror or str(exc)
    return None


def run(opts: LiveOptions, out: TextIO = sys.stdout, err: TextIO = sys.stderr,
        domain: Optional[int] = None) -> int:
    """
    Run the live twin for ``opts.duration_s`` (or until Ctrl-C); return the exit status.

    ``domain``: the ROS domain to use; None picks a free one (see
    :func:`~.live_monitor.open_domain`). Returns 2 at once when the
    recording's path exists (file or directory).
    """
    opts, record_path = _check_outputs(opts, err)
    if opts is None:
        return 2
    _load_model(opts, out)
    log_dir = Path(tempfile.mkdtemp(prefix='wet-eha-live-'))
    stop = {'why': None}

    def on_signal(signum, frame) -> None:
        stop['why'] = 'interrupted' if signum == signal.SIGINT else 'terminated'

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    children: List[Child] = []
    context = node = executor = None
    state = TwinState()
    printer = StatusPrinter(out)
    early: Optional[Child] = None
    t0 = time.monotonic()
    try:
        os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'   # for this process's node
        context, domain = open_domain(domain)
        _announce(opts, domain, out)
        node = monitor_node(context, state)
        children = start_children(opts, domain, state.hardware_id, record_path, log_dir)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        early = _follow(opts, state, children, executor, printer, stop, t0,
                        waited_nodes(record_path is not None))
    finally:
        printer.finish()
        end = time.monotonic()
        start_s = (state.rig_started if state.rig_started is not None else end) - t0
        _shut_down(children, node, executor, context)
        for s, handler in old.items():
            signal.signal(s, handler)
    for line in summary(opts, state, children, end - t0 - start_s, domain,
                        stop['why'] or 'stopped', record_path, start_s):
        print(line, file=out)
    out.flush()
    ok = _report_errors(state, children, early, start_s, record_path, err)
    if ok:
        shutil.rmtree(log_dir, ignore_errors=True)
    else:
        print(f'(logs of the children kept in {log_dir})', file=err)
    err.flush()
    return 0 if ok else 1


def _load_model(opts: LiveOptions, out: TextIO) -> None:
    """Compile the model's kernels, or load them from numba's cache, saying so."""
    # here, once: the rig and the estimator then load numba's cache in about a second each,
    # instead of both compiling at once (minutes on a busy machine) after an install
    print('loading the compiled model (after an install or a change of the model code it '
          'compiles once, in a minute or two) ...', file=out, flush=True)
    print(f'model ready in {compile_estimator(load_config(opts.config)):.1f} s', file=out,
          flush=True)


def _announce(opts: LiveOptions, domain: int, out: TextIO) -> None:
    """Print what runs, for how long, on which domain, and where the Foxglove view is."""
    print(f'Live digital twin: {duty_text(opts)} on the simulated rig for '
          f'{opts.duration_s:g} s (Ctrl-C stops it earlier), ROS domain {domain}'
          + ("; closed loop: the rig's drive honours the estimator's current limit"
             if opts.closed_loop else ''),
          file=out, flush=True)
    if opts.foxglove is not None:
        print('\n'.join(foxglove_lines(*opts.foxglove)), file=out, flush=True)


def _check_outputs(opts: LiveOptions,
                   err: TextIO) -> Tuple[Optional[LiveOptions], Optional[Path]]:
    """
    Return ``(opts, record_path)`` once the Foxglove address and the recording are checked.

    A taken address turns the view off (one line on ``err``); an existing
    recording path returns ``(None, None)``: a recording is never overwritten.
    """
    if opts.foxglove is not None:
        taken = address_taken(*opts.foxglove)
        if taken:
            print(f'Foxglove view: {address_text(*opts.foxglove)}: {taken}; the twin runs '
                  'without it (--foxglove HOST:PORT for another address)', file=err, flush=True)
            opts = replace(opts, foxglove=None)
    record_path = None
    if opts.record:
        record_path = Path(opts.record_path or default_output('live')).resolve()
        if record_path.exists():
            print(f'error: {record_path} exists: a recording is never overwritten', file=err)
            return None, None
    return opts, record_path


def _follow(opts: LiveOptions, state: TwinState, children: List[Child], executor,
            printer: StatusPrinter, stop: Dict[str, Optional[str]], t0: float,
            waits: List[str]) -> Optional[Child]:
    """
    Spin the monitor and print the status until the run ends; return a child that died early.

    The run ends at ``opts.duration_s`` after the rig's start, at a signal
    (``stop['why']`` set by its handler), when the start-up takes too long or
    when a child exits; ``stop['why']`` then says which.
    """
    # the rig starts anyway after START_TIMEOUT_S; a little later the run gives up
    start_limit = t0 + START_TIMEOUT_S + 10.0
    early = None
    while stop['why'] is None:
        now = time.monotonic()
        if state.rig_started is None:
            if now >= start_limit:
                stop['why'] = 'start-up timed out'
                break
            line = starting_line(state, now - t0, waits)
        else:
            elapsed = now - state.rig_started
            if elapsed >= opts.duration_s:
                stop['why'] = 'duration reached'
                break
            line = status_line(state, elapsed, opts.duration_s)
        executor.spin_once(timeout_sec=0.05)
        early = next((c for c in children if not c.running()), None)
        if early is not None:
            stop['why'] = f'the {early.name} exited early'
            break
        printer.update(now, line, state.estimates > 0)
    if state.rig_started is not None:
        printer.update(math.inf, status_line(state, time.monotonic() - state.rig_started,
                                             opts.duration_s), state.estimates > 0)
    return early


def _shut_down(children: List[Child], node, executor, context) -> None:
    """Stop the children, then this process's node, executor and ROS context."""
    # the recorder last, so that it keeps what the others sent until they stopped
    stop_children([c for c in children if c.name != 'recorder'])
    stop_children([c for c in children if c.name == 'recorder'])
    for c in children:
        c.close()
    if node is not None:
        node.destroy_node()
    if executor is not None:
        executor.shutdown(timeout_sec=1.0)
    if context is not None:
        rclpy.try_shutdown(context=context)


def _report_errors(state: TwinState, children: List[Child], early: Optional[Child],
                   start_s: float, record_path: Optional[Path], err: TextIO) -> bool:
    """Print what went wrong (with the last lines of a failed child); return whether all ran."""
    ok = (early is None and state.rig_started is not None and state.estimates > 0
          and all(c.clean() for c in children))
    if state.rig_started is None and early is None:
        missing = [n for n in waited_nodes(record_path is not None) if n not in state.ready]
        print(f'error: the rig did not start its duty within {start_s:.0f} s of start-up'
              + (f': not ready: {", ".join(missing)}' if missing else ''), file=err)
    elif early is not None:
        print(f'error: the {early.name} {early.describe()} before the end of the run; its last '
              'lines:', file=err)
        for line in early.tail():
            print(f'  {line}', file=err)
    elif not state.estimates:
        print('error: no estimate received from the estimator', file=err)
    for c in children:
        if c is not early and not c.clean():
            print(f'error: the {c.name} {c.describe()}; its last lines:', file=err)
            for line in c.tail(8):
                print(f'  {line}', file=err)
    return ok
