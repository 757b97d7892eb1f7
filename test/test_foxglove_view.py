"""
The Foxglove view (:mod:`wet_eha_thermal.live_view`) seen by a WebSocket client, and the layouts.

The client speaks the Foxglove WebSocket protocol with the ``websockets``
package: it reads ``serverInfo`` and ``advertise``, subscribes, and decodes
the binary message frames (opcode 1, subscription id, log time, JSON). Real
estimates of the estimator core are fed to a view on a free port. Every wait
has a timeout; nothing sleeps to synchronise.
"""

import dataclasses
import json
from pathlib import Path
import re
import socket
import struct
import threading
import time

from child_process import in_a_fresh_process
import numpy as np
import pytest
from websockets.sync.client import connect
from wet_eha_thermal import interface
from wet_eha_thermal.cli import main as cli_main
from wet_eha_thermal.config import load_config
from wet_eha_thermal.estimator.session import EstimatorSession
from wet_eha_thermal.layouts import layout_for, where_to_get
from wet_eha_thermal.live_view import (address_text, app_url, LiveView, parse_address,
                                       PENDING_ESTIMATES)
from wet_eha_thermal.model.quantity_table import LIMITED
from wet_eha_thermal.offline.whatif import model_outputs, parse_request
from wet_eha_thermal.offline.whatif_worker import run_request
from wet_eha_thermal.ros.recorder_node import recorded_topics
from wet_eha_thermal.ros.topics import message_class
from wet_eha_thermal.view_channels import BAND_SIGMAS, CHANNELS, view_topics

pytestmark = pytest.mark.slow     # measured: see docs/development.md#tests-and-ci

ROOT = Path(__file__).resolve().parents[1]
SUBPROTOCOL = 'foxglove.sdk.v1'    # foxglove-sdk's server refuses foxglove.websocket.v1
TIMEOUT_S = 10.0
RATE_HZ = 1000.0
# the oil crosses this early on: a WARN event and an alert timeline to check
ALERTS = {'estimator.alerts.oil.warn_C': 21.0, 'estimator.alerts.oil.critical_C': 60.0,
          'estimator.alerts.oil.min_duration_s': 0.5}


def _session(cfg, items):
    """
    Return a session that puts each estimate it publishes in ``items``.

    As ``(estimate, thermocouple readings, alert summary or None)``, the
    summary as the node publishes it: when the level changed or events came
    (one published before the first estimate goes with it).
    """
    pending = []

    def publish(out):
        if out.alerts is not None:
            pending[:] = [out.alerts]
        if out.estimates:
            items.append((out.estimates[-1], session.measured_C, pending.pop() if pending
                          else None))

    session = EstimatorSession(cfg, outlook='background', publish=publish)
    return session


def _feed(est, t0, seconds):
    """
    Feed every input at 1 kHz over (t0, t0 + seconds] and a frame reading; return the end.

    As live: 20 ms of samples at a time, then the model steps with the clock
    at the last sample.
    """
    est.add_measured('frame', t0, 21.5)
    for k in range(int(round(seconds / 0.02))):
        t = t0 + 0.02 * k + np.arange(1, 21) / RATE_HZ
        signals = {'current_A': 25.0 + 5.0 * np.sin(2 * np.pi * 3.0 * t),
                   'speed_rad_s': 800.0 + 50.0 * np.sin(t), 'p_a_Pa': np.full_like(t, 3e6),
                   'p_b_Pa': np.full_like(t, 1e6), 'p_acc_Pa': np.full_like(t, 1e6),
                   'position_m': 0.002 * np.sin(t)}
        for name in est.inputs:
            est.add(name, t, signals[name], now_s=float(t[-1]))
        est.step(float(t[-1]))
    return float(t[-1])


@pytest.fixture(scope='module')
def run():
    """
    Return ``[(estimate, measured, summary or None)]``: 4 s of a real estimator.

    The forecast and the margin of the first tick (0.5 s) are completed after
    3 s, so the later estimates carry a time to limit and a margin current.
    """
    items = []
    est = _session(load_config(overrides=ALERTS), items)
    t = _feed(est, 0.0, 3.0)
    deadline = time.monotonic() + 60.0
    while items[-1][0].margin_current_A is None or items[-1][0].forecast_stamp_s is None:
        assert time.monotonic() < deadline, 'no forecast and margin within 60 s'
        est.work(0.5)
        t = _feed(est, t, 0.02)
    _feed(est, t, 1.0)
    assert any(e.time_to_limit_s.get(q) is not None for e, _, _ in items for q in LIMITED)
    assert any(s and s['events'] for _, _, s in items), 'no alert event'
    return items


