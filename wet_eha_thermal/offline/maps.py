"""
Motor maps: steady-state temperatures, losses and heat paths versus speed and current.

The job behind ``wet-eha-thermal maps``: for a given oil inlet temperature
and flow it solves the motor's nonlinear steady state at every operating
point of two sweeps (speed at fixed current, current at fixed speed) and
reports winding mean and hot-spot, frame, magnet and oil outlet temperatures,
where the heat is made (every loss of :data:`~.model.motor.LOSS_NAMES`) and
where it goes (through the bore, through the end spaces, to ambient, carried
off by the oil) at each point.
"""

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np

from ..config import Config
from ..model import quantity_table
from ..model.motor import LOSS_NAMES, MotorInputs, WetMotor
from ..model.oil import get_oil
from ..model.validity import ValidityLog
from ..output_files import atomic, pyplot, save_figure
from ..units import C_TO_K, L_MIN_PER_M3_S, RPM

TEMPERATURES = ('winding_mean', 'winding_hotspot', 'end_winding_hotspot', 'frame', 'magnet',
                'airgap_oil_outlet', 'motor_oil_outlet')
#: the heat paths of :meth:`~.model.motor.WetMotor.heat_balance` a map reports
PATHS = ('bore', 'end_spaces', 'to_ambient', 'to_oil')


@dataclass
class MapPoint:
    """One steady operating point: temperatures in degC, losses and heat paths in W."""

    sweep: str
    speed_rpm: float
    current_A: float
    temperatures_C: Dict[str, float]
    losses_W: Dict[str, float]
    heat_W: Dict[str, float]

    def row(self) -> Dict[str, float]:
        """Flatten into one CSV row with units in the column names."""
        r = {'sweep': self.sweep, 'speed_rpm': self.speed_rpm, 'current_A': self.current_A}
        r.update({f'{k}_C': round(v, 4) for k, v in self.temperatures_C.items()})
        r.update({f'{k}_W': round(v, 4) for k, v in self.losses_W.items()})
        r['total_loss_W'] = round(sum(self.losses_W.values()), 4)
        r.update({f'{k}_W': round(self.heat_W[k], 4) for k in PATHS})
        return r


def map_points(cfg: Config) -> List[Tuple[str, float, float]]:
    """Return the operating points of both sweeps: (sweep, r/min, A RMS)."""
    job = cfg.maps
    return ([('speed', s, job.sweep_current_A) for s in job.speeds_rpm]
            + [('current', job.sweep_speed_rpm, i) for i in job.currents_A])


def compute_maps(cfg: Config, progress: Optional[Callable[[int, int, str], None]] = None,
                 log: Optional[ValidityLog] = None) -> List[MapPoint]:
    """Solve every operating point of both sweeps; call ``progress(done, total, label)``."""
    job = cfg.maps
    motor = WetMotor(cfg.motor, get_oil(cfg.fluid.grade), log)
    points = map_points(cfg)
    out = []
    for k, (sweep, rpm, amps) in enumerate(points):
        if progress is not None:
            progress(k, len(points), f'{sweep} sweep: {rpm:.0f} r/min, {amps:g} A')
        u = MotorInputs(current_sq_mean_A2=amps ** 2, speed_rad_s=rpm * RPM,
                        oil_inlet_K=job.oil_inlet_C + C_TO_K,
                        oil_flow_m3_s=job.oil_flow_L_min / L_MIN_PER_M3_S,
                        ambient_K=job.ambient_C + C_TO_K,
                        case_pressure_Pa=job.case_pressure_Pa)
        T = motor.steady_state(u)
        bal = motor.heat_balance(T, u)
        temps = {k_: v - C_TO_K for k_, v in motor.outputs(T).items()}
        out.append(MapPoint(sweep, rpm, amps, temps, dict(motor.losses_W),
                            {k: bal[k] for k in PATHS}))
    if progress is not None:
        progress(len(points), len(points), 'done')
    return out


