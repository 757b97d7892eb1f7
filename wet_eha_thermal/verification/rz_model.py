"""
The whole motor in r-z, with the airgap and end-space oil as lumped unknowns.

Built from the network solved at an operating point (:func:`motor_rz`): its
contacts from the configuration, its oil and ambient links read link by link
(h x area as the network has it, spread uniformly over the surface that stands
for the link's node), its losses (each source's power spread uniformly over
its part's volume in its slice) and the oil's advection chain. The two
effective coefficients of the tooth/slot annulus are fitted to the 2-D slot
pitch (:func:`fit_coupling`).
"""

from typing import Dict, List, Tuple

import numpy as np

from .fe_grid import Block, GridFE
from .network_nodes import oil_nodes, source_names, split_name
from .slot_section import slice_motor, slot_coupling, SlotProblem
from ..model.motor import MotorInputs, WetMotor

#: h (W/(m^2 K)) of a contact that is perfect (the bearing ring to the cap)
PERFECT_HTC = 1e7


def bearing_conductance(motor: WetMotor, side: str) -> float:
    """
    Return the network's conductance (W/K) from the shaft end to the end cap at ``side``.

    A direct link, or the series of the links through a ``bearing_<side>`` node.
    """
    net = motor.net
    names = net.node_names + net.boundary_names
    G = net.coefficients_in_use()[0]
    ends = net.link_ends(np.arange(G.size))
    shaft, cap, brg = f'shaft_end_{side}', f'end_cap_{side}', f'bearing_{side}'

    def between(p, q):
        return sum(G[k] for k, (a, b) in enumerate(ends)
                   if {names[a].split('.')[0], names[b].split('.')[0]} == {p, q})
    direct = between(shaft, cap)
    if brg in names:
        g1, g2 = between(shaft, brg), between(brg, cap)
        direct += g1 * g2 / (g1 + g2)
    return float(direct)


def rz_blocks(motor: WetMotor) -> List[Block]:
    """
    Return the blocks of the r-z model of ``motor``'s configuration (z = 0 at the front face).

    The tooth/slot annulus is two continua on the same cells, each with its
    volume share: teeth (``tooth_fraction``) and winding (the rest), with the
    conductivities of their material times that share (radial: the tooth and the
    slot conduct in parallel). The end windings continue the winding continuum.
    The tooth tips are iron over the whole pitch (closed slots, as in
    :func:`slot_pitch`). Each cap carries its hub (the rotor's radius, from the
    cap to ``rotor_clearance_m`` from the rotor's end face, one material with
    the cap), as the network draws it. Each bearing is a ring in the cap's
    bore, shaft to cap, whose conductivity gives the network's bearing
    conductance.
    """
    c = motor.cfg
    fr, st, wd, ro, es = c.frame, c.stator, c.winding, c.rotor, c.end_spaces
    n, Ls = c.slices, c.stack_length_m
    dz = Ls / n
    r_mo = ro.outer_radius_m - ro.sleeve_thickness_m
    r_mi = r_mo - ro.magnet_thickness_m
    r_sh, r_b = ro.core_inner_radius_m, c.bearings.seat_radius_m
    r_tip = st.bore_radius_m + st.tooth_tip_depth_m
    l_fe = 0.5 * (fr.length_m - Ls)
    l_se = 0.5 * (ro.shaft_length_m - Ls)
    t_cap, oh, s_cap = es.cap_thickness_m, wd.end_overhang_m, es.rotor_clearance_m
    tf = st.tooth_fraction
    sf = 1.0 - tf

    def ks(mat, f=1.0):
        return (f * mat.k_radial_W_mK, f * mat.k_axial_W_mK)
    k_wind = (sf * wd.k_radial_W_mK, sf * wd.k_axial_W_mK)
    # the winding's radial layers as the network's (one continuum: blocks of one group)
    radii = motor.layer_radii_m
    layers = list(zip(motor.winding_layers, radii[:-1], radii[1:]))
    stack = [('frame', 'frame', (fr.inner_radius_m, fr.outer_radius_m), ks(fr.material), 1.0),
             ('yoke', 'stator', (st.yoke_inner_radius_m, st.outer_radius_m), ks(st.material),
              1.0),
             ('teeth', 'tip', (st.bore_radius_m, r_tip), ks(st.material), 1.0),
             ('teeth', 'stator', (r_tip, st.yoke_inner_radius_m), ks(st.material, tf), tf),
             *((w.name, 'winding', (r_in, r_out), k_wind, sf) for w, r_out, r_in in layers),
             ('sleeve', 'sleeve', (r_mo, ro.outer_radius_m), ks(ro.sleeve), 1.0),
             ('magnet', 'magnet', (r_mi, r_mo), ks(ro.magnet), 1.0),
             ('rotor_core', 'core', (r_sh, r_mi), ks(ro.core), 1.0),
             ('shaft', 'shaft', (0.0, r_sh), ks(ro.shaft), 1.0)]
    blocks = [Block(part, group, a, (i * dz, (i + 1) * dz), k, frac, i + 1)
              for part, group, a, k, frac in stack for i in range(n)]
    for side in ('front', 'rear'):
        def span(inner, outer):
            """Axial range from ``inner`` to ``outer`` past the stack face of this side."""
            return (-outer, -inner) if side == 'front' else (Ls + inner, Ls + outer)
        g_b = bearing_conductance(motor, side)
        k_b = g_b * np.log(r_b / r_sh) / (2 * np.pi * t_cap)
        blocks += [
            Block(f'frame_end_{side}', 'frame', (fr.inner_radius_m, fr.outer_radius_m),
                  span(0.0, l_fe), ks(fr.material)),
            Block(f'end_cap_{side}', f'cap_{side}', (r_b, fr.outer_radius_m),
                  span(l_fe, l_fe + t_cap), ks(es.cap_material)),
            Block(f'end_cap_hub_{side}', f'cap_{side}', (r_b, ro.outer_radius_m),
                  span(s_cap, l_fe), ks(es.cap_material)),
            *(Block(f'end_winding_{side}.{w.name.split(".")[-1]}', 'winding', (r_in, r_out),
                    span(0.0, oh), k_wind, sf) for w, r_out, r_in in layers),
            Block(f'shaft_end_{side}', 'shaft', (0.0, r_sh), span(0.0, l_se), ks(ro.shaft)),
            Block(f'bearing_{side}', 'shaft', (r_sh, r_b), span(l_fe, l_fe + t_cap),
                  (k_b, k_b))]
    return blocks


