"""
The CDR layout of the few message types this package reads without rclpy.

A serialised ROS 2 message starts with a 4-byte encapsulation header (00 01:
plain CDR, little-endian, what rclpy and Fast DDS write on x86 and ARM); each
field follows, aligned to its size counted from the end of that header.

- std_msgs/Float64: ``data`` (float64) at 0;
- sensor_msgs/FluidPressure and sensor_msgs/Temperature: a std_msgs/Header
  (stamp: int32 sec at 0, uint32 nanosec at 4; frame_id: uint32 length with
  its NUL at 8, the bytes from 12), then two float64 aligned to 8.

The bag reader gathers these fields with numpy for whole chunks; the live
estimator node decodes one message at a time with :func:`float64_data` and
:func:`header_stamp_and_value` (a fraction of rclpy's deserialisation).
"""

import struct
from typing import Tuple

#: Bytes of the encapsulation header; the fields' alignment counts from its end.
ENCAPSULATION_BYTES = 4
#: The encapsulation header of little-endian plain CDR.
PLAIN_LE = b'\x00\x01'
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
