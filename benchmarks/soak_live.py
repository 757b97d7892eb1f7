"""
Soak benchmark of the live twin: memory, CPU and recording of ``live`` over a long run.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/soak_live.py --minutes 60
     [--stage 6] [--out DIR] [--interval-s 5] [--warmup-min 5] [--record PATH]
     [any other option of ``wet-eha-thermal live``, passed on: --no-foxglove, --rate-Hz ...]

Starts ``python -m wet_eha_thermal.cli live --duration <minutes * 60>`` in a
process group of its own (Ctrl-C here is passed on to it as SIGINT; a second
one kills it), finds its children in ``/proc`` by their command lines (the
rig ``sim_rig_node``, the estimator ``estimator_node``, the recorder
``recorder_node``) and every ``--interval-s`` samples, for each of them and
for ``live``'s own process (the monitor): the RSS (``VmRSS`` of
``/proc/<pid>/status``) and the CPU time (utime + stime of
``/proc/<pid>/stat``, as a share of one core over the interval); the
recording's size on disk (all its files); the monitor's last status line
(the estimated winding hot-spot, the inputs on fallback); and, since the
machine may be shared, the CPU its other processes took (the busy time of
``/proc/stat`` less that of live's processes) and the time the hypervisor
stole.

Time counts from the rig's start (``duty_s``, read from ``live``'s status
line), so the start-up (model loading, discovery) is left out of the figures.
At the end it parses ``live``'s summary and prints, per process, the RSS at
the end of the warm-up (``--warmup-min`` of duty) and at the end of the duty,
the RSS slope after the warm-up (a least-squares line, MB/h, with the
standard error of its slope), the mean CPU over the duty and its drift (the
slope of the CPU share over the duty, % of a core per hour); then the
samples the rig published, the estimator received and lost, the stale
events, the recording's size and its growth after the warm-up (MiB/h), the
other processes' mean CPU. MB
are 10^6 bytes, MiB 2^20. It writes every sample to ``soak.csv``, a plot
(RSS, CPU and recording against time) to ``soak.png``, the table to
``soak.txt`` and ``live``'s output to ``live.log`` in ``--out`` (default
``runs/soak_<UTC time>``; the recording ``<out>/bag`` unless ``--record``).

Exit status: ``live``'s (1 when it was killed). Whatever happens, ``live``
gets SIGINT, then SIGKILL of its group, and any child still running SIGKILL;
should this script be killed, the kernel sends ``live`` SIGINT.
"""

import argparse
import csv
import ctypes
import io
import math
import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time
from typing import Dict, List, Optional

import procfs
from soak_stats import Fit, linear_fit, parse_status_line, parse_summary
from wet_eha_thermal.output_files import save_figure, write_text

#: The children of ``live``, by a piece of their command line.
NODES = {'rig': 'wet_eha_thermal.ros.sim_rig_node',
         'estimator': 'wet_eha_thermal.ros.estimator_node',
         'recorder': 'wet_eha_thermal.ros.recorder_node'}
#: Processes sampled: ``live`` itself (its status monitor) and its children.
PROCESSES = ('monitor',) + tuple(NODES)
#: Longest wait for ``live`` to stop its children and print its summary after a SIGINT (s):
#: live's own shutdown takes at most (6 + 3 + 5) s for the rig and estimator, then again for
#: the recorder, then it reads the recording.
SHUTDOWN_S = 60.0
MB, MiB = 1e6, 2.0 ** 20


def _parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0].strip(), allow_abbrev=False,
                                epilog='Other options are passed on to wet-eha-thermal live.')
    p.add_argument('--minutes', type=float, required=True, help='duty to run, minutes')
    p.add_argument('--stage', type=int, default=None, help="reference stage (live's default: 6)")
    p.add_argument('--out', type=Path, default=None,
                   help='folder of the results (default: runs/soak_<UTC time>)')
    p.add_argument('--interval-s', type=float, default=5.0,
                   help='seconds between samples (default: %(default)g)')
    p.add_argument('--warmup-min', type=float, default=5.0,
                   help='minutes of duty left out of the RSS slope and the recording growth '
                        '(default: %(default)g)')
    p.add_argument('--record', type=Path, default=None, metavar='PATH',
                   help="live's recording (default: <out>/bag)")
    args, rest = p.parse_known_args(argv)
    if any(a == '--duration' or a.startswith('--duration=') for a in rest):
        p.error('--duration is --minutes here')
    if args.minutes <= 0 or args.interval_s <= 0 or args.warmup_min < 0:
        p.error('--minutes and --interval-s must be positive, --warmup-min not negative')
    return args, rest


