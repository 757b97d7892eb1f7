"""
A replay's plan: which configuration, and which topic of the bag feeds which input.

The topics that feed each input are those of the estimator's inputs file
(:mod:`wet_eha_thermal.inputs`: topic, message type, joint and field, unit, scale,
offset, sign), else the live defaults (:mod:`wet_eha_thermal.interface`), their /eha
moved to the prefix the recorder recorded under (an actuator in a namespace); ``--map
name=/topic`` puts a default-typed topic in place of either. The inputs file is, in
this order, the one given (``--inputs``), the one the recorder stored in the bag, or
none. A topic the inputs file declares otherwise than the default is decoded message
by message as the node decodes it (a ros2_control rig's JointStates, a batched
block, a sensor in bar), so such a rig's bag replays with no code. Thermocouples
(``/eha/measured/<name>`` by default) are compared with the estimate each one
measures. The configuration is, in this order, the one given, the one the recorder
stored in the bag, or the shipped reference rig. A plan routes each decoded block of
the bag to what it feeds (:meth:`ReplayPlan.route`).
"""

import dataclasses
from dataclasses import dataclass, field
import os
from pathlib import Path
from typing import Dict, List, Mapping, Optional, Sequence

import numpy as np
import yaml

from ... import inputs as inputs_file, interface
from ...bag.reader import BagError, BagInfo, Columns, open_bag
from ...config import (Config, config_from_yaml, ConfigError, default_config_path, load_config,
                       with_values)
from ...estimator.intake import INPUTS, sensor_inputs
from ...estimator.session import Samples
from ...units import C_TO_K


class ReplayError(ValueError):
    """A bag or a topic mapping that cannot be replayed; the message says why."""


class InputsDecoder:
    """
    A topic of the inputs file, decoded message by message as the estimator node does.

    A :class:`~wet_eha_thermal.bag.columns.MessageDecoder`: its fields are the
    channels the topic carries (inputs in SI, the ambient and thermocouples in
    K). A message without a stamp (a Float64, or a zero header stamp) takes
    its log time, as the node takes its receive time.
    """

    def __init__(self, decoder: inputs_file.TopicDecoder) -> None:
        self.decoder = decoder
        self.type_name = decoder.message_type
        self.fields = decoder.channels

    def decode(self, log_time_ns: np.ndarray, messages: List[bytes]) -> tuple:
        """Return the samples' times (ns) and each channel's values."""
        dec = self.decoder
        if dec.batched:
            blocks = [dec.decode_batch(m) for m in messages]
            time_ns = np.concatenate([np.round(t * 1e9).astype(np.int64) for t, _ in blocks])
            values = np.vstack([v for _, v in blocks])
        else:
            rows = [dec.decode(m) for m in messages]
            time_ns = np.array([stamp or log for (stamp, _), log in
                                zip(rows, log_time_ns.tolist())], dtype=np.int64)
            values = np.array([v for _, v in rows], dtype=np.float64).reshape(-1, len(self.fields))
        return time_ns, {c: np.ascontiguousarray(values[:, k]) for k, c in enumerate(self.fields)}


