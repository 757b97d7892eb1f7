"""
Campaigns: many logs replayed at once on ``dask.distributed``, and one summary of them.

Each log is replayed as ``wet-eha-thermal replay BAG`` replays it (the same
plan, estimator and outputs) into a subfolder of its own, as one Dask task: a
pure function of the bag and the options (:func:`replay_log`). The estimates
are therefore those of a single replay, bit for bit, on whichever worker the
task runs, and a task whose worker dies is simply run again elsewhere (Dask
does so up to ``distributed.scheduler.allowed-failures`` times). A log that
cannot be replayed (missing, damaged, no topic to feed the estimator) is a row
with status ``failed`` and its reason; the others go on.

:func:`write_summary` writes ``campaign.csv`` (every figure, full precision),
``campaign.md`` and ``campaign.png``: one row per log with its duration, the
peak of every estimate, the minimum thermal margin (the least, over the
limited estimates and the log, of limit minus estimate), the time at or above
each alert level and the error of every thermocouple's estimate.

The workers read the bags and write the outputs by their paths: on a cluster
of several machines, both must be on a shared filesystem under the same names.
"""

from contextlib import contextmanager
import csv
import logging
import math
from pathlib import Path
import time
from typing import Callable, Dict, List, Optional, Sequence

import numpy as np

from . import replay as rp     # a campaign is one replay per bag
from .. import interface
from ..bag.reader import is_bag
from ..estimator.alerts import Level
from ..output_files import atomic, markdown_table, pyplot, save_figure, write_text

#: How long to wait for a scheduler to answer, and for a worker to join it (s).
CONNECT_TIMEOUT_S = 30.0
#: Dask settings of the local cluster's processes. A replay holds the GIL for
#: its whole run, and Dask's defaults wake each process's event loop every
#: 20 ms (a health check) and sample the system every 0.5 s: each wake-up
#: takes the GIL from the replay, and the in-process scheduler a share of the
#: cores the workers use (measured: docs/scaling.md). Dask still logs a loop
#: that went more than 3 s between two ticks (its tick.limit, unchanged).
LOCAL_CLUSTER_CONFIG = {'distributed.admin.tick.interval': '1s',
                        'distributed.admin.system-monitor.interval': '5s'}
#: Estimates shown in campaign.md (campaign.csv has the peak of every one).
SHOWN_PEAKS = ('winding_hotspot', 'magnet', 'pump_case', 'oil')
ALERT_LEVELS = (Level.WARN, Level.CRITICAL)


class ClusterError(RuntimeError):
    """No Dask cluster to run on; the message says why."""


def expand(paths: Sequence[Path]) -> List[Path]:
    """
    Return the bags that ``paths`` name, in order.

    A folder that is no bag itself (:func:`~.bag.reader.is_bag`: no
    ``metadata.yaml``, and its ``.mcap`` files, if any, not one split series)
    stands for the bags in it, sorted by name: its ``.mcap`` files and its bag
    directories. Anything else stays as given, a missing path too: its
    replay says what is wrong.
    """
    bags = []
    for path in map(Path, paths):
        children = []
        if not is_bag(path):
            children = sorted((p for p in path.iterdir()
                               if p.suffix == '.mcap' and p.is_file()
                               or p.is_dir() and is_bag(p)),
                              key=lambda p: p.name)
        bags.extend(children or [path])
    return bags


def output_names(bags: Sequence[Path]) -> List[str]:
    """Return a distinct output folder name per bag: its name, then _2, _3... for repeats."""
    names: List[str] = []
    taken = set()
    for bag in bags:
        stem = bag.stem if bag.suffix == '.mcap' else bag.name
        name, k = stem, 1
        while name in taken:
            k += 1
            name = f'{stem}_{k}'
        taken.add(name)
        names.append(name)
    return names


def summarise(result: rp.ReplayResult) -> Dict[str, object]:
    """Return the summary figures of one replay (SI units, degC for temperatures)."""
    row: Dict[str, object] = {'duration_s': result.sample_time_s, 'messages': result.messages}
    for name in rp.OUTPUT_ESTIMATES:
        row[f'peak_{name}_C'] = float(np.max(result.temperatures_C[name]))
    margins = {q: limit - float(np.max(result.temperatures_C[q]))
               for q, limit in result.limits_C.items()}
    least = min(margins, key=margins.get)
    row['min_margin_K'], row['min_margin_of'] = margins[least], least
    # each estimate's alert level holds until the next (at the output rate)
    held_s = np.diff(result.stamp_s)
    for level in ALERT_LEVELS:
        row[f'time_{level.name.lower()}_s'] = float(
            np.sum(held_s[result.alert_level[:-1] >= level]))
    for tc, e in rp.thermocouple_errors(result).items():
        for stat in ('max_abs_K', 'rms_K', 'bias_K'):
            row[f'{tc}_{stat}'] = e[stat]
    return row


