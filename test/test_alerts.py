"""Over-temperature alerts: hysteresis, minimum duration, escalation, latching, config."""

import math

import pytest
from wet_eha_thermal.config import load_config
from wet_eha_thermal.estimator.alerts import (
    AlertEvent, AlertManager, AlertRule, Level, rules_from_config)

Q = 'winding_hotspot'


def rule(**kw):
    """Return one rule, checked as the configuration checks ``estimator.alerts``."""
    args = {'quantity': Q, 'warn_C': 170.0, 'critical_C': 180.0, 'hysteresis_K': 3.0,
            'min_duration_s': 0.0, 'latch': False}
    args.update(kw)
    return rules_from_config({args.pop('quantity'): args})[0]


def run(manager, samples, quantity=Q):
    """Feed ``(stamp_s, value_C)`` pairs; return all events as (stamp, kind, level) tuples."""
    out = []
    for stamp_s, value_C in samples:
        for ev in manager.update(stamp_s, {quantity: value_C}):
            out.append((ev.stamp_s, ev.kind, ev.level))
    return out


def reported(manager, quantity=Q):
    return manager.state(quantity)[0]


# --- rule validation -------------------------------------------------------

@pytest.mark.parametrize('kw, words', [
    ({'critical_C': 170.0}, ['critical_C', '170', 'warn_C']),
    ({'critical_C': 160.0}, ['critical_C', '160']),
    ({'hysteresis_K': -1.0}, ['hysteresis_K', '-1']),
    ({'min_duration_s': -0.5}, ['min_duration_s', '-0.5']),
    ({'warn_C': math.nan}, ['warn_C', 'nan']),
    ({'critical_C': 'hot'}, ['critical_C', 'hot']),
    ({'latch': 1}, ['latch', '1']),
    ({'quantity': ''}, ['quantity']),
])
def test_bad_rule_names_field_and_value(kw, words):
    with pytest.raises(ValueError) as err:
        rule(**kw)
    for word in words:
        assert word in str(err.value)


def test_rule_stores_floats_and_levels_match_diagnostic_status():
    r = rule(warn_C=160, critical_C=175, hysteresis_K=3, min_duration_s=2)
    assert isinstance(r.warn_C, float) and r.critical_C == 175.0
    assert (Level.OK, Level.WARN, Level.CRITICAL) == (0, 1, 2)


def test_duplicate_rules_rejected():
    with pytest.raises(ValueError, match=Q):
        AlertManager([rule(), rule()])


# --- raise / hysteresis ----------------------------------------------------

def test_raises_at_threshold_not_below():
    m = AlertManager([rule()])
    assert run(m, [(0.0, 169.99)]) == []
    assert run(m, [(1.0, 170.0)]) == [(1.0, 'raised', Level.WARN)]


def test_clears_only_below_threshold_minus_hysteresis():
    m = AlertManager([rule()])
    events = run(m, [(0, 171.0), (1, 168.0), (2, 167.0), (3, 169.9), (4, 167.0)])
    assert events == [(0, 'raised', Level.WARN)]  # 167.0 is the band edge: still WARN
    assert run(m, [(5, 166.99)]) == [(5, 'cleared', Level.OK)]
    assert m.state(Q) == (Level.OK, Level.OK, False, 5.0)


def test_oscillation_inside_hysteresis_band_raises_once():
    # +-1 K around the threshold with 3 K hysteresis, fast and slow pickup.
    for min_duration_s in (0.0, 2.0):
        m = AlertManager([rule(min_duration_s=min_duration_s)])
        samples = [(0.5 * i, 170.0 + (1.0 if i % 2 == 0 else -1.0)) for i in range(200)]
        events = run(m, samples)
        assert events == [(min_duration_s, 'raised', Level.WARN)], min_duration_s
        assert reported(m) == Level.WARN


