"""The drive's limits as numbers (interface.DriveLimits): the layout, its checks, the codes."""

import math

import pytest
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from wet_eha_thermal import messages
from wet_eha_thermal.estimator.limits import current_limits, fallback_limits
from wet_eha_thermal.interface import DriveLimits, LimitStatus


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
