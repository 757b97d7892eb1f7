"""
Motor maps: steady-state temperatures and losses versus speed and versus current.

The job behind ``wet-eha-thermal maps``: for a given oil inlet temperature
and flow it solves the motor's nonlinear steady state at every operating
point of two sweeps (speed at fixed current, current at fixed speed) and
reports winding mean and hot-spot, frame, magnet and oil outlet temperatures
with the loss split of each point.
"""

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Dict, List, Optional

import numpy as np

from .config import Config
from .model.motor import C_TO_K, MotorInputs, WetMotor
from .model.oil import get_oil
from .model.validity import ValidityLog
from .outputs import atomic, save_figure

TEMPERATURES = ('winding_mean', 'winding_hotspot', 'frame', 'magnet', 'airgap_oil_outlet',
                'motor_oil_outlet')
LOSSES = ('copper_slot', 'copper_end', 'core_yoke', 'core_teeth', 'oil_friction')
RPM = np.pi / 30.0  # rad/s per r/min


@dataclass
class MapPoint:
    """One steady operating point: temperatures in degC, losses and heat flows in W."""

    sweep: str
    speed_rpm: float
    current_A: float
    temperatures_C: Dict[str, float]
    losses_W: Dict[str, float]
    to_ambient_W: float
    to_oil_W: float

    def row(self) -> Dict[str, float]:
        """Flatten into one CSV row with units in the column names."""
        r = {'sweep': self.sweep, 'speed_rpm': self.speed_rpm, 'current_A': self.current_A}
        r.update({f'{k}_C': round(v, 4) for k, v in self.temperatures_C.items()})
        r.update({f'{k}_W': round(v, 4) for k, v in self.losses_W.items()})
        r['total_loss_W'] = round(sum(self.losses_W.values()), 4)
        r['to_ambient_W'] = round(self.to_ambient_W, 4)
        r['to_oil_W'] = round(self.to_oil_W, 4)
        return r


def compute_maps(cfg: Config, progress: Optional[Callable[[int, int, str], None]] = None,
                 log: Optional[ValidityLog] = None) -> List[MapPoint]:
    """Solve every operating point of both sweeps; call ``progress(done, total, label)``."""
    job = cfg.maps
    motor = WetMotor(cfg.motor, get_oil(cfg.fluid.grade), log)
    points = ([('speed', s, job.sweep_current_A) for s in job.speeds_rpm]
              + [('current', job.sweep_speed_rpm, i) for i in job.currents_A])
    out = []
    for k, (sweep, rpm, amps) in enumerate(points):
        if progress is not None:
            progress(k, len(points), f'{sweep} sweep: {rpm:.0f} r/min, {amps:g} A')
        u = MotorInputs(current_sq_mean_A2=amps ** 2, speed_rad_s=rpm * RPM,
                        oil_inlet_K=job.oil_inlet_C + C_TO_K,
                        oil_flow_m3_s=job.oil_flow_L_min / 60000.0,
                        ambient_K=job.ambient_C + C_TO_K,
                        case_pressure_Pa=job.case_pressure_Pa)
        T = motor.steady_state(u)
        bal = motor.heat_balance(T, u)
        temps = {k_: v - C_TO_K for k_, v in motor.outputs(T).items()}
        out.append(MapPoint(sweep, rpm, amps, temps, dict(motor.losses_W),
                            bal['to_ambient'], bal['to_oil']))
    if progress is not None:
        progress(len(points), len(points), 'done')
    return out


def format_table(points: List[MapPoint], sweep: str) -> str:
    """Return a fixed-width text table of one sweep."""
    head = (f'{"speed":>7} {"current":>7} | {"wind.mean":>9} {"hot-spot":>8} {"frame":>6} '
            f'{"magnet":>6} {"gap out":>7} {"oil out":>7} | {"copper":>6} {"core":>5} '
            f'{"fric.":>6} {"amb.":>5}')
    units = (f'{"r/min":>7} {"A":>7} | {"degC":>9} {"degC":>8} {"degC":>6} {"degC":>6} '
             f'{"degC":>7} {"degC":>7} | {"W":>6} {"W":>5} {"W":>6} {"W":>5}')
    lines = [head, units, '-' * len(head)]
    for p in points:
        if p.sweep != sweep:
            continue
        t, ls = p.temperatures_C, p.losses_W
        lines.append(
            f'{p.speed_rpm:7.0f} {p.current_A:7.1f} | {t["winding_mean"]:9.1f} '
            f'{t["winding_hotspot"]:8.1f} {t["frame"]:6.1f} {t["magnet"]:6.1f} '
            f'{t["airgap_oil_outlet"]:7.1f} {t["motor_oil_outlet"]:7.1f} | '
            f'{ls["copper_slot"] + ls["copper_end"]:6.1f} '
            f'{ls["core_yoke"] + ls["core_teeth"]:5.1f} {ls["oil_friction"]:6.1f} '
            f'{p.to_ambient_W:5.1f}')
    return '\n'.join(lines)


def write_csv(points: List[MapPoint], path: Path) -> None:
    """Write every point of both sweeps to one CSV file."""
    rows = [p.row() for p in points]
    with atomic(path) as tmp, open(tmp, 'w', newline='') as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def plot_maps(points: List[MapPoint], path: Path, title: str) -> None:
    """Plot temperatures (top) and the loss split (bottom) of both sweeps to a PNG."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(12, 8), sharex='col')
    labels = {'winding_mean': 'winding mean', 'winding_hotspot': 'winding hot-spot',
              'frame': 'frame', 'magnet': 'magnet (hottest)',
              'motor_oil_outlet': 'motor oil outlet'}
    for col, (sweep, xkey, xlabel) in enumerate((('speed', 'speed_rpm', 'speed (r/min)'),
                                                 ('current', 'current_A', 'current (A RMS)'))):
        pts = [p for p in points if p.sweep == sweep]
        x = [getattr(p, xkey) for p in pts]
        ax = axes[0, col]
        for key, label in labels.items():
            ax.plot(x, [p.temperatures_C[key] for p in pts], marker='o', ms=3, label=label)
        ax.set_ylabel('temperature (degC)')
        ax.grid(True, alpha=0.3)
        held = (f'{pts[0].current_A:g} A' if sweep == 'speed'
                else f'{pts[0].speed_rpm:.0f} r/min')
        ax.set_title(f'versus {sweep}, at {held}')
        ax.legend(fontsize=8)
        ax = axes[1, col]
        bottom = np.zeros(len(pts))
        for key in LOSSES:
            v = np.array([p.losses_W[key] for p in pts])
            width = (x[1] - x[0]) * 0.7 if len(x) > 1 else 1.0
            ax.bar(x, v, width=width, bottom=bottom, label=key.replace('_', ' '))
            bottom += v
        ax.set_ylabel('loss (W)')
        ax.set_xlabel(xlabel)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(title)
    save_figure(fig, path)
