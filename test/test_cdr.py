"""
The CDR encoders write what rclpy serialises, and the decoders read it back.

Byte for byte except the alignment padding, which rclpy (Fast CDR) leaves as
it finds it in memory and the encoders write as zeros.
"""

import math

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.typesys import get_typestore, Stores
from sensor_msgs.msg import FluidPressure, JointState, Temperature
from std_msgs.msg import Float64, Float64MultiArray, MultiArrayDimension, String

from wet_eha_thermal.bag import cdr

# frame_id lengths that put the first float64 at each alignment case (NUL included: 1 to 9)
FRAME_IDS = ['', 'a', 'eha', 'abcd', 'port_a', 'abcdefg', 'abcdefgh']
STAMPS_NS = [0, 1, 999_999_999, 1_000_000_000, 1_700_000_000_123_456_789, 2**31 * 10**9 - 1]
VALUES = [0.0, -0.0, 1.5, -273.15, 1e-300, 6.02e23, math.inf, -math.inf]


@pytest.mark.parametrize('value', VALUES + [math.nan])
def test_float64(value):
    assert cdr.encode_float64(value) == serialize_message(Float64(data=value))
    decoded = cdr.float64_data(cdr.encode_float64(value))
    assert decoded == value or (math.isnan(value) and math.isnan(decoded))


@pytest.mark.parametrize('text', ['', 'x', 'abc', 'abcd', '{"level": 2, "message": "é °C"}',
                                  'z' * 1000])
def test_string(text):
    assert cdr.encode_string(text) == serialize_message(String(data=text))


@pytest.mark.parametrize('frame_id', FRAME_IDS)
@pytest.mark.parametrize('cls,field', [(Temperature, 'temperature'),
                                       (FluidPressure, 'fluid_pressure')])
def test_stamped(frame_id, cls, field):
    rng = np.random.default_rng(len(frame_id))
    values = np.column_stack([rng.choice(VALUES, len(STAMPS_NS)),
                              rng.uniform(0, 1e3, len(STAMPS_NS))])
    encoded = cdr.encode_stamped(np.array(STAMPS_NS), frame_id, values)
    assert len(encoded) == len(STAMPS_NS)
    for data, ns, (value, variance) in zip(encoded, STAMPS_NS, values):
        msg = cls(variance=variance)
        setattr(msg, field, value)
        msg.header.frame_id = frame_id
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
        theirs = serialize_message(msg)
        first = cdr.ENCAPSULATION_BYTES + cdr.first_after_header(len(frame_id) + 1)
        padding = slice(cdr.ENCAPSULATION_BYTES + cdr.FRAME_ID_AT + len(frame_id) + 1, first)
        assert len(data) == len(theirs) == first + 16
        assert data[:padding.start] == theirs[:padding.start]
        assert data[padding] == bytes(padding.stop - padding.start)
        assert data[first:] == theirs[first:]
        assert deserialize_message(data, cls) == msg
        assert cdr.header_stamp_and_value(data) == (ns, value)


@pytest.mark.parametrize('frame_id', ['ok', 'fallback: stale inputs: current_A, speed_rad_s'])
@pytest.mark.parametrize('names', [[], ['continuous'], ['continuous', '10s', '60s', '600s'],
                                   ['a', 'abcd', 'abcdefg', '']])
def test_joint_state(frame_id, names):
    # a tick's limits as the estimator node publishes them: position the horizons,
    # effort the limits, velocity empty; names of every length for the string padding
    position = [math.inf, 10.0, 60.0, 600.0][:len(names)]
    effort = [25.0 - 1.5 * k for k in range(len(names))]
    ns = STAMPS_NS[-2]
    data = cdr.encode_joint_state(ns, frame_id, names, position, [], effort)
    msg = JointState(name=names, position=position, effort=effort)
    msg.header.frame_id = frame_id
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
    assert deserialize_message(data, JointState) == msg
    # rclpy's buffer runs 8 bytes past the message when a sequence is empty (its size is
    # reckoned with the alignment of an empty float64[]) and leaves the padding unset:
    # rosbags, which zeroes it, is the byte-for-byte reference
    typestore = get_typestore(Stores.ROS2_JAZZY)
    ours = typestore.deserialize_cdr(data, 'sensor_msgs/msg/JointState')
    assert bytes(typestore.serialize_cdr(ours, 'sensor_msgs/msg/JointState')) == data
    assert (ours.header.stamp.sec, ours.header.stamp.nanosec) == divmod(ns, 1_000_000_000)
    assert ours.header.frame_id == frame_id and ours.name == names
    assert ours.position.tolist() == position and ours.effort.tolist() == effort
    assert not ours.velocity.size


@pytest.mark.parametrize('frame_id', FRAME_IDS)
def test_stamped_one_at_a_time_is_the_batch_encoding(frame_id):
    # the live node's encoder and the bag writers' give the same bytes
    stamped = cdr.Stamped(frame_id)
    values = np.column_stack([VALUES[:6], np.linspace(0.0, 4.0, 6)])
    batch = cdr.encode_stamped(np.array(STAMPS_NS), frame_id, values)
    for data, ns, (value, variance) in zip(batch, STAMPS_NS, values.tolist()):
        assert stamped.encode(stamped.head(ns), value, variance) == data


@pytest.mark.parametrize('label', ['', 'x', 'state_K: names on /eha/state_names'])
@pytest.mark.parametrize('n', [0, 1, 7])
def test_float64_array(label, n):
    values = np.linspace(280.0, 400.0, n)
    data = cdr.encode_float64_array(label, values)
    msg = Float64MultiArray(data=values.tolist())
    msg.layout.dim = [MultiArrayDimension(label=label, size=n, stride=n)]
    assert deserialize_message(data, Float64MultiArray) == msg
    typestore = get_typestore(Stores.ROS2_JAZZY)
    ours = typestore.deserialize_cdr(data, 'std_msgs/msg/Float64MultiArray')
    assert bytes(typestore.serialize_cdr(ours, 'std_msgs/msg/Float64MultiArray')) == data
