"""
Thermal network of the wet PMSM: Mellor blocks, advected airgap oil, losses.

Layout (front = oil-inlet side, rear = outlet side; stack slices 1..n):

- stack parts, one Mellor slice per axial section: ``frame``, ``yoke``,
  ``teeth`` (iron share of the tooth annulus), the slot share in radial layers
  ``winding.l1..`` (slot bottom to tip), ``sleeve``, ``magnet``, ``rotor_core``,
  ``shaft``; airgap oil ``gap_oil.s1..``;
- each end: ``frame_end_<side>``, ``end_cap_<side>`` and its hub
  ``end_cap_hub_<side>``, the end winding's layers ``end_winding_<side>.l1..``
  (continuing the slot's), ``shaft_end_<side>``, the bearing ``bearing_<side>``
  and the end-space oil ``end_oil_<side>``;
- boundaries ``ambient`` and ``oil_inlet``.

Oil path: oil_inlet -> end_oil_front -> gap_oil.s1 .. s<n> -> end_oil_rear
(the motor outlet). Heat leaves by the oil and by the frame and end caps to
ambient (natural convection and radiation, or a fan coefficient).
"""

from dataclasses import dataclass
import math
from typing import Dict, Optional, Tuple, Union

import numpy as np

from . import correlations as corr
from .loss_table import build_loss_table, COPPER_EXCESS, IRON, MAGNET, ROTOR_CORE, SLEEVE, \
    table_values
from .losses import copper_resistance
from .motor_build import LOSS_GROUPS, LOSS_NAMES, MotorNetworkBuilder  # noqa: F401 (importers)
from .motor_kernels import AmbientLedger, CopperLaw, core_loss_density, end_drag, \
    END_ROTOR_FACE, END_SHAFT, end_space_htc, end_space_swirl, end_space_torques, EndDrag, \
    EndGeometry, FILTER_CASCADE, filter_coefficient_point, FILTER_RUNNING_MEAN, FILTER_START, \
    gap_friction, GapFriction, IronLaw, motor_losses, MotorLossConstants, step_energies
from .network import ThermalNetwork
from .oil import Oil
from .quantities import motor_outputs, QuantityMap
from .rotor_losses import rotor_eddy_loss_breakdown
from .validity import ValidityLog
from ..config import Motor
from ..units import C_TO_K, RPM, RPM_PER_RAD_S


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


