"""
What rosbag2 (Jazzy) keeps of a bag besides the messages, written as rosbag2 writes it.

Checked in ros2/rosbag2: rosbag2_storage_mcap/src/mcap_storage.cpp, rosbag2_cpp's
local_message_definition_source.cpp and sequential_writer.cpp, and
rosbag2_storage's yaml.hpp and qos.cpp of metadata version 9, Jazzy:

- one schema per type, named ``pkg/msg/Type``, encoding ``ros2msg``: the .msg
  file as installed (comments kept, as rosbag2 keeps them), then every type it
  uses, depth first in sorted order, each after a line of 80 ``=`` and
  ``MSG: pkg/Type`` (:func:`message_definition`);
- per topic the channel metadata ``offered_qos_profiles`` (YAML list of the
  publishers' QoS, :func:`qos_profiles`) and ``topic_type_hash``
  (``RIHS01_...``, :func:`type_hash`);
- the bag's BagMetadata (:func:`bag_metadata`), as the YAML of a Metadata record
  ``rosbag2`` and, in a bag directory, as ``metadata.yaml``
  (:func:`write_metadata_yaml`), what ``ros2 bag info`` and rosbag2_py open a
  bag by.
"""

import contextlib
import json
import os
from pathlib import Path
import re
import sys
import textwrap
from typing import Dict, Iterable, List, Optional

import yaml

from .. import interface

#: The file of a rosbag2 bag directory that lists its files, and its top-level key.
ROSBAG2_METADATA = 'metadata.yaml'
ROSBAG2_METADATA_ROOT = 'rosbag2_bagfile_information'
#: The Metadata record of every file that holds the BagMetadata, and its key.
ROSBAG2_METADATA_NAME = 'rosbag2'
ROSBAG2_METADATA_KEY = 'serialized_metadata'
ROSBAG2_METADATA_VERSION = 9      # rosbag2 Jazzy

