"""
The channels of the live view (:mod:`.live_view`): their topics and JSON schemas.

Under ``<prefix>/view`` (``/eha/view`` by default; see :data:`CHANNELS`):

- ``temperatures``: every estimate with its 1 sigma and the band of
  ``BAND_SIGMAS`` sigma around it, at each estimate;
- ``limits``: the winding hot-spot, the magnet and the oil against their
  limits and alert thresholds, the margin to the limit, the time left to it
  and the margin current, at each estimate;
- ``alerts``: the alert level overall and per quantity (reported, active,
  acknowledged), data gap and clock jumps, at each estimate (so that a State
  Transitions panel draws a continuous timeline);
- ``events``: each alert event and time-base notice as a ``foxglove.Log``;
- ``inputs``: the sensor inputs averaged over ``inputs_rate_Hz`` windows of
  sample time (the current as RMS), from the grid values the model took;
- ``input_health``: per input OK or STALE, with the received and rejected
  counts of the last snapshot, at the inputs' rate;
- ``thermocouples``: each thermocouple's last reading beside the estimate it
  measures and their difference, at the inputs' rate;
- ``recorder``: the recorder's health (its level, state, what it wrote and
  dropped, the write rate, the free space and the time it leaves, the file
  being written, its errors), as the recorder reports it: at 1 Hz and at
  once on a change; a change of level is also an event;
- ``whatif``: the last what-if answer (:meth:`.live_view.LiveView.offer_whatif`), its
  trajectories as arrays over ``time_min`` for a Plot panel, when it comes.

The schemas are data, one JSON schema per channel for the estimates, the
limited quantities, the inputs and the thermocouples of a configuration; no
import of the package or of the Foxglove SDK, so that the view's owner and
the tests read them without starting a view.
"""

from typing import Any, Dict, Mapping, Sequence

#: Schema name prefix of the view's own JSON schemas.
SCHEMA_PREFIX = 'wet_eha_thermal.view.'
#: Width of the uncertainty band: estimate +- BAND_SIGMAS sigma (about 95 %).
BAND_SIGMAS = 2.0
#: Alert level names, by level (0, 1, 2).
LEVEL_NAMES = ('OK', 'WARN', 'CRITICAL')
#: Channels of the view: name -> schema title (the schema name Foxglove shows).
CHANNELS = {
    'temperatures': SCHEMA_PREFIX + 'Temperatures',
    'limits': SCHEMA_PREFIX + 'Limits',
    'alerts': SCHEMA_PREFIX + 'Alerts',
    'events': 'foxglove.Log',
    'inputs': SCHEMA_PREFIX + 'Inputs',
    'input_health': SCHEMA_PREFIX + 'InputHealth',
    'thermocouples': SCHEMA_PREFIX + 'Thermocouples',
    'recorder': SCHEMA_PREFIX + 'Recorder',
    'whatif': SCHEMA_PREFIX + 'WhatIf',
}
#: Recorder health levels (as diagnostic_msgs has them) and their foxglove.Log levels.
RECORDER_LEVELS = ('OK', 'WARN', 'ERROR')

_NUMBER = {'type': 'number'}
_MAYBE_NUMBER = {'type': ['number', 'null']}
_TIME = {'type': 'object', 'description': 'sample time of the estimate',
         'properties': {'sec': {'type': 'integer', 'minimum': 0},
                        'nsec': {'type': 'integer', 'minimum': 0}}}


def view_topics(prefix: str = '/eha') -> Dict[str, str]:
    """Return the topic of each channel of :data:`CHANNELS` under ``prefix``."""
    return {name: f'{prefix.rstrip("/")}/view/{name}' for name in CHANNELS}


def _obj(title: str, description: str, properties: Dict[str, Any]) -> Dict[str, Any]:
    return {'type': 'object', 'title': title, 'description': description,
            'properties': properties}


def _group(description: str, fields: Mapping[str, str], nullable=()) -> Dict[str, Any]:
    """Return the schema of a nested object of numbers (``nullable`` ones may be null)."""
    return {'type': 'object', 'description': description,
            'properties': {k: dict(_MAYBE_NUMBER if k in nullable else _NUMBER, description=d)
                           for k, d in fields.items()}}


