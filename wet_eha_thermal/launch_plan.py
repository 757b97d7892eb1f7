"""
What ``launch/eha_twin.launch.py`` starts, as data: the nodes of a list of actuators.

``launch`` and ``launch_ros`` are not on PyPI, so the decisions live here,
where the tests check them: which nodes run, in which namespace, with which
parameters files, parameters, remappings and Foxglove port. The launch file
only turns each :class:`NodePlan` into a ``launch_ros.actions.Node``.

One actuator is one namespace: its estimator, and optionally its simulated
rig, its recorder and its Foxglove view, all started with that namespace, so
every topic of theirs moves with it (``topic_prefix`` '' is the namespace),
their diagnostic statuses are named after it and their ``hardware_id``
defaults to it (:func:`~wet_eha_thermal.interface.hardware_id`). The
actuators come from the ``actuators`` launch argument (namespaces, comma
separated; default ``eha``, the twin's one actuator) or from an actuators
file (YAML)::

    actuators:
      - namespace: left
        config_file: /rigs/left.yaml      # thermal configuration; '' = the reference rig
        params_file: ''                   # the nodes' parameters; '' = the shipped
        inputs_file: ros2_control_rig.inputs.yaml   # the estimator's inputs
        hardware_id: eha-sn-0042          # '' = wet-eha-rig/<namespace>
        stage: 3                          # the simulated rig's duty (default: stage)
        remappings: {/joint_states: /left/joint_states}   # for every node of it
      - namespace: right

Nothing here imports ROS.
"""

import dataclasses
from dataclasses import dataclass, field
import os
import re
from typing import Dict, List, Mapping, Optional, Sequence, Tuple

from wet_eha_thermal import inputs, interface
import yaml

PACKAGE = 'wet_eha_thermal'
#: The executables of ``setup.py``'s console scripts
ESTIMATOR_EXE = 'wet-eha-thermal-estimator'
RIG_EXE = 'wet-eha-thermal-rig'
RECORDER_EXE = 'wet-eha-thermal-record'
#: The namespace of the twin's one actuator when none is named (its topics stay /eha/...)
DEFAULT_NAMESPACE = interface.PREFIX.strip('/')
#: The first actuator's Foxglove view listens here, the next on the next port, and so on
FOXGLOVE_PORT = 8765
#: The view's address: this machine only
FOXGLOVE_HOST = '127.0.0.1'
#: The keys an actuator of an actuators file may have
ACTUATOR_KEYS = ('namespace', 'config_file', 'params_file', 'inputs_file', 'hardware_id',
                 'stage', 'remappings')
_NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_]*')


@dataclass(frozen=True)
class Actuator:
    """One actuator: its namespace and the files its nodes read ('' = the default)."""

    namespace: str                      # absolute: /left
    config_file: str = ''
    params_file: str = ''
    inputs_file: str = ''
    hardware_id: str = ''
    stage: Optional[int] = None         # None: the launch's stage
    remappings: Tuple[Tuple[str, str], ...] = ()


@dataclass(frozen=True)
class NodePlan:
    """One node to start: what ``launch_ros.actions.Node`` takes."""

    executable: str
    name: str
    namespace: str
    parameters: List[object]            # parameters files (paths), then one dict
    arguments: List[str] = field(default_factory=list)
    remappings: List[Tuple[str, str]] = field(default_factory=list)
    foxglove_port: Optional[int] = None


def namespace_of(text: str, where: str) -> str:
    """
    Return ``text`` as an absolute ROS namespace (``left`` -> ``/left``).

    ValueError, naming ``where``, for an empty namespace, the root or a
    token that is not a ROS name.
    """
    tokens = str(text).strip().strip('/').split('/')
    if not all(_NAME.fullmatch(t) for t in tokens):
        raise ValueError(f'{where} = {text!r}: a namespace is one or more names of letters, '
                         'digits and _ (not starting with a digit) separated by /, and not '
                         'the root')
    return '/' + '/'.join(tokens)


def actuators_from_names(text: str) -> List[Actuator]:
    """Return the actuators of the ``actuators`` launch argument: namespaces, comma separated."""
    names = [n.strip() for n in str(text).split(',') if n.strip()]
    if not names:
        raise ValueError(f'actuators = {text!r}: name at least one namespace '
                         f'(e.g. {DEFAULT_NAMESPACE}, or left,right)')
    return [Actuator(namespace_of(n, 'actuators')) for n in names]


