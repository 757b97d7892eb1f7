"""
What ``live`` prints: where to watch, the status line, and the end-of-run summary.

The status line and most of the summary come from the :class:`.TwinState`
the monitor node keeps; the samples the rig published and the estimator
received come from the children's :class:`~wet_eha_thermal.interface.NodeReport`,
as data (their human summary lines are for people reading their logs).
``benchmarks/soak_stats.py`` parses the status line and the summary: keep
their wording, or change it there too.
"""

import math
from pathlib import Path
import shutil
from typing import Dict, List, Optional, TextIO

from wet_eha_thermal.bag.reader import BagError, open_bag
from wet_eha_thermal.interface import ESTIMATOR_NODE, NodeReport
from wet_eha_thermal.live_view import address_text, app_url
from wet_eha_thermal.model.quantity_table import label
from wet_eha_thermal.ros.live_children import Child, LiveOptions
from wet_eha_thermal.ros.live_monitor import TRUTH_BAND_SIGMA, TwinState, WATCHED
from wet_eha_thermal.ros.sim_rig_node import clamp_text, figures_text

#: Seconds between status lines: on a terminal (updated in place) and in a log.
TTY_PERIOD_S, LOG_PERIOD_S = 0.5, 5.0
LIVE_LAYOUT = Path(__file__).resolve().parents[2] / 'layouts' / 'live.json'


def foxglove_lines(host: str, port: int) -> List[str]:
    """Return the lines that tell where to watch the live view in Foxglove."""
    url = f'ws://{address_text(host, port)}'
    # an install from a wheel has no source tree: colcon puts the layouts in share/
    layout = LIVE_LAYOUT if LIVE_LAYOUT.is_file() else 'layouts/live.json of the sources'
    return [f'Foxglove view: open {app_url(host, port)}',
            f'  (Foxglove desktop: Open connection > Foxglove WebSocket > {url}); layout: '
            f'Import from file {layout}']


def duty_text(opts: LiveOptions) -> str:
    """Return what the rig runs: the stage or the duty file."""
    return f'duty file {opts.duty}' if opts.duty is not None else f'stage {opts.stage}'


# ------------------------------------------------------------------ the status line
def limit_text(state: TwinState) -> str:
    """Return the nearest limit crossing of the forecast, or why there is none."""
    if not state.time_to_limit:
        return 'pending'
    found = []
    for q, text in state.time_to_limit.items():
        try:
            found.append((float(text), q))
        except ValueError:
            pass
    if found:
        s, q = min(found)
        return f'{q} in {_duration(s)}'
    if all(t == 'beyond horizon' for t in state.time_to_limit.values()):
        return 'beyond horizon'
    return 'pending'


def starting_line(state: TwinState, waited_s: float, waits: List[str]) -> str:
    """Return the status line of the start-up: who the rig still waits for."""
    missing = [n for n in waits if n not in state.ready]
    what = ('waiting for ' + ', '.join(missing) + ' (starting, warming the model, '
            'matching the inputs)') if missing else 'everyone ready, the rig starts'
    return f'start-up {waited_s:5.1f} s | {what}'


def status_line(state: TwinState, elapsed_s: float, duration_s: float) -> str:
    """Return the one-line status."""
    if not state.estimates:
        return f't {elapsed_s:5.1f}/{duration_s:g} s | waiting for the first estimate ...'

    def t(name: str) -> str:
        v = state.temps.get(name)
        return f'{v:6.1f}' if v is not None else '   ---'

    margin = f'{state.margin} A' if _is_number(state.margin) else state.margin
    alert = state.alert_level if state.alert_message in ('OK', '') else \
        f'{state.alert_level}: {state.alert_message}'
    return (f't {elapsed_s:5.1f}/{duration_s:g} s | '
            f'{label("winding_hotspot")} {t("winding_hotspot")}'
            f' mean {t("winding_mean")} | magnet {t("magnet")} | oil {t("oil")} degC | '
            f'{truth_text(state)} | margin {margin} | limit: {limit_text(state)} | '
            f'drive {drive_text(state)} | '
            f'alerts {alert} | '
            f'stale: {state.fallback}' + _recorder_part(state))