def schemas(estimates: Sequence[str], limited: Sequence[str], inputs: Sequence[str],
            thermocouples: Mapping[str, str]) -> Dict[str, Dict[str, Any]]:
    """Return the JSON schema of every channel of :data:`CHANNELS`."""
    head = {'timestamp': _TIME, 'step': {'type': 'integer', 'description': 'model step'}}
    band = {'estimate_C': 'estimate, degC', 'sigma_K': 'uncertainty, 1 sigma, K',
            'band_low_C': f'estimate - {BAND_SIGMAS:g} sigma, degC',
            'band_high_C': f'estimate + {BAND_SIGMAS:g} sigma, degC'}
    limit = {'estimate_C': 'estimate, degC',
             'band_high_C': f'estimate + {BAND_SIGMAS:g} sigma, degC',
             'limit_C': 'limit, degC', 'warn_C': 'warning threshold, degC',
             'critical_C': 'critical threshold, degC',
             'margin_K': 'limit - estimate, K',
             'time_to_limit_s': 'time left until the forecast reaches the limit, counted from '
                                'this estimate, s; null: beyond the horizon or no forecast yet'}
    level = {'type': 'string', 'enum': list(LEVEL_NAMES)}
    quantity = {'type': 'object', 'properties': {
        'reported': dict(level, description='level reported (latched until acknowledged)'),
        'active': dict(level, description='level the temperatures hold now'),
        'acknowledged': {'type': 'boolean'},
        'level': {'type': 'integer', 'description': 'reported level: 0 OK, 1 WARN, 2 CRITICAL'}}}
    health = {'type': 'object', 'properties': {
        'state': {'type': 'string', 'enum': ['OK', 'STALE']},
        'received': {'type': 'integer', 'description': 'samples received (last snapshot)'},
        'rejected': {'type': 'integer', 'description': 'samples rejected (last snapshot)'}}}
    tc = {'measured_C': 'last reading, degC', 'estimate_C': 'estimate it measures, degC',
          'error_K': 'estimate - reading, K', 'age_s': 'age of the reading, s'}
    return {
        'temperatures': _obj(CHANNELS['temperatures'],
                             'estimated temperatures with their uncertainty bands',
                             {**head, **{n: _group(n, band) for n in estimates}}),
        'limits': _obj(CHANNELS['limits'], 'limited temperatures against their limits', {
            **head,
            'margin_current_A': dict(_MAYBE_NUMBER, description='largest continuous current '
                                     'at the present oil and duty, A RMS; null: pending'),
            'current_limit_A': dict(_MAYBE_NUMBER, description="the drive's binding current "
                                    'limit (the shortest horizon), A RMS; null: pending'),
            'current_limits_status': {'type': 'string', 'description': (
                "ok, fallback: <why>, or pending: the drive's current limits")},
            'forecast_started_s': dict(_MAYBE_NUMBER, description='sample time at which the '
                                       'latest forecast started, s'),
            **{q: _group(q, limit, nullable=('time_to_limit_s',)) for q in limited}}),
        'alerts': _obj(CHANNELS['alerts'], 'alert levels', {
            **head, 'level': {'type': 'integer', 'description': 'worst reported level'},
            'level_name': level, 'message': {'type': 'string'},
            'data_gap': {'type': 'boolean', 'description': 'every input silent now'},
            'clock_jumps': {'type': 'integer'},
            **{q: quantity for q in limited}}),
        # the fields of foxglove.Log: Foxglove's Log panel takes a channel by this schema name
        'events': _obj(CHANNELS['events'], 'alert events and time-base notices', {
            'timestamp': _TIME, 'level': {'type': 'integer', 'description': '2 INFO, 3 WARNING, '
                                          '4 ERROR'},
            'message': {'type': 'string'}, 'name': {'type': 'string'},
            'file': {'type': 'string'}, 'line': {'type': 'integer', 'minimum': 0}}),
        'inputs': _obj(CHANNELS['inputs'], 'sensor inputs averaged since the last message '
                       '(current: RMS), SI units', {
                           **head, **{n: dict(_MAYBE_NUMBER, description=n) for n in inputs}}),
        'input_health': _obj(CHANNELS['input_health'], 'input health', {
            **head, 'stale_count': {'type': 'integer'}, **{n: health for n in inputs}}),
        'recorder': _obj(CHANNELS['recorder'], "the recorder's health (null: not known)", {
            'timestamp': _TIME,
            'level': {'type': 'integer', 'description': '0 OK, 1 WARN, 2 ERROR'},
            'level_name': {'type': 'string', 'enum': list(RECORDER_LEVELS)},
            'message': {'type': 'string'},
            'state': {'type': 'string', 'enum': ['recording', 'suspended', 'closed']},
            'messages_written': {'type': 'integer'},
            'messages_dropped': {'type': 'integer'},
            'bytes_written': {'type': 'integer'},
            'write_rate_B_s': dict(_MAYBE_NUMBER, description='bytes written per second'),
            'free_bytes': {'type': ['integer', 'null'],
                           'description': 'free space at the destination'},
            'time_left_s': dict(_MAYBE_NUMBER, description='free space over the write rate'),
            'errors': {'type': 'integer'},
            'last_error': {'type': 'string'},
            'file': {'type': ['string', 'null'], 'description': 'file being written'},
            'files': {'type': 'integer'}}),
        'whatif': _whatif_schema(estimates, limited),
        'thermocouples': _obj(CHANNELS['thermocouples'], 'thermocouples beside their estimates '
                              '(null: no reading yet)', {
                                  **head, **{t: _group(f'{t} measures {q}', tc,
                                                       nullable=tuple(tc)) for t, q in
                                             thermocouples.items()}}),
    }


def _whatif_schema(estimates: Sequence[str], limited: Sequence[str]) -> Dict[str, Any]:
    """Return the schema of the what-if channel: an answer's trajectories as arrays."""
    series = {'type': 'array', 'items': _NUMBER}
    text = {'type': ['string', 'null']}
    return _obj(CHANNELS['whatif'], 'the last what-if answer (an error: empty arrays)', {
        'timestamp': _TIME, 'id': {'type': 'string'}, 'ok': {'type': 'boolean'},
        'error': dict(text, description='why it did not run; null: it ran'),
        'source': text, 'duty': text,
        'start_stamp_s': dict(_MAYBE_NUMBER, description='sample time of the start state, s'),
        'duration_s': _MAYBE_NUMBER, 'ambient_C': _MAYBE_NUMBER,
        'stopped': dict(text, description='why it ended early; null: it ran to the end'),
        'time_min': dict(series, description='time from the start state, min'),
        'temperatures_C': {'type': 'object', 'properties': {
            n: dict(series, description=f'{n}, degC (empty: not asked for)')
            for n in estimates}},
        'peaks_C': _group('peak of each quantity asked for, degC', dict.fromkeys(
            estimates, 'degC'), nullable=estimates),
        'limits_C': _group('limits, degC', dict.fromkeys(limited, 'degC'), nullable=limited),
        'time_to_limit_s': _group('time from the start to the limit, s; null: not within',
                                  dict.fromkeys(limited, 's'), nullable=limited)})