# What rosbag2 takes for the field types of a .msg file, and the primitives it skips
# (rosbag2_cpp local_message_definition_source.cpp).
_MSG_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+', re.ASCII)
_PRIMITIVE_TYPES = frozenset({
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string'})
_DEFINITION_DELIMITER = '=' * 80 + '\n'
# libyaml's emitter when PyYAML has it: the bag metadata is dumped at every file change
_YAML_DUMPER = getattr(yaml, 'CSafeDumper', yaml.SafeDumper)


def _share_dir(package: str) -> Path:
    """Return the share folder of a ROS package (ament index, else the running prefix)."""
    try:
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory(package))
    except Exception:  # noqa: B902 - no ament environment (pip venv) or package not indexed
        return Path(sys.prefix) / 'share' / package


def _split_type_name(type_name: str):
    """Return (package, Type) of 'pkg/msg/Type' or 'pkg/Type'."""
    parts = type_name.split('/')
    if len(parts) == 3 and parts[1] == 'msg':
        return parts[0], parts[2]
    if len(parts) == 2:
        return parts[0], parts[1]
    raise ValueError(f'message type {type_name!r}: expected pkg/msg/Type')


def _interface_file(type_name: str, suffix: str) -> Path:
    package, name = _split_type_name(type_name)
    path = _share_dir(package) / 'msg' / f'{name}{suffix}'
    if not path.is_file():
        raise ValueError(f'message type {type_name!r}: no {path}')
    return path


def message_definition(type_name: str) -> str:
    """
    Return the complete ``ros2msg`` definition of a message type, as rosbag2 stores it.

    That is rosbag2's own algorithm: the .msg text unchanged, then for each
    field type not seen before (sorted by name, depth first) a newline, the
    80 ``=`` delimiter line, ``MSG: <type as written in the .msg>`` and its
    text, recursively.
    """
    seen = set()

    def with_dependencies(name: str) -> str:
        text = _interface_file(name, '.msg').read_text()
        package = _split_type_name(name)[0]
        dependencies = sorted({
            t if '/' in t else f'{package}/{t}'
            for t in _MSG_FIELD_TYPE.findall(text) if t not in _PRIMITIVE_TYPES})
        for dependency in dependencies:
            if dependency not in seen:
                seen.add(dependency)
                text += ('\n' + _DEFINITION_DELIMITER + f'MSG: {dependency}\n'
                         + with_dependencies(dependency))
        return text

    return with_dependencies(type_name)


def type_hash(type_name: str) -> str:
    """Return the RIHS01 type hash of a message type, from its generated .json description."""
    description = json.loads(_interface_file(type_name, '.json').read_text())
    package, name = _split_type_name(type_name)
    full_name = f'{package}/msg/{name}'
    for entry in description['type_hashes']:
        if entry['type_name'] == full_name:
            return entry['hash_string']
    raise ValueError(f'message type {type_name!r}: no type hash in its .json description')


def _rosbag2_profile(history: str, depth: int, reliability: str, durability: str,
                     deadline_ns: int, lifespan_ns: int, liveliness: str, lease_ns: int,
                     avoid_ros_namespace_conventions: bool) -> dict:
    """Return one offered QoS profile as rosbag2 (metadata version 9) stores it."""
    def rmw_time(ns: int) -> Dict[str, int]:  # a new dict each: a shared one dumps as an alias
        sec, nsec = divmod(ns, 1_000_000_000)
        return {'sec': sec, 'nsec': nsec}

    return {'history': history, 'depth': depth, 'reliability': reliability,
            'durability': durability, 'deadline': rmw_time(deadline_ns),
            'lifespan': rmw_time(lifespan_ns), 'liveliness': liveliness,
            'liveliness_lease_duration': rmw_time(lease_ns),
            'avoid_ros_namespace_conventions': avoid_ros_namespace_conventions}


def qos_profiles(qos) -> List[dict]:
    """
    Return an rclpy QoSProfile as rosbag2 (metadata version 9) lists a topic's offered QoS.

    Read by attribute, so this module imports nothing of ROS: the recorder
    passes what its publishers offer.
    """
    return [_rosbag2_profile(
        qos.history.short_key, qos.depth, qos.reliability.short_key,
        qos.durability.short_key, qos.deadline.nanoseconds, qos.lifespan.nanoseconds,
        qos.liveliness.short_key, qos.liveliness_lease_duration.nanoseconds,
        qos.avoid_ros_namespace_conventions)]


def offered_qos(reliability: str = 'reliable', durability: str = 'volatile',
                depth: int = 10) -> List[dict]:
    """
    Return the offered QoS of a keep-last publisher, as :func:`qos_profiles` lists it.

    For bags written without ROS (replay's estimates, the simulated rig's
    logs): rclpy's defaults for the rest (no deadline, lifespan or lease,
    system-default liveliness).
    """
    return [_rosbag2_profile('keep_last', depth, reliability, durability, 0, 0,
                             'system_default', 0, False)]


def offered_profiles(kind: str, depth: int = 10) -> List[dict]:
    """
    Return what a bag stores as offered by a publisher of a QoS kind (``interface.SENSOR`` ...).

    The sensor kind is the sensor_data profile (best effort), the nodes' default.
    """
    if kind == interface.SENSOR:
        return offered_qos('best_effort', depth=depth)
    if kind == interface.OUTPUT:
        return offered_qos(depth=depth)
    if kind == interface.LATCHED:
        return offered_qos(durability='transient_local', depth=1)
    raise ValueError(f'QoS kind {kind!r}: expected one of {interface.SENSOR}, '
                     f'{interface.OUTPUT}, {interface.LATCHED}')


def to_yaml(data) -> str:
    """Return ``data`` as rosbag2's YAML: block style, keys in order, no final newline."""
    return yaml.dump(data, Dumper=_YAML_DUMPER, sort_keys=False,
                     default_flow_style=False).rstrip('\n')


class Topic:
    """What the bag keeps of a topic: type, definition, hash, QoS and message counts."""

    def __init__(self, name: str, type_name: str, qos: Optional[List[dict]]):
        package, short = _split_type_name(type_name)
        self.name = name
        self.type_name = f'{package}/msg/{short}'
        self.definition = message_definition(self.type_name)
        self.type_hash = type_hash(self.type_name)
        self.qos = list(qos or [])  # [] is what rosbag2 stores when it does not know them
        # the channel metadata of every file: dumped once, not at each split (~0.1 ms a topic)
        self.qos_yaml = to_yaml(self.qos)
        self.message_count = 0      # in complete chunks of the bag's files
        self.pending = 0            # in the chunk being built
        self.dropped = 0            # in no file (suspended, or a chunk that could not be written)

    def record_bytes(self) -> int:
        """Return about what its schema and channel records take in a file."""
        return (2 * len(self.type_name) + len(self.definition) + len(self.name)
                + len(self.qos_yaml) + len(self.type_hash) + 200)


def bag_metadata(topics: Iterable[Topic], files: List) -> dict:
    """
    Return a bag's rosbag2 BagMetadata (rosbag2_storage yaml.hpp, version 9).

    ``files``: the bag's files so far, each with its path, message count and
    log time span (:class:`~.split.FileStats`).
    """
    with_messages = [f for f in files if f.message_count]
    start_ns = min((f.start_ns for f in with_messages), default=0)
    end_ns = max((f.end_ns for f in with_messages), default=0)
    return {
        'version': ROSBAG2_METADATA_VERSION,
        'storage_identifier': 'mcap',
        'duration': {'nanoseconds': end_ns - start_ns},
        'starting_time': {'nanoseconds_since_epoch': start_ns},
        'message_count': sum(f.message_count for f in files),
        'topics_with_message_count': [
            {'topic_metadata': {'name': t.name, 'type': t.type_name,
                                'serialization_format': 'cdr',
                                'offered_qos_profiles': t.qos,
                                'type_description_hash': t.type_hash},
             'message_count': t.message_count}
            for t in topics],
        # chunk compression is the storage's business, not rosbag2's compression
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [f.path.name for f in files],
        'files': [f.as_rosbag2() for f in files],
        'custom_data': {},
        # the ROS wheels of requirements.txt are Jazzy's; a sourced ROS sets this
        'ros_distro': os.environ.get('ROS_DISTRO', 'jazzy'),
    }


def write_metadata_yaml(directory: Path, bag_yaml: str) -> None:
    """Replace a bag directory's metadata.yaml whole (a reader never sees half of one)."""
    # the record's YAML, indented under the root key (a block mapping nests so): PyYAML's
    # representer is the dear part of a split, about 10 ms for the recorder's 32 topics
    text = f'{ROSBAG2_METADATA_ROOT}:\n' + textwrap.indent(bag_yaml, '  ') + '\n'
    target = directory / ROSBAG2_METADATA
    temporary = target.with_name(f'.{ROSBAG2_METADATA}.partial')
    try:
        temporary.write_text(text)
        os.replace(temporary, target)
    except OSError:
        with contextlib.suppress(OSError):
            temporary.unlink()
        raise