def test_event_message_and_fields():
    m = AlertManager([rule(min_duration_s=5.0)])
    assert m.update(0.0, {Q: 171.0}) == []
    (ev,) = m.update(5.0, {Q: 172.4})
    assert isinstance(ev, AlertEvent)
    assert (ev.stamp_s, ev.quantity, ev.level, ev.value_C, ev.threshold_C, ev.kind) == (
        5.0, Q, Level.WARN, 172.4, 170.0, 'raised')
    assert ev.message == 'winding_hotspot WARN: 172.4 degC above 170.0 degC for 5.0 s'
    (ev,) = m.update(6.0, {Q: 150.0})
    assert ev.kind == 'cleared' and ev.threshold_C == 170.0
    assert '150.0 degC below 167.0 degC' in ev.message


# --- minimum duration --------------------------------------------------------

def test_spike_shorter_than_min_duration_never_raises():
    m = AlertManager([rule(min_duration_s=2.0)])
    samples = [(0.0, 150.0), (0.5, 175.0), (1.0, 176.0), (1.5, 175.0), (2.0, 150.0),
               (2.5, 150.0), (10.0, 150.0)]
    assert run(m, samples) == []
    assert m.state(Q)[:3] == (Level.OK, Level.OK, False)


def test_raises_exactly_after_min_duration():
    m = AlertManager([rule(min_duration_s=2.0)])
    assert run(m, [(0.0, 171.0), (1.0, 171.0), (1.999, 171.0)]) == []
    assert run(m, [(2.0, 171.0)]) == [(2.0, 'raised', Level.WARN)]


def test_summed_float_stamps_reach_min_duration():
    m = AlertManager([rule(min_duration_s=1.0)])
    stamp, events = 0.0, []
    for _ in range(11):
        events += m.update(stamp, {Q: 171.0})
        stamp += 0.1  # 0.1 * 10 sums to 0.9999999999999999
    assert len(events) == 1 and abs(events[0].stamp_s - 1.0) < 1e-9


def test_timer_resets_below_threshold_minus_hysteresis():
    m = AlertManager([rule(min_duration_s=2.0)])
    # Timer starts at 0, is reset at 1 (166 < 167), restarts at 1.5.
    samples = [(0.0, 171.0), (1.0, 166.0), (1.5, 171.0), (2.0, 171.0), (3.0, 171.0)]
    assert run(m, samples) == []
    assert run(m, [(3.5, 171.0)]) == [(3.5, 'raised', Level.WARN)]


def test_dip_into_band_does_not_reset_timer():
    m = AlertManager([rule(min_duration_s=2.0)])
    assert run(m, [(0.0, 171.0), (1.0, 168.0)]) == []
    assert run(m, [(2.0, 171.0)]) == [(2.0, 'raised', Level.WARN)]


def test_raising_sample_must_be_at_or_above_threshold():
    # A spike, then a value sitting inside the band: the timer runs, but the
    # level is raised only at a sample that is itself above the threshold.
    m = AlertManager([rule(min_duration_s=2.0)])
    samples = [(0.0, 171.0)] + [(float(t), 168.0) for t in range(1, 100)]
    assert run(m, samples) == []
    assert run(m, [(100.0, 170.5)]) == [(100.0, 'raised', Level.WARN)]


def test_gap_counts_when_condition_holds_at_both_ends():
    m = AlertManager([rule(min_duration_s=2.0)])
    assert run(m, [(0.0, 171.0)]) == []
    events = m.update(100.0, {Q: 171.0})
    assert [(e.stamp_s, e.kind) for e in events] == [(100.0, 'raised')]
    assert 'for 100.0 s' in events[0].message


def test_gap_does_not_count_when_condition_starts_after_it():
    m = AlertManager([rule(min_duration_s=2.0)])
    assert run(m, [(0.0, 150.0), (100.0, 171.0), (101.0, 171.0)]) == []
    assert run(m, [(102.0, 171.0)]) == [(102.0, 'raised', Level.WARN)]


# --- escalation --------------------------------------------------------------

def test_escalation_and_de_escalation():
    m = AlertManager([rule(warn_C=160.0, critical_C=175.0, min_duration_s=2.0)])
    samples = [(0, 165.0), (1, 165.0), (2, 165.0),  # WARN at 2
               (3, 176.0), (4, 176.0), (5, 176.0),  # CRITICAL at 5 (own timer from 3)
               (6, 172.0),                          # inside the critical band
               (7, 171.9),                          # below 175 - 3: back to WARN
               (8, 158.0),                          # inside the warn band
               (9, 156.9)]                          # below 160 - 3: OK
    assert run(m, samples) == [(2, 'raised', Level.WARN), (5, 'escalated', Level.CRITICAL),
                               (7, 'cleared', Level.WARN), (9, 'cleared', Level.OK)]