def truth_text(state: TwinState) -> str:
    """Return the hot-spot's error against the rig's truth and whether its band holds it."""
    err = state.truth_error_K.get('winding_hotspot')
    if err is None:
        return 'truth pending'
    sigma = state.sigmas_K.get('winding_hotspot', math.nan)
    where = 'inside' if abs(err) <= TRUTH_BAND_SIGMA * sigma else 'OUTSIDE'
    return f'vs truth {err:+.1f} K, {where} 2 sigma ({TRUTH_BAND_SIGMA * sigma:.1f} K)'


def drive_text(state: TwinState) -> str:
    """
    Return the drive's current limit, and in a closed loop whether and since when it binds.

    The limit is the estimator's (its status when not ok); the clamp comes
    from the rig's last diagnostics, which carry it only when its drive
    honours the limit.
    """
    if state.limit_A is None:
        text = 'limit pending'
    else:
        text = f'<= {state.limit_A:.1f} A'
        if state.limit_status not in ('', 'ok'):
            text += f' ({state.limit_status})'
    try:
        clamped_s = float(state.rig['limit_clamped_s'])
        share = 100.0 * clamped_s / max(float(state.rig['duty_time_s']), 1e-9)
        first_s = float(state.rig['limit_first_clamp_s'])
    except (KeyError, ValueError):
        return text                 # open loop, or no word from the rig yet
    if not clamped_s > 0.0:
        return text + ', not clamped'
    return text + f', clamped {share:.0f} % since {first_s:.1f} s'


def _recorder_part(state: TwinState) -> str:
    """Return the recorder's part of the status line ('' when not recording)."""
    if not state.recorder_level:
        return ''
    if state.recorder_level == 'OK':
        written = state.recorder.get('bytes written', '')
        return f' | rec OK {_mib_text(written)}'
    return f' | REC {state.recorder_level}: {state.recorder_message}'


def _mib_text(n_bytes: str) -> str:
    """Return a byte count (text) in MiB, or the text as it is when it is no number."""
    try:
        return f'{int(n_bytes) / 2 ** 20:.1f} MiB'
    except ValueError:
        return n_bytes


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _duration(s: float) -> str:
    if s < 120.0:
        return f'{s:.0f} s'
    if s < 7200.0:
        return f'{s / 60.0:.0f} min'
    return f'{s / 3600.0:.1f} h'


class StatusPrinter:
    """One status line: rewritten in place on a terminal, a line every few seconds otherwise."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self.tty = stream.isatty()
        self.period = TTY_PERIOD_S if self.tty else LOG_PERIOD_S
        self.next = 0.0
        self.width = 0
        self.had_estimate = False

    def update(self, now: float, line: str, has_estimate: bool) -> None:
        """Show ``line`` if it is time (at once for the first estimate)."""
        first = has_estimate and not self.had_estimate
        self.had_estimate = self.had_estimate or has_estimate
        if now < self.next and not first:
            return
        self.next = now + self.period
        if self.tty:
            cols = shutil.get_terminal_size((160, 24)).columns - 1
            line = line[:cols]
            self.stream.write('\r' + line.ljust(self.width))
            self.width = len(line)
        else:
            self.stream.write(line + '\n')
        self.stream.flush()

    def finish(self) -> None:
        """End the in-place line on a terminal."""
        if self.tty and self.width:
            self.stream.write('\n')
            self.stream.flush()


# ------------------------------------------------------------------ the summary
def recording_text(path: Path) -> str:
    """Return what a finished recording holds, in words."""
    try:
        bag = open_bag(path)
    except (OSError, BagError) as exc:
        return f'{path}: not readable ({exc})'
    size_MiB = sum(f.stat().st_size for f in bag.files) / 2 ** 20
    text = (f'{path}: {bag.message_count} messages on {len(bag.topics)} topics, '
            f'{size_MiB:.1f} MiB')
    return text + (f' (cut: {bag.problem})' if bag.truncated else '')


def recorder_health_text(state: TwinState) -> str:
    """Return the recorder's last status for the summary: level, what it dropped and why."""
    if not state.recorder_level:
        return 'no report from the recorder'
    kv = state.recorder
    text = (f'{state.recorder_level} at the end ({state.recorder_message}); '
            f'{kv.get("messages written", "?")} messages written, '
            f'{kv.get("messages dropped", "?")} dropped, {kv.get("errors", "?")} errors; '
            f'{len(state.recorder_faults)} fault report(s) during the run')
    return text


