"""
The 2-D cross-section of one slot pitch, against a one-slice network of the same problem.

Frame, contact gap, yoke, tooth with its tip, slot liner and winding,
axially adiabatic, per metre of stack (:func:`slot_pitch`); the same problem
built by the production builder (:func:`slice_motor`, :func:`slot_network`);
the problem of one slice of the full network, its axial heat flows as
sources, each winding layer's in its own radial band (:func:`slice_problem`:
the FE peak the published hot spot is checked against); and the
winding-to-teeth coupling the r-z model takes from it (:func:`slot_coupling`).
"""

from dataclasses import dataclass, replace
import re
from typing import Dict, Tuple

import numpy as np
from skfem import asm, Basis, LinearForm

from .fe_grid import Block, GridFE
from .network_nodes import source_names
from ..model.motor import MotorInputs, WetMotor


@dataclass(frozen=True)
class SlotProblem:
    """
    The 2-D problem of one operating point: losses of the whole machine per metre of stack.

    Copper, yoke and teeth losses (W/m); h (W/(m^2 K)) of the frame barrel to
    ambient and of the bore to the airgap oil; the ambient and oil temperatures (K);
    heat into the frame (W/m: a slice's axial inflow, spread over the frame).
    """

    copper_W_m: float
    yoke_W_m: float
    teeth_W_m: float
    h_ambient_W_m2K: float
    h_bore_W_m2K: float
    ambient_K: float
    oil_K: float
    frame_W_m: float = 0.0
    #: the copper's heat in radial bands of equal depth, slot bottom first (W/m, summing
    #: to ``copper_W_m``): a slice's layers, each with its own axial gain; () uniform
    copper_bands_W_m: Tuple[float, ...] = ()


def slot_problem(motor: WetMotor, u: MotorInputs) -> SlotProblem:
    """Read the 2-D problem from a network solved at ``u``: its losses and coefficients."""
    c = motor.cfg
    names, P = source_names(motor), motor.power_W
    per_m = {p: sum(w for nm, w in zip(names, P) if nm.startswith(p + '.')) / c.stack_length_m
             for p in ('winding', 'yoke', 'teeth')}
    G = motor.net.coefficients_in_use()[0]
    ends = motor.net.link_ends(motor.ambient_links)
    frame = [k for k, (a, _) in enumerate(ends)
             if a < motor.net.n and motor.net.node_names[a].startswith('frame.')]
    h_amb = (G[np.array(motor.ambient_links)[frame]].sum()
             / np.asarray(motor.ambient_areas)[frame].sum())
    h_bore = (G[motor.gap_links_stator].sum()
              / (2 * np.pi * c.stator.bore_radius_m * c.stack_length_m))
    return SlotProblem(per_m['winding'], per_m['yoke'], per_m['teeth'], float(h_amb),
                       float(h_bore), u.ambient_K, float(motor.T[motor.idx_gap].mean()))


#: the parts of the slot pitch, as the network names them
PITCH_PARTS = ('frame', 'yoke', 'teeth', 'winding')


def slice_problem(motor: WetMotor, u: MotorInputs, i: int) -> SlotProblem:
    """
    Return the 2-D problem of slice ``i`` (1-based) of a network solved at ``u``.

    Each part's sources in the slice plus the heat it gains along the stack
    (through its blocks' axial junctions, from the neighbouring slices, end
    windings and frame ends), spread over the part as the FE spreads its loss;
    the frame's and the bore's h of the slice; the slice's airgap oil. With
    the axial flows as sources the slice is a 2-D problem (exact when they
    are uniform over each part's section).
    """
    net, T = motor.net, motor.T
    names = net.node_names + net.boundary_names
    # a part's nodes in the slice, its radial layers' (``winding.l2.s3``) included
    own = re.compile(rf'({"|".join(PITCH_PARTS)})(\.l\d+)?\.s{i}(\.(outer|inner|ja|jr))?')

    def part(name):
        m = own.fullmatch(name)
        return (m.group(1) + (m.group(2) or '')) if m else None

    layers = [w.name for w in motor.winding_layers]
    heat = dict.fromkeys(PITCH_PARTS[:-1] + tuple(layers), 0.0)
    for name, w in zip(source_names(motor), motor.power_W):
        if part(name):
            heat[part(name)] += float(w)
    flows = net.link_heat_flows(T, motor.boundaries(u))
    cut = {'ambient', f'gap_oil.s{i}'}         # the 2-D problem's own boundaries
    for k, (a, b) in enumerate(net.link_ends(np.arange(flows.size))):
        pa, pb = part(names[a]), part(names[b])
        if pa and not pb and names[b] not in cut:
            heat[pa] -= float(flows[k])
        elif pb and not pa and names[a] not in cut:
            heat[pb] += float(flows[k])
    bands = tuple(heat[w] / motor.dz for w in layers)
    c, dz = motor.cfg, motor.dz
    G = net.coefficients_in_use()[0]
    frame = [k for k, (a, _) in zip(motor.ambient_links, net.link_ends(motor.ambient_links))
             if names[a] == f'frame.s{i}.outer']
    h_amb = G[frame].sum() / (2 * np.pi * c.frame.outer_radius_m * dz)
    h_bore = G[motor.gap_links_stator[i - 1]] / (2 * np.pi * c.stator.bore_radius_m * dz)
    return SlotProblem(sum(bands), heat['yoke'] / dz, heat['teeth'] / dz,
                       float(h_amb), float(h_bore), u.ambient_K,
                       float(T[net.index(f'gap_oil.s{i}')]), heat['frame'] / dz, bands)