def test_short_critical_spike_does_not_escalate():
    m = AlertManager([rule(min_duration_s=2.0)])
    samples = [(0, 175.0), (2, 175.0), (3, 181.0), (4, 181.0), (4.5, 176.0), (10, 181.0)]
    assert run(m, samples) == [(2, 'raised', Level.WARN)]
    assert m.state(Q)[:2] == (Level.WARN, Level.WARN)


def test_jump_straight_to_critical_raises_critical_once():
    m = AlertManager([rule(min_duration_s=2.0)])
    assert run(m, [(0, 150.0), (1, 190.0), (2, 190.0), (3, 190.0), (4, 190.0)]) == [
        (3, 'raised', Level.CRITICAL)]
    # Straight back down clears both levels in one event.
    assert run(m, [(5, 100.0)]) == [(5, 'cleared', Level.OK)]


# --- latching and acknowledgement ---------------------------------------------

def test_latched_alert_survives_clearing_until_acknowledged():
    m = AlertManager([rule(latch=True)])
    assert run(m, [(0, 171.0), (1, 150.0), (2, 100.0), (1000, 100.0)]) == [
        (0, 'raised', Level.WARN)]
    assert m.state(Q) == (Level.WARN, Level.OK, False, 0.0)
    assert m.worst() == Level.WARN
    (ev,) = m.acknowledge(Q, stamp_s=1001.0)
    assert (ev.kind, ev.level, ev.stamp_s) == ('acknowledged', Level.OK, 1001.0)
    assert m.state(Q) == (Level.OK, Level.OK, False, 1001.0)
    assert m.acknowledge(Q) == []  # nothing left to acknowledge
    assert run(m, [(1002, 100.0)]) == []


def test_non_latching_alert_clears_by_itself():
    m = AlertManager([rule(latch=False)])
    assert run(m, [(0, 171.0), (1, 150.0)]) == [
        (0, 'raised', Level.WARN), (1, 'cleared', Level.OK)]


def test_acknowledged_active_alert_clears_without_second_acknowledgement():
    m = AlertManager([rule(latch=True)])
    run(m, [(0, 171.0)])
    (ev,) = m.acknowledge(Q, stamp_s=1.0)
    assert (ev.kind, ev.level) == ('acknowledged', Level.WARN)
    assert m.state(Q) == (Level.WARN, Level.WARN, True, 0.0)
    assert m.acknowledge(Q, stamp_s=1.5) == []  # already acknowledged
    # Still active: stays reported, no re-latch while it oscillates in the band.
    assert run(m, [(2, 172.0), (3, 168.0), (4, 171.0)]) == []
    assert run(m, [(5, 150.0)]) == [(5, 'cleared', Level.OK)]
    assert m.state(Q) == (Level.OK, Level.OK, False, 5.0)
    # A new excursion latches again.
    assert run(m, [(6, 171.0), (7, 150.0)]) == [(6, 'raised', Level.WARN)]
    assert reported(m) == Level.WARN


def test_latched_critical_held_while_active_de_escalates():
    m = AlertManager([rule(latch=True)])
    assert run(m, [(0, 181.0), (1, 171.0)]) == [(0, 'raised', Level.CRITICAL)]
    assert m.state(Q)[:3] == (Level.CRITICAL, Level.WARN, False)
    (ev,) = m.acknowledge(Q, stamp_s=2.0)
    assert (ev.kind, ev.level, ev.threshold_C) == ('acknowledged', Level.WARN, 170.0)
    assert m.state(Q) == (Level.WARN, Level.WARN, True, 2.0)
    assert run(m, [(3, 160.0)]) == [(3, 'cleared', Level.OK)]


