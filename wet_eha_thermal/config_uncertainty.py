"""
The ``uncertainty`` section: what is not known about the rig, and how the estimator carries it.

Each uncertain parameter of the thermal model (a dotted key of a number under
``motor`` or ``hydraulics``, checked by :class:`~wet_eha_thermal.config.Config`)
has a stated 1 sigma, relative to its configured value or absolute in the
key's unit, and where that figure comes from. The structural part covers
what no parameter does: a copy of the model with finer axial slices and
copies with the other laws the configuration can select, plus a share of
each temperature's rise above ambient. ``estimator/uncertainty.py``
propagates all of them (docs/model.md, Uncertainty).
"""

from dataclasses import dataclass
from typing import Dict, Optional

from .config_spec import ConfigError, spec

#: the keys whose alternative choices the structural copies take (docs/model.md)
LAW_KEYS = ('motor.airgap_nusselt', 'motor.frame.natural_convection')


@dataclass(frozen=True, kw_only=True)
class UncertainParameter:
    """One uncertain parameter: its 1 sigma, relative or absolute, and its source."""

    relative_sigma: Optional[float] = spec(0.0, 2.0, low_open=True, default=None, doc=(
        '1 sigma of the natural logarithm of the value (0.3: about 30 %): a positive '
        'quantity, lognormal'))
    sigma: Optional[float] = spec(0.0, None, low_open=True, default=None, doc=(
        "1 sigma in the key's own unit, Gaussian (a value whose nominal is 0, a fraction)"))
    source: str = spec(doc='where the figure comes from: a reference, a spread, a judgement')

    def check(self, key: str) -> None:
        """Check exactly one of relative_sigma and sigma is given, and a source."""
        if (self.relative_sigma is None) == (self.sigma is None):
            raise ConfigError(f'{key}: give one of relative_sigma or sigma (relative_sigma = '
                              f'{self.relative_sigma!r}, sigma = {self.sigma!r})')
        if not self.source.strip():
            raise ConfigError(f'{key}.source: say where the sigma comes from')


@dataclass(frozen=True, kw_only=True)
class Structural:
    """What no parameter covers: the discretisation, the choice of law, the rest."""

    slices_factor: int = spec(1, 10, default=2, doc=(
        'a copy of the model with this many times motor.slices (at most the 50 allowed): its '
        'difference from the configured model counts as one sigma of the axial '
        'discretisation (1: none)'))
    other_laws: bool = spec(default=True, doc=(
        'copies with each other choice of ' + ' and '.join(LAW_KEYS) + ': the difference '
        'between two laws the literature offers for one surface counts as one sigma'))
    rise_fraction: float = spec(0.0, 1.0, default=0.03, doc=(
        '1 sigma of what no copy covers (the lumped network itself), as a share of each '
        "temperature's rise above ambient"))


@dataclass(frozen=True, kw_only=True)
class Uncertainty:
    """
    The stated uncertainty of the model and its propagation (``estimator/uncertainty.py``).

    Without this section the estimator gives every open-loop estimate the
    constant ``estimator.model_uncertainty_K``.
    """

    copy_period_s: float = spec(0.02, 600.0, default=10.0, doc=(
        'the perturbed copies of the model are stepped over each period of this much '
        "sample time (a whole number of estimator steps) on the estimator's duty; the "
        'uncertainty published until the next period ends is the one at its start'))
    copy_substep_s: float = spec(1e-4, 10.0, default=1.0, doc=(
        "longest sub-step of the copies' oil volumes (s): the copies give differences "
        "between models stepped alike, which a coarser sub-step than the estimate's moves "
        'by about 1 % (docs/model.md, Uncertainty)'))
    parameters: Dict[str, UncertainParameter] = spec(doc=(
        'dotted key of a number under motor or hydraulics: its 1 sigma and source'))
    structural: Structural = spec(default_factory=Structural, doc=(
        'what no parameter covers'))
