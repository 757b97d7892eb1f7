"""
Which unknown matters: the steady hot spot and magnet moved by each uncertain parameter.

The job behind ``wet-eha-thermal sensitivity``: at every operating point of
the motor maps (:mod:`.maps`, the same oil inlet, flow and sweeps) it solves
the motor's steady state with each uncertain parameter of the configuration's
``uncertainty`` section moved by its one sigma
(:func:`~..model.uncertainty.parameter_perturbations`), and with each
structural alternative, and reports how far the winding hot spot and the
magnets move: the engineer's list of what to measure first on the rig. The
case leakage coefficient enters as the motor's oil flow (laminar leakage: the
flow in proportion); the other parameters of the pump and the circuit move
the oil inlet temperature, which a motor map holds: they are listed, not
ranked (their effect is in the propagated uncertainty of a coupled run).
"""

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np

from .maps import map_points
from ..config import Config
from ..model import quantity_table
from ..model.motor import MotorInputs, WetMotor
from ..model.oil import get_oil
from ..model.uncertainty import parameter_perturbations, Perturbation, structural_perturbations
from ..output_files import atomic, save_figure
from ..units import C_TO_K, RPM

#: the quantities ranked
RANKED = ('winding_hotspot', 'magnet')
#: the pump's leakage into the case: the motor's cooling flow, in proportion
LEAKAGE_KEY = 'hydraulics.pump.external_leak_coeff_m3'


@dataclass
class Sensitivity:
    """Each perturbation's move (K) of each ranked quantity at each map point."""

    points: List[Tuple[str, float, float]]      # (sweep, r/min, A)
    base_C: Dict[str, np.ndarray]               # the nominal steady temperatures (degC)
    moves_K: Dict[str, Dict[str, np.ndarray]]   # perturbation -> quantity -> per point
    sigmas: Dict[str, str]                      # perturbation -> its sigma, in words
    not_ranked: List[str]                       # parameters a motor map cannot see

    def largest(self, quantity: str) -> List[Tuple[str, float, int]]:
        """Return (perturbation, signed move K, point) at its largest |move|, largest first."""
        out = []
        for name, moves in self.moves_K.items():
            k = int(np.argmax(np.abs(moves[quantity])))
            out.append((name, float(moves[quantity][k]), k))
        return sorted(out, key=lambda r: -abs(r[1]))


def _steady(cfg: Config, motor: WetMotor, points, flow_scale: float) -> Dict[str, np.ndarray]:
    """Return the ranked quantities' steady temperatures (degC) of ``motor`` at ``points``."""
    job = cfg.maps
    out = {q: np.empty(len(points)) for q in RANKED}
    for k, (_, rpm, amps) in enumerate(points):
        u = MotorInputs(current_sq_mean_A2=amps ** 2, speed_rad_s=rpm * RPM,
                        oil_inlet_K=job.oil_inlet_C + C_TO_K,
                        oil_flow_m3_s=flow_scale * job.oil_flow_L_min / 60000.0,
                        ambient_K=job.ambient_C + C_TO_K, case_pressure_Pa=job.case_pressure_Pa)
        temps = motor.outputs(motor.steady_state(u))
        for q in RANKED:
            out[q][k] = temps[q] - C_TO_K
    return out


def _sigma_text(cfg: Config, p: Perturbation) -> str:
    """Return a perturbation's step in words: the factor or the move, or the alternative."""
    stated = cfg.uncertainty.parameters.get(p.name)
    if stated is None:
        return 'alternative'
    if stated.relative_sigma is not None:
        return f'x exp(-{stated.relative_sigma:g})'
    return f'{p.step:+g}'


