"""
Over-temperature alerts on the estimator's predicted temperatures.

Each :class:`AlertRule` gives one quantity (``'winding_hotspot'``,
``'magnet'``, ...) a warn and a critical threshold, a hysteresis, a minimum
duration and whether a raised level latches until acknowledged.
:class:`AlertManager` evaluates the rules in *sample time*, the estimator's
own timestamps in seconds, so replaying a log gives the same alerts as the
live run.

Semantics, per threshold (warn and critical are tracked independently):

* Pickup: a pickup timer starts at the first sample at or above the
  threshold. The level is raised at the first sample at or above the
  threshold that comes ``min_duration_s`` or more after the timer started
  (with ``min_duration_s == 0`` at once).
* Timer reset: the timer resets only when the value falls below
  ``threshold - hysteresis_K``, not when it dips just under the threshold.
  Pickup and drop-out thus share one hysteresis band (a Schmitt trigger
  followed by an on-delay): a temperature hovering at the threshold with
  noise smaller than the hysteresis is a sustained exceedance and cannot
  postpone its alert forever by dipping for one sample. Because the raising
  sample itself must be at or above the threshold, a lone spike followed by
  a value sitting just under the threshold never alerts, and the alert
  message is always true.
* Drop-out: a raised level clears at the first sample below
  ``threshold - hysteresis_K`` (no minimum duration for clearing); values
  inside the band keep the level, so they never chatter.
* Gaps: the condition is only known at the samples. Elapsed time is the
  difference of sample stamps, so one update after a long gap counts the
  whole gap toward ``min_duration_s`` if the condition held at both ends
  (the last sample before and the one after), and none of it otherwise;
  excursions inside the gap are not seen. A missing or non-finite value is
  skipped: the state, timers included, is kept as it was.
* Escalation: the critical level has its own pickup timer, started at the
  first sample at or above ``critical_C``; a value that jumps straight
  above ``critical_C`` for ``min_duration_s`` raises CRITICAL directly.
  CRITICAL de-escalates to WARN below ``critical_C - hysteresis_K`` while
  the warn level still holds.
* Latching: with ``latch`` the reported level is the highest level raised
  since the last acknowledgement, even after the condition cleared.
  Acknowledging a latched alert whose condition cleared returns it to OK.
  Acknowledging an alert that is still active leaves it reported at its
  active level, follows that level down, and lets it clear without another
  acknowledgement; it does not latch again until the condition clears and
  re-raises, or escalates above the acknowledged level (a new, more severe
  alarm needs its own acknowledgement).

Events are emitted once per change of the *reported* level and once per
acknowledgement; a latched alert whose condition clears emits nothing (its
active level shows in :meth:`AlertManager.state` and the summary).
"""

import dataclasses
from dataclasses import dataclass
import enum
import math
import numbers
from typing import Any, Dict, List, Mapping, NamedTuple, Optional

from ..config import AlertLevels, Alerts, ConfigError, from_dict

# Slack on ``elapsed >= min_duration_s`` so that stamps built by summing
# steps (0.1 + 0.1 + ...) reach the duration they are meant to reach.
_TIME_EPS_S = 1e-9


class Level(enum.IntEnum):
    """
    Alert level of one quantity.

    The values equal diagnostic_msgs/DiagnosticStatus OK, WARN and ERROR;
    STALE is not an alert level and is handled by the health monitor.
    """

    OK = 0
    WARN = 1
    CRITICAL = 2