def slot_pitch(c, prob: SlotProblem, h_m: float) -> Tuple[GridFE, Dict[str, float]]:
    """
    Solve one slot pitch of motor config ``c`` (2-D, per metre); return the model and results.

    Radial-sided tooth of angular share ``tooth_fraction`` (the network's
    annulus share), centred on the pitch's sides; the tooth tips close the slot
    over the whole pitch from the bore to ``tooth_tip_depth_m`` (the network
    joins the slot's inner liner to the bore); the liner a thin layer on the
    slot's four sides; the frame fit a thin layer; the copper's heat uniform
    over each of the problem's radial bands. Results: winding mean and
    peak, teeth (tips included), yoke and frame means (K); the heat (W/m, whole
    machine) through the bore, the frame barrel and the slot sides.
    """
    fr, st, wd = c.frame, c.stator, c.winding
    pitch = 2 * np.pi / c.slots
    half = 0.5 * st.tooth_fraction * pitch
    r_tip = st.bore_radius_m + st.tooth_tip_depth_m
    k_fe, k_w = st.material.k_radial_W_mK, wd.k_radial_W_mK
    bands = prob.copper_bands_W_m or (prob.copper_W_m,)
    radii = np.linspace(st.yoke_inner_radius_m, r_tip, len(bands) + 1)
    blocks = [Block('frame', 'frame', (fr.inner_radius_m, fr.outer_radius_m), (0, pitch),
                    (fr.material.k_radial_W_mK,) * 2),
              Block('yoke', 'stator', (st.yoke_inner_radius_m, st.outer_radius_m), (0, pitch),
                    (k_fe, k_fe)),
              Block('teeth', 'stator', (st.bore_radius_m, r_tip), (0, pitch), (k_fe, k_fe)),
              Block('teeth', 'stator', (r_tip, st.yoke_inner_radius_m), (0, half), (k_fe, k_fe)),
              Block('teeth', 'stator', (r_tip, st.yoke_inner_radius_m), (pitch - half, pitch),
                    (k_fe, k_fe))]
    # the winding in bands of the given heats, slot bottom first (one block when uniform)
    blocks += [Block('winding', 'winding', (r_in, r_out), (half, pitch - half), (k_w, k_w))
               for r_out, r_in in zip(radii[:-1], radii[1:])]
    wind = list(range(5, len(blocks)))
    fe = GridFE(blocks, h_m, axisymmetric=False)
    liner = wd.liner_conductivity_W_mK / wd.liner_thickness_m
    fe.add_contact('frame fit', fe.face([0], 'inner'), 'stator',
                   st.contact_gap_conductivity_W_mK / st.frame_contact_gap_m)
    fe.add_contact('slot bottom', fe.face(wind[:1], 'outer'), 'stator', liner)
    fe.add_contact('slot top', fe.face(wind[-1:], 'inner'), 'stator', liner)
    fe.add_contact('slot sides', fe.face(wind, 'front') + fe.face(wind, 'rear'), 'stator',
                   liner)
    for k, heat in zip(wind, bands):
        fe.add_source([k], heat / c.slots)
    fe.add_source([1], prob.yoke_W_m / c.slots)
    fe.add_source([2, 3, 4], prob.teeth_W_m / c.slots)
    if prob.frame_W_m:
        fe.add_source([0], prob.frame_W_m / c.slots)
    outer, bore = fe.face([0], 'outer'), fe.face([2], 'inner')
    fe.add_link('frame', outer, prob.h_ambient_W_m2K * fe.area(outer), prob.ambient_K)
    fe.add_link('bore', bore, prob.h_bore_W_m2K * fe.area(bore), prob.oil_K)
    T = fe.solve()
    return fe, {'winding_mean': fe.mean(wind, T), 'winding_peak': fe.peak(wind, T),
                'teeth': fe.mean([2, 3, 4], T), 'yoke': fe.mean([1], T),
                'frame': fe.mean([0], T),
                'bore_W_m': c.slots * fe.link_flow(fe.links[1], T),
                'frame_W_m': c.slots * fe.link_flow(fe.links[0], T),
                'slot_sides_W_m': c.slots * fe.contact_flow('slot sides', T)}


