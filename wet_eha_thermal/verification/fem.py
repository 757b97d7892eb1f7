"""
Finite-element check of the wet motor's lumped thermal network (scikit-fem).

An independent field solution of the problems the network of
:mod:`wet_eha_thermal.model.motor` solves with Mellor blocks, for
``test/test_fem_check.py`` and ``benchmarks/fem_check.py``; nothing at run
time imports it. Three models, all steady, P1 triangles on a structured
grid whose lines pass through every material boundary:

- :func:`annulus_check`: a hollow cylinder with uniform generation, adiabatic
  inside and cooled outside, against its exact solution (the mesh check);
- :func:`slot_pitch`: the 2-D cross-section of one slot pitch (frame, contact
  gap, yoke, tooth with its tip, slot liner, winding), axially adiabatic,
  against a one-slice network of the same problem (:func:`slot_network`);
- :func:`motor_rz`: the whole motor in r-z, with the airgap and end-space oil
  as lumped unknowns advected along the oil path, against the full network.

The modules by job: :mod:`.fe_grid` the meshing and the FE problem (and the
mesh check), :mod:`.slot_section` the 2-D slot pitch, :mod:`.rz_model` the
r-z motor, :mod:`.network_nodes` what they read of the network's node names;
here the operating points and the comparison of the FE figures with the
network's.

Contacts (frame fit, slot liner, rotor fits, cap joint) are thin layers: the
nodes on the two sides are distinct and joined by h (T_a - T_b) per area.
Oil and ambient links are read from the built network at its operating
point, link by link (h x area as the network has it, spread uniformly over the
surface that stands for the link's node), as are the losses (each source's
power spread uniformly over its part's volume in its slice). The model is
built from node names (``part.sI``, ``part.sI.outer``, ``part.fJ``), so that
it follows the network's builder as long as those names keep their meaning.
"""

from dataclasses import dataclass
from typing import Dict, Tuple

import numpy as np

# the check's names, wherever they live: the test and the benchmark import them from here
from .fe_grid import annulus_check, annulus_exact, Block, GridFE, SIDES  # noqa: F401
from .network_nodes import oil_nodes, source_names, split_name  # noqa: F401
from .rz_model import (bearing_conductance, end_space_box, fit_coupling,  # noqa: F401
                       motor_rz, PERFECT_HTC, rz_blocks)
from .slot_section import (slice_motor, slice_problem, slot_coupling,  # noqa: F401
                           slot_network, slot_pitch, slot_problem, SlotProblem)
from ..model.motor import MotorInputs, WetMotor
from ..units import C_TO_K, L_MIN_PER_M3_S, RPM


# ------------------------------------------------------------------ operating points


def map_inputs(maps, rpm: float, amps: float) -> MotorInputs:
    """Return the inputs of a map point of ``config.MapsJob`` ``maps`` (speed r/min, A)."""
    return MotorInputs(current_sq_mean_A2=amps ** 2, speed_rad_s=rpm * RPM,
                       oil_inlet_K=maps.oil_inlet_C + C_TO_K,
                       oil_flow_m3_s=maps.oil_flow_L_min / L_MIN_PER_M3_S,
                       ambient_K=maps.ambient_C + C_TO_K, case_pressure_Pa=maps.case_pressure_Pa)


ROTOR_PARTS = ('sleeve', 'magnet', 'rotor_core', 'shaft', 'bearing')

# ------------------------------------------------------------------ comparisons
TEMPERATURES = ('winding_mean', 'winding_hottest_block', 'magnet', 'yoke', 'teeth', 'frame',
                'rotor_core', 'shaft', 'airgap_oil_outlet', 'motor_oil_outlet')
HEAT_PATHS = ('bore', 'rotor_to_gap', 'end_spaces', 'frame_to_ambient', 'caps_to_ambient')


def _heat_path(solid: str, other: str) -> str:
    """Return the heat path of a link from node ``solid`` to ``other`` (oil or ambient)."""
    rotor = solid.startswith(ROTOR_PARTS)
    if other.startswith('gap_oil'):
        return 'rotor_to_gap' if rotor else 'bore'
    if other.startswith('end_oil'):
        return 'end_spaces'
    return 'frame_to_ambient' if solid.startswith('frame') else 'caps_to_ambient'


