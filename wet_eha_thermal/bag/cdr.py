"""
The CDR layout of the few message types this package reads and writes without rclpy.

A serialised ROS 2 message starts with a 4-byte encapsulation header (00 01:
plain CDR, little-endian, what rclpy and Fast DDS write on x86 and ARM); each
field follows, aligned to its size counted from the end of that header.

- std_msgs/Float64: ``data`` (float64) at 0;
- sensor_msgs/FluidPressure and sensor_msgs/Temperature: a std_msgs/Header
  (stamp: int32 sec at 0, uint32 nanosec at 4; frame_id: uint32 length with
  its NUL at 8, the bytes from 12), then two float64 aligned to 8.

- std_msgs/String: ``data`` as a uint32 length counting its NUL, the UTF-8
  bytes, the NUL.
- sensor_msgs/JointState: the Header, then ``name`` (a uint32 count aligned
  to 4, each string as above, aligned to 4), then ``position``, ``velocity``
  and ``effort``: each a uint32 count aligned to 4 and its float64 values
  aligned to 8 (no padding when it is empty).
- std_msgs/Float64MultiArray: ``layout.dim`` (a uint32 count, each
  dimension's label as a string, then uint32 size and stride), the uint32
  ``layout.data_offset``, then ``data`` as a float64 sequence as above.

The bag reader gathers these fields with numpy for whole chunks; the live
estimator node decodes one message at a time with :func:`float64_data` and
:func:`header_stamp_and_value` (a fraction of rclpy's deserialisation). The
encoders write what rclpy's ``serialize_message`` writes (byte for byte but
the alignment padding, which Fast CDR leaves unset and these write as zeros:
``test/test_cdr.py``), so that replay and the simulated rig write bags
without ROS and without building a message object per sample.
"""

import struct
from typing import List, Sequence, Tuple

import numpy as np

#: Bytes of the encapsulation header; the fields' alignment counts from its end.
ENCAPSULATION_BYTES = 4
#: The encapsulation header of little-endian plain CDR.
PLAIN_LE = b'\x00\x01'
#: The whole header as rclpy writes it: the two option bytes are zero.
_HEADER = PLAIN_LE + b'\x00\x00'
#: Offsets (after the encapsulation header) of the Header's fields.
STAMP_SEC_AT, STAMP_NANOSEC_AT, FRAME_ID_LENGTH_AT, FRAME_ID_AT = 0, 4, 8, 12

_F64 = struct.Struct('<d')
_STAMP = struct.Struct('<iI')
_U32 = struct.Struct('<I')


def first_after_header(frame_id_length: int) -> int:
    """Return the offset of the first float64 after a Header with that frame_id length."""
    return (FRAME_ID_AT + frame_id_length + 7) & ~7


def is_plain_le(data: bytes) -> bool:
    """Tell whether ``data`` starts with the encapsulation header that the decoders read."""
    return data[:2] == PLAIN_LE


def float64_data(data: bytes) -> float:
    """Return ``data`` of a serialised std_msgs/Float64 (plain little-endian CDR)."""
    return _F64.unpack_from(data, ENCAPSULATION_BYTES)[0]


def header_stamp_and_value(data: bytes) -> Tuple[int, float]:
    """
    Return (header stamp in ns, first float64) of a serialised Header-first message.

    The value is ``fluid_pressure`` of a sensor_msgs/FluidPressure or
    ``temperature`` of a sensor_msgs/Temperature (plain little-endian CDR).
    """
    sec, nanosec = _STAMP.unpack_from(data, ENCAPSULATION_BYTES + STAMP_SEC_AT)
    length = _U32.unpack_from(data, ENCAPSULATION_BYTES + FRAME_ID_LENGTH_AT)[0]
    value = _F64.unpack_from(data, ENCAPSULATION_BYTES + first_after_header(length))[0]
    return sec * 1_000_000_000 + nanosec, value


def encode_float64(value: float) -> bytes:
    """Return a std_msgs/Float64 holding ``value``, serialised."""
    return _HEADER + _F64.pack(value)


def encode_string(text: str) -> bytes:
    """Return a std_msgs/String holding ``text``, serialised."""
    out = bytearray(_HEADER)
    _put_string(out, text)
    return bytes(out)


def encode_joint_state(stamp_ns: int, frame_id: str, names: Sequence[str],
                       position: Sequence[float], velocity: Sequence[float],
                       effort: Sequence[float]) -> bytes:
    """Return a sensor_msgs/JointState, serialised: one message (the limits of a tick)."""
    out = bytearray(_HEADER)
    out += _STAMP.pack(*divmod(int(stamp_ns), 1_000_000_000))
    _put_string(out, frame_id)
    _align(out, 4)
    out += _U32.pack(len(names))
    for name in names:
        _put_string(out, name)
    for values in (position, velocity, effort):
        _align(out, 4)
        out += _U32.pack(len(values))
        if len(values):
            _align(out, 8)
            out += struct.pack(f'<{len(values)}d', *values)
    return bytes(out)