@dataclass
class ReplayPlan:
    """What feeds what: the configuration and the topic of every input and thermocouple."""

    cfg: Config
    config_source: str
    config_yaml: str                       # the file's text (before a pressure-input switch)
    inputs: Dict[str, str]                 # estimator input -> topic (found in the bag)
    missing: List[str]                     # inputs with no topic in the bag: on fallback
    thermocouples: Dict[str, str]          # thermocouple name -> topic
    ambient: Optional[str]
    info: BagInfo
    #: topics the inputs file declares otherwise than the defaults, with their decoders
    decoded: Dict[str, InputsDecoder] = field(default_factory=dict)
    inputs_source: str = 'none: the /eha topics'
    #: the prefix of the replay's outputs (estimates.mcap), as a live node's under it: the one
    #: the bag was recorded under (:func:`recorded_prefix`), or ReplayOptions.prefix
    prefix: str = interface.PREFIX

    @property
    def specs(self) -> Dict[str, object]:
        """Return topic -> message type (or decoder) of every topic to decode."""
        specs = {topic: interface.INPUT_TYPES[name] for name, topic in self.inputs.items()}
        specs.update({topic: interface.TEMPERATURE for topic in self.thermocouples.values()})
        if self.ambient is not None:
            specs[self.ambient] = interface.TEMPERATURE
        specs.update(self.decoded)
        return specs

    def route(self, block: Dict[str, Columns], origin_ns: int = 0) -> Samples:
        """
        Return a block of decoded columns (:func:`iter_column_blocks`) by what each topic feeds.

        Stamps are seconds from ``origin_ns``. Every name mapped to a topic
        gets its samples; thermocouples in the order of the block's topics.
        """
        samples = Samples()
        for topic, columns in block.items():
            if not len(columns) or not len(columns.time_ns):
                continue
            t = (columns.time_ns - origin_ns).astype(np.float64) * 1e-9
            samples.first_s = float(t.min()) if samples.first_s is None \
                else min(samples.first_s, float(t.min()))
            if topic in self.decoded:
                self._route_decoded(samples, t, columns.values)
                continue
            for name, input_topic in self.inputs.items():
                if input_topic == topic:
                    samples.inputs[name] = (t, next(iter(columns.values.values())))
            if topic == self.ambient:
                samples.ambient = (t, columns.values['temperature'])
            for tc, tc_topic in self.thermocouples.items():
                if tc_topic == topic:
                    samples.thermocouples[tc] = (t, columns.values['temperature'],
                                                 columns.values['variance'])
        return samples

    def _route_decoded(self, samples: Samples, t: np.ndarray,
                       values: Dict[str, np.ndarray]) -> None:
        """Route the channels of a topic of the inputs file: temperatures in degC."""
        for channel, v in values.items():
            if channel == inputs_file.AMBIENT:
                samples.ambient = (t, v - C_TO_K)
            elif channel in self.inputs:
                samples.inputs[channel] = (t, v)
            else:
                tc = next(tc for tc in self.thermocouples
                          if inputs_file.thermocouple_channel(tc) == channel)
                samples.thermocouples[tc] = (t, v - C_TO_K, np.full(len(t), np.nan))


def choose_config(info: BagInfo, config_path: Optional[os.PathLike]) -> tuple:
    """Return (configuration, where it came from, its YAML text): given, stored, or shipped."""
    if config_path is not None:
        cfg = load_config(config_path)        # a ConfigError names an unreadable file
        return cfg, str(config_path), Path(config_path).read_text()
    stored = info.metadata.get(interface.CONFIG_METADATA, {}).get(interface.CONFIG_METADATA_KEY)
    if stored:
        try:
            cfg = config_from_yaml(stored, f'{info.path} (stored configuration)')
        except ConfigError as exc:
            # a bag outlives the model it was recorded with: its configuration may lack what
            # a later model needs (or hold what it dropped)
            raise ConfigError(f'{exc}; the configuration stored in the bag does not fit this '
                              'version of the model (recorded by an older one?): replay it '
                              'with --config YOUR_RIG.yaml') from exc
        return cfg, f'stored in {info.path.name}', stored
    return load_config(None), 'shipped reference_eha.yaml (the bag stores none)', \
        default_config_path().read_text()


def choose_inputs(info: BagInfo, spec: Optional[inputs_file.Inputs]) -> tuple:
    """Return (inputs, where they came from): given, stored in the bag, or the defaults."""
    if spec is not None:
        return spec, 'given'
    stored = info.metadata.get(interface.INPUTS_METADATA, {})
    text = stored.get(interface.CONFIG_METADATA_KEY)
    if text:
        return inputs_file.inputs_from_yaml(text, f'{info.path} (stored inputs file)'), \
            f"stored in {info.path.name} ({Path(stored.get('path', 'inputs')).name})"
    return inputs_file.Inputs(), 'none: the /eha topics'


def recorded_prefix(info: BagInfo) -> str:
    """
    Return the topic prefix the recorder of ``info`` recorded under (its resolved parameter).

    /eha for a bag without the recorder's record (another recorder's, a replay's).
    """
    stored = info.metadata.get(interface.RECORDER_METADATA, {}).get('parameters')
    try:
        prefix = yaml.safe_load(stored).get('topic_prefix') if stored else None
    except (yaml.YAMLError, AttributeError):
        prefix = None
    return prefix if isinstance(prefix, str) and prefix.startswith('/') else interface.PREFIX