def network_figures(motor: WetMotor, u: MotorInputs) -> Dict[str, float]:
    """
    Return the network's temperatures (degC) and heat paths (W) at its solved state.

    Winding mean, hot spot, magnet, frame and the oil outlets as its outputs
    (conductor-length mean; the peak in the slot; hottest magnet slice; frame
    volume mean over the stack); the hottest winding block (slot slice or end
    winding: what the r-z field resolves); yoke, teeth, rotor core and shaft
    the volume means of their stack slices. Heat paths: the sum over the links
    of each path.
    """
    T, net = motor.T, motor.net
    out = {k: v - C_TO_K for k, v in motor.outputs(T).items()}
    out['winding_hottest_block'] = float(T[motor.idx_copper].max()) - C_TO_K
    for part in ('yoke', 'teeth', 'rotor_core', 'shaft'):
        cyl = motor.parts[part]
        out[part] = float(np.dot([T[net.index(m)] for m in cyl.mean], cyl.volume_m3)
                          / np.sum(cyl.volume_m3)) - C_TO_K
    names = net.node_names + net.boundary_names
    flows = net.link_heat_flows(T, motor.boundaries(u))
    oil, bounds = oil_nodes(net), set(net.boundary_names)
    paths = dict.fromkeys(HEAT_PATHS, 0.0)
    for k, (ia, ib) in enumerate(net.link_ends(np.arange(flows.size))):
        a, b = names[ia], names[ib]
        if b in oil or b in bounds:
            paths[_heat_path(a, b)] += float(flows[k])
        elif a in oil or a in bounds:
            paths[_heat_path(b, a)] -= float(flows[k])
    out.update(paths)
    return out


def fe_figures(fe: GridFE, motor: WetMotor) -> Dict[str, float]:
    """
    Return the r-z model's figures formed as :func:`network_figures` forms the network's.

    Winding mean: the block means of the slot slices and end windings weighted
    by the network's conductor-length shares; the hottest of those block means
    (``winding_peak``: the hottest point of the winding continua: the r-z
    field averages the slot across the pitch, so it is not the slot's peak);
    magnet: the hottest magnet slice mean; the other parts their stack means;
    the oil outlets the lumped oil unknowns.
    """
    def block_mean(node):
        part, sl, _ = split_name(node)
        return fe.mean(fe.blocks_of(part, sl))
    wind = np.array([block_mean(m) for m in motor.copper_nodes])
    share = np.asarray(motor.copper_share)
    out = {'winding_mean': float(wind @ share / share.sum()),
           'winding_hottest_block': float(wind.max()),
           'winding_peak': max(fe.peak(fe.blocks_of(p)) for p in
                               {split_name(m)[0] for m in motor.copper_nodes}),
           'magnet': max(fe.mean([k]) for k in fe.blocks_of('magnet'))}
    for part in ('yoke', 'teeth', 'frame', 'rotor_core', 'shaft'):
        out[part] = fe.mean(fe.blocks_of(part))
    out['airgap_oil_outlet'] = fe.T[fe.node(motor.gap[-1])]
    out['motor_oil_outlet'] = fe.T[fe.node(motor.oil_nodes[-1])]
    out = {k: float(v) - C_TO_K for k, v in out.items()}
    paths = dict.fromkeys(HEAT_PATHS, 0.0)
    for lk in fe.links:
        solid, other = lk.name.split('|')
        paths[_heat_path(solid, other)] += fe.link_flow(lk)
    out.update(paths)
    return out


@dataclass
class PointCheck:
    """One map point: the network, its 2-D slot pitch and the r-z model, solved."""

    rpm: float
    amps: float
    motor: WetMotor
    inputs: MotorInputs
    slot_fe: GridFE
    slot: Dict[str, float]
    slot_net: Dict[str, float]
    coupling: Tuple[float, float]
    rz: GridFE
    network: Dict[str, float]
    fe: Dict[str, float]


def check_point(cfg, oil, rpm: float, amps: float, h_slot_m: float,
                h_rz_m: float) -> PointCheck:
    """
    Solve one map point of ``cfg.maps``: the network, the slot pitch, the r-z model.

    The slot pitch runs at this point's losses and coefficients; its solution
    gives the winding-teeth coupling of the r-z model.
    """
    motor = WetMotor(cfg.motor, oil)
    u = map_inputs(cfg.maps, rpm, amps)
    motor.steady_state(u)
    prob = slot_problem(motor, u)
    slot_fe, slot = slot_pitch(cfg.motor, prob, h_slot_m)
    g = fit_coupling(cfg.motor, oil, prob, slot_fe, slot)
    rz = motor_rz(motor, u, g, h_rz_m)
    return PointCheck(rpm, amps, motor, u, slot_fe, slot, slot_network(cfg.motor, oil, prob),
                      g, rz, network_figures(motor, u), fe_figures(rz, motor))
