"""
Thermal network of the wet PMSM: Mellor blocks, advected airgap oil, losses.

Layout (front = oil-inlet side, rear = outlet side; stack slices 1..n):

- stack parts, one Mellor slice per axial section: ``frame``, ``yoke``,
  ``teeth`` (iron share of the tooth annulus), ``winding`` (slot share),
  ``sleeve``, ``magnet``, ``rotor_core``, ``shaft``; airgap oil ``gap_oil.s1..``;
- each end: ``frame_end_<side>``, ``end_cap_<side>``, ``end_winding_<side>``,
  ``shaft_end_<side>``, the bearing ``bearing_<side>`` and the end-space oil
  ``end_oil_<side>``;
- boundaries ``ambient`` and ``oil_inlet``.

Oil path: oil_inlet -> end_oil_front -> gap_oil.s1 .. s<n> -> end_oil_rear
(the motor outlet). Heat leaves by the oil and by the frame and end caps to
ambient (natural convection and radiation, or a fan coefficient).
"""

from dataclasses import dataclass
import math
from typing import Dict, NamedTuple, Optional, Tuple, Union

import numpy as np

from . import correlations as corr
from .compiled import jit
from .loss_table import build_loss_table, COPPER_EXCESS, IRON, MAGNET, ROTOR_CORE, SLEEVE, \
    table_values
from .losses import copper_resistance, electrical_frequency, steinmetz_loss_density
from .mellor import add_cylinder
from .network import ThermalNetwork
from .oil import conductivity as oil_conductivity, density as oil_density, \
    kinematic_viscosity as oil_nu, Oil, specific_heat as oil_cp
from .quantities import motor_outputs, QuantityMap
from .rotor_losses import rotor_eddy_loss_breakdown
from .validity import ValidityLog
from ..config import Motor
from ..units import C_TO_K

#: the kinds of surface the end-space oil washes (:meth:`WetMotor._end_space_htc`): the
#: rotor's end face, the end cap (its part facing the rotor, and the rest), a stator
#: surface in the oil's swirl (end winding, stack faces, frame), the turning shaft end
END_ROTOR_FACE, END_CAP, END_STATOR, END_SHAFT = range(4)
#: the motor's loss groups in the order of its sources (:meth:`WetMotor.losses`)
LOSS_GROUPS = ('copper', 'core_yoke', 'core_teeth', 'gap_friction', 'magnet', 'sleeve',
               'rotor_core', 'end_face_friction', 'bearings')
#: the names of :attr:`WetMotor.losses_W`: the groups, copper split into slots and end windings
LOSS_NAMES = ('copper_slot', 'copper_end') + LOSS_GROUPS[1:]
#: bearing steel (AISI 52100)
BEARING_STEEL_SPECIFIC_HEAT_J_KGK = 475.0
#: how :func:`filter_coefficient_point` moves the filter: start at the input, the running
#: mean of the first time constant, or the two cascaded first-order stages
FILTER_START, FILTER_RUNNING_MEAN, FILTER_CASCADE = range(3)


def _mean(a, axis: Optional[int] = None):
    """Return ``np.mean(a, axis)``, the same sum over the count, without np.mean's overhead."""
    a = np.asarray(a)
    return a.sum(axis) / (a.size if axis is None else a.shape[axis])


@dataclass
class MotorInputs:
    """Operating point of the motor over one step (SI units, temperatures in K)."""

    current_sq_mean_A2: float  # mean of I_rms^2 over the step (never the square of a sample)
    speed_rad_s: Union[float, np.ndarray]   # or its samples over the step: losses average them
    oil_inlet_K: float
    oil_flow_m3_s: float
    ambient_K: float
    case_pressure_Pa: float = 0.0
    # RMS current samples (A) beside the speed samples: the electromagnetic losses that do
    # not grow as I^2 (PWM ripple) are averaged over them; None: all at the mean I^2
    current_A: Optional[np.ndarray] = None


class _Radii(NamedTuple):
    """Radii (m) the builders share: tooth tip, magnet outer and inner, shaft."""

    tip: float
    magnet_outer: float
    magnet_inner: float
    shaft: float


