"""
The uncertain parameters of a configuration, and configurations perturbed by them.

The configuration's ``uncertainty`` section states a 1 sigma for each
uncertain parameter (:mod:`~wet_eha_thermal.config_uncertainty`). Here they
become :class:`Perturbation` s: the configuration with one parameter moved by
one sigma (the sensitivity copies of :mod:`~wet_eha_thermal.estimator.uncertainty`
and the maps' sensitivity bars), the structural alternatives (finer slices,
the other laws), and seeded draws of every parameter at once (a rig "as
built": the simulated rig's truth and the coverage tests).
"""

import dataclasses
import math
from typing import Any, Dict, List, NamedTuple, Optional

import numpy as np

from ..config import Config, config_value, ConfigError, LAW_KEYS, with_values
from ..config_spec import check_value, choices_of


#: a draw's standard normal deviates are cut at this many sigma
TRUNCATE = 2.5


class Perturbation(NamedTuple):
    """One perturbed configuration: its name, the values it sets, and the configuration."""

    name: str                  # the dotted key, or the structural alternative
    values: Dict[str, Any]     # the keys it sets, to what
    cfg: Config
    step: float                # the parameter's move in its unit (+-1 sigma); nan: structural


def _meta(cfg: Config, key: str) -> dict:
    """Return the spec metadata of the dotted ``key``."""
    node: Any = cfg
    *parents, last = key.split('.')
    for part in parents:
        node = getattr(node, part)
    return dict({f.name: f for f in dataclasses.fields(node)}[last].metadata)


def replaced(cfg: Config, key: str, value: Any) -> Config:
    """
    Return ``cfg`` with the dotted ``key`` set to ``value``, checked, quicker than ``with_values``.

    The value is checked against the key's range and its section's own
    consistency check runs; the rest of the configuration is the one
    already validated, shared, not rebuilt (a model copy per uncertain
    parameter: 30 full validations would cost seconds at every start).
    """
    *parents, last = key.split('.')
    chain = [cfg]
    for part in parents:
        chain.append(getattr(chain[-1], part))
    where = '.'.join(parents)
    new = dataclasses.replace(chain[-1], **{last: check_value(key, value, type(
        config_value(cfg, key)), _meta(cfg, key))})
    check = getattr(new, 'check', None)
    if check is not None:
        check(where)
    for node, part in zip(reversed(chain[:-1]), reversed(parents)):
        new = dataclasses.replace(node, **{part: new})
    return new


def sigmas(cfg: Config) -> Dict[str, float]:
    """Return each uncertain parameter's 1 sigma: of its log if relative, else in its unit."""
    return {key: p.relative_sigma if p.relative_sigma is not None else p.sigma
            for key, p in cfg.uncertainty.parameters.items()}


def _moved(cfg: Config, key: str, sigma: float) -> float:
    """
    Return the parameter moved by one sigma.

    A relative sigma moves it down by the factor exp(sigma): a temperature
    is convex in a conductance (it goes as 1/h), so the step down gives the
    larger of the two differences; for a heat, linear, either is the same.
    An absolute sigma moves it up, or down when up leaves the key's range.
    """
    nominal = config_value(cfg, key)
    meta = _meta(cfg, key)
    if cfg.uncertainty.parameters[key].relative_sigma is not None:
        steps = (nominal * math.exp(-sigma),)
    else:
        steps = (nominal + sigma, nominal - sigma)
    for value in steps:
        try:
            return check_value(key, value, float, meta)
        except ConfigError:
            continue
    raise ConfigError(f'uncertainty.parameters.{key}: {nominal!r} +- {sigma!r} leaves the '
                      "key's allowed range both ways; state a smaller sigma")


def parameter_perturbations(cfg: Config) -> List[Perturbation]:
    """Return one configuration per uncertain parameter, moved by one sigma."""
    out = []
    for key, sigma in sigmas(cfg).items():
        value = _moved(cfg, key, sigma)
        out.append(Perturbation(key, {key: value}, replaced(cfg, key, value),
                                value - config_value(cfg, key)))
    return out


def structural_perturbations(cfg: Config) -> List[Perturbation]:
    """Return the structural alternatives: finer slices, each other selectable law."""
    s = cfg.uncertainty.structural
    alternatives = []
    # finer slices, as many as allowed (none when the model already has the most)
    finer = min(cfg.motor.slices * s.slices_factor, _meta(cfg, 'motor.slices')['high'])
    if finer > cfg.motor.slices:
        alternatives.append(('motor.slices', finer))
    if s.other_laws:
        for key in LAW_KEYS:
            nominal = config_value(cfg, key)
            alternatives.extend((key, c) for c in choices_of(_meta(cfg, key)) if c != nominal)
    return [Perturbation(f'{key}={value}', {key: value}, replaced(cfg, key, value),
                         float('nan'))
            for key, value in alternatives]


def draw(cfg: Config, seed: int, structural: bool = True,
         scale: float = 1.0) -> Dict[str, Any]:
    """
    Return a seeded draw of every uncertain parameter: the values of a rig "as built".

    Each parameter with its stated sigma times ``scale``: lognormal for a
    relative sigma (a gap or a coefficient is positive: the nominal times
    exp(sigma z)), Gaussian for an absolute one, z truncated at
    +-``TRUNCATE`` (a parameter further off than that is a mistake in the
    stated sigma, not a draw from it), kept
    inside its key's range (a draw outside is clipped to the nearest
    allowed value at a relative 1e-6 inside, so that a gap or a coefficient
    never becomes zero) and inside its calibration bounds, if it has any (a
    rig the calibration could not reach); with ``structural``, each structural alternative
    taken with probability one half (finer slices, the other laws).
    """
    rng = np.random.default_rng(seed)
    values: Dict[str, Any] = {}
    for key, sigma in sigmas(cfg).items():
        nominal = config_value(cfg, key)
        meta = _meta(cfg, key)
        z = scale * min(max(float(rng.standard_normal()), -TRUNCATE), TRUNCATE)
        value = nominal * math.exp(sigma * z) \
            if cfg.uncertainty.parameters[key].relative_sigma is not None else nominal + sigma * z
        lo, hi = meta.get('low'), meta.get('high')
        if lo is not None and value <= lo:
            value = lo + 1e-6 * abs(nominal - lo) if meta['low_open'] else lo
        if hi is not None and value >= hi:
            value = hi - 1e-6 * abs(hi - nominal) if meta['high_open'] else hi
        bounds = cfg.calibration.bounds.get(key)
        if bounds is not None:
            value = min(max(value, bounds[0]), bounds[1])
        values[key] = value
    if structural:
        for p in structural_perturbations(cfg):
            pick = bool(rng.integers(2))
            if pick:
                values.update(p.values)
    return values


def as_built(cfg: Config, seed: Optional[int], scale: float = 1.0) -> Config:
    """Return the configuration of a rig drawn with ``seed`` (None: ``cfg`` itself)."""
    if seed is None or cfg.uncertainty is None:
        return cfg
    return with_values(cfg, draw(cfg, seed, scale=scale))