def test_escalation_after_acknowledgement_latches_again():
    m = AlertManager([rule(latch=True)])
    run(m, [(0, 171.0)])
    m.acknowledge(Q, stamp_s=0.5)
    assert run(m, [(1, 181.0)]) == [(1, 'escalated', Level.CRITICAL)]
    assert m.state(Q)[2] is False
    assert run(m, [(2, 150.0)]) == []  # CRITICAL latched again
    assert m.state(Q)[:2] == (Level.CRITICAL, Level.OK)


def test_acknowledged_critical_follows_level_down_and_up_without_latching():
    m = AlertManager([rule(latch=True)])
    run(m, [(0, 181.0)])
    m.acknowledge(Q, stamp_s=0.0)
    assert run(m, [(1, 176.0), (2, 181.0), (3, 150.0)]) == [
        (1, 'cleared', Level.WARN), (2, 'escalated', Level.CRITICAL), (3, 'cleared', Level.OK)]


def test_acknowledge_all_and_unknown_quantity():
    m = AlertManager([
        rule(latch=True),
        rule(quantity='magnet', warn_C=100.0, critical_C=120.0, latch=True),
        rule(quantity='oil', warn_C=90.0, critical_C=110.0),
    ])
    m.update(0.0, {Q: 171.0, 'magnet': 121.0, 'oil': 50.0})
    m.update(1.0, {Q: 100.0, 'magnet': 50.0, 'oil': 50.0})
    events = m.acknowledge(stamp_s=2.0)
    assert sorted((e.quantity, e.level) for e in events) == [('magnet', Level.OK),
                                                             (Q, Level.OK)]
    assert m.worst() == Level.OK
    with pytest.raises(ValueError, match='coolant'):
        m.acknowledge('coolant')


def test_events_emitted_once_per_transition():
    m = AlertManager([rule(min_duration_s=1.0, latch=True)])
    samples = [(0.1 * i, 185.0) for i in range(100)]
    assert run(m, samples) == [(pytest.approx(1.0), 'raised', Level.CRITICAL)]
    assert run(m, [(20.0 + i, 100.0) for i in range(10)]) == []
    assert len(m.acknowledge(stamp_s=40.0)) == 1
    assert m.acknowledge(stamp_s=41.0) == []


# --- time and bad inputs --------------------------------------------------------

def test_stamp_going_backwards_raises_and_names_both_stamps():
    m = AlertManager([rule()])
    m.update(10.0, {Q: 150.0})
    m.update(10.0, {Q: 150.0})  # equal stamps are fine
    with pytest.raises(ValueError) as err:
        m.update(9.5, {Q: 150.0})
    assert '10.0' in str(err.value) and '9.5' in str(err.value)
    with pytest.raises(ValueError, match='9.0'):
        m.acknowledge(stamp_s=9.0)
    with pytest.raises(ValueError, match='nan'):
        m.update(math.nan, {Q: 150.0})


@pytest.mark.parametrize('bad', [math.nan, math.inf, None, 'missing'])
def test_nan_or_missing_value_keeps_state(bad):
    def values(v):
        return {} if v == 'missing' else {Q: v}

    # A running pickup timer is kept: the raise comes at 2 s as without the gap.
    m = AlertManager([rule(min_duration_s=2.0)])
    assert m.update(0.0, {Q: 171.0}) == []
    assert m.update(1.0, values(bad)) == []
    assert run(m, [(2.0, 171.0)]) == [(2.0, 'raised', Level.WARN)]
    # A raised level neither clears nor escalates on a bad value.
    before = m.state(Q)
    assert m.update(3.0, values(bad)) == []
    assert m.state(Q) == before
    assert m.summary()['quantities'][Q]['value_C'] == 171.0
    # And an OK quantity does not raise.
    m2 = AlertManager([rule()])
    assert m2.update(0.0, values(bad)) == []
    assert m2.state(Q)[:3] == (Level.OK, Level.OK, False)


def test_non_numeric_value_is_an_error():
    m = AlertManager([rule()])
    with pytest.raises(ValueError, match=Q):
        m.update(0.0, {Q: 'hot'})