def slice_motor(c, oil, prob: SlotProblem) -> Tuple[WetMotor, MotorInputs]:
    """
    Return the 2-D problem built by the production builder: a one-slice ``WetMotor`` of ``c``.

    Everything at the ends and the rotor are cut off (end-space, end-cap,
    frame-end and rotor-to-oil links to zero, no end-winding or friction loss):
    they are then dead ends that carry no heat, and the slice is the axially
    adiabatic cross-section. The frame barrel and the bore get the problem's h,
    and an oil flow so large that the airgap oil sits at the problem's oil
    temperature. The motor is solved: its ``T`` and ``power_W`` are set.
    """
    m = WetMotor(replace(c, slices=1), oil)
    u = MotorInputs(0.0, 0.0, prob.oil_K, 1e-3, prob.ambient_K, 0.0)
    m.refresh(np.full(m.net.n, prob.oil_K), u)
    net, L = m.net, c.stack_length_m
    ends = net.link_ends(m.ambient_links)
    is_frame = np.array([a < net.n and net.node_names[a].startswith('frame.') for a, _ in ends])
    net.set_conductances(m.ambient_links, np.where(is_frame, prob.h_ambient_W_m2K
                                                   * np.asarray(m.ambient_areas), 0.0))
    net.set_conductances(m.cap_links, 0.0)
    net.set_conductances(m.end_links, 0.0)
    # the rotor too: the frame ends, caps and bearings would join it to the stator
    net.set_conductances(m.gap_links_rotor, 0.0)
    net.set_conductances(m.gap_links_stator, prob.h_bore_W_m2K * 2 * np.pi
                         * c.stator.bore_radius_m * L)
    net.set_advection_rates(m.adv, 1e9)
    P = np.zeros(net.ns)
    per_m = {w.mean[0]: prob.copper_W_m * share for w, share in zip(m.winding_layers,
                                                                    m.layer_share)}
    per_m.update({'yoke.s1': prob.yoke_W_m, 'teeth.s1': prob.teeth_W_m})
    for k, nm in enumerate(source_names(m)):
        P[k] = per_m.get(nm, 0.0) * L
    m.power_W = P
    m.T = net.steady_state(m.boundaries(u), P)
    return m, u


def slot_network(c, oil, prob: SlotProblem) -> Dict[str, float]:
    """Solve :func:`slice_motor`; return the figures :func:`slot_pitch` returns (K, W/m)."""
    m, u = slice_motor(c, oil, prob)
    net, T, L = m.net, m.T, c.stack_length_m
    flows = net.link_heat_flows(T, m.boundaries(u))
    frame_links = [k for k, (a, _) in zip(m.ambient_links, net.link_ends(m.ambient_links))
                   if a < net.n and net.node_names[a].startswith('frame.')]
    t = {p: float(T[net.index(p + '.s1')]) for p in ('teeth', 'yoke', 'frame')}
    t.update({'winding_mean': float(m.winding_slices_K(T)[0]),
              'bore_W_m': float(flows[m.gap_links_stator].sum()) / L,
              'frame_W_m': float(flows[frame_links].sum()) / L})
    return t


def slot_coupling(fe: GridFE, c) -> float:
    """
    Return the slot-to-teeth conductance per volume of the tooth annulus (W/(m^3 K)).

    From a solved :func:`slot_pitch`: the heat through the slot sides over
    the integral of (winding mean - tooth mean) at each radius, the means taken
    over each grid row of the slot and of the teeth. This is the coupling of the
    two continua (winding and teeth) of the r-z model: q = g (T_w - T_t).
    """
    T = fe.T
    q = fe.contact_flow('slot sides', T)
    integral = 0.0
    for i in np.unique(fe.row[np.isin(fe.owner, [3, 4] + fe.blocks_of('winding'))]):
        means, area = [], 0.0
        for blocks in (fe.blocks_of('winding'), [3, 4]):
            els = np.flatnonzero(np.isin(fe.owner, blocks) & (fe.row == i))
            wts = asm(LinearForm(lambda v, w: v), Basis(fe.mesh, fe.elem, elements=els))
            means.append(float(wts @ T[:fe.n]) / wts.sum())
            area += wts.sum()
        integral += (means[0] - means[1]) * area
    return q / integral