class WetMotor:
    """
    Lumped-parameter thermal model of the wet motor, built from :class:`config.Motor`.

    States are the temperatures (K) of the nodes with heat capacity; any node
    temperature is available by name. ``steady_state`` solves the nonlinear
    steady state; ``step`` advances in time with the exact zero-order-hold
    solution of the network linearised at the start of the step.

    Coefficients are re-evaluated only when they can have moved: when the
    airgap oil drifted by more than ``refresh_dT_K`` since the last refresh
    (end-space oil and outer surfaces: four times that), when speed or flow
    moved by more than 1 %, an inlet or ambient temperature by more than
    0.2/0.5 K, or the case pressure by more than 0.1 MPa; copper resistance
    and friction viscosity follow the temperatures every step. Steps longer
    than ``max_substep_s`` are split internally (inputs held), so that fast
    oil-temperature changes inside a long step still update the coefficients.

    With ``coefficient_filter_s`` > 0 the speed, flow and temperatures that
    set the coefficients first pass a low-pass filter in sample time (two
    cascaded first-order stages of that time constant): a duty cycle faster
    than the motor's thermal response (speed and leakage flow swinging at a
    few Hz) then no longer re-discretises the network every step; losses stay
    exact for every step. The coupled EHA model uses this.

    With ``defer_refresh`` a refresh found due in one (sub-)step sets the new
    coefficients but the step still runs on the previous discretisation; the
    new one comes into use at the next (sub-)step, or earlier through
    :meth:`prepare`. The live estimator uses this to re-discretise after an
    estimate has left rather than before; the result does not depend on when
    (or whether) ``prepare`` is called.
    """

    def __init__(self, cfg: Motor, oil: Oil, log: Optional[ValidityLog] = None,
                 refresh_dT_K: float = 0.25, max_substep_s: float = 0.1,
                 coefficient_filter_s: float = 0.0, defer_refresh: bool = False) -> None:
        self.cfg = cfg
        self.oil = oil
        self.log = log if log is not None else ValidityLog()
        self.net = ThermalNetwork()
        self._build()
        self.net.freeze()
        #: the named states and the outputs over them (evaluated on node temperatures)
        self.quantities = QuantityMap(self.net.state_names, motor_outputs(self), self.net.index)
        # the constants of the losses kernel (see motor_losses)
        wd, st, ro = cfg.winding, cfg.stator, cfg.rotor
        self._copper_weight = wd.phases * self.copper_share
        self._copper_law = (float(wd.phase_resistance_20C_ohm), float(wd.copper_tempco_1_K))
        self._iron = tuple(float(v) for v in (
            cfg.pole_pairs, st.hysteresis_coeff_W_kgHzT, st.steinmetz_exponent,
            st.eddy_coeff_W_kgHz2T2, st.yoke_flux_density_T, st.teeth_flux_density_T))
        couette, re_geo, self._gap_ratio, self._gap_in_data, g03, bb_rho, ta_per_re2 = \
            corr.airgap_friction_factors(ro.outer_radius_m, st.bore_radius_m, self.dz)
        self._gap_factors = tuple(float(v) for v in (couette, re_geo, g03, bb_rho, ta_per_re2))
        # a map's iron loss goes to the yoke and teeth slices as mass x B^2 (Steinmetz's
        # split when alpha = 2)
        weights = np.concatenate([self.yoke_mass * st.yoke_flux_density_T ** 2,
                                  self.teeth_mass * st.teeth_flux_density_T ** 2])
        self._iron_split = weights / weights.sum()
        # the rotor's end faces as Daily and Nece's disc: its laws at the clearance ratio
        g = cfg.end_spaces.rotor_clearance_m / ro.outer_radius_m
        disc_laws = corr.daily_nece_laws(g)
        bg = cfg.bearings
        self._ends = (float(ro.outer_radius_m), disc_laws, float(bg.mean_diameter_m),
                      float(bg.lubrication_factor_f0),
                      float(corr.deep_groove_ball_f1(bg.radial_load_N, bg.static_load_rating_N)),
                      float(bg.radial_load_N), float(bg.friction_factor))
        self._loss_nodes = (self.idx_copper, self.idx_gap, self.idx_end_oil)
        # the end-space geometry of end_space_htc
        self._end_geometry = (float(ro.outer_radius_m), disc_laws, float(g),
                              float(self._cap_disc_share),
                              0.5 * (cfg.frame.length_m - cfg.stack_length_m))
        #: the electromagnetic losses over speed and current (rotor, AC copper; a map's all)
        self.loss_table = build_loss_table(cfg)
        self._em_checked = set()    # (speed, current) bins whose rotor-loss validity is logged
        # the books' links to ambient (the frame's, then the end caps'), ends in [T; T_b]
        self._ambient_ends = self.net.link_ends(self._to_ambient_ids)
        self.net.hold_changes = defer_refresh
        self.x: Optional[np.ndarray] = None
        self.T: Optional[np.ndarray] = None
        self.power_W = np.zeros(self.net.ns)
        # heat (W) per source added to the losses of every step: a state estimator's learned
        # correction (None: nothing added, the losses are the model's own)
        self.extra_power_W: Optional[np.ndarray] = None
        self._refreshed_at: Optional[tuple] = None
        self.refresh_dT_K = refresh_dT_K
        self.max_substep_s = max_substep_s
        self.coefficient_filter_s = coefficient_filter_s
        # the coefficient filter's two stages: mean |speed| (rad/s), flow (m^3/s), the
        # temperatures idx_watch (K); and those temperatures at the last refresh
        self._filter_state: Optional[np.ndarray] = None
        self._T_refreshed = np.zeros(self.idx_watch.size)
        self._friction_memo: Optional[tuple] = None
        self._case_pressure_Pa = 0.0
        self.refresh_count = 0
        self.last_substeps = 1      # sub-steps of the last step (a state estimator needs it)
        # energies (J) since construction: heat generated, stored, to ambient, carried by the oil
        self.energy_J = {'losses': 0.0, 'stored': 0.0, 'to_ambient': 0.0, 'to_oil': 0.0}
        # coefficients that moved less than this (relative) keep the cached discretisation
        self.net.refresh_rtol = 1e-3

    # ------------------------------------------------------------------ build
    def _build(self) -> None:
        """Build the network part by part, in a fixed order (it sets the node indices)."""
        c, net = self.cfg, self.net
        self.dz = c.stack_length_m / c.slices
        self.amb = net.add_boundary('ambient')
        self.inlet = net.add_boundary('oil_inlet')
        st, ro = c.stator, c.rotor
        r_mag_out = ro.outer_radius_m - ro.sleeve_thickness_m
        g = _Radii(tip=st.bore_radius_m + st.tooth_tip_depth_m, magnet_outer=r_mag_out,
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
        """Link a surface to its end space's oil: its kind, mean radius and plate length (m)."""
        self.end_links.append(self.net.add_conductance(node, self.end_oil[side]))
        self.end_areas.append(area_m2)
        self.end_surfaces.append((node, self.end_oil[side], kind, radius_m, length_m))

    def _build_stack(self, g: '_Radii') -> None:
        """Add the cylinders of the active length, a block per slice: frame to shaft."""
        c, cyl = self.cfg, self._cylinder
        stack = [self.dz] * c.slices
        fr, st, wd, ro = c.frame, c.stator, c.winding, c.rotor
        frame = cyl('frame', fr.outer_radius_m, fr.inner_radius_m, stack, fr.material)
        yoke = cyl('yoke', st.outer_radius_m, st.yoke_inner_radius_m, stack, st.material)
        teeth = cyl('teeth', st.yoke_inner_radius_m, st.bore_radius_m, stack, st.material,
                    st.tooth_fraction, outer=yoke.inner)
        # slot winding: copper + insulation mixture
        rc_wind = (wd.copper_fill * wd.copper_density_kg_m3 * wd.copper_specific_heat_J_kgK
                   + (1 - wd.copper_fill) * wd.insulation_density_kg_m3
                   * wd.insulation_specific_heat_J_kgK)
        winding = add_cylinder(self.net, 'winding', st.yoke_inner_radius_m, g.tip, stack,
                               wd.k_radial_W_mK, wd.k_axial_W_mK, rc_wind,
                               1.0 - st.tooth_fraction)
        sleeve = cyl('sleeve', ro.outer_radius_m, g.magnet_outer, stack, ro.sleeve)
        magnet = cyl('magnet', g.magnet_outer, g.magnet_inner, stack, ro.magnet)
        core = cyl('rotor_core', g.magnet_inner, g.shaft, stack, ro.core)
        shaft = cyl('shaft', g.shaft, 0.0, stack, ro.shaft)
        self.parts = {'frame': frame, 'yoke': yoke, 'teeth': teeth, 'winding': winding,
                      'sleeve': sleeve, 'magnet': magnet, 'rotor_core': core, 'shaft': shaft}

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

    def _build_slice_contacts(self, g: '_Radii') -> None:
        """Link each slice radially: frame to ambient and yoke, slot liners, airgap, rotor."""
        c, net, dz = self.cfg, self.net, self.dz
        fr, st, wd, ro = c.frame, c.stator, c.winding, c.rotor
        frame, yoke, teeth, winding, sleeve, magnet, core, shaft = (
            self.parts[k] for k in ('frame', 'yoke', 'teeth', 'winding', 'sleeve', 'magnet',
                                    'rotor_core', 'shaft'))
        ring = 2 * np.pi * dz  # lateral area per unit radius of one slice
        slot_frac = 1.0 - st.tooth_fraction
        liner_h = wd.liner_conductivity_W_mK / wd.liner_thickness_m
        gap_h = st.contact_gap_conductivity_W_mK / st.frame_contact_gap_m
        tooth_pitch = 2 * np.pi * 0.5 * (st.yoke_inner_radius_m + g.tip) / c.slots
        slot_depth = st.yoke_inner_radius_m - g.tip
        for i in range(c.slices):
            self._to_ambient(frame.outer[i], fr.outer_radius_m * ring)
            net.add_conductance(frame.inner[i], yoke.outer[i],
                                gap_h * fr.inner_radius_m * ring)
            net.add_conductance(winding.outer[i], yoke.inner[i],
                                liner_h * slot_frac * st.yoke_inner_radius_m * ring)
            net.add_conductance(winding.inner[i], teeth.inner[i],
                                liner_h * slot_frac * g.tip * ring)
            # slot sides to the teeth: liner in series with the mean-to-wall
            # resistance of a slab with uniform generation (w / (6 k A_walls))
            walls = 2 * c.slots * slot_depth * dz
            r_lat = (1 / (liner_h * walls)
                     + slot_frac * tooth_pitch / (6 * wd.k_radial_W_mK * walls)
                     + st.tooth_fraction * tooth_pitch / (6 * st.material.k_radial_W_mK
                                                          * walls))
            net.add_resistance(winding.mean[i], teeth.mean[i], r_lat)
            self.gap_links_stator.append(net.add_conductance(teeth.inner[i], self.gap[i]))
            self.gap_links_rotor.append(net.add_conductance(sleeve.outer[i], self.gap[i]))
            net.add_conductance(sleeve.inner[i], magnet.outer[i],
                                ro.sleeve_magnet_htc_W_m2K * g.magnet_outer * ring)
            net.add_conductance(magnet.inner[i], core.outer[i],
                                ro.magnet_core_htc_W_m2K * g.magnet_inner * ring)
            net.add_conductance(core.inner[i], shaft.outer[i],
                                ro.core_shaft_htc_W_m2K * g.shaft * ring)

    def _build_end(self, side: str, g: '_Radii') -> None:
        """
        Add one end of the motor: end winding, stack faces, frame end, end cap, shaft end.

        Everything there exchanges heat with the end space's oil; the frame end
        and the cap also with ambient, the shaft end through the bearing (half its
        conductance on either side of the bearing node).
        """
        c, net, cyl, n = self.cfg, self.net, self._cylinder, self.cfg.slices
        fr, st, wd, ro, es = c.frame, c.stator, c.winding, c.rotor, c.end_spaces
        p = self.parts
        slot_frac = 1.0 - st.tooth_fraction
        L_fend = 0.5 * (fr.length_m - c.stack_length_m)
        L_send = 0.5 * (ro.shaft_length_m - c.stack_length_m)
        # end windings: the slot conductors continue out of the stack; per side the
        # end turns hold copper volume fill * A_slots * l_end_turn / 2
        a_slots = slot_frac * np.pi * (st.yoke_inner_radius_m ** 2 - g.tip ** 2)
        v_block = a_slots * wd.end_overhang_m
        v_cu = wd.copper_fill * a_slots * wd.end_turn_length_m / 2
        if v_cu > v_block:
            v_cu = v_block  # tightly packed end turns: the block is all copper
        rc_end = (v_cu * wd.copper_density_kg_m3 * wd.copper_specific_heat_J_kgK
                  + (v_block - v_cu) * wd.insulation_density_kg_m3
                  * wd.insulation_specific_heat_J_kgK) / v_block
        stack_face = 0 if side == 'front' else n
        outward = 0 if side == 'front' else 1   # index of the face away from the stack

        def joined(part: str) -> dict:
            """Join an end block to the stack face of ``part``."""
            return ({'rear_face': p[part].faces[0]} if side == 'front'
                    else {'front_face': p[part].faces[n]})

        ew = add_cylinder(net, f'end_winding_{side}', st.yoke_inner_radius_m, g.tip,
                          [wd.end_overhang_m], wd.k_radial_W_mK, wd.k_axial_W_mK, rc_end,
                          slot_frac, **joined('winding'))
        self.end_winding[side] = ew
        # the end turns are one coil per tooth: the oil's swirl meets each as a plate of
        # one coil pitch; the smooth stack faces, frame and cap as one turn of the swirl
        r_ew = 0.5 * (st.yoke_inner_radius_m + g.tip)
        coil = 2 * np.pi * r_ew / c.slots
        end = self._to_end_oil
        end(ew.faces[outward], side, a_slots, END_STATOR, r_ew, coil)
        end(ew.outer[0], side, 2 * np.pi * st.yoke_inner_radius_m * slot_frac * wd.end_overhang_m,
            END_STATOR, st.yoke_inner_radius_m, coil)
        end(ew.inner[0], side, 2 * np.pi * g.tip * slot_frac * wd.end_overhang_m, END_STATOR,
            g.tip, coil)
        # stack faces open to the end space
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
        # frame end segment, end cap, bearing, shaft end
        fe = cyl(f'frame_end_{side}', fr.outer_radius_m, fr.inner_radius_m, [L_fend],
                 fr.material, **joined('frame'))
        self._to_ambient(fe.outer[0], 2 * np.pi * fr.outer_radius_m * L_fend)
        end(fe.inner[0], side, 2 * np.pi * fr.inner_radius_m * L_fend, END_STATOR,
            fr.inner_radius_m, 2 * np.pi * fr.inner_radius_m)
        bg = c.bearings
        cap = cyl(f'end_cap_{side}', fr.outer_radius_m, bg.seat_radius_m,
                  [es.cap_thickness_m], es.cap_material)
        net.add_conductance(cap.outer[0], fe.faces[outward], es.cap_frame_htc_W_m2K * np.pi
                            * (fr.outer_radius_m ** 2 - fr.inner_radius_m ** 2))
        self.cap_links.append(net.add_conductance(cap.faces[outward], self.amb))
        self.cap_areas.append(np.pi * (fr.outer_radius_m ** 2 - bg.seat_radius_m ** 2))
        # the cap's face: facing the rotor's end face out to its radius, a swirl plate beyond
        a, r_seat = ro.outer_radius_m, bg.seat_radius_m
        self._cap_disc_share = max(a ** 2 - r_seat ** 2, 0.0) / (fr.inner_radius_m ** 2
                                                                 - r_seat ** 2)
        r_cap = 0.5 * (fr.inner_radius_m + max(a, r_seat))
        end(cap.faces[1 - outward], side, np.pi * (fr.inner_radius_m ** 2 - r_seat ** 2),
            END_CAP, r_cap, 2 * np.pi * r_cap)
        se = cyl(f'shaft_end_{side}', g.shaft, 0.0, [L_send], ro.shaft, **joined('shaft'))
        end(se.outer[0], side, 2 * np.pi * g.shaft * min(L_send, L_fend), END_SHAFT, g.shaft,
            2 * np.pi * g.shaft)
        # the bearing between shaft end and cap: its rings and balls, heated by its friction
        b = self.bearing[side] = net.add_node(
            f'bearing_{side}', bg.mass_kg * BEARING_STEEL_SPECIFIC_HEAT_J_KGK)
        net.add_conductance(se.outer[0], b, 2.0 * bg.conductance_W_K)
        net.add_conductance(b, cap.inner[0], 2.0 * bg.conductance_W_K)
        p.update({f'end_winding_{side}': ew, f'frame_end_{side}': fe,
                  f'end_cap_{side}': cap, f'shaft_end_{side}': se})

    def _build_sources(self) -> None:
        """
        Add the heat sources, one per heated node, in groups (:data:`LOSS_GROUPS`).

        Copper (slot slices, end windings), stator iron (yoke and teeth slices),
        airgap friction (its oil sections), rotor eddy currents (magnet, sleeve,
        rotor core slices), end-face friction (the end-space oil) and bearings.
        """
        c, net, p = self.cfg, self.net, self.parts
        wd, n = c.winding, c.slices
        ends = [self.end_winding['front'].mean[0], self.end_winding['rear'].mean[0]]
        self.copper_nodes = p['winding'].mean + ends
        turn = c.stack_length_m + wd.end_turn_length_m   # half a turn's conductor length
        self.copper_share = np.array([self.dz / turn] * n
                                     + [wd.end_turn_length_m / (2 * turn)] * 2)
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
        # the surfaces the end-space oil washes: node, its oil, kind, radius, plate length
        surf, oil, kind, radius, length = zip(*self.end_surfaces)
        self.end_surfaces = (np.array([net.index(m) for m in surf]),
                             np.array([net.index(m) for m in oil]), np.array(kind),
                             np.array(radius), np.array(length))
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
        ends = [net.index(self.end_winding[s].mean[0]) for s in ('front', 'rear')]
        self.idx_watch = np.concatenate([self.idx_gap, self.idx_end_oil, ends,
                                         self.idx_frame_outer, self.idx_cap_outer])
        self.watch_scale = np.concatenate([np.ones(self.idx_gap.size),
                                           np.full(self.idx_watch.size - self.idx_gap.size, 4.0)])
        # the links to ambient (frame, then end caps) for the ledger
        self._to_ambient_ids = np.array(self.ambient_links + self.cap_links)

    # ------------------------------------------------------------ coefficients
    def _oil_rho_cp(self, T_K, p_Pa):
        return self.oil.density(T_K, p_Pa) * self.oil.specific_heat(T_K)

    def refresh(self, T: np.ndarray, u: MotorInputs) -> None:
        """
        Set every temperature- and speed-dependent coefficient at temperatures ``T`` (K).

        Conductances (airgap and end-space convection, frame and end caps to
        ambient), oil heat capacities and enthalpy flow go to the network; the
        copper-loss factor R(T) and the airgap oil properties are kept for
        :meth:`losses`.
        """
        c, net, log = self.cfg, self.net, self.log
        st, ro = c.stator, c.rotor
        w = float(_mean(np.abs(u.speed_rad_s)))
        p = u.case_pressure_Pa
        self.refresh_count += 1
        T_gap = T[self.idx_gap]
        self._case_pressure_Pa = p
        gap_h = corr.airgap_wall_to_bulk_htc(
            w, ro.outer_radius_m, st.bore_radius_m, u.oil_flow_m3_s, self.oil.density(T_gap, p),
            self.oil.dynamic_viscosity(T_gap, p), self.oil.conductivity(T_gap),
            self.oil.specific_heat(T_gap), log=log)
        h = np.broadcast_to(gap_h.h, T_gap.shape)
        net.set_conductances(self.gap_links_stator, h * 2 * np.pi * st.bore_radius_m * self.dz)
        net.set_conductances(self.gap_links_rotor, h * 2 * np.pi * ro.outer_radius_m * self.dz)
        net.set_conductances(self.end_links, self._end_space_htc(T, w, p) * self.end_areas)
        Ts_frame = float(np.mean(T[self.idx_frame_outer]))
        net.set_conductances(self.ambient_links, self.ambient_areas * self._to_ambient_htc(
            Ts_frame, u.ambient_K, corr.natural_convection_htc_horizontal_cylinder))
        net.set_conductances(self.cap_links, self.cap_areas * self._to_ambient_htc(
            T[self.idx_cap_outer], u.ambient_K, corr.natural_convection_htc_vertical_plate))
        net.set_capacities(self.idx_oil, self._oil_rho_cp(T[self.idx_oil], p) * self.oil_volumes)
        # enthalpy flow: one c_p for the whole chain (the inlet's) keeps it conservative
        m_cp = u.oil_flow_m3_s * self._oil_rho_cp(u.oil_inlet_K, p)
        net.set_advection_rates(self.adv, np.full(len(self.adv), m_cp))
        self._check_electromagnetic(w, float(u.current_sq_mean_A2))
        self._refreshed_at = (w, u.oil_flow_m3_s, u.oil_inlet_K, u.ambient_K,
                              u.case_pressure_Pa)
        self._T_refreshed = T[self.idx_watch]

    def _check_electromagnetic(self, w: float, i_sq: float) -> None:
        """
        Log the validity of the analytical rotor losses near |speed| ``w`` and I^2 ``i_sq``.

        The table holds values, not their validity: the harmonic sum is run
        with the log once per bin of 2000 r/min and 10 A that the model visits
        (about 30 ms each).
        """
        if self.loss_table.from_map:
            return
        current = float(np.sqrt(max(i_sq, 0.0)))
        key = (int(w * 30.0 / np.pi // 2000.0), int(current // 10.0))
        if key not in self._em_checked:
            self._em_checked.add(key)
            rotor_eddy_loss_breakdown(self.cfg, w, current, self.log)

    def _end_space_htc(self, T: np.ndarray, w: float, p_Pa: float) -> np.ndarray:
        """
        Return h (W/(m^2 K)) of each end-space surface at temperatures ``T`` (K), |speed| ``w``.

        docs/model.md (End spaces); :func:`end_space_htc`, times
        ``end_spaces.htc_multiplier``, with the correlations' ranges flagged.
        """
        surface, oil, kind, radius, length = self.end_surfaces
        h, re_disc, re_plate, pr = end_space_htc(T, surface, oil, kind, radius, length, w, p_Pa,
                                                 self._end_geometry, self.oil.laws)
        corr.check_enclosed_disc(self.log, re_disc, self._end_geometry[2])
        corr.check_flat_plate(self.log, re_plate, pr)
        return self.cfg.end_spaces.htc_multiplier * h

    def _to_ambient_htc(self, Ts_K, T_amb_K, natural_convection) -> np.ndarray:
        """Return the surface-to-ambient h (W/(m^2 K)): fan or natural convection, + radiation."""
        fr = self.cfg.frame
        h_rad = corr.radiation_htc(Ts_K, T_amb_K, fr.emissivity)
        if fr.forced_air_htc_W_m2K is not None:
            return fr.forced_air_htc_W_m2K + h_rad
        return natural_convection(Ts_K, T_amb_K, 2 * fr.outer_radius_m, log=self.log,
                                  law=fr.natural_convection) + h_rad

    def _coefficient_point(self, dt_s: float, u: MotorInputs) -> Tuple[float, float, float]:
        """
        Advance the coefficient filter by ``dt_s`` (s); return the filtered speed and flow.

        Returns (speed rad/s, flow m^3/s, drift): the drift is the largest
        move of the (filtered) watched temperatures since the last refresh,
        in units of their thresholds (meaningless before the first refresh).
        """
        tau = self.coefficient_filter_s
        if self._filter_state is None or tau <= 0.0:
            mode, weight = FILTER_START, 1.0
            self._filter_state = np.empty((2, self.idx_watch.size + 2))
            self._filter_age_s = dt_s
        elif self._filter_age_s < tau:
            # first time constant: the running mean since the start, so the state does
            # not depend on how long the first step was
            self._filter_age_s += dt_s
            mode, weight = FILTER_RUNNING_MEAN, dt_s / self._filter_age_s
        else:
            mode, weight = FILTER_CASCADE, -math.expm1(-dt_s / tau)
        return filter_coefficient_point(
            np.asarray(u.speed_rad_s, dtype=float).reshape(-1), float(u.oil_flow_m3_s),
            self.T, self.idx_watch, self._filter_state, mode, weight, self._T_refreshed,
            self.watch_scale)

    def _refresh_point(self, speed_rad_s: float, flow_m3_s: float,
                       u: MotorInputs) -> Tuple[np.ndarray, MotorInputs]:
        """Return the (temperatures, inputs) that set the coefficients: filtered, if asked."""
        T = self.T.copy()
        T[self.idx_watch] = self._filter_state[1, 2:]
        # u with the filtered speed and flow (dataclasses.replace, without its overhead)
        return T, MotorInputs(current_sq_mean_A2=u.current_sq_mean_A2, speed_rad_s=speed_rad_s,
                              oil_inlet_K=u.oil_inlet_K, oil_flow_m3_s=flow_m3_s,
                              ambient_K=u.ambient_K, case_pressure_Pa=u.case_pressure_Pa)

    @property
    def coefficient_flow_m3_s(self) -> float:
        """Return the oil flow (m^3/s) the coefficients were last evaluated at (0 before that)."""
        return self._refreshed_at[1] if self._refreshed_at else 0.0

    def _refresh_due(self, speed_rad_s: float, flow_m3_s: float, drift: float,
                     u: MotorInputs) -> bool:
        """Tell whether a temperature or an input moved too far since the last refresh."""
        if self._refreshed_at is None:
            return True
        w0, q0, tin0, tamb0, p0 = self._refreshed_at
        return (drift > self.refresh_dT_K
                or abs(speed_rad_s - w0) > 0.01 * max(w0, 5.0)
                or abs(flow_m3_s - q0) > 0.01 * max(q0, 1e-8)
                or abs(u.oil_inlet_K - tin0) > 0.2 or abs(u.ambient_K - tamb0) > 0.5
                or abs(u.case_pressure_Pa - p0) > 1e5)

    def losses(self, u: MotorInputs, T: Optional[np.ndarray] = None) -> np.ndarray:
        """
        Source powers (W) over a step, in the order of :data:`LOSS_GROUPS`.

        Every loss but copper is averaged over the speed samples of the step
        (friction grows as about speed^2.5: the loss at the mean speed would be
        wrong); copper resistance and oil viscosity are taken at the present
        temperatures ``T`` (default: the model's); the electromagnetic losses
        at the step's mean current squared (:mod:`.loss_table`).
        """
        T = self.T if T is None else T
        w = np.asarray(u.speed_rad_s, dtype=float).reshape(-1)
        # R(T) at the present winding temperatures: cheap, and the winding is what
        # a filtered coefficient would lag most
        i_sq = float(u.current_sq_mean_A2)
        if u.current_A is None:
            i_sq_samples = np.full(w.size, i_sq)
        else:
            i_sq_samples = np.asarray(u.current_A, dtype=float).reshape(-1)
            i_sq_samples = i_sq_samples * i_sq_samples
        lt = self.loss_table
        power, re_bb_max, outside = motor_losses(
            i_sq, i_sq_samples, w, T, self._case_pressure_Pa, self._loss_nodes,
            self._copper_weight, self._copper_law, self.yoke_mass, self.teeth_mass, self._iron,
            self._iron_split, self._gap_factors, self._ends, lt.values, lt.grid, lt.from_map,
            self.oil.laws)
        if re_bb_max > corr.BILGEN_BOULOS_RE_MAX or not self._gap_in_data:
            self.airgap_friction_W(w, T)     # the friction again, to flag it in the log
        if outside:
            lt.flag(self.log, np.abs(w), i_sq_samples)
        return power

    def shaft_drag_W(self, speed_rad_s, T: Optional[np.ndarray] = None) -> np.ndarray:
        """
        Return the friction on the shaft (W) at each speed sample (rad/s).

        The airgap's oil friction, both end faces' and both bearings', with the
        oil at the temperatures of ``T`` (default: the model's): what the
        motor's torque must overcome besides the pump.
        """
        T = self.T if T is None else T
        w = np.abs(np.atleast_1d(np.asarray(speed_rad_s, dtype=float)))
        face, bearing = end_drag(w, T[self.idx_end_oil], self._case_pressure_Pa, self._ends,
                                 self.oil.laws)
        return self.airgap_friction_W(w, T).sum(axis=1) + face.sum(axis=1) + bearing.sum(axis=1)

    def electromagnetic_loss_W(self, speed_rad_s, current_A,
                               T: Optional[np.ndarray] = None) -> np.ndarray:
        """
        Return the electromagnetic losses but the DC copper loss (W) at each sample.

        Stator iron, the rotor's eddy currents and the copper's AC excess (at
        the winding's mean resistance, from ``T``, default the model's), at
        the samples' speeds (rad/s) and RMS currents (A): with phases I^2 R_dc
        what the drive's electrical input pays besides the shaft's work.
        """
        T = self.T if T is None else T
        w = np.abs(np.atleast_1d(np.asarray(speed_rad_s, dtype=float)))
        i_sq = np.square(np.broadcast_to(np.asarray(current_A, dtype=float), w.shape))
        lt = self.loss_table
        v, outside = table_values(lt.values, lt.grid, w, np.ascontiguousarray(i_sq))
        if outside:
            lt.flag(self.log, w, i_sq)
        if lt.from_map:
            iron = v[:, IRON]
        else:
            d_yoke, d_teeth = core_loss_density(w, self._iron)
            iron = self.yoke_mass.sum() * d_yoke + self.teeth_mass.sum() * d_teeth
        T_w = float(np.dot(self.copper_share, T[self.idx_copper]) / self.copper_share.sum())
        r_phase = copper_resistance(*self._copper_law, T_w)
        return (iron + v[:, MAGNET] + v[:, SLEEVE] + v[:, ROTOR_CORE]
                + self.cfg.winding.phases * r_phase * v[:, COPPER_EXCESS])

    def airgap_friction_W(self, speed_rad_s, T: Optional[np.ndarray] = None) -> np.ndarray:
        """
        Return the oil-friction power (W) of each airgap section at each speed (samples x n).

        The oil viscosity is taken at the airgap temperatures of ``T`` (default:
        the model's present ones): the gap oil swings by about a kelvin within
        a duty cycle, and friction follows it.
        """
        T = self.T if T is None else T
        w = np.abs(np.atleast_1d(speed_rad_s))
        # a simulator asks for the same speeds (for the current) that the losses then come
        # back with when the friction is to be flagged: evaluated and flagged once
        memo = self._friction_memo
        if memo is not None and memo[0] is T and np.array_equal(memo[1], w):
            return memo[2]
        out, regime, re = gap_friction(w.astype(float), T[self.idx_gap], self._case_pressure_Pa,
                                       self._gap_factors, self.oil.laws)
        corr.check_airgap_friction(self.log, regime, re, self._gap_ratio, self._gap_in_data)
        self._friction_memo = (T, w, out)
        return out

    @property
    def losses_W(self) -> Dict[str, float]:
        """Loss split (W) of the last step or steady state: :data:`LOSS_NAMES`."""
        P, src = self.power_W, self.sources
        copper = P[src['copper']]
        out = {'copper_slot': float(copper[:-2].sum()), 'copper_end': float(copper[-2:].sum())}
        out.update({g: float(P[src[g]].sum()) for g in LOSS_GROUPS[1:]})
        return out

    def boundaries(self, u: MotorInputs) -> np.ndarray:
        """Boundary temperatures (K) in network order: ambient, oil inlet."""
        return np.array([u.ambient_K, u.oil_inlet_K])

    # ----------------------------------------------------------------- solve
    def steady_state(self, u: MotorInputs, tol_K: float = 1e-6,
                     max_iter: int = 200) -> np.ndarray:
        """
        Solve the nonlinear steady state by fixed-point iteration; return all node temperatures.

        Raises RuntimeError when the coefficients do not settle (for example a
        thermal runaway where copper loss grows faster than the cooling).
        """
        steps = self.steady_state_steps(u, tol_K, max_iter)
        while True:
            try:
                next(steps)
            except StopIteration as done:
                return done.value

    def steady_state_steps(self, u: MotorInputs, tol_K: float = 1e-6, max_iter: int = 200):
        """
        Solve the steady state as :meth:`steady_state`, yielding after each iteration.

        A generator whose return value is the temperature vector: a caller with
        a time budget (the live estimator's margin) spreads the solve over
        several calls of about a millisecond each.
        """
        T = np.full(self.net.n, u.oil_inlet_K) if self.T is None else self.T.copy()
        Tb = self.boundaries(u)
        for it in range(max_iter):
            self.refresh(T, u)
            self.power_W = self.losses(u, T)
            T_new = self.net.steady_state(Tb, self.power_W)
            change = float(np.max(np.abs(T_new - T)))
            T = T_new
            if change < tol_K:
                break
            yield
        else:
            raise RuntimeError(f'steady state did not converge in {max_iter} iterations '
                               f'(last change {change:.3g} K)')
        # keep the coefficients and losses T was solved with: the balance then
        # closes to round-off, and T is within tol_K of the fixed point
        self.iterations = it + 1
        self.T = T
        self.x = self.net.initial_state(T)
        return T

    def initialise(self, T_K: float) -> None:
        """Set every node to one temperature (K), e.g. a cold start at ambient."""
        self.T = np.full(self.net.n, float(T_K))
        self.x = self.net.initial_state(self.T)

    def step(self, dt_s: float, u: MotorInputs, max_substep_s: Optional[float] = None,
             exact_coefficients: bool = False) -> np.ndarray:
        """
        Advance by ``dt_s`` with inputs ``u`` held over the step; return all node temperatures.

        Coefficients are refreshed at the start of each (sub-)step when due,
        losses are evaluated for every step, and the linear network is then
        integrated exactly over the step. ``max_substep_s`` overrides the
        sub-step limit for this step (the estimator's long steps over a
        silence, the forecast's); with ``exact_coefficients`` the coefficients
        are refreshed and put into use however little they moved: the
        tolerances that spare a re-discretisation between 20 ms steps (1 % of
        the oil flow) must not be integrated over minutes.
        """
        if self.x is None:
            raise RuntimeError('set an initial state first (initialise or steady_state)')
        substeps, h = self._substeps(dt_s, max_substep_s)
        self.last_substeps = substeps
        exact = exact_coefficients
        Tb = self._boundary_K = self.boundaries(u)
        for k in range(substeps):
            # changes held by defer_refresh in the previous step come into use, discretised
            # before this step's refresh (which is then held in turn)
            self.net.apply_changes(h)
            speed, flow, drift = self._coefficient_point(h, u)
            if exact or self._refresh_due(speed, flow, drift, u):
                self.refresh(*self._refresh_point(speed, flow, u))
                if exact:
                    self.net.use_new_coefficients()
            self.power_W = self.losses(u)
            if self.extra_power_W is not None:
                self.power_W = self.power_W + self.extra_power_W
            x_new, T_new, T_mean = self.net.step_temperatures(self.x, h, Tb, self.power_W)
            self._book(h, x_new - self.x, T_mean, u, Tb)
            # the mean over the sub-steps (summed from zero, as 0 + x is x)
            if substeps == 1:
                self.T_mean = T_mean
            else:
                self.T_mean = T_mean / substeps if k == 0 else self.T_mean + T_mean / substeps
            self.x = x_new
            self.T = T_new
        return self.T

    def prepare(self, dt_s: float) -> bool:
        """Discretise now for a next step of ``dt_s`` if a deferred refresh is pending."""
        return self.net.apply_changes(self._substeps(dt_s)[1])

    def _substeps(self, dt_s: float,
                  max_substep_s: Optional[float] = None) -> Tuple[int, float]:
        """Return the number and length (s) of the sub-steps of a step of ``dt_s``."""
        n = max(1, math.ceil(dt_s / (max_substep_s or self.max_substep_s) - 1e-9))
        return n, dt_s / n

    def _book(self, h: float, dx: np.ndarray, T_mean: np.ndarray, u: MotorInputs,
              Tb: np.ndarray) -> None:
        """Add one step's energies (J) to the ledger, with the coefficients the step used."""
        g, m_cp, cap = self.net.coefficients_in_use()
        losses, stored, to_ambient, to_oil = step_energies(
            h, self.power_W, dx, cap, self.net.dynamic, T_mean, Tb, g, self._to_ambient_ids,
            self._ambient_ends, len(self.ambient_links), float(m_cp[self.adv[0]]),
            int(self.idx_oil[-1]), float(u.oil_inlet_K))
        e = self.energy_J
        e['losses'] += losses
        e['stored'] += stored
        e['to_ambient'] += to_ambient
        e['to_oil'] += to_oil

    # --------------------------------------------------------------- outputs
    def temperature(self, name: str, T: Optional[np.ndarray] = None) -> float:
        """Return one node's temperature in K by name, e.g. winding slice 3 is 'winding.s3'."""
        T = self.T if T is None else T
        return float(T[self.net.index(name)])

    def outputs(self, T: Optional[np.ndarray] = None) -> Dict[str, float]:
        """Return the outputs of :func:`~.quantities.motor_outputs` at ``T``, in K."""
        return self.quantities.values(self.T if T is None else T)

    def heat_balance(self, T: np.ndarray, u: MotorInputs) -> Dict[str, float]:
        """
        Heat flows (W) at temperatures ``T``: losses in, the paths they take, the heat out.

        ``losses``; ``bore``: from the stator and the rotor into the airgap oil;
        ``end_spaces``: from the solids into the end-space oil; ``to_ambient``:
        frame and end caps to the air; ``to_oil``: carried off by the oil
        (m_dot c_p times its rise), which is the bore's and the end spaces'
        heat plus the friction made in the oil.
        """
        flows = self.net.link_heat_flows(T, self.boundaries(u))
        to_amb = float(flows[self.ambient_links].sum() + flows[self.cap_links].sum())
        m_cp = self.net.advection_rate[self.adv[0]]
        to_oil = float(m_cp * (T[self.idx_oil[-1]] - u.oil_inlet_K))
        bore = float(flows[self.gap_links_stator].sum() + flows[self.gap_links_rotor].sum())
        return {'losses': float(np.sum(self.power_W)), 'bore': bore,
                'end_spaces': float(flows[self.end_links].sum()), 'to_ambient': to_amb,
                'to_oil': to_oil}

    def heat_paths_W(self) -> Dict[str, float]:
        """
        Return where the last step's heat went (W), from its mean temperatures.

        ``bore`` and ``end_spaces``: from the solids into the airgap and the
        end-space oil; ``to_ambient``: frame and end caps to the air (see
        :meth:`heat_balance`, its steady-state counterpart).
        """
        flows = self.net.link_heat_flows(self.T_mean, self._boundary_K)
        return {'bore': float(flows[self.gap_links_stator].sum()
                              + flows[self.gap_links_rotor].sum()),
                'end_spaces': float(flows[self.end_links].sum()),
                'to_ambient': float(flows[self.ambient_links].sum()
                                    + flows[self.cap_links].sum())}

    @property
    def node_count(self) -> int:
        """Count the network nodes (capacitive and algebraic, boundaries excluded)."""
        return self.net.n

    @property
    def state_count(self) -> int:
        """Count the states (nodes with heat capacity)."""
        return int(self.net.dynamic.size)


@jit
def core_loss_density(speed_abs_rad_s, iron):
    """
    Return the Steinmetz loss per kg (W/kg) of the yoke and of the teeth at each speed (rad/s).

    ``iron``: pole pairs, k_h (W/(kg Hz T^alpha)), alpha, k_e (W/(kg Hz^2
    T^2)), flux density (T) of the yoke and of the teeth.
    """
    pole_pairs, k_h, alpha, k_e, b_yoke, b_teeth = iron
    f = electrical_frequency(speed_abs_rad_s, pole_pairs)
    return (steinmetz_loss_density(f, b_yoke, k_h, alpha, k_e),
            steinmetz_loss_density(f, b_teeth, k_h, alpha, k_e))


@jit
def gap_friction(speed_abs_rad_s, T_gap_K, p_Pa, gap, laws):
    """
    Return the oil friction (W) of each airgap section at each speed (samples x sections).

    The oil at the sections' temperatures ``T_gap_K`` (K) and ``p_Pa``;
    ``gap``: the factors (couette, re_per_rho_w, g03, bb_rho, ta_per_re2) of
    :func:`~.correlations.airgap_friction_factors` for one section; ``laws``:
    the oil's. Returns (power W, regime, Re_d) as
    :func:`~.correlations.airgap_friction_power`.
    """
    rho = oil_density(T_gap_K, p_Pa, laws)
    mu = oil_nu(T_gap_K, p_Pa, laws) * rho     # the dynamic viscosity
    couette, re_geo, g03, bb_rho, ta_per_re2 = gap
    return corr.airgap_friction_power(rho, mu, speed_abs_rad_s.reshape(-1, 1), couette, re_geo,
                                      g03, bb_rho, ta_per_re2)


@jit
def end_space_htc(T_K, surface, oil, kind, radius_m, length_m, w, p_Pa, geometry, laws):
    """
    Return h (W/(m^2 K)) of each end-space surface, and the disc's and plates' Re and Pr.

    The surfaces: node ``surface`` washed by node ``oil`` of ``T_K`` (K), of
    ``kind`` (END_*), mean radius and plate length (m); ``w`` |speed|
    (rad/s); oil properties at the film temperature and ``p_Pa``.
    ``geometry``: disc radius a (m), the Daily-Nece laws and G at its
    clearance, the share of the cap facing the disc, the end space's depth
    (m). The rotor's end face, and the cap where it faces it:
    :func:`~.correlations.disc_nusselt`; the stator surfaces and the shaft
    end: :func:`~.correlations.plate_nusselt` in the swirl of
    :func:`~.correlations.end_space_swirl_speed` (relative to the shaft for
    the shaft), never below conduction through half the end space's depth.
    """
    a, disc_laws, g, cap_share, depth = geometry
    T_film = 0.5 * (T_K[surface] + T_K[oil])
    rho = oil_density(T_film, p_Pa, laws)
    nu = oil_nu(T_film, p_Pa, laws)
    k = oil_conductivity(T_film, laws)
    pr = nu * rho * oil_cp(T_film, laws) / k
    v = corr.end_space_swirl_speed(w, a, radius_m, corr.CORE_SWIRL_RATIO)
    v = np.where(kind == END_SHAFT, w * radius_m - v, v)
    re_plate = v * length_m / nu
    h = np.maximum(corr.plate_nusselt(re_plate, pr) * k / length_m, 2.0 * k / depth)
    re_disc = np.zeros(kind.size)
    for i in range(kind.size):
        if kind[i] <= END_CAP:
            re_disc[i] = w * a * a / nu[i]
            h_disc = corr.disc_nusselt(re_disc[i], pr[i], disc_laws, g) * k[i] / a
            if kind[i] == END_ROTOR_FACE:
                h[i] = h_disc
            else:
                h[i] = cap_share * h_disc + (1.0 - cap_share) * h[i]
    return h, re_disc, re_plate, pr


@jit
def end_drag(speed_abs_rad_s, T_end_K, p_Pa, ends, laws):
    """
    Return the friction (W) of each end face and of each bearing at each |speed| (samples x 2).

    With the end spaces' oil at ``T_end_K`` (K, front and rear) and ``p_Pa``:
    the rotor's end face, :func:`~.correlations.enclosed_disc_friction`; the
    bearing, :func:`~.correlations.palmgren_bearing_torque` times the speed
    and the calibration factor. ``ends``: disc radius (m), the Daily-Nece
    laws at its clearance (:func:`~.correlations.daily_nece_laws`), bearing
    pitch diameter (m), f0, f1, load (N), factor.
    """
    a, disc, dm, f0, f1, load, factor = ends
    rho = oil_density(T_end_K, p_Pa, laws)
    nu = oil_nu(T_end_K, p_Pa, laws)
    n = speed_abs_rad_s.size
    face = np.empty((n, 2))
    bearing = np.empty((n, 2))
    for e in range(2):
        mu = nu[e] * rho[e]
        for k in range(n):
            w = speed_abs_rad_s[k]
            face[k, e] = corr.enclosed_disc_friction(rho[e], mu, w, a, disc)[0]
            torque = corr.palmgren_bearing_torque(nu[e], w, dm, f0, f1, load)
            bearing[k, e] = factor * w * torque
    return face, bearing


@jit
def motor_losses(current_sq_mean_A2, current_sq_A2, speed_rad_s, T_K, case_pressure_Pa, nodes,
                 copper_weight, copper_law, yoke_mass_kg, teeth_mass_kg, iron, iron_split, gap,
                 ends, table, grid, from_map, laws):
    """
    Return the source powers (W), the largest Bilgen-Boulos Re_d, whether the table ran out.

    The powers of :meth:`WetMotor.losses`; whether the loss table was extrapolated.

    ``nodes``: the indices in ``T_K`` (K) of the copper nodes, the airgap
    sections and the two end spaces. The table (``table``, ``grid``: see
    :mod:`.loss_table`) at each speed sample (rad/s) and its current squared
    ``current_sq_A2`` (A^2). Copper: ``current_sq_mean_A2`` (A^2)
    plus the table's AC excess, x ``copper_weight`` (phases x each source's
    share of the conductor length) x R(T) of each copper node,
    ``copper_law`` the phase resistance at 20 degC (ohm) and its tempco
    (1/K); iron: the yoke's and the teeth's masses (kg) x their Steinmetz
    loss per kg (``iron``, see :func:`core_loss_density`), or with
    ``from_map`` the table's iron loss shared by ``iron_split``; friction
    (:func:`gap_friction`, :func:`end_drag`) at ``case_pressure_Pa``;
    magnet, sleeve and rotor core from the table, the same in every slice.
    Every loss but the DC copper is a mean over the samples. The Re_d returned is the largest
    where Bilgen-Boulos set the airgap friction (0 where it set none): what
    the validity log would flag.
    """
    idx_copper, idx_gap, idx_end = nodes
    w = np.abs(speed_rad_s)
    n_s = w.size
    n_cu, n = idx_copper.size, idx_gap.size
    power = np.empty(n_cu + 6 * n + 4)
    em, outside = table_values(table, grid, w, current_sq_A2)
    em_mean = em.sum(axis=0) / n_s
    power[:n_cu] = (current_sq_mean_A2 + em_mean[COPPER_EXCESS]) * copper_weight \
        * copper_resistance(copper_law[0], copper_law[1], T_K[idx_copper])
    k = n_cu
    if from_map:
        power[k:k + 2 * n] = em_mean[IRON] * iron_split
    else:
        d_yoke, d_teeth = core_loss_density(w, iron)
        power[k:k + n] = yoke_mass_kg * (d_yoke.sum() / n_s)
        power[k + n:k + 2 * n] = teeth_mass_kg * (d_teeth.sum() / n_s)
    k += 2 * n
    friction, regime, re = gap_friction(w, T_K[idx_gap], case_pressure_Pa, gap, laws)
    power[k:k + n] = friction.sum(axis=0) / n_s
    k += n
    for column in (MAGNET, SLEEVE, ROTOR_CORE):
        power[k:k + n] = em_mean[column] / n
        k += n
    face, bearing = end_drag(w, T_K[idx_end], case_pressure_Pa, ends, laws)
    power[k:k + 2] = face.sum(axis=0) / n_s
    power[k + 2:k + 4] = bearing.sum(axis=0) / n_s
    re_bb_max = 0.0
    for i in range(re.size):
        if regime.flat[i] != 0 and re.flat[i] > re_bb_max:
            re_bb_max = re.flat[i]
    return power, re_bb_max, outside


@jit
def step_energies(dt_s, power_W, dx, capacity, dynamic, T_mean, boundary_K, conductance,
                  ambient_ids, ambient_ends, n_frame, inlet_rate_W_K, outlet, inlet_K):
    """
    Return a step's energies (J): generated, stored, to ambient, carried off by the oil.

    Over ``dt_s`` (s): the sources' ``power_W`` (W); the states' change ``dx``
    (K) times their heat capacities (``capacity`` J/K of every node, the
    states at ``dynamic``); the heat through the links ``ambient_ids`` of
    ``conductance`` (W/K) at the step-mean temperatures ``T_mean`` (K) and
    ``boundary_K`` (their ends index [T; T_b], the frame's ``n_frame``
    first, then the end caps'); the enthalpy flow ``inlet_rate_W_K`` (m c_p,
    W/K) from ``inlet_K`` (K) to the mean of node ``outlet``.
    """
    n = T_mean.size
    to_frame = 0.0
    to_caps = 0.0
    for k in range(ambient_ids.size):
        a, b = ambient_ends[k, 0], ambient_ends[k, 1]
        dT = ((T_mean[a] if a < n else boundary_K[a - n])
              - (T_mean[b] if b < n else boundary_K[b - n]))
        if k < n_frame:
            to_frame += conductance[ambient_ids[k]] * dT
        else:
            to_caps += conductance[ambient_ids[k]] * dT
    return (power_W.sum() * dt_s, np.dot(capacity[dynamic], dx), (to_frame + to_caps) * dt_s,
            inlet_rate_W_K * (T_mean[outlet] - inlet_K) * dt_s)


@jit
def filter_coefficient_point(speed_rad_s, oil_flow_m3_s, T_K, idx_watch, stages, mode, weight,
                             T_refreshed_K, watch_scale):
    """
    Move the coefficient filter by one step, in place; return (speed, flow, drift).

    The filter's input is [mean |speed| (rad/s), ``oil_flow_m3_s``, the
    temperatures (K) of the nodes ``idx_watch`` of ``T_K``]; ``stages``
    (2 x that) its two stages. ``mode`` FILTER_START sets both to the input;
    FILTER_RUNNING_MEAN moves the first by ``weight`` (dt / age) towards the
    input and the second with it; FILTER_CASCADE moves the first by
    ``weight`` (1 - exp(-dt / tau)) towards the input and the second by the
    same weight towards the first. Returns the second stage's speed and flow, and
    the largest move of its temperatures from ``T_refreshed_K`` in units of
    ``watch_scale``.
    """
    raw = np.empty(idx_watch.size + 2)
    raw[0] = np.abs(speed_rad_s).sum() / speed_rad_s.size
    raw[1] = oil_flow_m3_s
    raw[2:] = T_K[idx_watch]
    f1, f2 = stages[0], stages[1]
    if mode == FILTER_START:
        f1[:] = raw
        f2[:] = raw
    elif mode == FILTER_RUNNING_MEAN:
        f1 += (raw - f1) * weight
        f2[:] = f1
    else:
        f1 += weight * (raw - f1)
        f2 += weight * (f1 - f2)
    drift = (np.abs(f2[2:] - T_refreshed_K) / watch_scale).max()
    return f2[0], f2[1], drift
