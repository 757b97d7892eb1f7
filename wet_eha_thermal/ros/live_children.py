"""
The child processes of ``live``: what to run, their command lines, starting and stopping them.

Each child runs in its own session, so a Ctrl-C on the terminal reaches
``live`` only and the shutdown stays in order; it also gets SIGKILL from the
kernel should ``live`` die without cleaning up, so no child outlives it. Its
output goes to a log file, where ``live`` finds the child's
:class:`~wet_eha_thermal.interface.NodeReport` after it exited.
"""

import ctypes
from dataclasses import dataclass
import os
from pathlib import Path
import signal
import subprocess
import sys
import time
from typing import Dict, List, Optional, Tuple

from wet_eha_thermal import interface
from wet_eha_thermal.interface import ESTIMATOR_NODE, NodeReport, RECORDER_NODE
from wet_eha_thermal.live_view import address_text

#: Shutdown timeouts (s) after SIGINT, then after SIGTERM. A clean stop closes the recording
#: and lets the estimator's last messages reach their readers (estimator_runner's
#: LAST_MESSAGES_WAIT_S); beside a busy machine (load 4.6 on 2 cores, where its start-up took
#: 21 s against 2 s quiet) the estimator took more than 6 s, and was killed mid-teardown.
SIGINT_WAIT_S, SIGTERM_WAIT_S = 15.0, 3.0
#: Longest start-up (processes, model warm-up, discovery) before the rig's duty (s): the
#: rig starts anyway after it, the run ends with an error a little later.
START_TIMEOUT_S = 120.0
#: History depth of the recorder's subscriptions (1 s of a 1 kHz topic).
RECORDER_DEPTH = 1000
PARAMS_FILE = Path(__file__).resolve().parents[2] / 'config' / 'estimator.params.yaml'


@dataclass
class LiveOptions:
    """What to run: a stage or a duty file, for how long, at which sample rate, closed loop."""

    stage: Optional[int] = 6
    duty: Optional[Path] = None
    duration_s: float = 60.0
    rate_Hz: float = 1000.0
    config: Optional[Path] = None
    noise: bool = True
    executor: str = 'events'
    record: bool = True
    record_path: Optional[Path] = None      # None: the bag directory runs/live_<UTC time>
    # splits of the recording, as ros2 bag record's --max-bag-size and --max-bag-duration
    max_bag_size_B: int = interface.LIVE_SPLIT_BYTES
    max_bag_duration_s: float = interface.LIVE_SPLIT_DURATION_S
    foxglove: Optional[Tuple[str, int]] = ('127.0.0.1', 8765)    # None: no Foxglove view
    closed_loop: bool = False       # the rig's drive honours the estimator's current limit
    as_built_seed: int = 1          # the rig's truth: a draw of the stated uncertainty (0: none)


def child_commands(opts: LiveOptions, hardware_id: str,
                   record_path: Optional[Path] = None) -> Dict[str, List[str]]:
    """
    Return the command lines of the children: ``{'rig': [...], 'estimator': [...], ...}``.

    With ``record_path``, also ``'recorder'``: it takes the estimator's
    parameters file and configuration (to store them) and always the events
    executor (the single-threaded one loses messages above about 2 k msg/s).
    """
    py = sys.executable
    waits = waited_nodes(record_path is not None)
    rig = [py, '-m', 'wet_eha_thermal.ros.sim_rig_node', '--executor', opts.executor,
           '--ros-args', '-p', f'rate_Hz:={float(opts.rate_Hz)!r}',
           '-p', f'noise:={"true" if opts.noise else "false"}', '-p', 'qos:=reliable',
           '-p', f'hardware_id:={hardware_id}',
           # the duty starts once the estimator and the recorder are warm and hear every
           # input: before that, samples would be lost or wait behind a start-up
           '-p', f'wait_for:=[{", ".join(waits)}]',
           '-p', f'wait_for_subscribers:={len(waits)}',
           '-p', f'start_timeout_s:={START_TIMEOUT_S!r}',
           '-p', f'honour_limit:={"true" if opts.closed_loop else "false"}',
           '-p', f'as_built_seed:={int(opts.as_built_seed)}']
    if opts.duty is not None:
        rig += ['-p', f'duty_file:={Path(opts.duty).resolve()}']
    else:
        rig += ['-p', f'stage:={int(opts.stage)}']
    est = [py, '-m', 'wet_eha_thermal.ros.estimator_node', '--executor', opts.executor,
           '--ros-args']
    if PARAMS_FILE.is_file():
        est += ['--params-file', str(PARAMS_FILE)]
    est += ['-p', 'qos:=reliable', '-p', f'hardware_id:={hardware_id}']
    if opts.foxglove is not None:
        est += ['-p', f'foxglove_address:={address_text(*opts.foxglove)}']
    rec = [py, '-m', 'wet_eha_thermal.ros.recorder_node', '--executor', 'events', '--ros-args']
    if PARAMS_FILE.is_file():
        rec += ['--params-file', str(PARAMS_FILE), '-p', f'params_file:={PARAMS_FILE}']
    # its own depth, not the file's 100: a 20 ms stall of the recorder would lose samples
    rec += ['-p', 'qos:=reliable', '-p', f'qos_depth:={RECORDER_DEPTH}',
            '-p', f'hardware_id:={hardware_id}', '-p', f'output:={record_path}',
            '-p', 'wait_for_estimator:=true',
            '-p', f'split_bytes:={int(opts.max_bag_size_B)}',
            '-p', f'split_duration_s:={float(opts.max_bag_duration_s)!r}']
    if opts.config is not None:
        cfg = str(Path(opts.config).resolve())
        rig += ['-p', f'config_file:={cfg}']
        est += ['-p', f'config_file:={cfg}']
        rec += ['-p', f'config_file:={cfg}']
    commands = {'rig': rig, 'estimator': est}
    if record_path is not None:
        commands['recorder'] = rec
    return commands