def compute_sensitivity(cfg: Config,
                        progress: Optional[Callable[[int, int, str], None]] = None
                        ) -> Sensitivity:
    """Solve the map points, nominal and with each perturbation; call ``progress``."""
    oil = get_oil(cfg.fluid.grade)
    points = map_points(cfg)
    base = _steady(cfg, WetMotor(cfg.motor, oil), points, 1.0)
    moves, sigmas, not_ranked = {}, {}, []
    todo = parameter_perturbations(cfg) + structural_perturbations(cfg)
    for k, p in enumerate(todo):
        if progress is not None:
            progress(k, len(todo), p.name)
        flow = 1.0
        if p.name == LEAKAGE_KEY:
            flow = p.cfg.hydraulics.pump.external_leak_coeff_m3 \
                / cfg.hydraulics.pump.external_leak_coeff_m3
        elif p.name.startswith('hydraulics.'):
            not_ranked.append(p.name)
            continue
        got = _steady(cfg, WetMotor(p.cfg.motor, oil), points, flow)
        moves[p.name] = {q: got[q] - base[q] for q in RANKED}
        sigmas[p.name] = _sigma_text(cfg, p)
    if progress is not None:
        progress(len(todo), len(todo), 'done')
    return Sensitivity(points, base, moves, sigmas, not_ranked)


def _point_text(point: Tuple[str, float, float]) -> str:
    """Return a map point in words."""
    return f'{point[1]:.0f} r/min {point[2]:g} A'


def format_table(result: Sensitivity) -> str:
    """Return the ranking: each perturbation's largest move of the hot spot and the magnet."""
    hot = {name: (move, k) for name, move, k in result.largest('winding_hotspot')}
    mag = {name: (move, k) for name, move, k in result.largest('magnet')}
    head = (f'{"parameter (1 sigma)":<58} {"hot spot K":>10} {"at":>17} {"magnet K":>9} '
            f'{"at":>17}')
    lines = [head, '-' * len(head)]
    for name in hot:
        (h, kh), (m, km) = hot[name], mag[name]
        lines.append(f'{name + " (" + result.sigmas[name] + ")":<58} {h:+10.2f} '
                     f'{_point_text(result.points[kh]):>17} {m:+9.2f} '
                     f'{_point_text(result.points[km]):>17}')
    return '\n'.join(lines)


def write_csv(result: Sensitivity, path: Path) -> None:
    """Write one row per perturbation and map point: the moves (K) and the nominal (degC)."""
    with atomic(path) as tmp, open(tmp, 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['perturbation', 'sigma', 'sweep', 'speed_rpm', 'current_A',
                    *(f'{q}_C' for q in RANKED), *(f'd_{q}_K' for q in RANKED)])
        for name, moves in result.moves_K.items():
            for k, (sweep, rpm, amps) in enumerate(result.points):
                w.writerow([name, result.sigmas[name], sweep, rpm, amps,
                            *(round(float(result.base_C[q][k]), 4) for q in RANKED),
                            *(round(float(moves[q][k]), 4) for q in RANKED)])


def plot_tornado(result: Sensitivity, path: Path, title: str) -> None:
    """Plot each perturbation's largest move of the hot spot and the magnet as bars, a tornado."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    order = [name for name, _, _ in result.largest('winding_hotspot')][::-1]
    fig, axes = plt.subplots(1, 2, figsize=(13, 0.3 * len(order) + 1.8), sharey=True)
    for ax, q in zip(axes, RANKED):
        largest = {name: move for name, move, _ in result.largest(q)}
        v = [largest[name] for name in order]
        ax.barh(range(len(order)), v, color=['tab:red' if x > 0 else 'tab:blue' for x in v])
        ax.axvline(0.0, color='k', lw=0.8)
        ax.set_xlabel(f'{quantity_table.label(q)}: largest move over the map points (K)')
        ax.grid(True, axis='x', alpha=0.3)
    axes[0].set_yticks(range(len(order)))
    axes[0].set_yticklabels([f'{n} ({result.sigmas[n]})' for n in order], fontsize=7)
    fig.suptitle(title)
    save_figure(fig, path)