def _is_number(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


@dataclass(frozen=True, kw_only=True)
class AlertRule(AlertLevels):
    """
    The configuration's :class:`~wet_eha_thermal.config.AlertLevels` of one quantity.

    The fields, their defaults and their checks are the configuration's (one
    definition); build rules with :func:`rules_from_config`, which checks them.
    """

    quantity: str

    def threshold(self, level: Level) -> float:
        """Return the threshold of ``level`` (WARN or CRITICAL) in degC."""
        if level == Level.WARN:
            return self.warn_C
        if level == Level.CRITICAL:
            return self.critical_C
        raise ValueError(f'level OK has no threshold (quantity {self.quantity!r})')


@dataclass
class AlertEvent:
    """
    One change of a quantity's reported level, or one acknowledgement.

    ``level`` is the reported level after the event; ``kind`` is one of
    ``'raised'``, ``'escalated'``, ``'cleared'`` (also CRITICAL -> WARN) and
    ``'acknowledged'``; ``message`` is one line for a log or a status topic.
    """

    stamp_s: float
    quantity: str
    level: Level
    value_C: float
    threshold_C: float
    kind: str
    message: str


class AlertState(NamedTuple):
    """State of one quantity, as returned by :meth:`AlertManager.state`."""

    reported: Level
    active: Level
    acknowledged: bool
    since_s: Optional[float]


class ActiveAlert(NamedTuple):
    """One quantity whose reported level is not OK, as listed by :meth:`AlertManager.active`."""

    quantity: str
    reported: Level
    active: Level
    acknowledged: bool
    since_s: Optional[float]
    value_C: Optional[float]
    threshold_C: float


class _Pickup:
    """Hysteresis and on-delay of one threshold."""

    __slots__ = ('threshold_C', 'on', 'since_s')

    def __init__(self, threshold_C: float) -> None:
        self.threshold_C = threshold_C
        self.on = False
        self.since_s: Optional[float] = None  # pickup timer start, None when not running

    def step(self, stamp_s: float, value_C: float, rule: AlertRule) -> None:
        if value_C < self.threshold_C - rule.hysteresis_K:
            self.on = False
            self.since_s = None
            return
        if self.on:
            return
        if value_C < self.threshold_C:
            return  # inside the band: a running timer keeps running, none starts
        if self.since_s is None:
            self.since_s = stamp_s
        if stamp_s - self.since_s >= rule.min_duration_s - _TIME_EPS_S:
            self.on = True


class _Track:
    """Everything the manager keeps about one rule."""

    def __init__(self, rule: AlertRule) -> None:
        self.rule = rule
        self.warn = _Pickup(rule.warn_C)
        self.critical = _Pickup(rule.critical_C)
        self.latched = Level.OK  # highest level held by the latch
        self.acknowledged = False
        self.ack_level = Level.OK  # active level when acknowledged
        self.reported = Level.OK
        self.since_s: Optional[float] = None  # stamp of the last change of `reported`
        self.value_C: Optional[float] = None  # last valid value

    @property
    def active(self) -> Level:
        if self.critical.on:
            return Level.CRITICAL
        if self.warn.on:
            return Level.WARN
        return Level.OK

    def pickup(self, level: Level) -> _Pickup:
        return self.critical if level == Level.CRITICAL else self.warn


def _fmt(value: float) -> str:
    return f'{value:.1f} degC'


class AlertManager:
    """
    Evaluate alert rules on timestamped values and keep their states.

    :param rules: one :class:`AlertRule` per quantity (no duplicates).
    """

    def __init__(self, rules) -> None:
        self._tracks: Dict[str, _Track] = {}
        for rule in rules:
            if not isinstance(rule, AlertRule):
                raise TypeError(f'expected an AlertRule, got {rule!r}')
            if rule.quantity in self._tracks:
                raise ValueError(f'two alert rules for quantity {rule.quantity!r}')
            self._tracks[rule.quantity] = _Track(rule)
        self._stamp_s: Optional[float] = None

    @property
    def rules(self) -> List[AlertRule]:
        """Return the rules, in the order given."""
        return [track.rule for track in self._tracks.values()]

    @property
    def stamp_s(self) -> Optional[float]:
        """Return the latest stamp given to update or acknowledge (None before any)."""
        return self._stamp_s

    def _advance(self, stamp_s: float, what: str) -> float:
        if not _is_number(stamp_s) or not math.isfinite(stamp_s):
            raise ValueError(f'{what}: stamp_s must be a finite number, got {stamp_s!r}')
        stamp_s = float(stamp_s)
        if self._stamp_s is not None and stamp_s < self._stamp_s:
            raise ValueError(f'{what}: stamp went backwards, from {self._stamp_s!r} s '
                             f'to {stamp_s!r} s')
        self._stamp_s = stamp_s
        for track in self._tracks.values():
            if track.since_s is None:
                track.since_s = stamp_s
        return stamp_s

    def shift_time(self, delta_s: float) -> None:
        """
        Move every stored stamp by ``delta_s``: the clock of the stamps jumped, no time passed.

        Pickup timers and the stamps of the last changes keep their age, so a
        running on-delay neither restarts nor completes because of the jump.
        """
        if self._stamp_s is not None:
            self._stamp_s += delta_s
        for track in self._tracks.values():
            if track.since_s is not None:
                track.since_s += delta_s
            for pickup in (track.warn, track.critical):
                if pickup.since_s is not None:
                    pickup.since_s += delta_s

    def _track(self, quantity: str) -> _Track:
        try:
            return self._tracks[quantity]
        except KeyError:
            known = ', '.join(self._tracks) or 'none'
            raise ValueError(f'no alert rule for quantity {quantity!r} '
                             f'(rules for: {known})') from None

    def update(self, stamp_s: float, values: Mapping[str, float]) -> List[AlertEvent]:
        """
        Evaluate every rule on the values sampled at ``stamp_s``.

        Values of quantities without a rule are ignored; a rule whose
        quantity is missing or not finite keeps its state. Raises ValueError
        if ``stamp_s`` is earlier than the previous stamp. Returns the events
        of this sample, in rule order.
        """
        stamp_s = self._advance(stamp_s, 'alert update')
        events = []
        for quantity, track in self._tracks.items():
            if quantity not in values or values[quantity] is None:
                continue
            try:
                value_C = float(values[quantity])
            except (TypeError, ValueError):
                raise ValueError(f'alert update: value of {quantity!r} is not a number: '
                                 f'{values[quantity]!r}') from None
            if not math.isfinite(value_C):
                continue
            event = self._evaluate(track, stamp_s, value_C)
            if event is not None:
                events.append(event)
        return events

    def _evaluate(self, track: _Track, stamp_s: float, value_C: float) -> Optional[AlertEvent]:
        rule = track.rule
        track.value_C = value_C
        track.warn.step(stamp_s, value_C, rule)
        track.critical.step(stamp_s, value_C, rule)
        active = track.active
        if active == Level.OK:
            # The condition cleared: an acknowledgement is used up.
            track.acknowledged = False
            track.ack_level = Level.OK
        elif track.acknowledged and active > track.ack_level:
            # Escalation past what was acknowledged: a new alarm.
            track.acknowledged = False
            track.ack_level = Level.OK
        if rule.latch and not track.acknowledged:
            track.latched = max(track.latched, active)
        old = track.reported
        new = max(active, track.latched)
        if new == old:
            return None
        track.reported = new
        track.since_s = stamp_s
        if new > old:
            pickup = track.pickup(new)
            threshold_C = pickup.threshold_C
            held_s = stamp_s - pickup.since_s if pickup.since_s is not None else 0.0
            kind = 'raised' if old == Level.OK else 'escalated'
            message = (f'{rule.quantity} {new.name}: {_fmt(value_C)} above '
                       f'{_fmt(threshold_C)} for {held_s:.1f} s')
            if kind == 'escalated':
                message += f' (escalated from {old.name})'
        else:
            kind = 'cleared'
            threshold_C = rule.threshold(Level(new + 1))
            message = (f'{rule.quantity} {new.name} (was {old.name}): {_fmt(value_C)} below '
                       f'{_fmt(threshold_C - rule.hysteresis_K)} '
                       f'({_fmt(threshold_C)} - {rule.hysteresis_K:g} K hysteresis)')
        return AlertEvent(stamp_s, rule.quantity, new, value_C, threshold_C, kind, message)

    def acknowledge(self, quantity: Optional[str] = None,
                    stamp_s: Optional[float] = None) -> List[AlertEvent]:
        """
        Acknowledge the alert of one quantity, or of all quantities if None.

        A latched level whose condition has cleared returns to OK; an alert
        still active stays reported at its active level, marked acknowledged,
        and clears by itself when its condition clears. Quantities that
        report OK or are already acknowledged give no event. ``stamp_s``
        defaults to the latest stamp and must not go backwards either.
        Raises ValueError for a quantity without a rule.
        """
        tracks = list(self._tracks.values()) if quantity is None else [self._track(quantity)]
        if stamp_s is None:
            stamp_s = self._stamp_s if self._stamp_s is not None else 0.0
        stamp_s = self._advance(stamp_s, 'alert acknowledge')
        events = []
        for track in tracks:
            if track.reported == Level.OK or (track.acknowledged
                                              and track.latched == Level.OK):
                continue
            rule = track.rule
            old = track.reported
            active = track.active
            track.latched = Level.OK
            track.acknowledged = active > Level.OK
            track.ack_level = active
            track.reported = active
            if active != old:
                track.since_s = stamp_s
            value_C = track.value_C if track.value_C is not None else math.nan
            if active > Level.OK:
                threshold_C = rule.threshold(active)
                message = (f'{rule.quantity} {active.name} acknowledged: {_fmt(value_C)}, '
                           f'still at or above {_fmt(threshold_C - rule.hysteresis_K)}')
                if old != active:
                    message += f' (latched {old.name} released)'
            else:
                threshold_C = rule.threshold(old)
                message = (f'{rule.quantity} {old.name} acknowledged, now OK: '
                           f'{_fmt(value_C)}, condition cleared')
            events.append(AlertEvent(stamp_s, rule.quantity, active, value_C, threshold_C,
                                     'acknowledged', message))
        return events

    def state(self, quantity: str) -> AlertState:
        """
        Return ``(reported, active, acknowledged, since_s)`` of ``quantity``.

        ``reported`` includes the latch, ``active`` is the level the values
        currently hold, ``since_s`` is the stamp of the last change of the
        reported level (the first stamp seen, None before any).
        """
        track = self._track(quantity)
        return AlertState(track.reported, track.active, track.acknowledged, track.since_s)

    def worst(self) -> Level:
        """Return the highest reported level over all quantities (OK without rules)."""
        return max((track.reported for track in self._tracks.values()), default=Level.OK)

    def active(self) -> List[ActiveAlert]:
        """List the quantities whose reported level is not OK, worst first, then by name."""
        alerts = []
        for quantity, track in self._tracks.items():
            if track.reported == Level.OK:
                continue
            alerts.append(ActiveAlert(quantity, track.reported, track.active, track.acknowledged,
                                      track.since_s, track.value_C,
                                      track.rule.threshold(track.reported)))
        alerts.sort(key=lambda a: (-a.reported, a.quantity))
        return alerts

    def summary(self) -> Dict[str, Any]:
        """
        Summarise all quantities as plain values, for a status line or diagnostics.

        Keys: ``level`` (the worst :class:`Level`), ``level_name``,
        ``stamp_s``, ``message`` (one line: ``'OK'`` or the alerts, worst
        first) and ``quantities`` (per quantity: reported, active,
        acknowledged, since_s, value_C, warn_C, critical_C).
        """
        parts = []
        for alert in self.active():
            text = f'{alert.quantity} {alert.reported.name}'
            if alert.value_C is not None:
                text += f' {_fmt(alert.value_C)}'
            if alert.acknowledged:
                text += ' (acknowledged)'
            elif alert.active < alert.reported:
                text += (' (latched, condition cleared)' if alert.active == Level.OK
                         else f' (latched, now {alert.active.name})')
            parts.append(text)
        quantities = {}
        for quantity, track in self._tracks.items():
            quantities[quantity] = {
                'reported': track.reported.name,
                'active': track.active.name,
                'acknowledged': track.acknowledged,
                'since_s': track.since_s,
                'value_C': track.value_C,
                'warn_C': track.rule.warn_C,
                'critical_C': track.rule.critical_C,
            }
        worst = self.worst()
        return {
            'level': worst,
            'level_name': worst.name,
            'stamp_s': self._stamp_s,
            'message': '; '.join(parts) if parts else 'OK',
            'quantities': quantities,
        }


def rules_from_config(alerts: Any, prefix: str = 'alerts') -> List[AlertRule]:
    """
    Return one alert rule per quantity of the configuration's alert settings.

    ``alerts`` is the loaded configuration's
    :class:`~wet_eha_thermal.config.Alerts` (checked when it was loaded), or a
    plain mapping of quantity to settings, e.g. ``{'winding_hotspot':
    {'warn_C': 160, 'critical_C': 175, 'hysteresis_K': 3, 'min_duration_s':
    2}}``, checked here as the configuration checks ``estimator.alerts``: the
    same keys, ranges and defaults. None or an empty mapping gives no rules.
    Every error is a :class:`~wet_eha_thermal.config.ConfigError` (a
    ValueError) naming the key (``prefix.quantity.key``) and the value.
    """
    if isinstance(alerts, Alerts):
        levels = {f.name: getattr(alerts, f.name) for f in dataclasses.fields(alerts)}
    elif alerts is None or isinstance(alerts, Mapping):
        levels = {}
        for quantity, settings in (alerts or {}).items():
            if not isinstance(quantity, str) or not quantity:
                raise ConfigError(f'{prefix}: quantity names must be non-empty strings, '
                                  f'got {quantity!r}')
            levels[quantity] = from_dict(AlertLevels, settings, f'{prefix}.{quantity}')
    else:
        raise ConfigError(f'{prefix}: expected a mapping of quantity to thresholds, '
                          f'got {alerts!r}')
    return [AlertRule(quantity=q, **dataclasses.asdict(v)) for q, v in levels.items()]
