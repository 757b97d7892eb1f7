"""
Build the wet motor's thermal network: its blocks, oil path, links and sources.

The layout is described in :mod:`.motor`; :class:`MotorNetworkBuilder` is
the part of :class:`~.motor.WetMotor` that adds the nodes, links and sources
once, in a fixed order (it sets the node indices), and indexes the nodes the
steps use.
"""

from typing import Dict, List, NamedTuple

import numpy as np

from .mellor import add_cylinder, Cylinder
from .motor_kernels import END_CAP, END_ROTOR_FACE, END_SHAFT, END_STATOR, EndSurfaces
from .winding import winding_layout
from ..units import C_TO_K

#: the motor's loss groups in the order of its sources (:meth:`WetMotor.losses`)
LOSS_GROUPS = ('copper', 'core_yoke', 'core_teeth', 'gap_friction', 'magnet', 'sleeve',
               'rotor_core', 'end_face_friction', 'bearings')
#: the names of :attr:`WetMotor.losses_W`: the groups, copper split into slots and end windings
LOSS_NAMES = ('copper_slot', 'copper_end') + LOSS_GROUPS[1:]
#: bearing steel (AISI 52100)
BEARING_STEEL_SPECIFIC_HEAT_J_KGK = 475.0


class Radii(NamedTuple):
    """Radii (m) the builders share: tooth tip, magnet outer and inner, shaft."""

    tip: float
    magnet_outer: float
    magnet_inner: float
    shaft: float