def _wait(condition, timeout=TIMEOUT_S):
    """Poll ``condition()`` until it is true; fail after ``timeout`` s."""
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, 'timed out'
        time.sleep(0.005)


@pytest.fixture
def view():
    v = LiveView('127.0.0.1', 0, estimates=interface.ESTIMATES, limited=LIMITED,
                 inputs=('current_A', 'speed_rad_s', 'p_a_Pa', 'p_b_Pa', 'p_acc_Pa',
                         'position_m'),
                 thermocouples=interface.THERMOCOUPLES, inputs_rate_Hz=20.0,
                 parameters={'publish_rate_Hz': 50.0, 'alerts.oil.warn_C': 21.0,
                             'topic_prefix': '/eha'},
                 settable={'publish_rate_Hz': (1.0, 500.0)},
                 whatif_request_topic=interface.WHATIF_REQUEST_TOPIC)
    yield v
    v.close()


class Client:
    """A Foxglove WebSocket client: the advertised channels, subscriptions, decoded messages."""

    def __init__(self, port, **kwargs):
        self.ws = connect(f'ws://127.0.0.1:{port}', subprotocols=[SUBPROTOCOL], proxy=None,
                          open_timeout=TIMEOUT_S, close_timeout=1.0, **kwargs).__enter__()
        self.info = None
        self.channels = {}       # topic -> advertised channel
        self.ops = []            # other text messages (status, parameterValues)
        self.subscribed = {}     # subscription id -> topic
        self.received = []       # (topic, log time ns, message)
        self.last = {}           # topic -> its last message

    def close(self):
        self.ws.__exit__(None, None, None)

    def drain(self, wait=0.0):
        """Take the frames that arrive within ``wait`` s, then those already there."""
        while True:
            try:
                frame = self.ws.recv(timeout=wait)
            except TimeoutError:
                return
            wait = 0.0
            if isinstance(frame, bytes):
                assert frame[0] == 1, f'unexpected binary opcode {frame[0]}'
                sub, log_time = struct.unpack_from('<IQ', frame, 1)
                topic, msg = self.subscribed[sub], json.loads(frame[13:].decode())
                self.received.append((topic, log_time, msg))
                self.last[topic] = msg
                continue
            msg = json.loads(frame)
            if msg['op'] == 'serverInfo':
                self.info = msg
            elif msg['op'] == 'advertise':
                self.channels.update({c['topic']: c for c in msg['channels']})
            else:
                self.ops.append(msg)

    def read(self, until, timeout=TIMEOUT_S):
        """Read frames until ``until()`` is true; fail after ``timeout`` s."""
        end = time.monotonic() + timeout
        while not until():
            assert time.monotonic() < end, 'timed out waiting for the server'
            # a short wait: ``until`` may also act (offer, publish) until it holds
            self.drain(0.05)

    def subscribe(self, names):
        subs = []
        for name in names:
            sub = len(self.subscribed) + 1
            self.subscribed[sub] = name
            subs.append({'id': sub, 'channelId': self.channels[name]['id']})
        self.ws.send(json.dumps({'op': 'subscribe', 'subscriptions': subs}))

    def messages(self, topic):
        return [(t, m) for name, t, m in self.received if name == topic]


def _advertised(view):
    client = Client(view.port)
    client.read(lambda: len(client.channels) == len(CHANNELS))
    return client


def _offer(view, items):
    """Offer ``items`` as the node does, each once the worker took the one before."""
    for e, measured, summary in items:
        if summary is not None:
            view.offer_alerts(summary)
        view.offer(e, measured)
        _wait(lambda: view.shown == view.offered)