def actuators_from_yaml(text: str, origin: str = 'actuators file') -> List[Actuator]:
    """
    Return the actuators of an actuators file (the module docstring shows one).

    ValueError names the file, the actuator and the key of anything wrong.
    """
    data = yaml.safe_load(text)
    items = data.get('actuators') if isinstance(data, dict) else None
    if not isinstance(items, list) or not items:
        raise ValueError(f'{origin}: expected a list of actuators under the key actuators')
    out = []
    for i, item in enumerate(items):
        where = f'{origin}: actuators[{i}]'
        if not isinstance(item, dict) or 'namespace' not in item:
            raise ValueError(f'{where}: expected a mapping with at least a namespace')
        unknown = sorted(set(item) - set(ACTUATOR_KEYS))
        if unknown:
            raise ValueError(f'{where}: unknown key {", ".join(unknown)}; allowed: '
                             f'{", ".join(ACTUATOR_KEYS)}')
        files = {}
        for key in ('config_file', 'params_file', 'inputs_file', 'hardware_id'):
            value = item.get(key, '')
            if not isinstance(value, str):
                raise ValueError(f'{where}.{key} = {value!r}: expected a string')
            files[key] = value
        stage = item.get('stage')
        if stage is not None and (isinstance(stage, bool) or stage not in range(1, 7)):
            raise ValueError(f'{where}.stage = {stage!r}: expected a reference stage 1..6')
        remaps = item.get('remappings') or {}
        if not isinstance(remaps, dict) or not all(
                isinstance(k, str) and isinstance(v, str) and k and v
                for k, v in remaps.items()):
            raise ValueError(f'{where}.remappings = {remaps!r}: expected a mapping of topic '
                             'names (from: to)')
        out.append(Actuator(namespace_of(item['namespace'], f'{where}.namespace'), stage=stage,
                            remappings=tuple(remaps.items()), **files))
    return out


def load_actuators(names: str, path: str = '') -> List[Actuator]:
    """Return the actuators of an actuators file when ``path`` is given, else of ``names``."""
    if path:
        with open(path, encoding='utf-8') as f:
            return actuators_from_yaml(f.read(), path)
    return actuators_from_names(names)


def check_sim_rig_feeds(a: Actuator) -> None:
    """
    Raise ValueError unless a simulated rig feeds every input of ``a``'s inputs file.

    The simulated rig publishes the default topics (interface.INPUT_TOPICS, the
    ambient and the thermocouples under the namespace, Float64, FluidPressure
    and Temperature in SI units). An inputs file that declares any of them
    otherwise (a real rig's JointStates, blocks, another topic or unit) would
    leave the estimator waiting for topics nobody publishes, or read the
    rig's values in the wrong unit: the message names the file, what it
    declares and what the simulated rig publishes. A bad inputs file raises
    its own ConfigError (a ValueError) naming the key.
    """
    spec, default = inputs.load_inputs(a.inputs_file), inputs.Inputs()
    channels = [f.name for f in dataclasses.fields(inputs.Inputs) if f.name != 'thermocouples']
    channels += [inputs.thermocouple_channel(tc) for tc in interface.THERMOCOUPLES]
    differ = [c for c in channels if spec.signal(c) != default.signal(c)]
    if not differ:
        return

    def where(sig: inputs.InputSignal) -> str:
        joint = f' joint {sig.joint} {sig.field}' if sig.joint else ''
        return (f'{interface.prefixed(sig.topic, a.namespace)} '
                f'({sig.message_type.split("/")[-1]}{joint}, {sig.unit})')

    raise ValueError(
        f'actuator {a.namespace}: inputs_file {a.inputs_file} declares '
        + '; '.join(f'{c} on {where(spec.signal(c))}' for c in differ)
        + ', but its simulated rig publishes '
        + '; '.join(f'{c} on {where(default.signal(c))}' for c in differ)
        + '. For a real rig launch with sim_rigs:=false; for the simulated rig leave this '
        "actuator's inputs_file empty")


def _check_namespaces_and_ports(actuators: Sequence[Actuator],
                                foxglove_port: Optional[int]) -> None:
    """Raise ValueError when two actuators share a namespace or their views leave 1..65535."""
    seen: Dict[str, int] = {}
    for i, a in enumerate(actuators):
        if a.namespace in seen:
            raise ValueError(f'actuators {seen[a.namespace]} and {i} share the namespace '
                             f'{a.namespace}: each actuator needs its own')
        seen[a.namespace] = i
    if foxglove_port is not None and not 1 <= foxglove_port <= 65536 - len(actuators):
        raise ValueError(f'foxglove_port = {foxglove_port}: {len(actuators)} views need ports '
                         f'{foxglove_port}..{foxglove_port + len(actuators) - 1} within 1..65535')


def _record_output(record_output: str, namespace: str) -> str:
    """Return where the recorder of ``namespace`` records when several share ``record_output``."""
    if not record_output:
        return record_output       # each recorder's own runs/eha_<UTC time>
    name = namespace.strip('/').replace('/', '_')
    stem, ext = os.path.splitext(record_output)
    return f'{stem}_{name}.mcap' if ext == '.mcap' else os.path.join(record_output, name)