def summary(opts: LiveOptions, state: TwinState, children: List[Child], run_s: float,
            domain: int, stopped_by: str, recording: Optional[Path] = None,
            start_s: float = 0.0) -> List[str]:
    """
    Return the lines of the end-of-run summary.

    ``run_s``: the duty's length (s), after ``start_s`` of start-up; ``recording``:
    the recorder's bag (directory or file). The children have exited: their
    reports are in their logs.
    """
    reports = {c.name: c.report() for c in children}
    out = ['', 'Live twin summary',
           f'  run             {run_s:.1f} s of duty after {start_s:.1f} s of start-up '
           f'({stopped_by}); {duty_text(opts)} on the simulated rig at {opts.rate_Hz:g} Hz, '
           f'noise {"on" if opts.noise else "off"}, ROS domain {domain}']
    out += _estimate_lines(state) + _drive_lines(opts, state, reports.get('rig'))
    out += _alert_lines(state)
    out += _sample_lines(state, reports.get('estimator'), reports.get('rig'))
    out += [f'  {c.name:<15} {c.describe()}' for c in children]
    if reports.get('rig') is not None:
        out.append(f'  rig figures     {figures_text(reports["rig"])}')
    if recording is not None:
        text = recording_text(recording) if recording.exists() else f'{recording}: not written'
        out.append(f'  recording       {text}')
        out.append(f'  recorder health {recorder_health_text(state)}')
        out += [f'                  {fault}' for fault in state.recorder_faults[-5:]]
    if opts.foxglove is not None:
        out.append(f'  foxglove view   {_foxglove_text(state)}')
    return out


def _estimate_lines(state: TwinState) -> List[str]:
    """Return the summary's lines on the estimates: count and rate, peaks, end, truth."""
    if not state.estimates or state.first_rx is None:
        return ['  estimates       none received']
    span = max(state.last_rx - state.first_rx, 1e-9)
    rate = (state.estimates - 1) / span if state.estimates > 1 else 0.0
    sample_span = state.last_stamp - state.first_stamp
    out = [f'  estimates       {state.estimates} received, {rate:.1f} per s over '
           f'{span:.1f} s ({sample_span:.1f} s of sample time)']
    peaks = ', '.join(f'{label(n)} {state.peaks[n]:.1f}' for n in WATCHED
                      if n in state.peaks)
    out.append(f'  peak estimates  {peaks} degC')
    ends = ', '.join(f'{label(n)} {state.temps[n]:.1f}' for n in WATCHED
                     if n in state.temps)
    sigma = f' (1 sigma {state.sigma_K:.1f} K)' if state.sigma_K is not None else ''
    out.append(f'  at the end      {ends} degC{sigma}')
    truth = {k: state.rig.get(f'truth_{k}_C') for k in WATCHED}
    if all(v is not None and _is_number(v) for v in truth.values()):
        diff = ', '.join(f'{label(n)} {float(truth[n]):.1f} '
                         f'({state.temps[n] - float(truth[n]):+.1f})' for n in WATCHED
                         if n in state.temps)
        out.append(f'  rig truth       {diff} degC (estimate - truth in brackets; last '
                   'rig report)')
    if state.truth_checks:
        share = {n: 100.0 * state.truth_inside.get(n, 0) / state.truth_checks for n in WATCHED}
        held = ', '.join(f'{label(n)} {share[n]:.0f} %' for n in WATCHED)
        out.append(f'  truth in band   {held} of {state.truth_checks} rig reports inside '
                   f'estimate +- {TRUTH_BAND_SIGMA:g} sigma; {_as_built_text(state)}')
    out.append(f'  margin, limits  margin current {state.margin} A RMS; time to limit: '
               f'{limit_text(state)}')
    return out