def _conforms(value, schema, where):
    """Assert that ``value`` has exactly the schema's properties, with their types."""
    kinds = schema.get('type')
    kinds = kinds if isinstance(kinds, list) else [kinds]
    python = {'object': dict, 'number': (int, float), 'integer': int, 'string': str,
              'boolean': bool, 'null': type(None), 'array': list}
    assert any(isinstance(value, python[k]) and not (k in ('number', 'integer')
                                                     and isinstance(value, bool))
               for k in kinds), f'{where}: {value!r} is not {kinds}'
    if 'enum' in schema:
        assert value in schema['enum'], f'{where}: {value!r} not in {schema["enum"]}'
    if isinstance(value, dict):
        assert set(value) == set(schema['properties']), where
        for k, v in value.items():
            _conforms(v, schema['properties'][k], f'{where}.{k}')
    if isinstance(value, list):
        for k, v in enumerate(value):
            _conforms(v, schema['items'], f'{where}[{k}]')


def test_address_parsing_and_url():
    assert parse_address('127.0.0.1:8765') == ('127.0.0.1', 8765)
    assert parse_address('[::1]:9000') == ('::1', 9000)
    for bad in ('8765', 'localhost', 'host:port', ':80', 'h:70000'):
        with pytest.raises(ValueError, match='HOST:PORT'):
            parse_address(bad)
    assert app_url('127.0.0.1', 8765) == ('https://app.foxglove.dev/?ds=foxglove-websocket'
                                          '&ds.url=ws://127.0.0.1:8765')
    assert parse_address(address_text('::1', 8765)) == ('::1', 8765)


def test_taken_port_is_a_clear_error(view):
    with pytest.raises(RuntimeError, match='in use'):
        LiveView('127.0.0.1', view.port, estimates=(), limited=(), inputs=(),
                 thermocouples={})


def test_channels_and_schemas_are_advertised(view):
    client = _advertised(view)
    try:
        assert {'parameters', 'clientPublish'} <= set(client.info['capabilities'])
        for name, topic in view_topics().items():
            c = client.channels[topic]
            assert c['encoding'] == 'json' and c['schemaEncoding'] == 'jsonschema'
            assert c['schemaName'] == CHANNELS[name]
            assert json.loads(c['schema']) == view.schemas[name]
        limits = view.schemas['limits']['properties']
        assert set(LIMITED) <= set(limits) and 'margin_current_A' in limits
        assert set(view.schemas['thermocouples']['properties']) >= set(interface.THERMOCOUPLES)
    finally:
        client.close()