def plan(actuators: Sequence[Actuator], share_dir: str, *, sim_rigs: bool = True,
         record: bool = True, view: bool = False, stage: int = 6, duty_file: str = '',
         use_sim_time: bool = False, executor: str = 'events', honour_limit: bool = False,
         record_output: str = '', foxglove_port: int = FOXGLOVE_PORT,
         managed: bool = False) -> List[NodePlan]:
    """
    Return every node to start for ``actuators``, in order: per actuator rig, estimator, recorder.

    ``share_dir``: the package's share directory (its ``config/``).
    ``sim_rigs``: start each actuator's simulated rig (off: a real rig
    publishes the inputs). ``record``: a recorder per actuator, into
    ``record_output`` for one actuator, ``record_output/<namespace>`` for
    several (``<stem>_<namespace>.mcap`` for a name ending .mcap; '': each
    recorder's own ``runs/eha_<UTC time>``). ``view``:
    each estimator serves its Foxglove view, the first on ``foxglove_port``,
    the next on the next port. ``managed``: the estimators start as
    lifecycle nodes (``--managed``), unconfigured until an operator or a
    lifecycle manager configures and activates them. ValueError when two
    actuators share a namespace, a port would leave 1..65535, or a simulated
    rig cannot feed an actuator's inputs file (:func:`check_sim_rig_feeds`).
    """
    _check_namespaces_and_ports(actuators, foxglove_port if view else None)
    shipped = os.path.join(share_dir, 'config', 'estimator.params.yaml')
    nodes = []
    for i, a in enumerate(actuators):
        params = a.params_file or shipped
        common = {'use_sim_time': use_sim_time}
        for key in ('config_file', 'hardware_id'):
            if getattr(a, key):
                common[key] = getattr(a, key)
        remaps = list(a.remappings)
        if sim_rigs:
            if a.inputs_file:
                check_sim_rig_feeds(a)
            rig = {**common, 'stage': a.stage or stage, 'duty_file': duty_file,
                   'honour_limit': honour_limit}
            nodes.append(NodePlan(RIG_EXE, interface.RIG_NODE, a.namespace, [params, rig],
                                  ['--executor', executor], remaps))
        est = dict(common)
        if a.inputs_file:
            est['inputs_file'] = a.inputs_file
        port = foxglove_port + i if view else None
        if port is not None:
            est['foxglove_address'] = f'{FOXGLOVE_HOST}:{port}'
        nodes.append(NodePlan(ESTIMATOR_EXE, interface.ESTIMATOR_NODE, a.namespace,
                              [params, est], ['--executor', executor] + ['--managed'] * managed,
                              remaps, port))
        if record:
            output = _record_output(record_output, a.namespace) if len(actuators) > 1 \
                else record_output
            # ready once it hears the estimator too: its estimates recorded from the first
            rec = {**common, 'params_file': params, 'output': output, 'wait_for_estimator': True}
            if a.inputs_file:       # its topics recorded, the file stored for replay
                rec['inputs_file'] = a.inputs_file
            # the events executor always: the single-threaded one loses messages
            nodes.append(NodePlan(RECORDER_EXE, interface.RECORDER_NODE, a.namespace,
                                  [params, rec], ['--executor', 'events'], remaps))
    return nodes


def as_bool(text: str, name: str) -> bool:
    """Return a launch argument's ``true``/``false`` as a bool; ValueError naming ``name``."""
    value = str(text).strip().lower()
    if value not in ('true', 'false'):
        raise ValueError(f'{name} = {text!r}: expected true or false')
    return value == 'true'


def plan_from_arguments(args: Mapping[str, str], share_dir: str) -> List[NodePlan]:
    """
    Return :func:`plan` for the launch file's arguments (name -> text, as launch gives them).

    The names are those of the launch file: ``actuators``, ``actuators_file``,
    ``sim_rigs``, ``record``, ``view``, ``foxglove_port``, ``stage``,
    ``duty_file``, ``use_sim_time``, ``executor``, ``honour_limit``,
    ``record_output`` and ``managed``.
    """
    def integer(name: str) -> int:
        try:
            return int(args[name])
        except ValueError:
            raise ValueError(f'{name} = {args[name]!r}: expected a whole number') from None

    stage = integer('stage')
    if stage not in range(1, 7):
        raise ValueError(f'stage = {stage}: expected a reference stage 1..6')
    return plan(load_actuators(args['actuators'], args['actuators_file']), share_dir,
                sim_rigs=as_bool(args['sim_rigs'], 'sim_rigs'),
                record=as_bool(args['record'], 'record'), view=as_bool(args['view'], 'view'),
                stage=stage, duty_file=args['duty_file'],
                use_sim_time=as_bool(args['use_sim_time'], 'use_sim_time'),
                executor=args['executor'],
                honour_limit=as_bool(args['honour_limit'], 'honour_limit'),
                record_output=args['record_output'], foxglove_port=integer('foxglove_port'),
                managed=as_bool(args['managed'], 'managed'))