def path_bytes(path: Path) -> Optional[int]:
    """Return the size of a file, or of all the files under a folder (bytes); None if absent."""
    try:
        if path.is_file():
            return path.stat().st_size
        if path.is_dir():
            total = 0
            for root, _, files in os.walk(path):
                for f in files:
                    try:
                        total += (Path(root) / f).stat().st_size
                    except OSError:         # renamed while walking (a .partial)
                        pass
            return total
    except OSError:
        pass
    return None


class Output:
    """Reads ``live``'s output in a thread: echoes it, keeps it, follows its status line."""

    def __init__(self, stream, echo) -> None:
        self.lines: List[str] = []
        self.status: Dict[str, object] = {}
        self.duty_start: Optional[float] = None      # monotonic time of the rig's start
        self._echo = echo
        self._thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._thread.start()

    def _read(self, stream) -> None:
        for line in stream:
            now = time.monotonic()
            line = line.rstrip('\n')
            self.lines.append(line)
            self._echo.write(line + '\n')
            self._echo.flush()
            status = parse_status_line(line)
            if status is not None:
                if self.duty_start is None:
                    self.duty_start = now - status['t_s']
                self.status = status

    def join(self, timeout: float) -> None:
        """Wait for the end of the output."""
        self._thread.join(timeout)


class Sampler:
    """The processes followed, and one row of figures per call."""

    def __init__(self, live_pid: int, record: Optional[Path]) -> None:
        self.pids: Dict[str, int] = {'monitor': live_pid}
        self.starts: Dict[int, int] = {}
        self.record = record
        self._last: Dict[str, tuple] = {}           # name -> (monotonic, cpu seconds, ...)
        self._remember(live_pid)

    def _remember(self, pid: int) -> None:
        try:
            self.starts[pid] = procfs.start_ticks(pid)
        except (OSError, ValueError, IndexError):
            pass

    def find(self) -> None:
        """Look for the children not found yet, and note every child of ``live``."""
        live_pid = self.pids['monitor']
        missing = {n: tag for n, tag in NODES.items() if n not in self.pids}
        if missing:
            for name, pid in procfs.children_by_command(live_pid, missing).items():
                self.pids[name] = pid
                self._remember(pid)
        for pid in procfs.children(live_pid):
            if pid not in self.starts:
                self._remember(pid)

    def sample(self) -> Dict[str, object]:
        """Return one row: the time, each process's RSS (MB) and CPU share (%), the bag (MiB)."""
        self.find()
        now = time.monotonic()
        row: Dict[str, object] = {'mono': now}
        for name, pid in self.pids.items():
            try:
                rss, cpu = procfs.rss_bytes(pid), procfs.cpu_seconds(pid)
            except (OSError, ValueError, IndexError):    # ended
                continue
            row[f'{name}_rss_MB'] = rss / MB
            last = self._last.get(name)
            if last is not None and now > last[0]:
                row[f'{name}_cpu_pct'] = 100.0 * (cpu - last[1]) / (now - last[0])
            self._last[name] = (now, cpu)
        try:
            busy, steal = procfs.machine_cpu_seconds()
        except (OSError, ValueError):
            busy = steal = None
        last = self._last.get('machine')
        ours = [row.get(f'{n}_cpu_pct') for n in self.pids]
        if busy is not None and last is not None and now > last[0] and None not in ours:
            # the machine is shared: what the others took is the context of every CPU figure
            row['others_cpu_pct'] = 100.0 * (busy - last[1]) / (now - last[0]) - sum(ours)
            row['steal_pct'] = 100.0 * (steal - last[2]) / (now - last[0])
        if busy is not None:
            self._last['machine'] = (now, busy, steal)
        size = path_bytes(self.record) if self.record is not None else None
        if size is not None:
            row['bag_MiB'] = size / MiB
        return row

    def survivors(self) -> List[int]:
        """Return the processes seen that still run (the same process, not a reused pid)."""
        return [pid for pid, start in self.starts.items() if procfs.same_process(pid, start)]