def _as_built_text(state: TwinState) -> str:
    """Return what the rig's truth is: a draw of the configured uncertainty, or the model."""
    seed = state.rig.get('as_built_seed', '')
    if not _is_number(seed):
        return 'the rig did not say what its truth is'
    if float(seed) == 0.0:
        return "the rig's truth is the estimator's own configuration (--rig-as-built 0)"
    return f'the rig is built as draw {float(seed):.0f} of the configured uncertainty'


def _drive_lines(opts: LiveOptions, state: TwinState, rig: Optional[NodeReport]) -> List[str]:
    """
    Return the summary's lines on the drive: the limit, the clamp, the rig truth's peak.

    The clamp and the peak come from the rig's report (exact), else from its
    last diagnostics.
    """
    if state.limit_A is None:
        limit = 'none received from the estimator'
    else:
        limit = (f'{state.limit_A:.1f} A RMS at the end ({state.limit_status or "no status"}), '
                 f'lowest {state.lowest_limit_A:.1f} A; {state.limit_fallbacks} limits said '
                 'fallback')
    out = [f'  drive limit     {limit}']
    figures = rig.figures if rig is not None else {}
    if not figures:
        figures = {k: float(v) for k, v in state.rig.items() if _is_number(v)}
    if opts.closed_loop:
        out.append(f'  closed loop     {clamp_text(figures) or "no word from the rig"}')
    else:
        out.append("  open loop       the rig's drive does not honour the limit "
                   '(--closed-loop: it does)')
    peak = figures.get('truth_winding_hotspot_peak_C')
    if peak is not None:
        out.append(f'  truth peak      {label("winding_hotspot")} {peak:.1f} degC (the rig\'s '
                   'truth model)')
    return out


def _alert_lines(state: TwinState) -> List[str]:
    """Return the summary's lines on the alerts: how many raised, the last events."""
    line = f'  alerts raised   {state.raised}'
    if state.alert_message not in ('OK', ''):
        line += f'; now {state.alert_level}: {state.alert_message}'
    return [line] + [f'                  {e}' for e in state.alert_events[-5:]]


def _sample_lines(state: TwinState, estimator: Optional[NodeReport],
                  rig: Optional[NodeReport]) -> List[str]:
    """
    Return the summary's lines on stale inputs and samples.

    Exact from the reports of the estimator and the rig; without them, from
    the estimator's last diagnostics (up to a second old).
    """
    if estimator is not None and estimator.inputs:
        during: Dict[str, int] = {n: c.stale_events for n, c in estimator.inputs.items()}
        since = 'during the duty'
    else:
        during = state.stale_events
        since = 'at the last diagnostics'
    per = ', '.join(f'{k} {v}' for k, v in during.items() if v)
    out = [f'  stale events    {sum(during.values())} ({since})' + (f': {per}' if per else '')
           + f'; inputs on fallback at the end: {state.fallback}']
    if (rig is not None and rig.samples_published is not None and estimator is not None
            and estimator.inputs):
        sent = rig.samples_published
        low = min(c.received for c in estimator.inputs.values())
        rejected = sum(c.rejected for c in estimator.inputs.values())
        out.append(f'  samples         the rig published {sent} per input; the estimator '
                   f'received {low} of them on its worst input ({100.0 * low / max(sent, 1):.2f} '
                   f'%), rejected {rejected}')
    elif state.received:
        mean = sum(state.received.values()) / len(state.received)
        out.append(f'  samples         the estimator had received {mean:.0f} per input at its '
                   'last diagnostics')
    return out


def _foxglove_text(state: TwinState) -> str:
    """Return whether the estimator served the Foxglove view, from its ready message."""
    said = state.ready.get(ESTIMATOR_NODE, {})
    if said.get('foxglove'):
        return f'{said["foxglove"]}, served by the estimator'
    if said.get('foxglove_error'):
        return f'not started: {said["foxglove_error"]}'
    return 'unknown: the estimator never said it was ready'
