"""
What of the twin's interface needs rclpy: the QoS profiles of its topics, publishing inputs.

The names (topics, message types, estimates, thermocouples) are in
:mod:`wet_eha_thermal.interface`, which needs no ROS.
"""

import importlib

from builtin_interfaces.msg import Time as TimeMsg
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, qos_profile_sensor_data, QoSProfile,
                       ReliabilityPolicy)
from wet_eha_thermal import interface


def message_class(type_name: str):
    """Return the rclpy message class of 'pkg/msg/Type' (or 'pkg/Type')."""
    parts = type_name.split('/')
    if len(parts) == 2:
        parts.insert(1, 'msg')
    if len(parts) != 3 or not all(parts):
        raise ValueError(f'message type {type_name!r}: expected pkg/msg/Type')
    module = importlib.import_module(f'{parts[0]}.{parts[1]}')
    return getattr(module, parts[2])


def time_msg(ns: int) -> TimeMsg:
    """Return a ROS time message of ``ns`` nanoseconds (cheaper than rclpy.time.Time.to_msg)."""
    return TimeMsg(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


#: What ``topic_prefix`` says by default: the node's namespace (or /eha at the root).
FROM_NAMESPACE = ''
PREFIX_DOC = ("replaces '/eha' in every topic name (not /diagnostics); '' = the node's "
              'namespace, or /eha when it has none: -r __ns:=/left moves every topic to /left')


def resolve_prefix(node, prefix: str) -> str:
    """
    Return the prefix of ``node``'s topics: ``prefix``, or its namespace, or /eha at the root.

    So two actuators run side by side as ``-r __ns:=/left`` and ``-r __ns:=/right``
    while a node started plainly keeps the /eha topics. ValueError for a
    prefix that is not absolute.
    """
    if prefix == FROM_NAMESPACE:
        return interface.namespace_prefix(node.get_namespace())
    if not prefix.startswith('/'):
        raise ValueError(f'parameter topic_prefix = {prefix!r}: must start with /, or be empty '
                         "(the node's namespace)")
    return prefix.rstrip('/') or '/'


def publish_inputs(publishers, messages, is_pressure, values, stamp) -> None:
    """Publish one sample of every input; pressures carry ``stamp`` in their header."""
    for pub, msg, pressure, value in zip(publishers, messages, is_pressure, values):
        if pressure:
            msg.header.stamp = stamp
            msg.fluid_pressure = value
        else:
            msg.data = value
        pub.publish(msg)


def input_qos(kind: str, depth: int = 100):
    """Return the QoS of the sensor inputs: 'sensor_data' (best effort) or 'reliable'."""
    if kind == 'sensor_data':
        q = QoSProfile(**{k: getattr(qos_profile_sensor_data, k) for k in
                          ('history', 'reliability', 'durability')}, depth=depth)
        return q
    if kind == 'reliable':
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
    raise ValueError(f'qos {kind!r}: expected sensor_data or reliable')


#: History depth of the nodes' outputs (reliable: a drive reads every limits message it can).
#: A reliable writer that keeps the last N drops an unacknowledged message once N newer ones
#: are sent: 10 (0.2 s of 50 Hz estimates) lost ticks of some topics to a recorder that
#: stalled 0.2 s beside a busy core (a live run's bag: stamp 3.70 s missing on the oil
#: alone, 4.64 s on all but the first topic); 100 is 2 s of them
OUTPUT_DEPTH = 100
_TABLE = interface.topic_table()


def profile_of(topic: str, sensor: str = 'sensor_data', depth: int = OUTPUT_DEPTH) -> tuple:
    """
    Return the message class and QoS of one of the interface's topics (named under /eha).

    Both from :func:`~wet_eha_thermal.interface.topic_table`, the one home of
    every topic's type and QoS kind; ``sensor`` and ``depth`` as in :func:`qos_profile`.
    """
    type_name, kind = _TABLE[topic]
    return message_class(type_name), qos_profile(kind, sensor, depth)


def qos_profile(kind: str, sensor: str = 'sensor_data', depth: int = 100):
    """
    Return the rclpy QoS of a topic's kind (:func:`~wet_eha_thermal.interface.topic_table`).

    ``sensor``: the nodes' ``qos`` parameter, for the sensor kind; ``depth``
    the history depth of the sensor and output kinds (latched keep the last).
    """
    if kind == interface.SENSOR:
        return input_qos(sensor, depth)
    if kind == interface.OUTPUT:
        return input_qos('reliable', depth)
    if kind == interface.LATCHED:
        return latched_qos()
    raise ValueError(f'QoS kind {kind!r}: expected one of {interface.SENSOR}, '
                     f'{interface.OUTPUT}, {interface.LATCHED}')


def latched_qos(depth: int = 1):
    """
    Return the QoS of the alert and ready topics: reliable, transient local, last kept.

    A subscriber to a topic several nodes latch on (the ready topic) takes a
    ``depth`` of one per node: with 1, messages that arrive together replace
    each other before its callback runs.
    """
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)
