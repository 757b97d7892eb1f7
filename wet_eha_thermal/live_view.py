"""
The live twin seen in Foxglove: a Foxglove WebSocket server fed with the estimator's estimates.

No ROS here: :class:`LiveView` takes plain :class:`~.estimator.core.Estimate`
objects, the alert summaries and the thermocouple readings, and serves them
with the Foxglove SDK (``foxglove-sdk``) as JSON messages with JSON schemas,
which Foxglove's Plot, Gauge, Indicator, Table, State Transitions and Log
panels read directly. Its channels and their schemas are in
:mod:`.view_channels`.

A client may publish what-if requests (Foxglove's Publish panel) on the
request topic the owner names: the view queues their text for the owner
(:meth:`LiveView.take_whatif_requests`), which runs them as it runs those of
ROS, and offers the answer back.

Every message is stamped with the estimate's sample time (``timestamp`` and
the WebSocket log time), never the wall clock, so all channels share one
time line that never goes back while the estimates' stamps do not.

The estimator's thread only hands over: :meth:`LiveView.offer` appends to
a bounded deque (the oldest is dropped when it is full: the newest always
wins) and wakes a worker thread, which builds and logs the messages. The SDK
queues each client's messages in its own bounded backlog
(``BACKLOG_MESSAGES``) and drops the oldest when a client does not read, so
a slow or stalled browser never holds up the worker, let alone the model.

Parameters (Foxglove's Parameters panel): the owner shows any read-only
values (thresholds, limits, settings); the names in ``settable`` may be set
from Foxglove within their range. An accepted request is queued for the
owner (:meth:`LiveView.take_requests`), which applies it on its own thread
and confirms with :meth:`LiveView.show_parameters` (a status; clients read
the values when they next ask for them).

The Foxglove SDK (foxglove-sdk, which rosdep has no key for) is imported
when a view starts, not with this module: the address helpers serve
without it, and an estimator without the view never needs it.
"""

from __future__ import annotations

from collections import deque
import json
import math
import threading
from typing import Any, Deque, Dict, List, Mapping, Optional, Sequence, Tuple, TYPE_CHECKING

from .view_channels import (BAND_SIGMAS, CHANNELS, LEVEL_NAMES, RECORDER_LEVELS, schemas,
                            view_topics)

if TYPE_CHECKING:
    from foxglove import Parameter

#: Per-client backlog of the server: about 1 s of the view's messages. A client that
#: falls further behind loses the oldest and sees the newest.
BACKLOG_MESSAGES = 256
#: Estimates waiting for the worker at most (about 0.3 s at 50 Hz); older ones are dropped.
PENDING_ESTIMATES = 16
#: Alert summaries waiting for the worker at most (they carry the events; they come only
#: when something changed).
PENDING_SUMMARIES = 256
#: foxglove.Log levels of an event, by the alert level right after it (OK, WARN, CRITICAL).
LOG_LEVELS = (2, 3, 4)       # INFO, WARNING, ERROR
#: What-if requests from clients waiting for the owner at most (it runs one at a time).
PENDING_REQUESTS = 4


def parse_address(text: str) -> Tuple[str, int]:
    """Return ``(host, port)`` of ``HOST:PORT`` (``[::1]:8765`` for IPv6); ValueError if bad."""
    host, sep, port = text.strip().rpartition(':')
    host = host.strip('[]')
    if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f'{text!r}: expected HOST:PORT, e.g. 127.0.0.1:8765')
    return host, int(port)


def address_text(host: str, port: int) -> str:
    """Return ``HOST:PORT`` (``[HOST]:PORT`` for an IPv6 host), as :func:`parse_address` reads."""
    return f'[{host}]:{port}' if ':' in host else f'{host}:{port}'


def app_url(host: str, port: int) -> str:
    """Return the Foxglove web app's address that opens the view at ``ws://host:port``."""
    return ('https://app.foxglove.dev/?ds=foxglove-websocket&ds.url=ws://'
            + address_text(host, port))


def _num(x: Optional[float]) -> Optional[float]:
    """Return ``x`` as a float, None when missing or not finite (JSON has no NaN)."""
    return float(x) if x is not None and math.isfinite(x) else None