def test_replay_gives_same_events():
    samples = [(0.25 * i, 165.0 + 20.0 * math.sin(0.05 * i)) for i in range(400)]
    a = AlertManager([rule(min_duration_s=1.5, latch=True)])
    b = AlertManager([rule(min_duration_s=1.5, latch=True)])
    assert run(a, samples) == run(b, samples) != []


# --- summaries ---------------------------------------------------------------

def test_worst_active_and_summary():
    m = AlertManager([rule(latch=True), rule(quantity='magnet', warn_C=100.0, critical_C=120.0),
                      rule(quantity='oil', warn_C=90.0, critical_C=110.0)])
    assert m.worst() == Level.OK
    assert m.summary()['message'] == 'OK'
    m.update(0.0, {Q: 171.0, 'magnet': 125.0, 'oil': 60.0})
    m.update(1.0, {Q: 150.0, 'magnet': 125.0, 'oil': 60.0})
    assert m.worst() == Level.CRITICAL
    active = m.active()
    assert [(a.quantity, a.reported, a.active) for a in active] == [
        ('magnet', Level.CRITICAL, Level.CRITICAL), (Q, Level.WARN, Level.OK)]
    s = m.summary()
    assert s['level'] == Level.CRITICAL and s['level_name'] == 'CRITICAL'
    assert s['stamp_s'] == 1.0
    assert s['message'] == ('magnet CRITICAL 125.0 degC; '
                            'winding_hotspot WARN 150.0 degC (latched, condition cleared)')
    assert s['quantities']['oil'] == {
        'reported': 'OK', 'active': 'OK', 'acknowledged': False, 'since_s': 0.0,
        'value_C': 60.0, 'warn_C': 90.0, 'critical_C': 110.0}


# --- config --------------------------------------------------------------------

def test_rules_from_config_builds_rules_with_the_configurations_defaults():
    rules = rules_from_config({
        'winding_hotspot': {'warn_C': 160, 'critical_C': 175, 'hysteresis_K': 3,
                            'min_duration_s': 2, 'latch': False},
        'magnet': {'warn_C': 100, 'critical_C': 120, 'hysteresis_K': 0, 'min_duration_s': 0},
    })
    assert rules[0] == AlertRule(quantity='winding_hotspot', warn_C=160.0, critical_C=175.0,
                                 hysteresis_K=3.0, min_duration_s=2.0, latch=False)
    assert rules[1] == AlertRule(quantity='magnet', warn_C=100.0, critical_C=120.0,
                                 hysteresis_K=0.0, min_duration_s=0.0, latch=True)
    assert rules_from_config(None) == [] and rules_from_config({}) == []


def test_rules_from_config_takes_the_loaded_configuration():
    alerts = load_config().estimator.alerts
    rules = rules_from_config(alerts)
    assert [r.quantity for r in rules] == ['winding_hotspot', 'magnet', 'oil']
    assert rules[0].critical_C == alerts.winding_hotspot.critical_C and rules[0].latch


BASE = {'warn_C': 100, 'critical_C': 120, 'hysteresis_K': 0, 'min_duration_s': 0}


@pytest.mark.parametrize('mapping, words', [
    ({'magnet': {'critical_C': 120}}, ['alerts.magnet.warn_C', 'missing']),
    ({'magnet': {**BASE, 'hysterisis_K': 2}},
     ['alerts.magnet.hysterisis_K', 'unknown', 'hysteresis_K']),
    ({'magnet': {**BASE, 'critical_C': 90}}, ['alerts.magnet', '90', '100']),
    ({'magnet': {**BASE, 'warn_C': 'hot'}}, ['alerts.magnet.warn_C', 'hot']),
    ({'magnet': {**BASE, 'latch': 'yes'}}, ['alerts.magnet.latch', 'yes']),
    ({'magnet': {**BASE, 'min_duration_s': -1}}, ['alerts.magnet.min_duration_s', '-1']),
    ({'magnet': 100}, ['alerts.magnet', '100']),
    ([1, 2], ['alerts', '[1, 2]']),
])
def test_rules_from_config_errors_name_the_key(mapping, words):
    with pytest.raises(ValueError) as err:
        rules_from_config(mapping)
    for word in words:
        assert word in str(err.value)