def _reason(exc: BaseException) -> str:
    """Return an exception as one line; ours say it all, others need their type."""
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ''
    if isinstance(exc, (rp.ReplayError, rp.BagError)):
        return text
    return f'{type(exc).__name__}: {text}' if text else type(exc).__name__


def replay_log(path: Path, out_dir: Path, options: rp.ReplayOptions) -> Dict[str, object]:
    """
    Replay the bag ``path`` into ``out_dir``; return its summary row.

    The row has the log's ``name`` (that of ``out_dir``), ``path``,
    ``status`` (``ok``, ``truncated``: replayed up to a damage, or
    ``failed``), ``reason``, the :func:`summarise` figures and ``wall_s``.
    Nothing raises: a log that fails is a row.
    """
    t0 = time.perf_counter()
    row: Dict[str, object] = {'name': out_dir.name, 'path': str(path)}
    try:
        # a Dask worker runs one log per core: reading in a forked child on another core
        # would only take a core from the next log (and a daemonic worker cannot fork)
        result = rp.replay(options.plan(path), output_rate_Hz=options.output_rate_Hz,
                           prefetch=False, outlook=options.outlook)
        rp.write_outputs(result, out_dir, options.report)
    except Exception as exc:      # noqa: BLE001 - any failure is this log's: its row says it
        row.update(status='failed', reason=_reason(exc))
    else:
        row.update(status='truncated' if result.truncated else 'ok',
                   reason=result.problem or '', **summarise(result))
    row['wall_s'] = time.perf_counter() - t0
    return row


@contextmanager
def dask_client(scheduler: Optional[str] = None, workers: Optional[int] = None):
    """
    Yield a ``distributed.Client``: of the scheduler at ``scheduler``, else of a new local cluster.

    The local cluster has ``workers`` processes (default: one per CPU) of one
    thread each, no dashboard, and logs errors only. Raises
    :class:`ClusterError` when the scheduler does not answer or no worker
    joins it within :data:`CONNECT_TIMEOUT_S`.
    """
    import dask
    from dask.system import CPU_COUNT
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as exc:
            raise ClusterError(f'--scheduler {scheduler}: cannot connect ({_reason(exc)})') \
                from None
        try:
            client.wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
        except TimeoutError:
            client.close()
            raise ClusterError(f'--scheduler {scheduler}: no worker joined within '
                               f'{CONNECT_TIMEOUT_S:g} s') from None
        with client:
            yield client
        return
    # set while the cluster lives: its scheduler runs in this process, and the nannies pass
    # the settings to their workers. No dashboard; the scheduler's HTTP server (health
    # checks) still starts: on a free port, not on 8787, which another cluster may hold
    with dask.config.set(LOCAL_CLUSTER_CONFIG), \
            LocalCluster(n_workers=workers or CPU_COUNT, threads_per_worker=1, processes=True,
                         dashboard_address=None, scheduler_kwargs={'dashboard_address': ':0'},
                         silence_logs=logging.ERROR) as cluster, \
            Client(cluster) as client:
        yield client


def describe(client) -> str:
    """Return what ``client`` runs on, e.g. ``2 worker(s) at tcp://127.0.0.1:8786``."""
    return f'{len(client.nthreads())} worker(s) at {client.scheduler.address}'


def run(client, bags: Sequence[Path], out: Path, options: rp.ReplayOptions,
        on_done: Optional[Callable[[int, int, Dict[str, object]], None]] = None
        ) -> List[Dict[str, object]]:
    """
    Replay ``bags`` on ``client``, each into ``out/<its name>``; return their rows in order.

    ``on_done(done, total, row)`` is called as each log completes. A log whose
    task is lost (its workers died ``allowed-failures`` times) is a failed row.
    """
    from distributed import as_completed

    names = output_names(bags)
    futures = {client.submit(replay_log, bag, out / name, options, pure=False): k
               for k, (bag, name) in enumerate(zip(bags, names))}
    rows: List[Optional[Dict[str, object]]] = [None] * len(bags)
    for done, future in enumerate(as_completed(futures), 1):
        k = futures[future]
        try:
            row = future.result()
        except Exception as exc:   # noqa: BLE001 - e.g. KilledWorker: this log's failure
            row = {'name': names[k], 'path': str(bags[k]), 'status': 'failed',
                   'reason': _reason(exc)}
        rows[k] = row
        if on_done is not None:
            on_done(done, len(bags), row)
    return rows


# ------------------------------------------------------------------ summary
def thermocouples(rows: Sequence[Dict[str, object]]) -> List[str]:
    """Return the thermocouples that any log of ``rows`` has errors of, in the rig's order."""
    return [tc for tc in interface.THERMOCOUPLES if any(f'{tc}_max_abs_K' in r for r in rows)]