def _stop_with_parent() -> None:
    """Ask the kernel to send this (child) process SIGINT when its parent dies (Linux)."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGINT), 0, 0, 0)  # PDEATHSIG
    except (OSError, AttributeError):
        pass


def run_live(args, rest: List[str], out_dir: Path, record: Optional[Path]):
    """Run ``live`` and sample it; return ``(exit status, rows, its output, pids)``."""
    cmd = [sys.executable, '-m', 'wet_eha_thermal.cli', 'live',
           '--duration', f'{args.minutes * 60.0:g}']
    if args.stage is not None:
        cmd += ['--stage', str(args.stage)]
    if record is not None:
        cmd += ['--record', str(record)]
    cmd += rest
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    env.setdefault('OPENBLAS_NUM_THREADS', '1')
    print('soak: ' + ' '.join(cmd), flush=True)
    proc = subprocess.Popen(cmd, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True,
                            preexec_fn=_stop_with_parent)   # live stops in order if we die
    signals = []

    def on_signal(signum, frame) -> None:
        signals.append(signum)
        try:        # the first asks live to stop in order; a second kills it
            os.killpg(proc.pid, signal.SIGINT if len(signals) == 1 else signal.SIGKILL)
        except ProcessLookupError:
            pass

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    output = Output(proc.stdout, sys.stdout)
    sampler = Sampler(proc.pid, record)
    rows: List[Dict[str, object]] = []
    try:
        due = time.monotonic()
        while proc.poll() is None:
            rows.append(sampler.sample())
            rows[-1]['status'] = dict(output.status)
            due += args.interval_s
            try:
                proc.wait(timeout=max(due - time.monotonic(), 0.0))
            except subprocess.TimeoutExpired:
                pass
    finally:
        _stop(proc, sampler)
        for s, handler in old.items():
            signal.signal(s, handler)
        output.join(10.0)
        write_text(out_dir / 'live.log', '\n'.join(output.lines) + '\n')
    start = output.duty_start
    for row in rows:
        row['t_s'] = row['mono'] - rows[0]['mono']
        row['duty_s'] = row['mono'] - start if start is not None else None
    return proc.returncode, rows, '\n'.join(output.lines), sampler.pids


def _stop(proc: subprocess.Popen, sampler: Sampler) -> None:
    """Stop ``live`` (SIGINT, then SIGKILL of its group) and kill any child still running."""
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGINT)
            proc.wait(timeout=SHUTDOWN_S)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            pass
    if proc.poll() is None:
        sampler.find()          # its children run in sessions of their own: by pid below
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait()
    for pid in sampler.survivors():
        if pid != proc.pid:
            print(f'soak: process {pid} of live still running: SIGKILL', file=sys.stderr)
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


# ------------------------------------------------------------------------------------ figures
def figures(rows: List[Dict[str, object]], duration_s: float, warmup_s: float,
            interval_s: float) -> Dict[str, Dict[str, object]]:
    """
    Return per process its RSS at warm-up end and end, RSS slope, CPU mean and drift.

    Only the duty counts: rows from the rig's start to ``duration_s`` (the
    later ones are the shutdown); the RSS slope and the recording's growth
    over the rows after ``warmup_s``; the CPU over the intervals wholly in the
    duty. Slopes are per hour.
    """
    duty = [r for r in rows if r['duty_s'] is not None and 0.0 <= r['duty_s'] <= duration_s]
    after = [r for r in duty if r['duty_s'] >= warmup_s]
    # a share covers the interval before its row: that interval must be in the duty
    cpu_rows = [r for r in duty if r['duty_s'] >= interval_s * 0.999]
    out: Dict[str, Dict[str, object]] = {}
    for name in PROCESSES + ('bag',):
        key = f'{name}_rss_MB' if name != 'bag' else 'bag_MiB'
        f: Dict[str, object] = {}
        warm = [r for r in after if key in r]
        seen = [r for r in duty if key in r]
        if warm:
            f['at_warmup'] = warm[0][key]
            f['slope'] = _per_hour(linear_fit([r['duty_s'] for r in warm],
                                              [r[key] for r in warm]))
        if seen:
            f['at_end'] = seen[-1][key]
        cpu = [r for r in cpu_rows if f'{name}_cpu_pct' in r]
        if cpu:
            shares = [r[f'{name}_cpu_pct'] for r in cpu]
            f['cpu_mean'] = sum(shares) / len(shares)
            f['cpu_drift'] = _per_hour(linear_fit([r['duty_s'] for r in cpu], shares))
        out[name] = f
    for key in ('others_cpu_pct', 'steal_pct'):
        values = [r[key] for r in cpu_rows if key in r]
        if values:
            out.setdefault('machine', {})[key] = (sum(values) / len(values), min(values),
                                                  max(values))
    return out


def _per_hour(fit: Fit) -> Fit:
    return Fit(fit.slope * 3600.0, fit.stderr * 3600.0, fit.intercept, fit.n)


def _num(value, fmt: str = '.1f') -> str:
    return '-' if value is None else format(value, fmt)


def _slope(fit: Optional[Fit]) -> str:
    if fit is None or fit.slope != fit.slope:
        return '-'
    return f'{fit.slope:+.2f} +- {fit.stderr:.2f}'


def report(fig, summary: Dict[str, object], args, rc: int, pids: Dict[str, int],
           record: Optional[Path]) -> List[str]:
    """Return the lines of the table and of the run's figures."""
    w = args.warmup_min
    lines = [f'Soak of the live twin: {args.minutes:g} min of duty, a sample every '
             f'{args.interval_s:g} s, warm-up {w:g} min; time from the start of the duty',
             '',
             f'{"process":<10} {"pid":>7} {f"RSS {w:g} min":>10} {"RSS end":>9} '
             f'{"RSS slope after warm-up":>24} {"CPU mean":>9} {"CPU drift":>17}',
             f'{"":<10} {"":>7} {"MB":>10} {"MB":>9} {"MB/h +- s.e.":>24} {"% core":>9} '
             f'{"% core/h +- s.e.":>17}']
    for name in PROCESSES:
        f = fig[name]
        lines.append(f'{name:<10} {pids.get(name, "-"):>7} {_num(f.get("at_warmup")):>10} '
                     f'{_num(f.get("at_end")):>9} {_slope(f.get("slope")):>24} '
                     f'{_num(f.get("cpu_mean")):>9} {_slope(f.get("cpu_drift")):>17}')
    lines.append('')
    if 'published' in summary:
        share = 100.0 * summary['lost'] / max(summary['published'], 1)
        lines.append(f'samples     the rig published {summary["published"]} per input; the '
                     f'estimator received {summary["received"]} on its worst input: lost '
                     f'{summary["lost"]} ({share:.3f} %); rejected {summary["rejected"]}')
    else:
        lines.append('samples     not in the summary of live')
    if 'stale_events' in summary:
        per = ', '.join(f'{k} {v}' for k, v in summary['stale_per_input'].items())
        lines.append(f'stale       {summary["stale_events"]} events ({summary["stale_since"]})'
                     + (f': {per}' if per else ''))
    bag = fig['bag']
    if record is not None:
        size = path_bytes(record)
        text = (f'recording   {record}: {_num(size / MiB if size is not None else None)} MiB '
                f'on disk after the run; growth after warm-up {_slope(bag.get("slope"))} MiB/h')
        if 'recording_messages' in summary:
            text += f'; {summary["recording_messages"]} messages'
        lines.append(text)
    machine = fig.get('machine', {})
    if 'others_cpu_pct' in machine:
        mean, low, high = machine['others_cpu_pct']
        text = (f'machine     {os.cpu_count()} cores; the other processes took {mean:.0f} % of a '
                f'core over the duty (samples {low:.0f} to {high:.0f} %)')
        if 'steal_pct' in machine:
            text += f', the hypervisor stole {machine["steal_pct"][0]:.1f} %'
        lines.append(text)
    if 'duty_s' in summary:
        lines.append(f'live        {summary["duty_s"]:g} s of duty after {summary["start_s"]:g} '
                     f's of start-up ({summary["stopped_by"]}); exit status {rc}; '
                     + ', '.join(f'{k} {v}' for k, v in summary.get('exits', {}).items()))
    else:
        lines.append(f'live        exit status {rc}; no summary found in its output')
    return lines


