"""
The figures of the soak benchmark (``soak_live.py``): slopes, and what ``live`` prints, parsed.

No ROS and no process here: a least-squares line with the standard error of
its slope, and parsers of the status line and of the end-of-run summary of
``wet-eha-thermal live`` (``wet_eha_thermal/ros/live.py``). The parsers rely on
the wording of those lines; a line they do not find leaves its keys out.
"""

from dataclasses import dataclass
import math
import re
from typing import Dict, Optional, Sequence

import numpy as np


@dataclass(frozen=True)
class Fit:
    """A least-squares line ``y = intercept + slope t`` over ``n`` points."""

    slope: float
    stderr: float           # standard error of the slope; NaN below three points
    intercept: float
    n: int


def linear_fit(t: Sequence[float], y: Sequence[float]) -> Fit:
    """
    Return the least-squares line through ``(t, y)`` and the standard error of its slope.

    The standard error is the textbook one, ``sqrt(s^2 / Sxx)`` with
    ``s^2 = sum(residual^2) / (n - 2)``: it takes the residuals as independent,
    so for samples that move in steps or drift together (an allocator's RSS) it
    is optimistic. NaN slope below two points or with all ``t`` equal.

    >>> f = linear_fit([0.0, 1.0, 2.0, 3.0], [1.0, 3.0, 5.0, 7.0])
    >>> (f.slope, f.intercept, f.stderr, f.n)
    (2.0, 1.0, 0.0, 4)
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    n = len(t)
    if n < 2:
        return Fit(math.nan, math.nan, math.nan, n)
    tm, ym = t.mean(), y.mean()
    sxx = float(np.sum((t - tm) ** 2))
    if sxx == 0.0:
        return Fit(math.nan, math.nan, math.nan, n)
    slope = float(np.sum((t - tm) * (y - ym))) / sxx
    intercept = float(ym - slope * tm)
    if n < 3:
        return Fit(slope, math.nan, intercept, n)
    s2 = float(np.sum((y - intercept - slope * t) ** 2)) / (n - 2)
    return Fit(slope, math.sqrt(s2 / sxx), intercept, n)


_STATUS_T = re.compile(r'^t\s+(\d+(?:\.\d*)?)/\S+ s \|')
_STATUS_HOTSPOT = re.compile(r'\| winding hot-spot\s+(-?\d+(?:\.\d*)?)')
_STATUS_STALE = re.compile(r'\| stale: ([^|]*?)\s*(?:\||$)')
_STATUS_RECORDER = re.compile(r'\| (rec OK|REC WARN|REC ERROR)\b')


def parse_status_line(line: str) -> Optional[Dict[str, object]]:
    """
    Return ``t_s`` (time since the rig's start), and ``hotspot_C``, ``stale``, ``recorder`` shown.

    None for a line that is not a status line of the duty (start-up lines,
    anything else). ``live`` prints one such line every few seconds when its
    output is not a terminal.

    >>> parse_status_line('t  14.0/20 s | winding hot-spot   20.3 mean   20.3 | magnet   23.1 '
    ...                   '| oil   26.0 degC | margin 19.5 A | limit: pending | alerts OK | '
    ...                   'stale: none | rec OK 3.2 MiB')
    {'t_s': 14.0, 'hotspot_C': 20.3, 'stale': 'none', 'recorder': 'OK'}
    """
    m = _STATUS_T.match(line.strip())
    if m is None:
        return None
    out: Dict[str, object] = {'t_s': float(m.group(1))}
    m = _STATUS_HOTSPOT.search(line)
    if m:
        out['hotspot_C'] = float(m.group(1))
    m = _STATUS_STALE.search(line)
    if m:
        out['stale'] = m.group(1)
    m = _STATUS_RECORDER.search(line)
    if m:
        out['recorder'] = m.group(1).split()[-1]
    return out


_SUMMARY = {
    'run': re.compile(r'^\s*run\s+(\d+(?:\.\d*)?) s of duty after (\d+(?:\.\d*)?) s of '
                      r'start-up \(([^)]*)\)'),
    'estimates': re.compile(r'^\s*estimates\s+(\d+) received, (\d+(?:\.\d*)?) per s'),
    'alerts': re.compile(r'^\s*alerts raised\s+(\d+)'),
    'stale': re.compile(r'^\s*stale events\s+(\d+) \(([^)]*)\)(?:: (.*?))?; inputs on fallback '
                        r'at the end: (.*?)\s*$'),
    'samples': re.compile(r'^\s*samples\s+the rig published (\d+) per input; the estimator '
                          r'received (\d+) of them on its worst input \([^)]*\), rejected (\d+)'),
    'recording': re.compile(r'^\s*recording\s+(.*): (\d+) messages on (\d+) topics, '
                            r'(\d+(?:\.\d*)?) MiB'),
    'exit': re.compile(r'^\s*(rig|estimator|recorder)\s{2,}(.*?)\s*$'),
}


def parse_summary(text: str) -> Dict[str, object]:
    """
    Return the figures of ``live``'s end-of-run summary found in ``text`` (its whole output).

    Keys, each only when its line was found: ``duty_s``, ``start_s``,
    ``stopped_by``; ``estimates``, ``estimate_rate_Hz``; ``alerts_raised``;
    ``stale_events`` (total), ``stale_per_input`` ({input: count}),
    ``stale_since``, ``fallback_at_end``; ``published`` (per input, the rig's
    count), ``received`` (on the estimator's worst input), ``lost`` (their
    difference), ``rejected``; ``recording``, ``recording_messages``,
    ``recording_topics``, ``recording_MiB``; ``exits`` ({child: how it ended}).
    Only the lines after ``Live twin summary`` are read.
    """
    head, found, body = text.partition('Live twin summary')
    out: Dict[str, object] = {}
    if not found:
        return out
    exits: Dict[str, str] = {}
    for line in body.splitlines():
        for key, pattern in _SUMMARY.items():
            m = pattern.match(line)
            if m is None:
                continue
            g = m.groups()
            if key == 'run':
                out.update(duty_s=float(g[0]), start_s=float(g[1]), stopped_by=g[2])
            elif key == 'estimates':
                out.update(estimates=int(g[0]), estimate_rate_Hz=float(g[1]))
            elif key == 'alerts':
                out['alerts_raised'] = int(g[0])
            elif key == 'stale':
                per = {}
                for item in (g[2] or '').split(', '):
                    name, _, count = item.rpartition(' ')
                    if name and count.isdigit():
                        per[name] = int(count)
                out.update(stale_events=int(g[0]), stale_since=g[1], stale_per_input=per,
                           fallback_at_end=g[3])
            elif key == 'samples':
                out.update(published=int(g[0]), received=int(g[1]),
                           lost=int(g[0]) - int(g[1]), rejected=int(g[2]))
            elif key == 'recording':
                out.update(recording=g[0], recording_messages=int(g[1]),
                           recording_topics=int(g[2]), recording_MiB=float(g[3]))
            elif key == 'exit':
                exits[g[0]] = g[1]
            break
    if exits:
        out['exits'] = exits
    return out
