"""
What the benchmarks read of a process in ``/proc`` (Linux): CPU time, RSS, children.

No dependency beyond the standard library; every function takes the root
(``/proc``) so that a test can hand it a directory of its own.
"""

import os
from pathlib import Path
from typing import Dict, List, Optional, Tuple

PROC = Path('/proc')


def _stat_fields(text: str) -> list:
    """Return the fields of a ``/proc/<pid>/stat`` line after the command name (field 3 on)."""
    # the name, in parentheses, may hold spaces and parentheses itself: cut at the last one
    return text[text.rindex(')') + 2:].split()


def cpu_seconds(pid: int, root: Path = PROC) -> float:
    """Return utime + stime of process ``pid`` (s) from ``/proc/<pid>/stat``."""
    fields = _stat_fields((root / str(pid) / 'stat').read_text())
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def tree_cpu_seconds(pid: int, root: Path = PROC) -> float:
    """
    Return the CPU time of ``pid`` and its descendants (s): utime + stime, cutime + cstime.

    The live ones' own time, and what their children that ended and were
    waited for used; a process that ends between two readings takes its
    time with it until its parent waits for it.
    """
    ticks, todo = 0, [pid]
    while todo:
        p = todo.pop()
        try:
            fields = _stat_fields((root / str(p) / 'stat').read_text())
        except OSError:                    # ended meanwhile
            continue
        ticks += sum(int(fields[k]) for k in (11, 12, 13, 14))
        todo += children(p, root)
    return ticks / os.sysconf('SC_CLK_TCK')


def start_ticks(pid: int, root: Path = PROC) -> int:
    """Return the start of process ``pid`` (clock ticks after boot): with the pid, its identity."""
    return int(_stat_fields((root / str(pid) / 'stat').read_text())[19])


def rss_bytes(pid: int, root: Path = PROC) -> int:
    """Return the resident set size of process ``pid`` (bytes), ``VmRSS`` of its status."""
    for line in (root / str(pid) / 'status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) * 1024      # the kernel's kB are KiB
    raise ValueError(f'process {pid}: no VmRSS (a kernel thread or a zombie)')


def machine_cpu_seconds(root: Path = PROC) -> Tuple[float, float]:
    """
    Return the CPU time of the whole machine: busy and stolen, summed over its cores (s).

    Busy: user, nice, system, irq and softirq of ``/proc/stat`` (guest time is
    in user already); stolen: what the hypervisor gave to other machines.
    """
    for line in (root / 'stat').read_text().splitlines():
        if line.startswith('cpu '):
            ticks = [int(v) for v in line.split()[1:]]
            busy = ticks[0] + ticks[1] + ticks[2] + ticks[5] + ticks[6]
            steal = ticks[7] if len(ticks) > 7 else 0
            return busy / os.sysconf('SC_CLK_TCK'), steal / os.sysconf('SC_CLK_TCK')
    raise ValueError(f'no cpu line in {root / "stat"}')


def children(parent: int, root: Path = PROC) -> List[int]:
    """Return the pids of the processes whose parent is ``parent``."""
    out = []
    for entry in _pids(root):
        try:
            if int(_stat_fields((root / entry / 'stat').read_text())[1]) == parent:
                out.append(int(entry))
        except (OSError, ValueError, IndexError):      # ended during the scan
            continue
    return out


def children_by_command(parent: int, names: Dict[str, str],
                        root: Path = PROC) -> Dict[str, int]:
    """
    Return ``{name: pid}`` of the children of ``parent`` whose command line holds ``names[name]``.

    A child whose command line holds none of them is left out; the first
    match per name wins.
    """
    found: Dict[str, int] = {}
    for pid in children(parent, root):
        try:
            cmd = (root / str(pid) / 'cmdline').read_bytes().replace(b'\0', b' ').decode(
                errors='replace')
        except OSError:
            continue
        name = next((n for n, tag in names.items() if tag in cmd and n not in found), None)
        if name is not None:
            found[name] = pid
    return found


def same_process(pid: int, start: Optional[int], root: Path = PROC) -> bool:
    """Return whether ``pid`` still runs and is the process that started at ``start`` ticks."""
    try:
        return start_ticks(pid, root) == start
    except (OSError, ValueError, IndexError):
        return False


def _pids(root: Path) -> List[str]:
    try:
        return [e for e in os.listdir(root) if e.isdigit()]
    except OSError:
        return []