def write_csv(path: Path, rows: List[Dict[str, object]]) -> None:
    """Write every sample: times (from the start of live, of the duty), figures, status."""
    cols = ['t_s', 'duty_s'] + [f'{p}_{q}' for p in PROCESSES for q in ('rss_MB', 'cpu_pct')] + [
        'others_cpu_pct', 'steal_pct', 'bag_MiB', 'hotspot_C', 'stale']
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator='\n')
    writer.writerow(cols)
    for r in rows:
        st = r.get('status', {})
        values = [r.get(c, st.get(c)) for c in cols]
        writer.writerow(['' if v is None else (f'{v:.4f}' if isinstance(v, float) else v)
                         for v in values])
    write_text(path, buf.getvalue())


def plot(path: Path, rows: List[Dict[str, object]], warmup_s: float, duration_s: float) -> None:
    """Plot RSS, CPU and the recording's size against the duty's time."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    rows = [r for r in rows if r['duty_s'] is not None and r['duty_s'] <= duration_s]
    fig, axes = plt.subplots(3, 1, figsize=(7.0, 7.5), sharex=True)
    for ax, q, label in ((axes[0], 'rss_MB', 'RSS [MB]'), (axes[1], 'cpu_pct', 'CPU [% core]')):
        for name in PROCESSES:
            pts = [(r['duty_s'] / 60.0, r[f'{name}_{q}']) for r in rows if f'{name}_{q}' in r]
            if pts:
                ax.plot(*zip(*pts), label=name, lw=1.0)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    pts = [(r['duty_s'] / 60.0, r['others_cpu_pct']) for r in rows if 'others_cpu_pct' in r]
    if pts:
        axes[1].plot(*zip(*pts), label='other processes', color='grey', ls='--', lw=0.8)
    axes[0].legend(fontsize=8, ncol=4)
    axes[1].legend(fontsize=8, ncol=5)
    pts = [(r['duty_s'] / 60.0, r['bag_MiB']) for r in rows if 'bag_MiB' in r]
    if pts:
        axes[2].plot(*zip(*pts), color='k', lw=1.0)
    axes[2].set_ylabel('recording [MiB]')
    axes[2].set_xlabel("time from the rig's start [min]")
    axes[2].grid(alpha=0.3)
    for ax in axes:
        ax.axvline(warmup_s / 60.0, color='grey', ls=':', lw=1.0)
    save_figure(fig, path)


def main(argv=None) -> int:
    """Run the soak; print and write the figures; return live's exit status."""
    args, rest = _parse_args(argv)
    out_dir = args.out or Path('runs') / f'soak_{time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())}'
    out_dir.mkdir(parents=True, exist_ok=True)
    record = None if '--no-record' in rest else (args.record or out_dir / 'bag').resolve()
    rc, rows, text, pids = run_live(args, rest, out_dir, record)
    summary = parse_summary(text)
    # the duty ends earlier on a Ctrl-C: what follows is the shutdown
    duration_s = min(args.minutes * 60.0, summary.get('duty_s', math.inf))
    warmup_s = args.warmup_min * 60.0
    if warmup_s >= duration_s:
        print(f'soak: the warm-up ({args.warmup_min:g} min) is as long as the run: no slope '
              'after it', file=sys.stderr)
    fig = figures(rows, duration_s, warmup_s, args.interval_s)
    lines = report(fig, summary, args, rc, pids, record)
    print('\n' + '\n'.join(lines))
    write_text(out_dir / 'soak.txt', '\n'.join(lines) + '\n')
    write_csv(out_dir / 'soak.csv', rows)
    if rows:
        plot(out_dir / 'soak.png', rows, warmup_s, duration_s)
    print(f'soak: samples in {out_dir / "soak.csv"}, plot {out_dir / "soak.png"}, live\'s '
          f'output {out_dir / "live.log"}')
    return rc if rc >= 0 else 1


if __name__ == '__main__':
    sys.exit(main())