def _match_pressure_inputs(cfg: Config, wanted, source: str, info: BagInfo, topic_of) -> tuple:
    """Switch between three pressures and one differential when the bag holds only the other."""
    def present(names):
        return any(topic_of(n) in info.topics for n in names)

    ports, differential = ('p_a_Pa', 'p_b_Pa', 'p_acc_Pa'), ('dp_Pa',)
    mine, other, mode = (ports, differential, 'differential') if 'p_a_Pa' in wanted else \
        (differential, ports, 'ports')
    if present(mine) or not present(other):
        return cfg, wanted, source
    cfg = dataclasses.replace(cfg, estimator=dataclasses.replace(cfg.estimator,
                                                                 pressure_inputs=mode))
    return cfg, sensor_inputs(cfg), f'{source}, with pressure_inputs: {mode} (what the bag holds)'


class _Topics:
    """
    Where each name is read in one bag: mapped (default type), or as the inputs file says.

    ``mapping`` maps names (``current_A``, ``measured/frame``, ``ambient``, ...)
    to topics of the default types; ``spec`` is the inputs file; the /eha
    topics of both are moved to ``prefix``.
    """

    def __init__(self, info: BagInfo, spec: inputs_file.Inputs, inputs_source: str,
                 mapping: Mapping[str, str], prefix: str) -> None:
        self.info = info
        self.spec = spec
        self.inputs_source = inputs_source
        self.mapping = dict(mapping)
        self.prefix = prefix
        self.default = inputs_file.Inputs()
        known = set(INPUTS) | {'dp_Pa', 'ambient'} | {f'measured/{tc}' for tc in
                                                      interface.THERMOCOUPLES}
        unknown = sorted(set(self.mapping) - known)
        if unknown:
            raise ReplayError(f'cannot map {unknown[0]!r}: the names are '
                              f'{", ".join(sorted(known))}')

    @staticmethod
    def channel(name: str) -> str:
        """Return the inputs file's channel of a mapping's name."""
        return inputs_file.thermocouple_channel(name[len('measured/'):]) \
            if name.startswith('measured/') else name

    def signal(self, name: str) -> inputs_file.InputSignal:
        """Return where ``name`` is read: mapped (default type), or as the inputs say."""
        sig = self.spec.signal(self.channel(name))
        if name in self.mapping:
            return dataclasses.replace(self.default.signal(self.channel(name)),
                                       topic=self.mapping[name])
        # an actuator in a namespace: its /eha topics were recorded under its prefix
        return dataclasses.replace(sig, topic=interface.prefixed(sig.topic, self.prefix))

    def found(self, name: str) -> Optional[str]:
        """Return the topic of ``name`` when the bag holds it, checked for its type."""
        sig = self.signal(name)
        held = self.info.topics.get(sig.topic)
        if held is None:
            return None
        if held.type_name != sig.message_type:
            raise ReplayError(f'{self.info.path}: topic {sig.topic} ({name}) holds '
                              f'{held.type_name}; expected {sig.message_type} '
                              f'({self.inputs_source})')
        return sig.topic

    def inputs(self, wanted: Sequence[str]) -> tuple:
        """Return the topic of each input of ``wanted`` the bag holds, and those it lacks."""
        found, missing = {}, []
        for name in wanted:
            topic = self.found(name)
            if topic is None:
                missing.append(name)
            else:
                found[name] = topic
        if not found:
            listing = ', '.join(f'{t} ({i.type_name})'
                                for t, i in sorted(self.info.topics.items()))
            raise ReplayError(
                f'{self.info.path}: no topic of the mapping is in the bag (looked for '
                f'{", ".join(self.signal(n).topic for n in wanted)}; inputs file: '
                f'{self.inputs_source}); the bag has: {listing or "no topics"}. Map them with '
                '--map name=/topic, or give the inputs file with --inputs.')
        return found, missing

    def temperature(self, name: str) -> Optional[str]:
        """Return the topic of a thermocouple or the ambient; None: not in the bag, or not one."""
        try:
            return self.found(name)
        except ReplayError:
            return None                    # not a temperature: compared with nothing

    def decoders(self, used: Sequence[str]) -> Dict[str, InputsDecoder]:
        """
        Return the decoder of each topic the inputs file declares otherwise than the defaults.

        Those topics are decoded as the node decodes them; ReplayError when one
        is also a default-typed topic of ``used``.
        """
        spec, default, channel = self.spec, self.default, self.channel
        configured = [channel(n) for n in used if n not in self.mapping
                      and spec.signal(channel(n)) != default.signal(channel(n))]
        try:
            decoded = {dec.topic: InputsDecoder(dec)
                       for dec in inputs_file.decoders(spec, configured)}
        except ConfigError as exc:
            raise ReplayError(str(exc)) from exc
        both = sorted(set(decoded) & {self.signal(n).topic for n in used
                                      if channel(n) not in configured})
        if both:
            raise ReplayError(f'{self.info.path}: topic {both[0]} is declared both as the inputs '
                              'file says and with the default type: map one of them elsewhere')
        return decoded