def columns(rows: Sequence[Dict[str, object]]) -> List[str]:
    """Return the columns of campaign.csv: the figures, then the thermocouples any log has."""
    tcs = thermocouples(rows)
    return (['name', 'status', 'duration_s', 'messages']
            + [f'peak_{n}_C' for n in rp.OUTPUT_ESTIMATES] + ['min_margin_K', 'min_margin_of']
            + [f'time_{level.name.lower()}_s' for level in ALERT_LEVELS]
            + [f'{tc}_{stat}' for tc in tcs for stat in ('max_abs_K', 'rms_K', 'bias_K')]
            + ['wall_s', 'path', 'reason'])


def write_summary(rows: Sequence[Dict[str, object]], out: Path) -> List[Path]:
    """Write campaign.csv, campaign.md and campaign.png into ``out``; return their paths."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / 'campaign.csv', out / 'campaign.md', out / 'campaign.png']
    with atomic(paths[0]) as tmp, open(tmp, 'w', newline='') as f:
        # repr of every float: the figures read back exactly
        writer = csv.DictWriter(f, columns(rows), restval='')
        writer.writeheader()
        writer.writerows(rows)
    write_text(paths[1], '\n'.join(summary_lines(rows, paths[2].name)) + '\n')
    plot(rows, paths[2])
    return paths


def _cell(row: Dict[str, object], key: str, fmt: str = '.1f') -> str:
    value = row.get(key)
    return '' if value is None else format(value, fmt)


def summary_lines(rows: Sequence[Dict[str, object]], image: str) -> List[str]:
    """Return campaign.md: a table of the main figures, the thermocouple errors, the failures."""
    count = {s: sum(r['status'] == s for r in rows) for s in ('ok', 'truncated', 'failed')}
    lines = [f'# Replay campaign of {len(rows)} logs', '',
             f'{count["ok"]} replayed, {count["truncated"]} replayed up to a damage, '
             f'{count["failed"]} failed. Temperatures in degC, margin in K (limit minus '
             'estimate, the least over the limited estimates), times at or above an alert '
             'level in s; every figure at full precision in campaign.csv.', '']
    lines += markdown_table(
        ['log', 'status', 'duration s'] + [f'peak {n}' for n in SHOWN_PEAKS] + ['min margin']
        + [level.name for level in ALERT_LEVELS],
        ([r['name'], r['status'], _cell(r, 'duration_s')]
         + [_cell(r, f'peak_{n}_C') for n in SHOWN_PEAKS]
         + [_cell(r, 'min_margin_K') + (f' ({r["min_margin_of"]})' if 'min_margin_of' in r
                                        else '')]
         + [_cell(r, f'time_{level.name.lower()}_s') for level in ALERT_LEVELS]
         for r in rows))
    tcs = thermocouples(rows)
    lines += ['', '## Estimate minus thermocouple: max abs / bias (K)', '']
    if tcs:
        lines += markdown_table(['log'] + tcs, ([r['name']] + [
            f'{r[f"{tc}_max_abs_K"]:.2f} / {r[f"{tc}_bias_K"]:+.2f}'
            if f'{tc}_max_abs_K' in r else '' for tc in tcs] for r in rows))
    else:
        lines.append('No log holds a thermocouple topic.')
    problems = [r for r in rows if r['reason']]
    lines += ['', '## Failed and damaged logs', '']
    lines += [f'- {r["name"]} ({r["status"]}, {r["path"]}): {r["reason"]}'
              for r in problems] or ['- none']
    return lines + ['', f'![campaign]({image})']


def plot(rows: Sequence[Dict[str, object]], path: Path) -> Path:
    """Plot the peak winding hot-spot and the minimum margin of every log; mark failures."""
    plt = pyplot()

    x = np.arange(len(rows))
    fig, axes = plt.subplots(2, 1, sharex=True,
                             figsize=(min(max(7.0, 1.5 + 0.3 * len(rows)), 40.0), 6.5))
    for ax, key, label in ((axes[0], 'peak_winding_hotspot_C', 'peak winding hot-spot [degC]'),
                           (axes[1], 'min_margin_K', 'minimum thermal margin [K]')):
        values = np.array([r.get(key, math.nan) for r in rows], dtype=float)
        colours = ['C1' if r['status'] == 'truncated' else 'C0' for r in rows]
        ax.bar(x, np.nan_to_num(values), color=colours)
        failed = np.array([r['status'] == 'failed' for r in rows])
        if failed.any():
            ax.plot(x[failed], np.zeros(int(failed.sum())), 'x', color='red', ms=10,
                    label='failed')
            ax.legend(fontsize=8)
        ax.set_ylabel(label, fontsize=9)
        ax.grid(alpha=0.3, axis='y')
    axes[1].axhline(0.0, color='k', lw=0.6)
    axes[1].set_xticks(x, [r['name'] for r in rows], rotation=60, ha='right', fontsize=7)
    axes[0].set_title(f'Replay campaign of {len(rows)} logs (orange: truncated)')
    return save_figure(fig, path)
