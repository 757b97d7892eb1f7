"""The drive's numbers (interface.DriveLimits, DriveAlerts): the layouts, their checks, codes."""

import math

import pytest
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from wet_eha_thermal import messages
from wet_eha_thermal.estimator.alerts import AlertManager, rules_from_config
from wet_eha_thermal.estimator.limits import current_limits, fallback_limits
from wet_eha_thermal.estimator.session import json_safe
from wet_eha_thermal.interface import DriveAlerts, DriveLimits, ESTIMATES, LimitStatus


def test_layout_round_trip_at_fixed_places():
    d = DriveLimits(stamp_ns=1_790_000_123_456_789_012, sequence=42,
                    status=LimitStatus.UNCERTAIN, binding_A=12.5, binding_horizon_s=10.0,
                    horizons_s=(math.inf, 10.0, 60.0), limits_A=(8.0, 12.5, math.inf))
    data = d.to_data()
    # the places a C++ drive reads, by index
    assert data[:8] == [1.0, 1_790_000_123.0, 456_789_012.0, 42.0, 2.0, 12.5, 10.0, 3.0]
    assert data[8:] == [math.inf, 8.0, 10.0, 12.5, 60.0, math.inf]
    assert DriveLimits.from_data(data) == d


@pytest.mark.parametrize('data, message', [
    ([], 'not drive limits v1'),
    ([2.0, 0, 0, 1, 0, 5.0, 10.0, 0], 'not drive limits v1'),
    ([1.0, 0, 0, 1, 0, 5.0, 10.0, 2, 10.0, 5.0], 'n = 2 for 10 numbers'),
    ([1.0, 0, 0, 1, 0, 5.0, 10.0, 1, 10.0, -1.0], 'negative or NaN'),
    ([1.0, 0, 0, 1, 0, math.nan, 10.0, 0], 'negative or NaN'),
])
def test_malformed_limits_are_refused(data, message):
    with pytest.raises(ValueError, match=message):
        DriveLimits.from_data(data)


def test_an_unknown_status_code_reads_as_a_fallback():
    data = [1.0, 0, 0, 1, 99.0, 5.0, 10.0, 0]
    assert DriveLimits.from_data(data).status == LimitStatus.OTHER


@pytest.mark.parametrize('code, detail, text', [
    (LimitStatus.STALE_INPUTS, 'speed_rad_s', 'fallback: stale inputs: speed_rad_s'),
    (LimitStatus.UNCERTAIN, 'magnet 1 sigma 12.0 K > 10 K',
     'fallback: uncertain: magnet 1 sigma 12.0 K > 10 K'),
    (LimitStatus.BEHIND, 'the model is catching up with its inputs',
     'fallback: behind: the model is catching up with its inputs'),
    (LimitStatus.FAILED, 'the limits could not be computed',
     'fallback: failed: the limits could not be computed'),
    (LimitStatus.OTHER, 'a reason not known here', 'fallback: a reason not known here'),
])
def test_the_code_is_carried_and_the_text_made_from_it(code, detail, text):
    limits = fallback_limits(3.0, (10.0, 60.0), 10.0, code, detail)
    assert (limits.code, limits.status, limits.frame_id) == (code, 'fallback', text)
    # the drive's numbers carry the code itself, the JointState the text made from it
    (_, joint, _), (_, single, _) = messages.limits(limits)
    assert deserialize_message(joint, JointState).header.frame_id == text
    _, data, _ = messages.drive_limits(limits, 7)
    drive = DriveLimits.from_data(deserialize_message(data, Float64MultiArray).data.tolist())
    assert (drive.status, drive.sequence, drive.binding_A) == (code, 7, 10.0)


def test_trusted_limits_say_ok_in_both_forms():
    limits = current_limits(3.0, (10.0,), (20.0, 'winding_hotspot'), [(30.0, 'magnet')])
    assert (limits.code, limits.status, limits.reason, limits.frame_id) == (
        LimitStatus.OK, 'ok', '', 'ok')
    _, data, _ = messages.drive_limits(limits, 1)
    assert deserialize_message(data, Float64MultiArray).data[4] == 0.0