def plan_replay(path: os.PathLike, config_path: Optional[os.PathLike] = None,
                mapping: Optional[Mapping[str, str]] = None,
                config: Optional[tuple] = None,
                inputs: Optional[inputs_file.Inputs] = None) -> ReplayPlan:
    """
    Open a bag and decide which topics feed the estimator; raise ReplayError when none does.

    ``mapping`` maps input or thermocouple names (``current_A``, ...,
    ``measured/frame``, ``ambient``) to topics of the default types, replacing
    the inputs file's and the defaults. ``config`` (a :func:`choose_config`
    tuple) is used instead of choosing one for this bag, e.g. one
    configuration for several bags. ``inputs``: the estimator's inputs
    (:func:`choose_inputs`: default, the file stored in the bag).
    """
    try:
        info = open_bag(path)
    except BagError as exc:
        raise ReplayError(str(exc)) from exc
    cfg, source, text = config if config is not None else choose_config(info, config_path)
    spec, inputs_source = choose_inputs(info, inputs)
    prefix = recorded_prefix(info)
    topics = _Topics(info, spec, inputs_source, mapping or {}, prefix)
    cfg, wanted, source = _match_pressure_inputs(cfg, sensor_inputs(cfg), source, info,
                                                 lambda n: topics.signal(n).topic)
    inputs_found, missing = topics.inputs(wanted)
    thermocouples = {tc: topic for tc in interface.THERMOCOUPLES
                     if (topic := topics.temperature(f'measured/{tc}')) is not None}
    ambient = topics.temperature('ambient')
    decoded = topics.decoders([*inputs_found, *(['ambient'] if ambient else []),
                               *(f'measured/{tc}' for tc in thermocouples)])
    return ReplayPlan(cfg=cfg, config_source=source, config_yaml=text, inputs=inputs_found,
                      missing=missing, thermocouples=thermocouples, ambient=ambient, info=info,
                      decoded=decoded, inputs_source=inputs_source, prefix=prefix)


@dataclass
class ReplayOptions:
    """What a replay runs with besides its bag: the options of ``wet-eha-thermal replay``."""

    config_path: Optional[Path] = None
    mapping: Dict[str, str] = field(default_factory=dict)
    inputs_path: Optional[Path] = None     # the estimator's inputs file (None: the bag's)
    output_rate_Hz: float = 10.0
    report: bool = True
    open_loop: bool = False       # estimator.correction off: the thermocouples only compared
    outlook: bool = True          # the current limits, forecast and margin (off: faster)
    prefix: Optional[str] = None  # the outputs' topic prefix (None: the bag's recorded one)

    def __post_init__(self) -> None:
        if self.prefix is not None and (not self.prefix.startswith('/') or self.prefix == '/'):
            raise ReplayError(f'--prefix {self.prefix!r}: expected a topic prefix such as '
                              '/left (absolute, not the root)')

    def plan(self, path: os.PathLike) -> ReplayPlan:
        """Return the :func:`plan_replay` of the bag ``path`` under these options."""
        spec = None if self.inputs_path is None else inputs_file.load_inputs(
            str(self.inputs_path))
        plan = plan_replay(path, self.config_path, self.mapping, inputs=spec)
        if self.open_loop:
            plan.cfg = with_values(plan.cfg, {'estimator.correction.enabled': False})
        if self.prefix is not None:
            plan.prefix = self.prefix.rstrip('/')
        return plan


def parse_mapping(items: Sequence[str]) -> Dict[str, str]:
    """Parse ``name=/topic`` items of the command line into a mapping."""
    out = {}
    for item in items:
        name, sep, topic = item.partition('=')
        if not sep or not name or not topic.startswith('/'):
            raise ReplayError(f'--map {item!r}: expected name=/topic, e.g. '
                              'current_A=/rig/phase_current')
        out[name] = topic
    return out