def waited_nodes(recording: bool) -> List[str]:
    """Return the nodes the rig waits for before its duty (the recorder when recording)."""
    return [ESTIMATOR_NODE] + ([RECORDER_NODE] if recording else [])


def _die_with_parent() -> None:
    """Ask the kernel to SIGKILL this (child) process when its parent dies (Linux)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)     # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


class Child:
    """One child process in its own session, its output in a log file."""

    def __init__(self, name: str, cmd: List[str], env: Dict[str, str], log_dir: Path) -> None:
        self.name = name
        self.log_path = log_dir / f'{name}.log'
        self._log = open(self.log_path, 'wb')
        self.proc = subprocess.Popen(cmd, env=env, stdin=subprocess.DEVNULL, stdout=self._log,
                                     stderr=subprocess.STDOUT, start_new_session=True,
                                     preexec_fn=_die_with_parent)
        self.signals: List[str] = []     # what it took to stop it
        #: what its exit statuses other than 0 mean when it stopped as asked (by SIGINT)
        self.meanings: Dict[int, str] = {}

    def running(self) -> bool:
        """Return whether the process is still running."""
        return self.proc.poll() is None

    def signal(self, sig: int) -> None:
        """Send ``sig`` to the child's process group (nothing if it already ended)."""
        if self.running():
            self.signals.append(signal.Signals(sig).name)
            try:
                os.killpg(self.proc.pid, sig)
            except ProcessLookupError:
                pass

    def close(self) -> None:
        """Close the log file."""
        self._log.close()

    def lines(self) -> List[str]:
        """Return its output so far, line by line."""
        try:
            return self.log_path.read_text(errors='replace').splitlines()
        except OSError:
            return []

    def tail(self, n: int = 15) -> List[str]:
        """Return the last ``n`` lines of its output."""
        return self.lines()[-n:]

    def report(self) -> Optional[NodeReport]:
        """Return the report the node printed at its shutdown (None without one)."""
        return NodeReport.find(self.lines())

    def clean(self) -> bool:
        """Return whether it exited by itself with status 0 after at most a SIGINT."""
        return self.proc.returncode == 0 and not (set(self.signals) - {'SIGINT'})

    def describe(self) -> str:
        """Return how it ended, in words."""
        rc = self.proc.returncode
        if rc is None:
            return 'still running'
        how = f'exit status {rc}' if rc >= 0 else f'killed by {signal.Signals(-rc).name}'
        if self.clean():
            return f'exited cleanly ({how})'
        if rc in self.meanings and not set(self.signals) - {'SIGINT'}:
            return f'exited ({how}: {self.meanings[rc]})'
        if not self.signals:
            return f'ended by itself ({how})'
        return f'did not exit cleanly ({how}; sent {", ".join(self.signals)})'


def start_children(opts: LiveOptions, domain: int, hardware_id: str,
                   record_path: Optional[Path], log_dir: Path) -> List[Child]:
    """Start the rig, the estimator and the recorder (with ``record_path``) on ``domain``."""
    env = dict(os.environ)
    env.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               PYTHONUNBUFFERED='1', RCUTILS_COLORIZED_OUTPUT='0')
    env.setdefault('OPENBLAS_NUM_THREADS', '1')
    commands = child_commands(opts, hardware_id, record_path)
    # all at once: the rig waits for the others to be ready before its duty starts
    children = [Child(name, commands[name], env, log_dir)
                for name in ('rig', 'estimator', 'recorder') if name in commands]
    for c in children:
        if c.name == 'recorder':     # the recorder's own summary line says what it lost
            c.meanings[1] = 'the recording lost messages to write errors'
    return children


def stop_children(children: List[Child]) -> None:
    """Stop every child: SIGINT, then SIGTERM, then SIGKILL, each after a timeout."""
    for sig, wait_s in ((signal.SIGINT, SIGINT_WAIT_S), (signal.SIGTERM, SIGTERM_WAIT_S),
                        (signal.SIGKILL, 5.0)):
        for c in children:
            c.signal(sig)
        deadline = time.monotonic() + wait_s
        for c in children:
            try:
                c.proc.wait(timeout=max(deadline - time.monotonic(), 0.01))
            except subprocess.TimeoutExpired:
                pass
        if not any(c.running() for c in children):
            return