def format_table(points: List[MapPoint], sweep: str) -> str:
    """Return fixed-width text tables of one sweep: temperatures, then losses and heat paths."""
    pts = [p for p in points if p.sweep == sweep]
    head = (f'{"speed":>7} {"current":>7} | {"wind.mean":>9} {"hot-spot":>8} {"end h-s":>7} '
            f'{"frame":>6} {"magnet":>6} {"gap out":>7} {"oil out":>7}')
    units = (f'{"r/min":>7} {"A":>7} | {"degC":>9} {"degC":>8} {"degC":>7} {"degC":>6} '
             f'{"degC":>6} {"degC":>7} {"degC":>7}')
    lines = [head, units, '-' * len(head)]
    for p in pts:
        t = p.temperatures_C
        lines.append(
            f'{p.speed_rpm:7.0f} {p.current_A:7.1f} | {t["winding_mean"]:9.1f} '
            f'{t["winding_hotspot"]:8.1f} {t["end_winding_hotspot"]:7.1f} {t["frame"]:6.1f} '
            f'{t["magnet"]:6.1f} '
            f'{t["airgap_oil_outlet"]:7.1f} {t["motor_oil_outlet"]:7.1f}')
    # where the heat is made, then where it goes (W)
    made = (('copper', ('copper_slot', 'copper_end')), ('iron', ('core_yoke', 'core_teeth')),
            ('magnet', ('magnet',)), ('sleeve', ('sleeve',)), ('r.core', ('rotor_core',)),
            ('gap fr', ('gap_friction',)), ('ends fr', ('end_face_friction',)),
            ('bearing', ('bearings',)))
    goes = (('bore', 'bore'), ('end sp.', 'end_spaces'), ('ambient', 'to_ambient'),
            ('by oil', 'to_oil'))
    head = (f'{"speed":>7} {"current":>7} | ' + ' '.join(f'{n:>7}' for n, _ in made)
            + ' | ' + ' '.join(f'{n:>7}' for n, _ in goes))
    lines += ['', 'Losses (W) and where the heat goes (W):', head, '-' * len(head)]
    for p in pts:
        lines.append(f'{p.speed_rpm:7.0f} {p.current_A:7.1f} | '
                     + ' '.join(f'{sum(p.losses_W[k] for k in keys):7.1f}' for _, keys in made)
                     + ' | ' + ' '.join(f'{p.heat_W[k]:7.1f}' for _, k in goes))
    return '\n'.join(lines)


def write_csv(points: List[MapPoint], path: Path) -> None:
    """Write every point of both sweeps to one CSV file."""
    rows = [p.row() for p in points]
    with atomic(path) as tmp, open(tmp, 'w', newline='') as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def plot_maps(points: List[MapPoint], path: Path, title: str) -> None:
    """Plot temperatures, the loss split and the heat paths of both sweeps to a PNG."""
    plt = pyplot()

    fig, axes = plt.subplots(3, 2, figsize=(13, 11), sharex='col')
    # the heat paths, stacked to the total loss: what the solids give the oil through
    # the bore and the end spaces, the friction made in the oil itself, and ambient
    paths = (('through the bore', lambda p: p.heat_W['bore']),
             ('through the end spaces', lambda p: p.heat_W['end_spaces']),
             ('friction made in the oil', lambda p: p.losses_W['gap_friction']
              + p.losses_W['end_face_friction']),
             ('frame and caps to ambient', lambda p: p.heat_W['to_ambient']))
    for col, (sweep, xkey, xlabel) in enumerate((('speed', 'speed_rpm', 'speed (r/min)'),
                                                 ('current', 'current_A', 'current (A RMS)'))):
        pts = [p for p in points if p.sweep == sweep]
        x = [getattr(p, xkey) for p in pts]
        width = (x[1] - x[0]) * 0.7 if len(x) > 1 else 1.0
        ax = axes[0, col]
        for key in ('winding_mean', 'winding_hotspot', 'end_winding_hotspot', 'frame', 'magnet',
                    'motor_oil_outlet'):
            ax.plot(x, [p.temperatures_C[key] for p in pts], marker='o', ms=3,
                    label=quantity_table.label(key))
        ax.set_ylabel('temperature (degC)')
        ax.grid(True, alpha=0.3)
        held = (f'{pts[0].current_A:g} A' if sweep == 'speed'
                else f'{pts[0].speed_rpm:.0f} r/min')
        ax.set_title(f'versus {sweep}, at {held}')
        ax.legend(fontsize=8)
        ax = axes[1, col]
        bottom = np.zeros(len(pts))
        for key in LOSS_NAMES:
            v = np.array([p.losses_W[key] for p in pts])
            if v.any():
                ax.bar(x, v, width=width, bottom=bottom, label=quantity_table.LOSS_LABELS[key])
                bottom += v
        ax.set_ylabel('where the heat is made (W)')
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, ncol=2)
        ax = axes[2, col]
        bottom = np.zeros(len(pts))
        for label, value in paths:
            v = np.array([value(p) for p in pts])
            ax.bar(x, v, width=width, bottom=bottom, label=label)
            bottom += v
        ax.set_ylabel('where the heat goes (W)')
        ax.set_xlabel(xlabel)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(title)
    save_figure(fig, path)