def _alerts_of(manager):
    """Return the drive's numbers of a manager's summary, as a reader decodes them."""
    _, data, _ = messages.alert_messages(json_safe(manager.summary()), 5, None)[1]
    return deserialize_message(data, Float64MultiArray).data.tolist()


def test_alerts_as_numbers_follow_the_levels_and_the_acknowledgement():
    band = {'hysteresis_K': 3.0, 'min_duration_s': 0.0}
    rules = rules_from_config({
        'winding_hotspot': {'warn_C': 160.0, 'critical_C': 175.0, 'latch': True, **band},
        'magnet': {'warn_C': 135.0, 'critical_C': 145.0, 'latch': False, **band},
        'oil': {'warn_C': 120.0, 'critical_C': 130.0, 'latch': False, **band}})
    manager = AlertManager(rules)
    data = _alerts_of(manager)
    # before any estimate: every level OK, no value, stamp 0; quantity i read by index
    assert data[:7] == [1.0, 0.0, 0.0, 5.0, 0.0, 3.0, 8.0]
    assert [data[7 + 8 * i] for i in range(3)] == [
        ESTIMATES.index(q) for q in ('winding_hotspot', 'magnet', 'oil')]
    assert math.isnan(data[7 + 4]) and math.isnan(data[7 + 7])
    manager.update(100.25, {'winding_hotspot': 176.0, 'magnet': 100.0, 'oil': 125.5})
    data = _alerts_of(manager)
    assert data[:5] == [1.0, 100.0, 250_000_000.0, 5.0, 2.0]
    # winding: CRITICAL reported and active, not acknowledged, 176 against 160/175, since 100.25
    assert data[7:15] == [1.0, 2.0, 2.0, 0.0, 176.0, 160.0, 175.0, 100.25]
    assert data[15 + 1:15 + 5] == [0.0, 0.0, 0.0, 100.0]      # magnet OK
    assert data[23 + 1:23 + 5] == [1.0, 1.0, 0.0, 125.5]      # oil WARN
    # the winding cools: its latch holds CRITICAL while the estimate says OK
    manager.update(101.0, {'winding_hotspot': 150.0})
    assert _alerts_of(manager)[7 + 1:7 + 5] == [2.0, 0.0, 0.0, 150.0]
    # the oil acknowledged while still hot: reported WARN, marked acknowledged
    manager.acknowledge('oil')
    assert _alerts_of(manager)[23 + 1:23 + 4] == [1.0, 1.0, 1.0]
    decoded = DriveAlerts.from_data(_alerts_of(manager))
    assert [(q.quantity, q.reported, q.acknowledged) for q in decoded.quantities] == [
        ('winding_hotspot', 2, False), ('magnet', 0, False), ('oil', 1, True)]
    assert DriveAlerts.from_data(decoded.to_data()) == decoded


@pytest.mark.parametrize('data, message', [
    ([], 'not drive alerts v1'),
    ([2.0, 0, 0, 1, 0, 0, 8], 'not drive alerts v1'),
    ([1.0, 0, 0, 1, 0, 1, 8], 'n = 1, m = 8 for 7 numbers'),
    ([1.0, 0, 0, 1, 0, 0, 3], 'm = 3'),
    ([1.0, 0, 0, 1, 0, 1, 8, 99, 0, 0, 0, 20.0, 160, 175, 0], 'quantity index 99'),
])
def test_malformed_alerts_are_refused(data, message):
    with pytest.raises(ValueError, match=message):
        DriveAlerts.from_data(data)


def test_a_longer_quantity_block_of_a_later_version_is_read_by_its_stride():
    one = [1.0, 0, 0, 1, 1, 2, 9]
    one += [1, 1, 1, 0, 161.0, 160, 175, 3.0, 42.0] + [4, 0, 0, 0, 90.0, 135, 145, 0.0, 42.0]
    got = DriveAlerts.from_data(one)
    assert [(q.quantity, q.reported, q.value_C) for q in got.quantities] == [
        ('winding_hotspot', 1, 161.0), ('magnet', 0, 90.0)]