def test_messages_match_the_estimates(view, run):
    items = run
    client = _advertised(view)
    try:
        names = view_topics()
        client.subscribe(names.values())
        _wait(lambda: len(view.watched()) == len(CHANNELS))
        _offer(view, items)
        # every estimate is sent on the temperatures channel, the worker sends in order: once
        # the last one is there, so is everything before it (the input-rate channels carry
        # only the estimates that start an input period, which the last need not be)
        last = items[-1][0].step
        client.read(lambda: client.last.get(names['temperatures'], {}).get('step') == last)
    finally:
        client.close()
    by_step = {e.step: (e, measured) for e, measured, _ in items}
    for name, topic in names.items():
        if name in ('recorder', 'whatif'):      # only when they report: their own tests
            continue
        got = client.messages(topic)
        assert got, f'nothing on {topic}'
        for log_time, m in got:
            _conforms(m, view.schemas[name], topic)
            if name != 'events':      # sample time, the estimate's stamp
                e = by_step[m['step']][0]
                assert log_time == round(e.stamp_s * 1e9)
                assert m['timestamp'] == {'sec': log_time // 10**9, 'nsec': log_time % 10**9}
    assert view.errors == 0, view.last_error
    temps = client.messages(names['temperatures'])
    assert len(temps) == len(items)             # nothing dropped at this pace
    for _, m in temps:
        e = by_step[m['step']][0]
        for n in interface.ESTIMATES:
            sigma = e.uncertainty_K[n]
            assert m[n]['estimate_C'] == e.temperatures_C[n] and m[n]['sigma_K'] == sigma
            assert m[n]['band_high_C'] == pytest.approx(e.temperatures_C[n]
                                                        + BAND_SIGMAS * sigma)
    for _, m in client.messages(names['limits']):
        e = by_step[m['step']][0]
        assert m['margin_current_A'] == e.margin_current_A
        for q in LIMITED:
            assert m[q]['margin_K'] == pytest.approx(e.limits_C[q] - e.temperatures_C[q])
            ttl = e.time_to_limit_s.get(q)
            if ttl is None:
                assert m[q]['time_to_limit_s'] is None
            else:
                assert m[q]['time_to_limit_s'] == pytest.approx(
                    max(ttl - (e.stamp_s - e.forecast_stamp_s), 0.0))
    assert client.messages(names['limits'])[-1][1]['margin_current_A'] is not None
    # the alert timeline: the oil's WARN is raised when the estimator raised it
    raised = next(e for e, _, _ in items if any(ev.kind == 'raised' for ev in e.alert_events))
    levels = {m['step']: m['oil']['reported'] for _, m in client.messages(names['alerts'])}
    assert levels[raised.step] == 'WARN' and levels[raised.step - 1] == 'OK'
    events = [m for _, m in client.messages(names['events'])]
    assert any('oil' in m['message'] and m['level'] == 3 for m in events), events
    # inputs: the mean of each window of 50 ms of sample time (the current: RMS)
    inputs = client.messages(names['inputs'])
    span_s = items[-1][0].stamp_s - items[0][0].stamp_s
    assert abs(len(inputs) - 20.0 * span_s) <= 2     # at 20 Hz of sample time
    steps = [m['step'] for _, m in inputs]
    for prev, (_, m) in zip(steps, inputs[1:]):
        window = [by_step[k][0].inputs for k in range(prev + 1, m['step'] + 1)]
        current = np.concatenate([w['current_A'] for w in window])
        assert m['current_A'] == pytest.approx(np.sqrt(np.mean(current ** 2)), rel=1e-12)
        speed = np.concatenate([w['speed_rad_s'] for w in window])
        assert m['speed_rad_s'] == pytest.approx(speed.mean(), rel=1e-12)
    # the thermocouples beside their estimates
    _, m = client.messages(names['thermocouples'])[-1]
    e, measured = by_step[m['step']]
    assert m['frame']['measured_C'] == measured['frame'][1] == 21.5
    assert m['frame']['error_K'] == pytest.approx(e.temperatures_C['frame'] - 21.5)
    assert m['winding']['measured_C'] is None
    health = client.messages(names['input_health'])[-1][1]
    assert health['current_A']['state'] == 'OK' and health['stale_count'] == 0


def test_parameters_are_shown_and_the_safe_ones_settable(view):
    client = _advertised(view)
    try:
        client.ws.send(json.dumps({'op': 'getParameters', 'parameterNames': [], 'id': 'g'}))
        client.read(lambda: any(o.get('id') == 'g' for o in client.ops))
        shown = {p['name']: p['value'] for p in client.ops[-1]['parameters']}
        assert shown == {'publish_rate_Hz': 50.0, 'alerts.oil.warn_C': 21.0,
                         'topic_prefix': '/eha'}
        client.ws.send(json.dumps({'op': 'setParameters', 'id': 's', 'parameters': [
            {'name': 'publish_rate_Hz', 'value': 20}, {'name': 'alerts.oil.warn_C',
                                                       'value': 200.0}]}))
        client.read(lambda: any(o.get('id') == 's' for o in client.ops)
                    and any(o['op'] == 'status' for o in client.ops))
        answer = {p['name']: p['value'] for p in next(o for o in client.ops
                                                      if o.get('id') == 's')['parameters']}
        assert answer == {'publish_rate_Hz': 20.0, 'alerts.oil.warn_C': 21.0}
        status = next(o for o in client.ops if o['op'] == 'status')
        assert 'alerts.oil.warn_C is read-only' in status['message']
        assert view.take_requests() == {'publish_rate_Hz': 20.0}
        assert view.take_requests() == {}
        # out of range: refused, the value kept
        client.ws.send(json.dumps({'op': 'setParameters', 'id': 'r', 'parameters': [
            {'name': 'publish_rate_Hz', 'value': 1e6}]}))
        client.read(lambda: any(o.get('id') == 'r' for o in client.ops))
        assert view.take_requests() == {}
        # the owner confirms a value: a status says it, and the next getParameters has it
        view.show_parameters({'publish_rate_Hz': 25.0})
        assert _parameters(client, 'h')['publish_rate_Hz'] == 25.0
        client.read(lambda: _status(client, 'parameters now: publish_rate_Hz = 25.0'))
    finally:
        client.close()


def _parameters(client, request_id):
    """Ask for every parameter; return them as name -> value."""
    client.ws.send(json.dumps({'op': 'getParameters', 'parameterNames': [], 'id': request_id}))
    client.read(lambda: any(o.get('id') == request_id for o in client.ops))
    answer = next(o for o in client.ops if o.get('id') == request_id)
    return {p['name']: p['value'] for p in answer['parameters']}


def _status(client, message):
    return any(o['op'] == 'status' and o['message'] == message for o in client.ops)


def test_values_shown_while_clients_subscribe_to_parameters_never_freeze_the_process():
    # a deadlock holds the interpreter's lock for ever: only another process can fail the test
    in_a_fresh_process('test_foxglove_view', 'show_values_while_a_client_churns', '3000',
                       '300', forks=False, timeout_s=120.0)


def show_values_while_a_client_churns(shows: str, churns: str) -> None:
    """
    Show ``shows`` values while a client subscribes and unsubscribes ``churns`` times or more.

    foxglove-sdk 0.30's publish_parameter_values froze the process when a
    client subscribed at that moment; the values are now shown another way.
    Both sides go on until each has done its count, so they overlap however
    the machine schedules them; the owner waits for the client to read (at
    most 64 statuses behind: the server drops a client 256 behind).
    """
    shows, churns = int(shows), int(churns)
    view = LiveView('127.0.0.1', 0, estimates=interface.ESTIMATES, limited=LIMITED,
                    inputs=('current_A',), thermocouples=interface.THERMOCOUPLES,
                    parameters={'publish_rate_Hz': 50.0},
                    settable={'publish_rate_Hz': (1.0, 500.0)})
    client = Client(view.port)
    churned = [0]
    done = threading.Event()

    def churn():
        while not done.is_set() or churned[0] < churns:
            op = ('subscribeParameterUpdates', 'unsubscribeParameterUpdates')[churned[0] % 2]
            client.ws.send(json.dumps({'op': op, 'parameterNames': ['publish_rate_Hz']}))
            client.drain()
            churned[0] += 1

    thread = threading.Thread(target=churn, daemon=True)
    thread.start()
    k = 0
    while k < shows or churned[0] < churns:
        if k - len(client.ops) < 64:        # the client reads nothing but these statuses
            view.show_parameters({'publish_rate_Hz': float(k)})
            k += 1
        else:
            time.sleep(0.001)
    done.set()
    thread.join()
    last = f'parameters now: publish_rate_Hz = {k - 1.0}'
    client.read(lambda: _status(client, last))
    assert _parameters(client, 'g')['publish_rate_Hz'] == k - 1.0
    client.close()
    view.close()


def test_a_client_that_stops_reading_stalls_nothing(view, run):
    e0, measured, _ = run[-1]
    names = view_topics()
    # max_queue=1: the client's reading thread stops at the first frame not taken, and
    # TCP, with a small receive buffer, soon pushes back on the server
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(('127.0.0.1', view.port))
    stalled = Client(view.port, max_queue=1, sock=sock)
    stalled.read(lambda: len(stalled.channels) == len(CHANNELS))
    stalled.subscribe(names.values())
    _wait(lambda: len(view.watched()) == len(CHANNELS))
    n = 3000      # about 10 MB of messages: more than the socket buffers and the backlog hold
    worst = 0.0
    start = time.monotonic()
    for k in range(1, n + 1):
        e = dataclasses.replace(e0, step=e0.step + k, stamp_s=e0.stamp_s + 0.02 * k)
        t = time.perf_counter()
        view.offer(e, measured)
        worst = max(worst, time.perf_counter() - t)
        if k % (PENDING_ESTIMATES // 2) == 0:
            # at the worker's pace, so that every estimate goes out to the stalled client
            _wait(lambda: view.shown == view.offered)
    # a 50 Hz estimator has 20 ms per estimate: the hand-off takes a tiny part of it, and
    # the worker went on although the client read nothing
    assert worst < 0.01, worst
    assert time.monotonic() - start < 40.0
    fresh = _advertised(view)
    later = [e0.step + n]

    def offer_next():
        """Offer one more estimate (the fresh subscription takes effect at some point)."""
        later.append(later[-1] + 1)
        k = later[-1] - e0.step
        view.offer(dataclasses.replace(e0, step=later[-1], stamp_s=e0.stamp_s + 0.02 * k),
                   measured)

    try:
        fresh.subscribe([names['temperatures']])
        fresh.read(lambda: offer_next() or names['temperatures'] in fresh.last)
        # the stalled client, reading again, gets the newest; the oldest were dropped for it
        stalled.read(lambda: stalled.last.get(names['temperatures'], {}).get('step')
                     == later[-1])
        assert len(stalled.messages(names['temperatures'])) < n
    finally:
        fresh.close()
        stalled.close()
    assert view.errors == 0, view.last_error


# ----------------------------------------------------------------- layouts
_PATH_KEYS = ('value', 'path', 'topicPath', 'topicToRender')


def message_paths(node):
    """Yield every message path a layout's panel configurations name."""
    if isinstance(node, dict):
        for k, v in node.items():
            if k in _PATH_KEYS and isinstance(v, str) and v.startswith('/'):
                yield v
            else:
                yield from message_paths(v)
    elif isinstance(node, list):
        for v in node:
            yield from message_paths(v)


def split_path(path):
    """Return ``(topic, [field, ...])`` of a message path, filters and slices dropped."""
    text = re.sub(r'\{[^}]*\}|\[[^\]]*\]', '', re.sub(r'"[^"]*"', '""', path))
    topic, _, rest = text.partition('.')
    return topic, [f for f in rest.split('.') if f and not f.startswith('@')]


def _json_fields_exist(schema, fields, path):
    for f in fields:
        assert f in schema.get('properties', {}), f'{path}: no field {f!r}'
        schema = schema['properties'][f]


def _ros_fields_exist(type_name, fields, path):
    cls = message_class(type_name)
    for f in fields:
        types = cls.get_fields_and_field_types()
        assert f in types, f'{path}: {type_name} has no field {f!r}'
        kind = re.sub(r'^sequence<(.*)>$', r'\1', types[f])
        if '/' not in kind:
            break
        pkg, name = kind.split('/')
        cls = message_class(f'{pkg}/msg/{name}')
        type_name = f'{pkg}/msg/{name}'


def _layout(name, namespace='/', tmp_path=None):
    """
    Return the layout file ``name``, checked: every panel placed is configured, and back.

    In a namespace other than the root: as ``wet-eha-thermal layout`` writes it (in ``tmp_path``).
    """
    path = ROOT / 'layouts' / name
    if namespace != '/':
        path = tmp_path / name
        assert cli_main(['layout', name.split('.')[0], '--namespace', namespace,
                         '-o', str(path)]) == 0
    layout = json.loads(path.read_text())
    assert set(layout) >= {'configById', 'layout', 'globalVariables', 'userNodes',
                           'playbackConfig'}
    config = layout['configById']
    placed = []

    def walk(node):
        if isinstance(node, str):
            placed.append(node)
            for tab in config[node]['tabs'] if node.startswith('Tab!') else ():
                walk(tab['layout'])
        else:
            walk(node['first'])
            walk(node['second'])

    walk(layout['layout'])
    assert sorted(placed) == sorted(config), 'panels placed and configured differ'
    # the gauges' dials end at the limits of the shipped configuration
    limits = EstimatorSession(load_config()).limits_C
    for panel, cfg in config.items():
        if panel.startswith('Gauge!') and panel[6:] in limits:
            assert cfg['maxValue'] == limits[panel[6:]], panel
    return layout


#: the shipped layouts, and as written for an actuator in a namespace
NAMESPACES = ('/', '/left', '/rig_pc/right')
#: how many message paths each shipped layout names (each one is moved in a namespace)
PATHS = {'live.json': 93, 'replay.json': 43}


@pytest.mark.parametrize('namespace', NAMESPACES)
def test_live_layout_names_only_channels_of_the_view(view, namespace, tmp_path):
    layout = _layout('live.json', namespace, tmp_path)
    prefix = interface.namespace_prefix(namespace)
    by_topic = {topic: view.schemas[name] for name, topic in view_topics(prefix).items()}
    paths = list(message_paths(layout['configById']))
    assert len(paths) == PATHS['live.json']
    assert '/eha/' not in json.dumps(layout) or prefix == '/eha'
    for path in paths:
        topic, fields = split_path(path)
        assert topic in by_topic, f'{path}: the view has no channel {topic}'
        _json_fields_exist(by_topic[topic], fields, path)
    panels = {k.split('!')[0] for k in layout['configById']}
    assert {'Plot', 'Gauge', 'Indicator', 'Table', 'StateTransitions'} <= panels
    # every channel of the view is shown somewhere
    assert {split_path(p)[0] for p in paths} == set(by_topic)
    # what-ifs are asked for where the estimator takes them, as a std_msgs/String of a request
    publish = layout['configById']['Publish!whatif']
    assert publish['topicName'] == interface.prefixed(interface.WHATIF_REQUEST_TOPIC, prefix)
    assert publish['datatype'] == 'std_msgs/String'
    assert parse_request(json.loads(publish['value'])['data'], load_config(),
                         interface.ESTIMATES).stage == 6


@pytest.mark.parametrize('namespace', NAMESPACES)
def test_replay_layout_names_only_recorded_topics(namespace, tmp_path):
    layout = _layout('replay.json', namespace, tmp_path)
    prefix = interface.namespace_prefix(namespace)
    cfg_inputs = EstimatorSession(load_config()).inputs
    unused = {interface.prefixed(interface.INPUT_TOPICS[n], prefix)
              for n in interface.INPUT_TOPICS if n not in cfg_inputs}
    recorded = {t: spec for t, spec in recorded_topics(prefix).items() if t not in unused}
    paths = list(message_paths(layout['configById']))
    assert len(paths) == PATHS['replay.json']
    for path in paths:
        topic, fields = split_path(path)
        assert topic in recorded, f'{path}: a live recording has no topic {topic}'
        _ros_fields_exist(recorded[topic][0], fields, path)
    # the statuses it reads are those the estimator in that namespace publishes
    names = {n for p in paths for n in re.findall(r'name=="([^"]*)"', p)}
    names.add(layout['configById']['DiagnosticStatusPanel!detail']['selectedName'])
    ours = interface.status_name('', interface.ESTIMATOR_NODE, namespace)
    assert len(names) > 2 and all(n.startswith(ours) for n in names), names


def test_a_layout_keeps_what_is_not_the_twins():
    """Only /eha topics and the twin's status names move; the root gives the layout back."""
    template = {'a': ['/eha/view/limits.oil', '/ehanot/x', '/diagnostics', 'eha: x',
                      'text /eha/estimate', '/eha', 'eha_recorder: recorder'],
                'b': {'topicName': '/eha/whatif/request', 'n': 3}}
    assert layout_for(template, '/') == template
    assert layout_for(template, '/eha') == {
        'a': ['/eha/view/limits.oil', '/ehanot/x', '/diagnostics', 'eha: x',
              'text /eha/estimate', '/eha', 'eha/eha_recorder: recorder'],
        'b': {'topicName': '/eha/whatif/request', 'n': 3}}
    assert layout_for(template, '/left') == {
        'a': ['/left/view/limits.oil', '/ehanot/x', '/diagnostics', 'eha: x',
              'text /eha/estimate', '/left', 'left/eha_recorder: recorder'],
        'b': {'topicName': '/left/whatif/request', 'n': 3}}
    assert layout_for(template, '/left', prefix='/rig_b')['b']['topicName'] == \
        '/rig_b/whatif/request'


def test_where_a_layout_comes_from():
    assert where_to_get('live') == 'layouts/live.json'
    assert where_to_get('live', '/left') == 'wet-eha-thermal layout live --namespace /left'
    assert where_to_get('replay', '/', '/rig_b') == \
        'wet-eha-thermal layout replay --namespace / --topic-prefix /rig_b'


def test_the_layout_command_refuses_a_bad_namespace(tmp_path, capsys):
    assert cli_main(['layout', 'live', '--namespace', '/2left', '-o',
                     str(tmp_path / 'x.json')]) == 2
    assert "--namespace = '/2left': a namespace is one or more names" in capsys.readouterr().err
    assert not (tmp_path / 'x.json').exists()


def test_the_recorder_health_is_shown_at_once_and_a_fault_is_an_event(view, run):
    """A recorder's report reaches its channel on the estimates' time line; ERROR is logged."""
    health = {'node': 'eha_recorder', 'hardware_id': 'rig', 'stamp_s': 1.0e9, 'level': 0,
              'level_name': 'OK', 'message': 'recording to x_0.mcap', 'state': 'recording',
              'messages_written': 1000, 'messages_dropped': 0, 'bytes_written': 123456,
              'write_rate_B_s': 2.5e5, 'free_bytes': 10 ** 9, 'time_left_s': 4000.0,
              'errors': 0, 'last_error': '', 'file': 'x_0.mcap', 'files': 1}
    fault = dict(health, level=2, level_name='ERROR', message='disk full: writing suspended',
                 state='suspended', messages_dropped=42, file=None, time_left_s=None,
                 errors=1, last_error='OSError: [Errno 28] No space left on device')
    client = _advertised(view)
    try:
        names = view_topics()
        client.subscribe([names['recorder'], names['events']])
        _wait(lambda: len(view.watched()) == 2)
        _offer(view, run[:3])
        view.offer_recorder(health)
        view.offer_recorder(fault)
        client.read(lambda: len(client.messages(names['recorder'])) == 2)
        client.read(lambda: any('recorder ERROR' in m['message']
                                for _, m in client.messages(names['events'])))
    finally:
        client.close()
    got = client.messages(names['recorder'])
    stamp = round(run[2][0].stamp_s * 1e9)            # the last estimate's sample time
    for (log_time, m), sent in zip(got, (health, fault)):
        _conforms(m, view.schemas['recorder'], names['recorder'])
        assert log_time == stamp
        assert {k: m[k] for k in sent if k in m} == {k: v for k, v in sent.items() if k in m}
    event = next(m for _, m in client.messages(names['events']) if 'recorder' in m['message'])
    assert event['level'] == 4 and 'disk full' in event['message']
    assert view.errors == 0, view.last_error


def test_a_client_asks_for_a_whatif_and_sees_the_answer(view, run):
    """A request published by a client reaches the owner; the answer is shown as arrays."""
    client = _advertised(view)
    names = view_topics()
    request = '{"id": "fox", "stage": 6, "duration_s": 60, "quantities": ["oil", "frame"]}'
    try:
        client.subscribe([names['whatif']])
        _wait(lambda: view.watched() == ['whatif'])
        # as Foxglove's Publish panel sends a std_msgs/String on a JSON channel
        client.ws.send(json.dumps({'op': 'advertise', 'channels': [{
            'id': 7, 'topic': interface.WHATIF_REQUEST_TOPIC, 'encoding': 'json',
            'schemaName': 'std_msgs/String'}]}))
        taken = []
        _wait(lambda: taken.extend(view.take_whatif_requests()) or taken
              or client.ws.send(struct.pack('<BI', 1, 7) + json.dumps({'data': request})
                                .encode()) or time.sleep(0.1))
        assert taken[0] == request
        _offer(view, run[:2])
        cfg = load_config()
        answer = run_request(taken[0], cfg, model_outputs(cfg), None, 20.0, 'cold', None)
        view.offer_whatif(answer)
        view.offer_whatif('{"id": "x", "ok": false, "error": "busy"}')
        client.read(lambda: len(client.messages(names['whatif'])) == 2)
    finally:
        client.close()
    (log_time, shown), (_, error) = client.messages(names['whatif'])
    for m in (shown, error):
        _conforms(m, view.schemas['whatif'], names['whatif'])
    assert log_time == round(run[1][0].stamp_s * 1e9)
    data = json.loads(answer)
    assert shown['id'] == 'fox' and shown['ok'] and shown['time_min'][-1] == 1.0
    assert shown['temperatures_C']['oil'] == data['temperatures_C']['oil']
    assert shown['temperatures_C']['winding_hotspot'] == []      # not asked for
    assert shown['time_to_limit_s'] == data['time_to_limit_s']
    assert error['error'] == 'busy' and error['time_min'] == [] and error['peaks_C']['oil'] is None
    assert view.errors == 0, view.last_error