def end_space_box(c, side: str):
    """Return the (r, z) box of the end space at ``side``: the oil's walls lie in it."""
    l_fe = 0.5 * (c.frame.length_m - c.stack_length_m)
    z = (-l_fe, 0.0) if side == 'front' else (c.stack_length_m, c.stack_length_m + l_fe)
    return (0.0, c.frame.inner_radius_m), z


def motor_rz(motor: WetMotor, u: MotorInputs, coupling: Tuple[float, float],
             h_m: float) -> GridFE:
    """
    Build and solve the r-z model of ``motor``, whose network is solved at ``u``.

    Contacts from the configuration (frame fit, slot liner on the slot's bottom
    and top, sleeve-magnet-core-shaft fits, cap joint); ``coupling`` the two
    effective coefficients fitted to the slot pitch (:func:`fit_coupling`): the
    volumetric conductance of the winding to the teeth continuum (W/(m^3 K))
    and the conductance per area of the teeth continuum to the tooth-tip ring
    (W/(m^2 K): the constriction where the tooth meets its tip and the
    spreading under the slot that r-z cannot resolve). Every network link
    from a solid node to an oil node or to ambient becomes a Robin link of the
    same conductance over the surface of that node (the end-space links over
    the part of it that bounds the end space); the oil nodes are lumped
    unknowns with the network's advection chain; every source's power goes to
    its part's slice (or oil node) as in the network.
    """
    fe = GridFE(rz_blocks(motor), h_m, axisymmetric=True)
    _add_contacts(fe, motor, coupling)
    _add_network_links(fe, motor, u)
    _add_sources(fe, motor)
    fe.solve()
    return fe


def _add_contacts(fe: GridFE, motor: WetMotor, coupling: Tuple[float, float]) -> None:
    """Join the groups of the r-z model: the configuration's contacts and the fitted coupling."""
    c = motor.cfg
    st, wd, ro = c.stator, c.winding, c.rotor
    liner = wd.liner_conductivity_W_mK / wd.liner_thickness_m * (1 - st.tooth_fraction)
    every = fe.blocks_of
    contacts = [('frame fit', every('frame'), 'inner', 'stator',
                 st.contact_gap_conductivity_W_mK / st.frame_contact_gap_m, None),
                ('slot bottom', every(motor.winding_layers[0].name), 'outer', 'stator', liner,
                 None),
                ('slot top', every(motor.winding_layers[-1].name), 'inner', 'tip', liner, None),
                ('tooth root of the tip', [k for k in every('teeth') if fe.blocks[k].frac < 1.0],
                 'inner', 'tip', coupling[1], None),
                ('sleeve-magnet', every('sleeve'), 'inner', 'magnet',
                 ro.sleeve_magnet_htc_W_m2K, None),
                ('magnet-core', every('magnet'), 'inner', 'core', ro.magnet_core_htc_W_m2K, None),
                ('core-shaft', every('rotor_core'), 'inner', 'shaft', ro.core_shaft_htc_W_m2K,
                 None)]
    for side, toward in (('front', 'rear'), ('rear', 'front')):
        box = ((c.frame.inner_radius_m, c.frame.outer_radius_m), (-1.0, 1.0))
        contacts += [(f'cap joint {side}', every(f'end_cap_{side}'), toward, 'frame',
                      c.end_spaces.cap_frame_htc_W_m2K, box),
                     (f'bearing seat {side}', every(f'bearing_{side}'), 'outer', f'cap_{side}',
                      PERFECT_HTC, None)]
    for name, blocks, side, group, h, box in contacts:
        fe.add_contact(name, fe.face(blocks, side, box), group, h)
    for k in every('teeth'):
        if fe.blocks[k].frac < 1.0:
            fe.add_volume_coupling(k, 'winding', coupling[0])