def _time(stamp_s: float) -> Dict[str, int]:
    ns = max(int(round(stamp_s * 1e9)), 0)
    return {'sec': ns // 1_000_000_000, 'nsec': ns % 1_000_000_000}


def _parameter_value(value: Any) -> Any:
    """Return a value Foxglove's parameters carry (None shown as '')."""
    return '' if value is None else value


def _listener(view: LiveView):
    """Return the server's listener for ``view``: its parameter and what-if requests."""
    from foxglove.websocket import ServerListener

    class _Listener(ServerListener):
        """The server's parameter requests, answered from the view's table."""

        def on_get_parameters(self, client, param_names: List[str],
                              request_id: Optional[str] = None) -> List[Parameter]:
            return view._parameters(param_names)

        def on_set_parameters(self, client, parameters: List[Parameter],
                              request_id: Optional[str] = None) -> List[Parameter]:
            return view._set_requested(parameters)

        def on_client_advertise(self, client, channel) -> None:
            if channel.topic == view.whatif_request_topic:
                view._request_channels.add((client.id, channel.id))

        def on_client_unadvertise(self, client, client_channel_id: int) -> None:
            view._request_channels.discard((client.id, client_channel_id))

        def on_message_data(self, client, client_channel_id: int, data: bytes) -> None:
            if (client.id, client_channel_id) in view._request_channels:
                view._take_request(data)

    return _Listener()


class LiveView:
    """
    Foxglove WebSocket server of the live twin, fed by the estimator without holding it up.

    ``host``, ``port``: where to listen (port 0: any free one, see
    :attr:`port`); RuntimeError when the server cannot start (the address is
    in use). ``estimates``: the names of the estimates; ``limited``: those
    with limits and alerts; ``inputs``: the sensor inputs; ``thermocouples``:
    thermocouple -> the estimate it measures; ``prefix``: replaces ``/eha`` in
    the topics. ``parameters``: read-only values to show; ``settable``:
    name -> ``(low, high)`` of the numbers Foxglove may set (shown with
    their current values from ``parameters``). ``whatif_request_topic``:
    where clients may publish what-if requests (None: nowhere).
    """

    def __init__(self, host: str, port: int, *, estimates: Sequence[str],
                 limited: Sequence[str], inputs: Sequence[str],
                 thermocouples: Mapping[str, str], inputs_rate_Hz: float = 20.0,
                 prefix: str = '/eha', parameters: Optional[Mapping[str, Any]] = None,
                 settable: Optional[Mapping[str, Tuple[float, float]]] = None,
                 whatif_request_topic: Optional[str] = None,
                 name: str = 'wet_eha_thermal live view') -> None:
        self.estimates = tuple(estimates)
        self.limited = tuple(limited)
        self.inputs = tuple(inputs)
        self.thermocouples = dict(thermocouples)
        self.inputs_rate_Hz = float(inputs_rate_Hz)
        self.topics = view_topics(prefix)
        self.schemas = schemas(self.estimates, self.limited, self.inputs, self.thermocouples)
        self._shown: Dict[str, Any] = dict(parameters or {})
        self._settable = dict(settable or {})
        self._requests: Dict[str, float] = {}
        self._lock = threading.Lock()         # the parameters: the server's thread and ours
        self.whatif_request_topic = whatif_request_topic
        self._request_channels: set = set()   # (client, channel) publishing requests
        self._whatif_requests: Deque[str] = deque(maxlen=PENDING_REQUESTS)
        import foxglove               # here: only a view needs the SDK
        from foxglove import Channel, Context
        from foxglove.websocket import Capability

        capabilities = [Capability.Parameters]
        if whatif_request_topic is not None:
            capabilities.append(Capability.ClientPublish)
        # a context of its own: channels of one view never meet another's (tests run several)
        self._context = Context()
        self.server = foxglove.start_server(
            name=name, host=host, port=port, context=self._context,
            capabilities=capabilities, server_listener=_listener(self),
            supported_encodings=['json'], message_backlog_size=BACKLOG_MESSAGES)
        self.port = self.server.port
        self.host = host
        self._channels = {n: Channel(self.topics[n], schema=self.schemas[n],
                                     context=self._context) for n in CHANNELS}
        # the hand-off: deque appends are atomic, so the estimator's thread never waits
        self._estimates: Deque[tuple] = deque(maxlen=PENDING_ESTIMATES)
        self._summaries: Deque[dict] = deque(maxlen=PENDING_SUMMARIES)
        self._recorder: Deque[dict] = deque(maxlen=PENDING_SUMMARIES)
        self._whatif: Deque[str] = deque(maxlen=PENDING_REQUESTS)
        self._recorder_level: Optional[str] = None
        self._health: Optional[Dict[str, Tuple[int, int]]] = None
        self._wake = threading.Event()
        self._stop = False
        #: estimates offered, and shown (the difference was dropped or waits)
        self.offered = 0
        self.shown = 0
        self.errors = 0
        self.last_error = ''
        # the worker's state
        self._summary: Optional[dict] = None
        self._last_stamp: Optional[float] = None
        self._next_inputs_s: Optional[float] = None
        self._sums: Dict[str, List[float]] = {}
        self._thread = threading.Thread(target=self._run, name='foxglove-view', daemon=True)
        self._thread.start()

    # ------------------------------------------------- the estimator's thread
    @property
    def url(self) -> str:
        """Return the WebSocket address of the server."""
        return f'ws://{address_text(self.host, self.port)}'

    def offer(self, estimate, measured: Optional[Mapping[str, Tuple[float, float]]] = None
              ) -> None:
        """
        Hand one estimate to the view; returns at once (never blocks, never raises).

        ``measured``: thermocouple -> ``(stamp_s, value_C)`` of its last
        reading (a copy: the view reads it on another thread).
        """
        self.offered += 1
        self._estimates.append((estimate, measured or {}))
        self._wake.set()

    def offer_alerts(self, summary: dict) -> None:
        """Hand over an alert summary as published (its ``events`` are shown once)."""
        self._summaries.append(summary)
        self._wake.set()

    def offer_recorder(self, health: Mapping[str, Any]) -> None:
        """Hand over the recorder's health as it published it (shown at once)."""
        self._recorder.append(dict(health))
        self._wake.set()

    def offer_whatif(self, answer: str) -> None:
        """Hand over a what-if answer (JSON text) as published; the worker parses it."""
        self._whatif.append(answer)
        self._wake.set()

    def take_whatif_requests(self) -> List[str]:
        """Return the what-if requests (JSON text) clients published since the last call."""
        taken = []
        while self._whatif_requests:
            taken.append(self._whatif_requests.popleft())
        return taken

    def offer_health(self, counts: Mapping[str, Tuple[int, int]]) -> None:
        """Hand over the inputs' ``(received, rejected)`` counts (shown with the next inputs)."""
        self._health = dict(counts)

    def watched(self) -> List[str]:
        """Return the channels some client subscribes to now."""
        return [n for n, c in self._channels.items() if c.has_sinks()]

    def take_requests(self) -> Dict[str, float]:
        """Return the parameter values Foxglove asked for since the last call (and forget them)."""
        if not self._requests:
            return {}
        with self._lock:
            requests, self._requests = self._requests, {}
        return requests

    def show_parameters(self, values: Mapping[str, Any]) -> None:
        """
        Show new parameter values: in the answers to getParameters, and at once as a status.

        Foxglove's clients ask for every parameter each 15 s. The values are
        not pushed: foxglove-sdk 0.30 holds its parameter-subscription lock
        while it calls the listener, which needs the interpreter's lock, and
        ``publish_parameter_values`` waits for the subscription lock holding
        the interpreter's, so a client subscribing to parameter updates at
        that moment froze the whole process (test_foxglove_view.py).
        """
        with self._lock:
            self._shown.update(values)
        from foxglove.websocket import StatusLevel
        changed = ', '.join(f'{k} = {_parameter_value(v)}' for k, v in values.items())
        self.server.publish_status(f'parameters now: {changed}', StatusLevel.Info)

    def close(self) -> None:
        """Stop the worker and the server."""
        self._stop = True
        self._wake.set()
        self._thread.join(timeout=5.0)
        self.server.stop()

    # --------------------------------------------------- the server's thread
    def _parameters(self, names: Sequence[str]) -> List[Parameter]:
        from foxglove import Parameter
        with self._lock:
            shown = dict(self._shown)
        return [Parameter(k, value=_parameter_value(v)) for k, v in shown.items()
                if not names or k in names]

    def _set_requested(self, parameters: Sequence[Parameter]) -> List[Parameter]:
        """Queue the settable values in range; answer every one with the value it will have."""
        refused = []
        with self._lock:
            for p in parameters:
                value = p.get_value()
                low, high = self._settable.get(p.name, (None, None))
                if low is None:
                    refused.append(f'{p.name} is read-only here')
                elif isinstance(value, bool) or not isinstance(value, (int, float)) \
                        or not low <= value <= high:
                    refused.append(f'{p.name} = {value!r}: expected a number in '
                                   f'[{low:g}, {high:g}]')
                else:
                    self._requests[p.name] = self._shown[p.name] = float(value)
        if refused:
            from foxglove.websocket import StatusLevel
            self.server.publish_status('; '.join(refused), StatusLevel.Warning)
        return self._parameters([p.name for p in parameters])

    def _take_request(self, data: bytes) -> None:
        """
        Queue a client's what-if request: a std_msgs/String as JSON, or the request itself.

        Foxglove's Publish panel sends ``{"data": "<request>"}`` for a String;
        anything else is passed on as it is, for the owner to answer.
        """
        text = data.decode('utf-8', errors='replace')
        try:
            message = json.loads(text)
        except ValueError:
            message = None
        if isinstance(message, dict) and set(message) == {'data'} \
                and isinstance(message['data'], str):
            text = message['data']
        self._whatif_requests.append(text)

    # --------------------------------------------------------- the worker
    def _run(self) -> None:
        while not self._stop:
            self._wake.wait()
            self._wake.clear()
            while self._summaries or self._recorder or self._whatif or self._estimates:
                try:
                    if self._summaries:
                        self._on_summary(self._summaries.popleft())
                    elif self._recorder:
                        self._on_recorder(self._recorder.popleft())
                    elif self._whatif:
                        self._on_whatif(json.loads(self._whatif.popleft()))
                    else:
                        self._on_estimate(*self._estimates.popleft())
                        self.shown += 1
                except Exception as exc:  # noqa: B902 - the view must outlive a bad message
                    self.errors += 1
                    self.last_error = f'{type(exc).__name__}: {exc}'

    def _log(self, name: str, message: dict, stamp_s: float) -> None:
        self._channels[name].log(json.dumps(message, allow_nan=False).encode(),
                                 log_time=max(int(round(stamp_s * 1e9)), 0))

    def _on_summary(self, summary: dict) -> None:
        self._summary = summary
        if not summary.get('events') or not self._channels['events'].has_sinks():
            return
        # never before what was already sent: Foxglove takes time going back for a seek
        stamp = max(summary.get('stamp_s') or 0.0, self._last_stamp or 0.0)
        level = LOG_LEVELS[min(max(int(summary.get('level', 0)), 0), 2)]
        for text in summary['events']:
            self._log('events', {'timestamp': _time(stamp), 'level': level,
                                 'message': str(text), 'name': 'wet_eha_thermal estimator',
                                 'file': '', 'line': 0}, stamp)

    def _on_recorder(self, health: dict) -> None:
        # on the estimates' time line: the last estimate's stamp (0 before the first)
        stamp = self._last_stamp or 0.0
        level = health.get('level_name')
        if level != self._recorder_level and self._recorder_level is not None:
            self._log('events', {
                'timestamp': _time(stamp), 'message': f'recorder {level}: '
                f'{health.get("message", "")}', 'name': 'wet_eha_thermal recorder',
                'level': LOG_LEVELS[RECORDER_LEVELS.index(level)] if level in RECORDER_LEVELS
                else LOG_LEVELS[2], 'file': '', 'line': 0}, stamp)
        self._recorder_level = level
        if self._channels['recorder'].has_sinks():
            fields = self.schemas['recorder']['properties']
            self._log('recorder', {'timestamp': _time(stamp),
                                   **{k: health.get(k) for k in fields if k != 'timestamp'}},
                      stamp)

    def _on_whatif(self, answer: dict) -> None:
        """Show a what-if answer, on the estimates' time line (the last estimate's stamp)."""
        stamp = self._last_stamp or 0.0
        series = answer.get('temperatures_C') or {}
        peaks = answer.get('peaks_C') or {}
        self._log('whatif', {
            'timestamp': _time(stamp), 'id': str(answer.get('id', '')),
            'ok': bool(answer.get('ok')), 'error': answer.get('error'),
            **{k: answer.get(k) for k in ('source', 'duty', 'start_stamp_s', 'duration_s',
                                          'ambient_C', 'stopped')},
            'time_min': [t / 60.0 for t in answer.get('time_s') or []],
            'temperatures_C': {n: series.get(n, []) for n in self.estimates},
            'peaks_C': {n: peaks.get(n) for n in self.estimates},
            'limits_C': {q: (answer.get('limits_C') or {}).get(q) for q in self.limited},
            'time_to_limit_s': {q: (answer.get('time_to_limit_s') or {}).get(q)
                                for q in self.limited}}, stamp)

    def _on_estimate(self, est, measured: Mapping[str, Tuple[float, float]]) -> None:
        t = est.stamp_s
        if self._last_stamp is not None and t < self._last_stamp:
            self._next_inputs_s = None          # the clock started over: so do the windows
            self._sums = {}
        self._last_stamp = t
        # nothing is built for a channel no client subscribes to: no client, (almost) no cost
        watched = set(self.watched())
        head = {'timestamp': _time(t), 'step': int(est.step)}
        if 'temperatures' in watched:
            self._log('temperatures', {**head, **{n: self._band(est, n)
                                                  for n in self.estimates}}, t)
        if 'limits' in watched:
            self._log('limits', self._limits(est, head), t)
        if 'alerts' in watched and self._summary is not None:
            self._log('alerts', self._alerts(head), t)
        if 'inputs' in watched:
            self._add_inputs(est)
        if self._next_inputs_s is None or t >= self._next_inputs_s - 1e-9:
            if 'inputs' in watched:
                self._log('inputs', self._inputs(head), t)
            if 'input_health' in watched:
                self._log('input_health', self._input_health(est, head), t)
            if 'thermocouples' in watched:
                self._log('thermocouples', self._thermocouples(est, measured, head, t), t)
            period = 1.0 / self.inputs_rate_Hz
            self._next_inputs_s = (math.floor(t / period + 1e-6) + 1) * period

    def _band(self, est, name: str) -> Dict[str, Optional[float]]:
        value, sigma = est.temperatures_C[name], est.uncertainty_K[name]
        return {'estimate_C': _num(value), 'sigma_K': _num(sigma),
                'band_low_C': _num(value - BAND_SIGMAS * sigma),
                'band_high_C': _num(value + BAND_SIGMAS * sigma)}

    def _limits(self, est, head: dict) -> dict:
        lim = est.current_limits
        out = {**head, 'margin_current_A': _num(est.margin_current_A),
               'forecast_started_s': _num(est.forecast_stamp_s),
               'current_limit_A': _num(lim.binding_A if lim is not None else None),
               'current_limits_status': 'pending' if lim is None else lim.frame_id}
        rules = (self._summary or {}).get('quantities', {})
        for q in self.limited:
            value, limit = est.temperatures_C[q], est.limits_C[q]
            sigma = est.uncertainty_K[q]
            ttl = est.time_to_limit_s.get(q)
            left = None
            if ttl is not None and est.forecast_stamp_s is not None:
                # the forecast counts from its start: what is left of it at this estimate
                left = max(ttl - (est.stamp_s - est.forecast_stamp_s), 0.0)
            out[q] = {'estimate_C': _num(value),
                      'band_high_C': _num(value + BAND_SIGMAS * sigma),
                      'limit_C': _num(limit), 'warn_C': _num(rules.get(q, {}).get('warn_C')),
                      'critical_C': _num(rules.get(q, {}).get('critical_C')),
                      'margin_K': _num(limit - value), 'time_to_limit_s': _num(left)}
        return out

    def _alerts(self, head: dict) -> dict:
        s = self._summary
        level = min(max(int(s.get('level', 0)), 0), 2)
        gaps = s.get('data_gaps') or {}
        out = {**head, 'level': level, 'level_name': LEVEL_NAMES[level],
               'message': str(s.get('message', '')),
               'data_gap': gaps.get('open_since_s') is not None,
               'clock_jumps': int(s.get('clock_jumps', 0))}
        for q in self.limited:
            d = s.get('quantities', {}).get(q, {})
            reported = d.get('reported', 'OK')
            out[q] = {'reported': reported, 'active': d.get('active', 'OK'),
                      'acknowledged': bool(d.get('acknowledged', False)),
                      'level': LEVEL_NAMES.index(reported) if reported in LEVEL_NAMES else 0}
        return out

    def _add_inputs(self, est) -> None:
        for name, values in est.inputs.items():
            acc = self._sums.setdefault(name, [0.0, 0])
            # the grid carries the current's RMS per interval: average its square
            acc[0] += float((values * values).sum() if name == 'current_A' else values.sum())
            acc[1] += values.size

    def _inputs(self, head: dict) -> dict:
        out = dict(head)
        for name in self.inputs:
            total, n = self._sums.get(name, (math.nan, 0))
            mean = total / n if n else math.nan
            out[name] = _num(math.sqrt(mean) if name == 'current_A' and mean >= 0 else mean)
        self._sums = {}
        return out

    def _input_health(self, est, head: dict) -> dict:
        counts = self._health or {}
        out = {**head, 'stale_count': len(est.stale)}
        for name in self.inputs:
            received, rejected = counts.get(name, (0, 0))
            out[name] = {'state': 'STALE' if name in est.stale else 'OK',
                         'received': int(received), 'rejected': int(rejected)}
        return out

    def _thermocouples(self, est, measured, head: dict, t: float) -> dict:
        out = dict(head)
        for tc, quantity in self.thermocouples.items():
            estimate = est.temperatures_C.get(quantity)
            stamp, value = measured.get(tc, (None, None))
            out[tc] = {'measured_C': _num(value), 'estimate_C': _num(estimate),
                       'error_K': _num(estimate - value) if value is not None
                       and estimate is not None else None,
                       'age_s': _num(t - stamp) if stamp is not None else None}
        return out