def encode_float64_array(label: str, values: np.ndarray) -> bytes:
    """Return a std_msgs/Float64MultiArray of one dimension (``label``, size = stride)."""
    values = np.ascontiguousarray(values, dtype='<f8')
    out = bytearray(_HEADER)
    out += _U32.pack(1)
    _put_string(out, label)
    _align(out, 4)
    out += _U32.pack(values.size) + _U32.pack(values.size) + _U32.pack(0)   # size, stride, offset
    out += _U32.pack(values.size)
    if values.size:
        _align(out, 8)
        out += values.tobytes()
    return bytes(out)


class Stamped:
    """
    Encode Header-first messages of one ``frame_id`` one at a time: what a live node sends.

    The bytes of :func:`encode_stamped` for one stamp, at a fraction of its
    cost for a single message (the frame and its padding are built once).
    """

    def __init__(self, frame_id: str, n_values: int = 2) -> None:
        name = frame_id.encode()
        first = first_after_header(len(name) + 1)
        self._frame = _U32.pack(len(name) + 1) + name + bytes(first - FRAME_ID_AT - len(name))
        self._values = struct.Struct(f'<{n_values}d')

    def head(self, stamp_ns: int) -> bytes:
        """Return the encapsulation header and the Header of ``stamp_ns``: shared by a batch."""
        return _HEADER + _STAMP.pack(*divmod(int(stamp_ns), 1_000_000_000)) + self._frame

    def encode(self, head: bytes, *values: float) -> bytes:
        """Return one message: a :meth:`head`, then the float64 fields ``values``."""
        return head + self._values.pack(*values)


def _align(out: bytearray, size: int) -> None:
    """Pad ``out`` with zeros to a multiple of ``size`` counted from the encapsulation header."""
    out += bytes(-(len(out) - ENCAPSULATION_BYTES) % size)


def _put_string(out: bytearray, text: str) -> None:
    """Append a string field to ``out``: aligned uint32 length counting the NUL, bytes, NUL."""
    data = text.encode()
    _align(out, 4)
    out += _U32.pack(len(data) + 1) + data + b'\x00'


def encode_stamped(stamps_ns: np.ndarray, frame_id: str, values: np.ndarray) -> List[bytes]:
    """
    Return Header-first messages, serialised: one per stamp (ns), ``values`` after the header.

    ``values`` (one row per stamp) are the message's float64 fields in order:
    (temperature, variance) of a sensor_msgs/Temperature, (fluid_pressure,
    variance) of a sensor_msgs/FluidPressure. Built for all stamps at once:
    what a bag of estimates or of the simulated rig needs.
    """
    stamps_ns = np.asarray(stamps_ns, dtype=np.int64)
    values = np.asarray(values, dtype=np.float64).reshape(stamps_ns.size, -1)
    name = frame_id.encode()
    first = ENCAPSULATION_BYTES + first_after_header(len(name) + 1)
    size = first + 8 * values.shape[1]
    rows = np.zeros((stamps_ns.size, size), dtype=np.uint8)
    rows[:, :ENCAPSULATION_BYTES] = np.frombuffer(_HEADER, dtype=np.uint8)
    sec, nanosec = np.divmod(stamps_ns, 1_000_000_000)
    head = ENCAPSULATION_BYTES
    rows[:, head + STAMP_SEC_AT:head + STAMP_NANOSEC_AT] = _columns(sec.astype('<i4'))
    rows[:, head + STAMP_NANOSEC_AT:head + FRAME_ID_LENGTH_AT] = _columns(nanosec.astype('<u4'))
    frame = _U32.pack(len(name) + 1) + name
    rows[:, head + FRAME_ID_LENGTH_AT:head + FRAME_ID_AT + len(name)] = np.frombuffer(
        frame, dtype=np.uint8)
    rows[:, first:] = _columns(values.astype('<f8'))
    blob = rows.tobytes()
    return [blob[k:k + size] for k in range(0, len(blob), size)]


def _columns(array: np.ndarray) -> np.ndarray:
    """Return the bytes of each row of ``array`` (1-D or 2-D) as the rows of a uint8 array."""
    array = np.ascontiguousarray(array.reshape(array.shape[0], -1))
    return array.view(np.uint8).reshape(array.shape[0], -1)
