"""
A replay's plan: which configuration, and which topic of the bag feeds which input.

The topics that feed each input are the live defaults (:mod:`wet_eha_thermal.interface`)
unless mapped otherwise (``--map name=/topic``); thermocouples
(``/eha/measured/<name>``) are compared with the estimate each one measures. The
configuration is, in this order, the one given, the one the recorder stored in
the bag, or the shipped reference rig. A plan routes each decoded block of the
bag to what it feeds (:meth:`ReplayPlan.route`).
"""

import dataclasses
from dataclasses import dataclass, field
import os
from pathlib import Path
from typing import Dict, List, Mapping, Optional, Sequence

import numpy as np

from ... import interface
from ...bag.reader import BagError, BagInfo, Columns, open_bag
from ...config import (Config, config_from_yaml, ConfigError, default_config_path, load_config,
                       with_values)
from ...estimator.intake import INPUTS, sensor_inputs
from ...estimator.session import Samples


class ReplayError(ValueError):
    """A bag or a topic mapping that cannot be replayed; the message says why."""


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

    @property
    def specs(self) -> Dict[str, str]:
        """Return topic -> message type of every topic to decode."""
        specs = {topic: interface.INPUT_TYPES[name] for name, topic in self.inputs.items()}
        specs.update({topic: interface.TEMPERATURE for topic in self.thermocouples.values()})
        if self.ambient is not None:
            specs[self.ambient] = interface.TEMPERATURE
        return specs

    def route(self, block: Dict[str, Columns], origin_ns: int = 0) -> Samples:
        """
        Return a block of decoded columns (:func:`iter_column_blocks`) by what each topic feeds.

        Stamps are seconds from ``origin_ns``. Every name mapped to a topic
        gets its samples; thermocouples in the order of the block's topics.
        """
        samples = Samples()
        for topic, columns in block.items():
            if not len(columns):
                continue
            t = (columns.time_ns - origin_ns).astype(np.float64) * 1e-9
            samples.first_s = float(t[0]) if samples.first_s is None \
                else min(samples.first_s, float(t[0]))
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


def _match_pressure_inputs(cfg: Config, wanted, source: str, info: BagInfo,
                           mapping: Mapping[str, str]) -> tuple:
    """Switch between three pressures and one differential when the bag holds only the other."""
    def present(names):
        return any(mapping.get(n, interface.INPUT_TOPICS[n]) in info.topics for n in names)

    ports, differential = ('p_a_Pa', 'p_b_Pa', 'p_acc_Pa'), ('dp_Pa',)
    mine, other, mode = (ports, differential, 'differential') if 'p_a_Pa' in wanted else \
        (differential, ports, 'ports')
    if present(mine) or not present(other):
        return cfg, wanted, source
    cfg = dataclasses.replace(cfg, estimator=dataclasses.replace(cfg.estimator,
                                                                 pressure_inputs=mode))
    return cfg, sensor_inputs(cfg), f'{source}, with pressure_inputs: {mode} (what the bag holds)'


def plan_replay(path: os.PathLike, config_path: Optional[os.PathLike] = None,
                mapping: Optional[Mapping[str, str]] = None,
                config: Optional[tuple] = None) -> ReplayPlan:
    """
    Open a bag and decide which topics feed the estimator; raise ReplayError when none does.

    ``mapping`` maps input or thermocouple names (``current_A``, ...,
    ``measured/frame``, ``ambient``) to topics, replacing the defaults.
    ``config`` (a :func:`choose_config` tuple) is used instead of choosing one
    for this bag, e.g. one configuration for several bags.
    """
    try:
        info = open_bag(path)
    except BagError as exc:
        raise ReplayError(str(exc)) from exc
    cfg, source, text = config if config is not None else choose_config(info, config_path)
    mapping = dict(mapping or {})
    known = set(INPUTS) | {'dp_Pa', 'ambient'} | {f'measured/{tc}' for tc in
                                                  interface.THERMOCOUPLES}
    unknown = sorted(set(mapping) - known)
    if unknown:
        raise ReplayError(f'cannot map {unknown[0]!r}: the names are '
                          f'{", ".join(sorted(known))}')
    wanted = sensor_inputs(cfg)
    cfg, wanted, source = _match_pressure_inputs(cfg, wanted, source, info, mapping)
    inputs, missing = {}, []
    for name in wanted:
        topic = mapping.get(name, interface.INPUT_TOPICS[name])
        found = info.topics.get(topic)
        if found is None:
            missing.append(name)
            continue
        if found.type_name != interface.INPUT_TYPES[name]:
            raise ReplayError(f'{info.path}: topic {topic} (input {name}) holds '
                              f'{found.type_name}; expected {interface.INPUT_TYPES[name]}')
        inputs[name] = topic
    if not inputs:
        listing = ', '.join(f'{t} ({i.type_name})' for t, i in sorted(info.topics.items()))
        raise ReplayError(
            f'{info.path}: no topic of the mapping is in the bag (looked for '
            f'{", ".join(mapping.get(n, interface.INPUT_TOPICS[n]) for n in wanted)}); the bag '
            f'has: {listing or "no topics"}. Map them with --map name=/topic.')
    thermocouples = {}
    for tc in interface.THERMOCOUPLES:
        topic = mapping.get(f'measured/{tc}', f'{interface.MEASURED_PREFIX}/{tc}')
        found = info.topics.get(topic)
        if found is not None and found.type_name == interface.TEMPERATURE:
            thermocouples[tc] = topic
    amb = mapping.get('ambient', interface.AMBIENT_TOPIC)
    ambient = amb if (amb in info.topics
                      and info.topics[amb].type_name == interface.TEMPERATURE) else None
    return ReplayPlan(cfg=cfg, config_source=source, config_yaml=text, inputs=inputs,
                      missing=missing, thermocouples=thermocouples, ambient=ambient, info=info)


@dataclass
class ReplayOptions:
    """What a replay runs with besides its bag: the options of ``wet-eha-thermal replay``."""

    config_path: Optional[Path] = None
    mapping: Dict[str, str] = field(default_factory=dict)
    output_rate_Hz: float = 10.0
    report: bool = True
    open_loop: bool = False       # estimator.correction off: the thermocouples only compared
    outlook: bool = True          # the current limits, forecast and margin (off: faster)

    def plan(self, path: os.PathLike) -> ReplayPlan:
        """Return the :func:`plan_replay` of the bag ``path`` under these options."""
        plan = plan_replay(path, self.config_path, self.mapping)
        if self.open_loop:
            plan.cfg = with_values(plan.cfg, {'estimator.correction.enabled': False})
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