class MotorNetworkBuilder:
    """The network builder of :class:`~.motor.WetMotor` (its ``cfg``, ``net`` and ``oil``)."""

    def _build(self) -> None:
        """Build the network part by part, in a fixed order (it sets the node indices)."""
        c, net = self.cfg, self.net
        self.dz = c.stack_length_m / c.slices
        self.amb = net.add_boundary('ambient')
        self.inlet = net.add_boundary('oil_inlet')
        st, ro = c.stator, c.rotor
        r_mag_out = ro.outer_radius_m - ro.sleeve_thickness_m
        g = Radii(tip=st.bore_radius_m + st.tooth_tip_depth_m, magnet_outer=r_mag_out,
                  magnet_inner=r_mag_out - ro.magnet_thickness_m,
                  shaft=ro.core_inner_radius_m)
        self._build_stack(g)
        self._build_airgap_oil()
        self.ambient_links, self.ambient_areas = [], []
        self.cap_links, self.cap_areas = [], []
        self.end_links, self.end_areas, self.end_surfaces = [], [], []
        self.bearing = {}
        self.gap_links_stator, self.gap_links_rotor = [], []
        self._build_slice_contacts(g)
        self.end_winding = {}
        for side in ('front', 'rear'):
            self._build_end(side, g)
        self._build_sources()
        self._build_indices()

    def _cylinder(self, name, r1, r2, lengths, mat, frac=1.0, **kw):
        return add_cylinder(self.net, name, r1, r2, lengths, mat.k_radial_W_mK,
                            mat.k_axial_W_mK, mat.rho_c_J_m3K, frac, **kw)

    def _to_ambient(self, node: str, area_m2: float) -> None:
        self.ambient_links.append(self.net.add_conductance(node, self.amb))
        self.ambient_areas.append(area_m2)

    def _to_end_oil(self, node: str, side: str, area_m2: float, kind: int, radius_m: float,
                    length_m: float) -> None:
        """
        Link a surface to its end space's oil: its kind, mean radius and length (m).

        The length is an annulus's radial width (the rotor's face and the hub's
        facing it), else the surface's length as a plate along the swirl.
        """
        self.end_links.append(self.net.add_conductance(node, self.end_oil[side]))
        self.end_areas.append(area_m2)
        self.end_surfaces.append((node, self.end_oil[side], ('front', 'rear').index(side), kind,
                                  radius_m, length_m, area_m2))

    def _build_stack(self, g: 'Radii') -> None:
        """Add the cylinders of the active length, a block per slice: frame to shaft."""
        c, cyl = self.cfg, self._cylinder
        stack = [self.dz] * c.slices
        fr, st, wd, ro = c.frame, c.stator, c.winding, c.rotor
        frame = cyl('frame', fr.outer_radius_m, fr.inner_radius_m, stack, fr.material)
        yoke = cyl('yoke', st.outer_radius_m, st.yoke_inner_radius_m, stack, st.material)
        teeth = cyl('teeth', st.yoke_inner_radius_m, st.bore_radius_m, stack, st.material,
                    st.tooth_fraction, outer=yoke.inner)
        # slot winding: copper + insulation mixture, the fill from the winding's description
        self.winding_layout = winding_layout(c)
        fill = self.winding_layout.copper_fill
        rc_wind = (fill * wd.copper_density_kg_m3 * wd.copper_specific_heat_J_kgK
                   + (1 - fill) * wd.insulation_density_kg_m3 * wd.insulation_specific_heat_J_kgK)
        # radial layers of equal depth, slot bottom (layer 1) to tip: a Mellor block joins
        # its axial and radial paths only at its mean, so one block per slice would send
        # the heat that runs along the wire (k_axial >> k_radial) through the middle of
        # the slot; layers let it run along the wire at its own depth, as the layered
        # winding of Motor-CAD does (docs/model.md, Winding layers)
        layers = c.winding_layers
        #: the layers' radii (m), slot bottom to tip (layers + 1 values)
        self.layer_radii_m = np.linspace(st.yoke_inner_radius_m, g.tip, layers + 1)
        area = self.layer_radii_m[:-1] ** 2 - self.layer_radii_m[1:] ** 2
        #: each layer's share of the winding's volume (and of its copper and loss)
        self.layer_share = area / area.sum()
        winding, above = [], None
        for j in range(layers):
            above = add_cylinder(self.net, f'winding.l{j + 1}', self.layer_radii_m[j],
                                 self.layer_radii_m[j + 1], stack, wd.k_radial_W_mK,
                                 wd.k_axial_W_mK, rc_wind, 1.0 - st.tooth_fraction,
                                 outer=above.inner if above else None)
            winding.append(above)
        #: the slot winding's layers (:class:`~.mellor.Cylinder` each), slot bottom first
        self.winding_layers: List[Cylinder] = winding
        sleeve = cyl('sleeve', ro.outer_radius_m, g.magnet_outer, stack, ro.sleeve)
        magnet = cyl('magnet', g.magnet_outer, g.magnet_inner, stack, ro.magnet)
        core = cyl('rotor_core', g.magnet_inner, g.shaft, stack, ro.core)
        shaft = cyl('shaft', g.shaft, 0.0, stack, ro.shaft)
        self.parts = {'frame': frame, 'yoke': yoke, 'teeth': teeth,
                      **{w.name: w for w in winding}, 'sleeve': sleeve, 'magnet': magnet,
                      'rotor_core': core, 'shaft': shaft}

    def _build_airgap_oil(self) -> None:
        """Add the oil path: front end space, n mixed airgap sections, rear end space."""
        c, net, n = self.cfg, self.net, self.cfg.slices
        st, ro, es = c.stator, c.rotor, c.end_spaces
        oil_rc = self._oil_rho_cp(C_TO_K + 40.0, 0.0)
        gap_vol = np.pi * (st.bore_radius_m ** 2 - ro.outer_radius_m ** 2) * self.dz
        self.gap = [net.add_node(f'gap_oil.s{i + 1}', oil_rc * gap_vol) for i in range(n)]
        self.end_oil = {s: net.add_node(f'end_oil_{s}', oil_rc * es.oil_volume_m3)
                        for s in ('front', 'rear')}
        self.oil_nodes = [self.end_oil['front']] + self.gap + [self.end_oil['rear']]
        self.oil_volumes = np.array([es.oil_volume_m3] + [gap_vol] * n + [es.oil_volume_m3])
        self.adv = [net.add_advection(u, d) for u, d in
                    zip([self.inlet] + self.oil_nodes[:-1], self.oil_nodes)]

    def _build_slice_contacts(self, g: 'Radii') -> None:
        """Link each slice radially: frame to ambient and yoke, slot liners, airgap, rotor."""
        c, net, dz = self.cfg, self.net, self.dz
        fr, st, wd, ro = c.frame, c.stator, c.winding, c.rotor
        frame, yoke, teeth, sleeve, magnet, core, shaft = (
            self.parts[k] for k in ('frame', 'yoke', 'teeth', 'sleeve', 'magnet', 'rotor_core',
                                    'shaft'))
        bottom, top = self.winding_layers[0], self.winding_layers[-1]
        ring = 2 * np.pi * dz  # lateral area per unit radius of one slice
        slot_frac = 1.0 - st.tooth_fraction
        liner_h = wd.liner_conductivity_W_mK / wd.liner_thickness_m
        gap_h = st.contact_gap_conductivity_W_mK / st.frame_contact_gap_m
        tooth_pitch = 2 * np.pi * 0.5 * (st.yoke_inner_radius_m + g.tip) / c.slots
        slot_depth = st.yoke_inner_radius_m - g.tip
        # slot sides to the teeth: liner in series with the mean-to-wall resistance of a
        # slab with uniform generation (w / (6 k A_walls)), the slot's and the tooth's
        walls = 2 * c.slots * slot_depth * dz
        r_tooth = st.tooth_fraction * tooth_pitch / (6 * st.material.k_radial_W_mK * walls)
        r_lat = (1 / (liner_h * walls) + slot_frac * tooth_pitch / (6 * wd.k_radial_W_mK * walls)
                 + r_tooth)
        layers = len(self.winding_layers)
        #: the slot's radii (m), tip and bottom, and each layer's lateral link (K/W): whole
        #: and the tooth's part of it (the hot spot reads the flanks' temperature from
        #: them); a layer has its share of the walls, the slot depth over the layers
        self.slot_radii_m = (g.tip, st.yoke_inner_radius_m)
        self.slot_lateral_R = (r_lat * layers, r_tooth * layers)
        #: the liner's conductances (W/K) at the slot bottom and at its top (one slice)
        self.slot_liner_G = (liner_h * slot_frac * st.yoke_inner_radius_m * ring,
                             liner_h * slot_frac * g.tip * ring)
        for i in range(c.slices):
            self._to_ambient(frame.outer[i], fr.outer_radius_m * ring)
            net.add_conductance(frame.inner[i], yoke.outer[i],
                                gap_h * fr.inner_radius_m * ring)
            net.add_conductance(bottom.outer[i], yoke.inner[i], self.slot_liner_G[0])
            net.add_conductance(top.inner[i], teeth.inner[i], self.slot_liner_G[1])
            for layer in self.winding_layers:
                net.add_resistance(layer.mean[i], teeth.mean[i], self.slot_lateral_R[0])
            self.gap_links_stator.append(net.add_conductance(teeth.inner[i], self.gap[i]))
            self.gap_links_rotor.append(net.add_conductance(sleeve.outer[i], self.gap[i]))
            net.add_conductance(sleeve.inner[i], magnet.outer[i],
                                ro.sleeve_magnet_htc_W_m2K * g.magnet_outer * ring)
            net.add_conductance(magnet.inner[i], core.outer[i],
                                ro.magnet_core_htc_W_m2K * g.magnet_inner * ring)
            net.add_conductance(core.inner[i], shaft.outer[i],
                                ro.core_shaft_htc_W_m2K * g.shaft * ring)

    def _build_end(self, side: str, g: 'Radii') -> None:
        """
        Add one end of the motor: end winding, stack faces, frame end, end cap, shaft end.

        Everything there exchanges heat with the end space's oil; the frame end
        and the cap also with ambient, the shaft end through the bearing (half its
        conductance on either side of the bearing node).
        """
        c, st, ro = self.cfg, self.cfg.stator, self.cfg.rotor
        p, n = self.parts, self.cfg.slices
        stack_face = 0 if side == 'front' else n
        outward = 0 if side == 'front' else 1   # index of the face away from the stack

        def joined(part: Cylinder) -> dict:
            """Join an end block to the stack face of ``part``."""
            return ({'rear_face': part.faces[0]} if side == 'front'
                    else {'front_face': part.faces[n]})

        ew = self._build_end_winding(side, g, joined, outward)
        # stack faces open to the end space
        end = self._to_end_oil
        r_ew = 0.5 * (st.yoke_inner_radius_m + g.tip)
        coil = 2 * np.pi * r_ew / c.slots
        r_yoke = 0.5 * (st.outer_radius_m + st.yoke_inner_radius_m)
        end(p['yoke'].faces[stack_face], side,
            np.pi * (st.outer_radius_m ** 2 - st.yoke_inner_radius_m ** 2), END_STATOR, r_yoke,
            2 * np.pi * r_yoke)
        end(p['teeth'].faces[stack_face], side,
            st.tooth_fraction * np.pi * (st.yoke_inner_radius_m ** 2 - st.bore_radius_m ** 2),
            END_STATOR, r_ew, coil)
        for part, r1, r2 in (('sleeve', ro.outer_radius_m, g.magnet_outer),
                             ('magnet', g.magnet_outer, g.magnet_inner),
                             ('rotor_core', g.magnet_inner, g.shaft)):
            end(p[part].faces[stack_face], side, np.pi * (r1 ** 2 - r2 ** 2), END_ROTOR_FACE,
                0.5 * (r1 + r2), r1 - r2)
        fe, cap, se = self._build_end_housing(side, g, joined, outward)
        p.update({w.name: w for w in ew})
        p.update({f'frame_end_{side}': fe, f'end_cap_{side}': cap, f'shaft_end_{side}': se})

    def _build_end_winding(self, side: str, g: 'Radii', joined, outward: int) -> List[Cylinder]:
        """
        Add one end winding (the end turns' copper and insulation) and its oil links.

        Its layers continue the slot's (each joined to its slot layer's face);
        the outer layer's outer surface, the inner's inner and each layer's end
        face meet the oil.
        """
        c, st, wd = self.cfg, self.cfg.stator, self.cfg.winding
        slot_frac = 1.0 - st.tooth_fraction
        # end windings: the slot conductors continue out of the stack; per side the
        # end turns hold copper volume fill * A_slots * l_end_turn / 2
        a_slots = slot_frac * np.pi * (st.yoke_inner_radius_m ** 2 - g.tip ** 2)
        v_block = a_slots * wd.end_overhang_m
        v_cu = self.winding_layout.copper_fill * a_slots * wd.end_turn_length_m / 2
        if v_cu > v_block:
            v_cu = v_block  # tightly packed end turns: the block is all copper
        rc_end = (v_cu * wd.copper_density_kg_m3 * wd.copper_specific_heat_J_kgK
                  + (v_block - v_cu) * wd.insulation_density_kg_m3
                  * wd.insulation_specific_heat_J_kgK) / v_block
        radii, ew, above = self.layer_radii_m, [], None
        for j, slot_layer in enumerate(self.winding_layers):
            above = add_cylinder(self.net, f'end_winding_{side}.l{j + 1}', radii[j],
                                 radii[j + 1], [wd.end_overhang_m], wd.k_radial_W_mK,
                                 wd.k_axial_W_mK, rc_end, slot_frac,
                                 outer=above.inner if above else None, **joined(slot_layer))
            ew.append(above)
        self.end_winding[side] = ew
        # the end turns are one coil per tooth: the oil's swirl meets each as a plate of
        # one coil pitch; the smooth stack faces, frame and cap as one turn of the swirl
        r_ew = 0.5 * (st.yoke_inner_radius_m + g.tip)
        coil = 2 * np.pi * r_ew / c.slots
        end = self._to_end_oil
        for j, layer in enumerate(ew):
            end(layer.faces[outward], side, a_slots * self.layer_share[j], END_STATOR,
                0.5 * (radii[j] + radii[j + 1]), coil)
        end(ew[0].outer[0], side,
            2 * np.pi * st.yoke_inner_radius_m * slot_frac * wd.end_overhang_m,
            END_STATOR, st.yoke_inner_radius_m, coil)
        end(ew[-1].inner[0], side, 2 * np.pi * g.tip * slot_frac * wd.end_overhang_m,
            END_STATOR, g.tip, coil)
        return ew

    def _build_end_housing(self, side: str, g: 'Radii', joined, outward: int) -> tuple:
        """
        Add one end's frame segment, end cap and its hub, bearing and shaft end; return the blocks.

        The cap closes the frame segment; its hub (the bearing's housing, of the
        rotor's radius, inside the end winding) reaches from it to
        ``rotor_clearance_m`` from the rotor's end face: the stationary wall
        of Daily and Nece's enclosed disc, the same clearance their gap ratio
        takes.
        """
        c, net, cyl = self.cfg, self.net, self._cylinder
        fr, ro, es, bg = c.frame, c.rotor, c.end_spaces, c.bearings
        L_fend = 0.5 * (fr.length_m - c.stack_length_m)
        L_send = 0.5 * (ro.shaft_length_m - c.stack_length_m)
        end = self._to_end_oil
        fe = cyl(f'frame_end_{side}', fr.outer_radius_m, fr.inner_radius_m, [L_fend],
                 fr.material, **joined(self.parts['frame']))
        self._to_ambient(fe.outer[0], 2 * np.pi * fr.outer_radius_m * L_fend)
        end(fe.inner[0], side, 2 * np.pi * fr.inner_radius_m * L_fend, END_STATOR,
            fr.inner_radius_m, 2 * np.pi * fr.inner_radius_m)
        cap = cyl(f'end_cap_{side}', fr.outer_radius_m, bg.seat_radius_m,
                  [es.cap_thickness_m], es.cap_material)
        net.add_conductance(cap.outer[0], fe.faces[outward], es.cap_frame_htc_W_m2K * np.pi
                            * (fr.outer_radius_m ** 2 - fr.inner_radius_m ** 2))
        self.cap_links.append(net.add_conductance(cap.faces[outward], self.amb))
        self.cap_areas.append(np.pi * (fr.outer_radius_m ** 2 - bg.seat_radius_m ** 2))
        a, r_seat = ro.outer_radius_m, bg.seat_radius_m
        # the hub on the cap's inner face (one material with it): its face at the clearance
        # from the rotor's face, its outer and bore surfaces in the swirl
        L_hub = L_fend - es.rotor_clearance_m
        hub = cyl(f'end_cap_hub_{side}', a, r_seat, [L_hub], es.cap_material,
                  **({'front_face': cap.faces[1]} if side == 'front'
                     else {'rear_face': cap.faces[0]}))
        end(hub.faces[1 - outward], side, np.pi * (a ** 2 - r_seat ** 2), END_CAP,
            0.5 * (a + r_seat), a - r_seat)
        end(hub.outer[0], side, 2 * np.pi * a * L_hub, END_STATOR, a, 2 * np.pi * a)
        end(hub.inner[0], side, 2 * np.pi * r_seat * L_hub, END_STATOR, r_seat,
            2 * np.pi * r_seat)
        # the cap's face beyond the hub, a plate in the swirl
        r_cap = 0.5 * (fr.inner_radius_m + a)
        end(cap.faces[1 - outward], side, np.pi * (fr.inner_radius_m ** 2 - a ** 2),
            END_STATOR, r_cap, 2 * np.pi * r_cap)
        se = cyl(f'shaft_end_{side}', g.shaft, 0.0, [L_send], ro.shaft,
                 **joined(self.parts['shaft']))
        end(se.outer[0], side, 2 * np.pi * g.shaft * min(L_send, L_fend), END_SHAFT, g.shaft,
            2 * np.pi * g.shaft)
        # the bearing between shaft end and cap: its rings and balls, heated by its friction
        b = self.bearing[side] = net.add_node(
            f'bearing_{side}', bg.mass_kg * BEARING_STEEL_SPECIFIC_HEAT_J_KGK)
        net.add_conductance(se.outer[0], b, 2.0 * bg.conductance_W_K)
        net.add_conductance(b, cap.inner[0], 2.0 * bg.conductance_W_K)
        self.parts[f'end_cap_hub_{side}'] = hub
        return fe, cap, se

    def _build_sources(self) -> None:
        """
        Add the heat sources, one per heated node, in groups (:data:`LOSS_GROUPS`).

        Copper (slot slices, end windings), stator iron (yoke and teeth slices),
        airgap friction (its oil sections), rotor eddy currents (magnet, sleeve,
        rotor core slices), end-face friction (the end-space oil) and bearings.
        """
        c, net, p = self.cfg, self.net, self.parts
        wd, n = c.winding, c.slices
        # the copper nodes slice by slice, slot bottom to tip, then the end windings' layers
        slot = [w.mean[i] for i in range(n) for w in self.winding_layers]
        ends = [w.mean[0] for s in ('front', 'rear') for w in self.end_winding[s]]
        self.copper_nodes = slot + ends
        #: how many of the copper nodes are in the slots (the end windings' follow)
        self.n_slot_copper = len(slot)
        turn = c.stack_length_m + wd.end_turn_length_m   # half a turn's conductor length
        # each node's share of a turn's conductor: its length's share times its layer's
        layers = np.tile(self.layer_share, n + 2)
        self.copper_share = layers * np.array([self.dz / turn] * self.n_slot_copper
                                              + [wd.end_turn_length_m / (2 * turn)]
                                              * len(ends))
        nodes = {'copper': self.copper_nodes, 'core_yoke': p['yoke'].mean,
                 'core_teeth': p['teeth'].mean, 'gap_friction': self.gap,
                 'magnet': p['magnet'].mean, 'sleeve': p['sleeve'].mean,
                 'rotor_core': p['rotor_core'].mean,
                 'end_face_friction': [self.end_oil['front'], self.end_oil['rear']],
                 'bearings': [self.bearing['front'], self.bearing['rear']]}
        #: each loss group's sources: a slice of the power vector
        self.sources: Dict[str, slice] = {}
        for group in LOSS_GROUPS:
            ids = [net.add_source(m) for m in nodes[group]]
            self.sources[group] = slice(ids[0], ids[-1] + 1)
        self.src_copper = list(range(self.sources['copper'].start, self.sources['copper'].stop))
        rho_fe = c.stator.material.density_kg_m3
        self.yoke_mass = rho_fe * np.array(p['yoke'].volume_m3)
        self.teeth_mass = rho_fe * np.array(p['teeth'].volume_m3)

    def _build_indices(self) -> None:
        """Index the nodes the steps and outputs use, and those that trigger a refresh."""
        net, p = self.net, self.parts
        self.ambient_areas = np.array(self.ambient_areas)
        self.cap_areas = np.array(self.cap_areas)
        self.end_areas = np.array(self.end_areas)
        self.idx_copper = np.array([net.index(m) for m in self.copper_nodes])
        self.idx_gap = np.array([net.index(m) for m in self.gap])
        self.idx_oil = np.array([net.index(m) for m in self.oil_nodes])
        self.idx_end_oil = self.idx_oil[[0, -1]]
        # the surfaces the end-space oil washes: node, its oil and side, kind, radius, length,
        # area
        surf, oil, side, kind, radius, length, area = zip(*self.end_surfaces)
        self.end_surfaces = EndSurfaces(
            surface=np.array([net.index(m) for m in surf]),
            oil=np.array([net.index(m) for m in oil]), side=np.array(side),
            kind=np.array(kind), radius_m=np.array(radius), length_m=np.array(length),
            area_m2=np.array(area))
        self.idx_frame_outer = np.array([net.index(m) for m in p['frame'].outer])
        self.idx_cap_outer = np.array([net.index(p[f'end_cap_{s}'].faces[o])
                                       for s, o in (('front', 0), ('rear', 1))])
        self.idx_frame = np.array([net.index(m) for m in p['frame'].mean])
        # nodes whose temperature sets a coefficient, with the drift (in units of
        # refresh_dT_K) that triggers a refresh: airgap oil viscosity sets the airgap h
        # (~1.5 %/K); the end spaces' h follow their film temperatures (~0.4 %/K: the end
        # oil and the end windings, the hottest surface there); end-space oil capacity
        # and natural convection move < 0.2 %/K. Copper R(T) and friction viscosity are
        # evaluated every step.
        ends = [net.index(w.mean[0]) for s in ('front', 'rear') for w in self.end_winding[s]]
        self.idx_watch = np.concatenate([self.idx_gap, self.idx_end_oil, ends,
                                         self.idx_frame_outer, self.idx_cap_outer])
        self.watch_scale = np.concatenate([np.ones(self.idx_gap.size),
                                           np.full(self.idx_watch.size - self.idx_gap.size, 4.0)])
        # the links to ambient (frame, then end caps) for the ledger
        self._to_ambient_ids = np.array(self.ambient_links + self.cap_links)