class WetMotor(MotorNetworkBuilder):
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
        self._copper_law = CopperLaw(float(wd.phase_resistance_20C_ohm),
                                     float(wd.copper_tempco_1_K))
        self._iron = IronLaw(*(float(v) for v in (
            cfg.pole_pairs, st.hysteresis_coeff_W_kgHzT, st.steinmetz_exponent,
            st.eddy_coeff_W_kgHz2T2, st.yoke_flux_density_T, st.teeth_flux_density_T)))
        couette, re_geo, self._gap_ratio, self._gap_in_data, g03, bb_rho, ta_per_re2 = \
            corr.airgap_friction_factors(ro.outer_radius_m, st.bore_radius_m, self.dz)
        self._gap_factors = GapFriction(*(float(v) for v in (couette, re_geo, g03, bb_rho,
                                                             ta_per_re2)))
        # a map's iron loss goes to the yoke and teeth slices as mass x B^2 (Steinmetz's
        # split when alpha = 2)
        weights = np.concatenate([self.yoke_mass * st.yoke_flux_density_T ** 2,
                                  self.teeth_mass * st.teeth_flux_density_T ** 2])
        self._iron_split = weights / weights.sum()
        # the end spaces: the rotor's end face as Daily and Nece's disc, its laws at the
        # clearance ratio of the hub the network draws (_build_end_housing)
        g = cfg.end_spaces.rotor_clearance_m / ro.outer_radius_m
        self._end_geometry = EndGeometry(
            float(ro.outer_radius_m), corr.daily_nece_laws(g), float(g),
            0.5 * (cfg.frame.length_m - cfg.stack_length_m), self.idx_end_oil)
        bg = cfg.bearings
        #: each end space's core swirl ratio K (front, rear) at the last coefficient refresh
        #: (before the first: at half the top speed, the oil at 40 degC)
        self.end_swirl_ratio = np.zeros(2)
        T0 = C_TO_K + 40.0
        for e in range(2):
            self.end_swirl_ratio[e] = end_space_swirl(
                e, 0.5 * cfg.max_speed_rpm * RPM, float(oil.density(T0, 0.0)),
                float(oil.kinematic_viscosity(T0, 0.0)), tuple(self.end_surfaces),
                tuple(self._end_geometry))[0]
        es = self.end_surfaces
        turning = (es.kind == END_ROTOR_FACE) | (es.kind == END_SHAFT)
        self._ends = tuple(EndDrag(
            float(ro.outer_radius_m), self._end_geometry.disc_laws,
            np.column_stack([es.side, es.kind, es.radius_m, es.length_m, es.area_m2])[turning],
            self.end_swirl_ratio, float(bg.mean_diameter_m), float(bg.lubrication_factor_f0),
            float(corr.deep_groove_ball_f1(bg.radial_load_N, bg.static_load_rating_N)),
            float(bg.radial_load_N), float(bg.friction_factor)))
        #: the electromagnetic losses over speed and current (rotor, AC copper; a map's all)
        self.loss_table = build_loss_table(cfg)
        lt = self.loss_table
        # a plain tuple: see motor_kernels
        self._loss_constants = tuple(MotorLossConstants(
            self.idx_copper, self.idx_gap, self.idx_end_oil, wd.phases * self.copper_share,
            self._copper_law, self.yoke_mass, self.teeth_mass, self._iron, self._iron_split,
            self._gap_factors, self._ends, lt.values, lt.grid, lt.from_map, self.oil.laws))
        self._em_checked = set()    # (speed, current) bins whose rotor-loss validity is logged
        self.check_rotor_validity = True
        # the books' links to ambient (the frame's, then the end caps'), ends in [T; T_b]
        self._ambient_ledger = tuple(AmbientLedger(
            self._to_ambient_ids, self.net.link_ends(self._to_ambient_ids),
            len(self.ambient_links), int(self.idx_oil[-1])))
        self.net.hold_changes = defer_refresh
        self.x: Optional[np.ndarray] = None
        self.T: Optional[np.ndarray] = None
        self.power_W = np.zeros(self.net.ns)
        #: the AC part of each copper source's loss (W) at the last losses
        self.copper_ac_W = np.zeros(self.idx_copper.size)
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
            self.oil.specific_heat(T_gap), log=log, nusselt=c.airgap_nusselt)
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
        (about 30 ms each). A copy that gives advice (the estimator's
        limits) sets ``check_rotor_validity`` false: its log is thrown away.
        """
        if self.loss_table.from_map or not self.check_rotor_validity:
            return
        current = float(np.sqrt(max(i_sq, 0.0)))
        key = (int(w * RPM_PER_RAD_S // 2000.0), int(current // 10.0))
        if key not in self._em_checked:
            self._em_checked.add(key)
            rotor_eddy_loss_breakdown(self.cfg, w, current, self.log)

    def _end_space_htc(self, T: np.ndarray, w: float, p_Pa: float) -> np.ndarray:
        """
        Return h (W/(m^2 K)) of each end-space surface at temperatures ``T`` (K), |speed| ``w``.

        docs/model.md (End spaces); :func:`end_space_htc`, times
        ``end_spaces.htc_multiplier``, with the correlations' ranges flagged.
        """
        h, re_disc, re_plate, pr = end_space_htc(T, tuple(self.end_surfaces), w, p_Pa,
                                                 tuple(self._end_geometry), self.oil.laws,
                                                 self.end_swirl_ratio)
        corr.check_enclosed_disc_nusselt(self.log, re_disc, self._end_geometry.gap_ratio)
        corr.check_flat_plate_nusselt(self.log, re_plate, pr)
        return self.cfg.end_spaces.htc_multiplier * h

    def end_space_torques_Nm(self, speed_rad_s: float, T: Optional[np.ndarray] = None,
                             p_Pa: Optional[float] = None) -> Tuple[np.ndarray, np.ndarray]:
        """
        Return each end space's core swirl ratio K and the torque (N m) of each wetted surface.

        docs/model.md (End spaces): K (front, rear) from the torque balance of
        each end space at |``speed_rad_s``| with the oil at the temperatures of
        ``T`` (K, default the model's) and ``p_Pa`` (default the case pressure
        of the last refresh), and the torque each surface of
        :attr:`end_surfaces` puts on its oil: positive from the rotating ones
        (the rotor's end face, the shaft end), negative on the stationary ones.
        The model's own K and friction are those of its last refresh.
        """
        T = self.T if T is None else T
        p = self._case_pressure_Pa if p_Pa is None else p_Pa
        w = abs(float(speed_rad_s))
        swirl = np.zeros(2)
        surfaces, geometry = tuple(self.end_surfaces), tuple(self._end_geometry)
        T_oil = T[self.idx_end_oil]
        rho, nu = self.oil.density(T_oil, p), self.oil.kinematic_viscosity(T_oil, p)
        for e in range(2):
            swirl[e] = end_space_swirl(e, w, float(rho[e]), float(nu[e]), surfaces, geometry)[0]
        return swirl, end_space_torques(T, surfaces, w, p, geometry, self.oil.laws, swirl)

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
            self.T, mode, weight,
            (self.idx_watch, self._filter_state, self._T_refreshed, self.watch_scale))

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
        power, re_bb_max, outside, excess = motor_losses(
            i_sq, i_sq_samples, w, T, self._case_pressure_Pa, self._loss_constants)
        # the copper sources' AC part (W): it falls as R(T) rises (a filter's dP/dT needs it)
        law = self._copper_law
        self.copper_ac_W = (excess * law.r_20C_ohm ** 2 * self.cfg.winding.phases
                            * self.copper_share / copper_resistance(
                                law.r_20C_ohm, law.tempco_1_K, T[self.idx_copper]))
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

        Stator iron, the rotor's eddy currents and the copper's AC excess (as
        1 / R at the winding's mean resistance, from ``T``, default the model's), at
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
        r_phase = copper_resistance(self._copper_law.r_20C_ohm, self._copper_law.tempco_1_K, T_w)
        return (iron + v[:, MAGNET] + v[:, SLEEVE] + v[:, ROTOR_CORE] + self.cfg.winding.phases
                * self._copper_law.r_20C_ohm ** 2 / r_phase * v[:, COPPER_EXCESS])

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
        k = self.n_slot_copper
        out = {'copper_slot': float(copper[:k].sum()), 'copper_end': float(copper[k:].sum())}
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
            h, self.power_W, dx, cap, self.net.dynamic, T_mean, Tb, g, self._ambient_ledger,
            float(m_cp[self.adv[0]]), float(u.oil_inlet_K))
        e = self.energy_J
        e['losses'] += losses
        e['stored'] += stored
        e['to_ambient'] += to_ambient
        e['to_oil'] += to_oil

    # --------------------------------------------------------------- outputs
    def temperature(self, name: str, T: Optional[np.ndarray] = None) -> float:
        """Return one node's temperature in K by name, e.g. magnet slice 3 is 'magnet.s3'."""
        T = self.T if T is None else T
        return float(T[self.net.index(name)])

    def winding_slices_K(self, T: Optional[np.ndarray] = None) -> np.ndarray:
        """Return each stack slice's slot winding mean (K), its layers' volume mean, at ``T``."""
        T = self.T if T is None else T
        slot = T[self.idx_copper[:self.n_slot_copper]].reshape(self.cfg.slices, -1)
        return slot @ self.layer_share

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