def _add_network_links(fe: GridFE, motor: WetMotor, u: MotorInputs) -> None:
    """Add every network link from a solid to oil or ambient, and the oil's advection chain."""
    c, net = motor.cfg, motor.net
    names = net.node_names + net.boundary_names
    Tb = motor.boundaries(u)
    bvals = dict(zip(net.boundary_names, Tb))
    oil = oil_nodes(net)
    G = net.coefficients_in_use()[0]
    ends = net.link_ends(np.arange(G.size))
    fe.network_links = []
    for k, (ia, ib) in enumerate(ends):
        a, b = names[ia], names[ib]
        if b in oil or b in bvals:
            solid, other = a, b
        elif a in oil or a in bvals:
            solid, other = b, a
        else:
            continue
        part, sl, side = split_name(solid)
        if side is None:
            raise ValueError(f'link {a}-{b}: the FE model has no surface for node {solid}')
        box = end_space_box(c, other[len('end_oil_'):]) if other.startswith('end_oil_') else None
        fe.add_link(f'{solid}|{other}', fe.face(fe.blocks_of(part, sl), side, box), G[k],
                    other if other in oil else bvals[other])
        fe.network_links.append(k)
    for up, down in net._advections:
        rate = net.advection_rate[net._advections.index((up, down))]
        fe.add_advection(up if up in oil else bvals[up], down, rate)


def _add_sources(fe: GridFE, motor: WetMotor) -> None:
    """Put every source's power in its part's slice (or its oil node), as the network does."""
    oil = oil_nodes(motor.net)
    for nm, P in zip(source_names(motor), motor.power_W):
        if nm in oil:
            fe.add_node_source(nm, P)
            continue
        part, sl, _ = split_name(nm)
        blocks = fe.blocks_of(part, sl)
        if not blocks:
            raise ValueError(f'source at {nm}: the FE model has no part {part!r}')
        fe.add_source(blocks, P)


def fit_coupling(c, oil, prob: SlotProblem, slot_fe: GridFE, slot: Dict[str, float],
                 h_m: float = 0.002) -> Tuple[float, float]:
    """
    Fit the r-z model's two effective coefficients so that it reproduces the slot pitch.

    The r-z model of the 2-D problem (:func:`slice_motor`: one slice, the ends
    cut off) must give the winding and yoke means of the 2-D field ``slot``
    (:func:`slot_pitch`); Newton's method on the logarithms of (winding-teeth
    conductance per volume, teeth-tip conductance per area), from the slot's own
    side flux over its winding-to-tooth difference (:func:`slot_coupling`) and
    the tooth's conduction over half a pitch at the tip. The teeth mean and the
    bore's heat then follow (``test/test_fem_check.py`` checks them). Returns
    the pair for :func:`motor_rz`.
    """
    st = c.stator
    motor, u = slice_motor(c, oil, prob)
    target = np.array([slot['winding_mean'], slot['yoke']])

    def residual(x):
        fe = motor_rz(motor, u, tuple(np.exp(x)), h_m)
        return np.array([fe.mean(fe.blocks_of('winding')), fe.mean(fe.blocks_of('yoke'))]) \
            - target
    half_pitch = np.pi * (st.bore_radius_m + st.tooth_tip_depth_m) / c.slots
    x = np.log([slot_coupling(slot_fe, c),
                st.tooth_fraction * st.material.k_radial_W_mK / half_pitch])
    for _ in range(12):
        r = residual(x)
        if np.max(np.abs(r)) < 1e-3:
            break
        jac = np.column_stack([(residual(x + d) - r) / 0.05 for d in np.eye(2) * 0.05])
        x = x + np.clip(np.linalg.solve(jac, -r), -2.0, 2.0)
    else:
        raise RuntimeError(f'the r-z model does not reproduce the slot pitch: {r} K')
    return float(np.exp(x[0])), float(np.exp(x[1]))
