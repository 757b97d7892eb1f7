"""
The rig described by the configuration: the motor, the hydraulic circuit, the oil.

The sections under ``motor``, ``hydraulics`` and ``fluid`` (the thermal
model's parameters); :mod:`wet_eha_thermal.config` holds the jobs done with
them (maps, estimator, calibration) and loads the whole file.
"""

from dataclasses import dataclass
from typing import Optional

from .config_spec import check_below, ConfigError, fraction, OIL_GRADE_NAMES, positive, spec
from .loss_map import LossMapError, read_loss_map


def laws(registry: str):
    """
    Return the choices of a selectable law: the names of ``registry`` in model/correlations.py.

    Read when a value is checked, not at import: the configuration layer
    imports nothing of the model (which imports it).
    """
    def names():
        from .model import correlations
        return tuple(getattr(correlations, registry))
    return names


@dataclass(frozen=True, kw_only=True)
class Solid:
    """Thermal properties of a solid material (anisotropic conductivity allowed)."""

    k_radial_W_mK: float = positive('radial (in-plane) conductivity')
    k_axial_W_mK: float = positive('axial conductivity')
    density_kg_m3: float = positive('times the specific heat: the heat capacity per volume')
    specific_heat_J_kgK: float = positive('specific heat capacity')

    @property
    def rho_c_J_m3K(self) -> float:
        """Volumetric heat capacity (J/(m^3 K))."""
        return self.density_kg_m3 * self.specific_heat_J_kgK


@dataclass(frozen=True, kw_only=True)
class Frame:
    """Motor frame (housing) over the stack and the end spaces."""

    outer_radius_m: float = positive('outer radius of the barrel, whose surface meets the air')
    inner_radius_m: float = positive('bore of the housing, where the stator sits')
    length_m: float = positive('total axial length, stack plus both end spaces')
    emissivity: float = spec(0.0, 1.0, doc=(
        'of the barrel and end caps, for radiation to ambient (reference rig: est.)'))
    forced_air_htc_W_m2K: Optional[float] = spec(
        0.0, None, low_open=True, default=None,
        doc='fan cooling; null for natural convection plus radiation')
    natural_convection: str = spec(
        choices=laws('NATURAL_CONVECTION'), default='churchill_chu',
        doc='free convection law of the barrel and the end caps: Churchill-Chu (1975), '
            'or the power laws of Morgan (1975, cylinder) and McAdams (1954, plate)')
    material: Solid = spec(doc='housing material, also of the frame over the end spaces')

    def check(self, key: str) -> None:
        """Check the frame geometry."""
        check_below(key, 'inner_radius_m', self.inner_radius_m, 'outer_radius_m',
                    self.outer_radius_m)


@dataclass(frozen=True, kw_only=True)
class Stator:
    """Laminated stator: yoke, teeth and the Steinmetz loss data of the steel."""

    outer_radius_m: float = positive('outer radius of the laminations, in the frame bore')
    yoke_inner_radius_m: float = positive('inner radius of the yoke: the slot bottoms')
    bore_radius_m: float = positive('at the tooth tips: the outer wall of the oil-filled airgap')
    tooth_tip_depth_m: float = spec(0.0, None, doc='tooth tips between bore and slot')
    tooth_fraction: float = spec(0.0, 1.0, low_open=True, high_open=True,
                                 doc='share of the tooth annulus that is iron')
    material: Solid = spec(doc='lamination steel; axial conductivity across the laminations')
    hysteresis_coeff_W_kgHzT: float = spec(0.0, None, doc='Steinmetz k_h per kg')
    steinmetz_exponent: float = spec(1.0, 3.0, doc='Steinmetz alpha of k_h f B^alpha')
    eddy_coeff_W_kgHz2T2: float = spec(0.0, None, doc='Steinmetz k_e per kg')
    yoke_flux_density_T: float = spec(0.0, 2.5, doc='in the yoke: the B of its iron loss')
    teeth_flux_density_T: float = spec(0.0, 2.5, doc='in the teeth: the B of their iron loss')
    frame_contact_gap_m: float = spec(0.0, 1e-3, low_open=True,
                                      doc='equivalent air gap of the interference fit')
    contact_gap_conductivity_W_mK: float = positive(
        'of the gas in that gap: h = conductivity / gap (reference rig: air at about 60 degC)')

    def check(self, key: str) -> None:
        """Check the stator geometry."""
        check_below(key, 'bore_radius_m', self.bore_radius_m, 'yoke_inner_radius_m',
                    self.yoke_inner_radius_m)
        check_below(key, 'yoke_inner_radius_m', self.yoke_inner_radius_m, 'outer_radius_m',
                    self.outer_radius_m)
        check_below(key, 'tooth_tip_depth_m', self.tooth_tip_depth_m, 'slot depth (yoke inner '
                    'radius - bore radius)', self.yoke_inner_radius_m - self.bore_radius_m)


@dataclass(frozen=True, kw_only=True)
class Winding:
    """Slot winding and end windings (copper + insulation + impregnation)."""

    phases: int = spec(1, 12, doc='the copper loss is phases x I^2 R, I the RMS phase current')
    phase_resistance_20C_ohm: float = positive('line to neutral')
    copper_tempco_1_K: float = spec(0.0, 0.01, doc=(
        'temperature coefficient of the resistance: R = R_20 (1 + a (T - 20 degC))'))
    k_radial_W_mK: float = positive(
        'slot-equivalent transverse conductivity (copper, enamel, impregnation; est. on the '
        'reference rig: measure it, or fit it with calibrate)')
    k_axial_W_mK: float = positive('along the conductors')
    copper_density_kg_m3: float = positive('of the conductors, for the heat capacity')
    copper_specific_heat_J_kgK: float = positive('of the conductors')
    insulation_density_kg_m3: float = positive(
        'of what is not copper (insulation, impregnation), for the heat capacity')
    insulation_specific_heat_J_kgK: float = positive('of what is not copper')
    end_overhang_m: float = positive('axial length of the end winding, each side')
    end_turn_length_m: float = positive('conductor length of one end turn, each side')
    liner_thickness_m: float = positive('slot liner (and wedge) thickness')
    liner_conductivity_W_mK: float = positive(
        'of the slot liner: winding to yoke and teeth through h = conductivity / thickness')
    insulation_limit_C: float = spec(0.0, 300.0, doc=(
        'insulation class limit: the winding hot-spot limit of the reports, the forecast and '
        'the margin current'))
    conductor_diameter_m: float = spec(0.0, 0.01, low_open=True, doc=(
        'bare diameter of the round wire: the copper area, the resistance and the AC factor'))
    insulated_diameter_m: float = spec(0.0, 0.01, low_open=True, doc=(
        'overall diameter over the enamel: how many rows of wire the slot depth holds'))
    strands_in_hand: int = spec(1, 1000, default=1, doc='parallel wires wound as one turn')
    turns_per_coil: int = spec(1, 10000, doc='turns of each tooth coil')
    coil_sides_per_slot: int = spec(1, 2, default=2, doc=(
        '2: double-layer tooth-coil winding (a coil on every tooth); 1: single-layer (every '
        'other tooth)'))
    parallel_paths: int = spec(1, 100, default=1, doc='parallel paths of each phase')

    #: keys this section had, and what replaces them (a clear error instead of "unknown")
    RETIRED = {'copper_fill': 'the fill is derived from the wire, the turns and the slot: '
                              'give conductor_diameter_m, insulated_diameter_m, '
                              'strands_in_hand, turns_per_coil, coil_sides_per_slot',
               'layers_per_slot_side': 'the rows of the AC factor are derived from the wire, '
                                       'the turns and the slot: give the keys that describe '
                                       'them (turns_per_coil, insulated_diameter_m, ...)'}


@dataclass(frozen=True, kw_only=True)
class Rotor:
    """Surface-mounted PM rotor: sleeve, magnets, core, shaft and their contacts."""

    outer_radius_m: float = positive('over the sleeve')
    sleeve_thickness_m: float = positive('radial thickness of the retaining sleeve')
    magnet_thickness_m: float = positive('radial thickness of the magnets, under the sleeve')
    core_inner_radius_m: float = positive('= shaft radius')
    shaft_length_m: float = positive(
        'whole shaft; its ends past the stack reach through the end spaces to the bearings')
    sleeve: Solid = spec(doc='retaining sleeve (reference rig: Inconel 718, est.)')
    magnet: Solid = spec(doc='the magnets (reference rig: NdFeB, catalogue values)')
    core: Solid = spec(doc='rotor core under the magnets')
    shaft: Solid = spec(doc='the shaft, through the stack and both end spaces')
    sleeve_magnet_htc_W_m2K: float = positive('contact conductance per area')
    magnet_core_htc_W_m2K: float = positive('glue layer')
    core_shaft_htc_W_m2K: float = positive('shrink fit')
    magnet_limit_C: float = spec(0.0, 400.0, doc=(
        "the magnet grade's limit: the magnet limit of the reports and the forecast"))

    def check(self, key: str) -> None:
        """Check that the rotor layers fit inside each other."""
        inner = self.outer_radius_m - self.sleeve_thickness_m - self.magnet_thickness_m
        check_below(key, 'core_inner_radius_m', self.core_inner_radius_m,
                    'magnet inner radius (outer_radius_m - sleeve - magnet thickness)', inner)


@dataclass(frozen=True, kw_only=True)
class EndSpaces:
    """The two oil-filled end spaces and end caps."""

    oil_volume_m3: float = positive('each end space')
    rotor_clearance_m: float = positive(
        "axial clearance between the rotor's end face and the end cap's hub (the bearing "
        "housing, of the rotor's radius, reaching in from the cap inside the end winding): "
        'the Daily-Nece disc friction and heat transfer of the face, and where the network '
        'and the finite-element check draw the hub')
    htc_multiplier: float = spec(0.0, 10.0, low_open=True, default=1.0, doc=(
        "calibration factor on every end-space coefficient (the correlations' value: 1)"))
    cap_thickness_m: float = positive('axial thickness of each end cap (reference rig: est.)')
    cap_material: Solid = spec(doc='end caps (reference rig: aluminium alloy)')
    cap_frame_htc_W_m2K: float = positive('bolted joint, per area of the frame end face')


@dataclass(frozen=True, kw_only=True)
class Bearings:
    """The two rolling bearings, one in each end cap, running flooded in the end-space oil."""

    seat_radius_m: float = positive('bearing seat (outer ring) radius in the end cap')
    mean_diameter_m: float = positive('pitch diameter (bore + outside diameter) / 2')
    conductance_W_K: float = positive(
        'through each bearing, shaft end to end cap (reference rig: est.)')
    mass_kg: float = positive('each bearing: its heat capacity (steel)')
    radial_load_N: float = spec(0.0, None, doc="each bearing's radial load: Palmgren's P1")
    static_load_rating_N: float = positive("C0 of the catalogue: Palmgren's load factor f1")
    lubrication_factor_f0: float = positive(
        "Palmgren's f0 of the bearing type and lubrication (Harris and Kotzalas, ch. 12)")
    friction_factor: float = spec(0.0, 10.0, default=1.0, doc=(
        "calibration factor on Palmgren's friction torque (the correlation's value: 1)"))


@dataclass(frozen=True, kw_only=True)
class LossMap:
    """Motor losses over speed and current from an electromagnetic FEA (Motor-CAD, JMAG, ...)."""

    file: str = spec(doc=(
        'CSV grid with the columns speed_rpm, current_A, copper_W, stator_iron_W, magnet_W, '
        'sleeve_W (and optionally rotor_core_W), one row per point of a full speed x current '
        "grid; a relative path is taken from the configuration file's folder"))
    copper_temperature_C: float = spec(-60.0, 250.0, default=20.0, doc=(
        "winding temperature of the map's copper loss: the model scales it by R(T)"))

    def check(self, key: str) -> None:
        """Read and check the CSV now, so that a bad map stops the load naming this key."""
        try:
            read_loss_map(self.file)
        except LossMapError as exc:
            raise ConfigError(f'{key}.file = {self.file!r}: {exc}') from exc


@dataclass(frozen=True, kw_only=True)
class Electromagnetic:
    """Data of the rotor's eddy-current losses and of the inverter's PWM ripple."""

    magnet_resistivity_ohm_m: float = positive('electrical resistivity of the magnets')
    magnet_relative_permeability: float = spec(1.0, 2.0, doc='recoil permeability')
    magnet_remanence_T: float = spec(0.1, 2.0, doc=(
        "at 20 degC: the magnets' airgap field, which with the torque constant sets the "
        'current sheet of the winding'))
    pole_arc_fraction: float = fraction('magnet arc over pole pitch')
    magnet_pieces_per_pole: int = spec(1, 100, doc='magnet pieces of one pole around the rotor')
    magnet_pieces_axial: int = spec(1, 100, doc='magnet pieces of one pole along the stack')
    sleeve_resistivity_ohm_m: float = positive('electrical resistivity of the retaining sleeve')
    slot_opening_m: float = spec(0.0, None, doc=(
        'width of the slot openings at the bore; the current sheet is spread over it'))
    pwm_frequency_Hz: float = positive('switching (carrier) frequency of the two-level inverter')
    dc_link_voltage_V: float = positive("the inverter's DC link")
    phase_inductance_H: float = positive('line to neutral, at the PWM frequencies')
    rotor_core: str = spec(choices=('solid', 'laminated'), doc=(
        'the steel under the magnets: solid (eddy loss by its surface impedance) or '
        'laminated (no loss)'))
    core_resistivity_ohm_m: float = positive('of a solid rotor core')
    core_relative_permeability: float = spec(1.0, 1.0e5, doc=(
        "of a solid rotor core, incremental, under the magnets' bias"))
    loss_factor: float = spec(0.0, 10.0, default=1.0, doc=(
        'calibration multiplier on the rotor eddy losses (magnets, sleeve, core)'))


@dataclass(frozen=True, kw_only=True)
class Motor:
    """The wet motor: geometry, materials, contacts and discretisation."""

    slices: int = spec(1, 50, doc='axial Mellor slices of the stack')
    winding_layers: int = spec(1, 20, doc=(
        'radial Mellor layers of the slot winding and the end windings, of equal depth: the '
        'heat that runs along the wire at each depth (docs/model.md, Winding layers)'))
    pole_pairs: int = spec(1, 50, doc=(
        'rotor pole pairs: the iron loss frequency is pole_pairs x speed / (2 pi)'))
    slots: int = spec(3, 200, doc=(
        "stator slots: the tooth pitch, and the slot sides that carry the winding's heat to "
        'the teeth'))
    stack_length_m: float = positive('axial length of the laminated stack (the active length)')
    airgap_nusselt: str = spec(
        choices=laws('AIRGAP_NUSSELT'), default='becker_kaye',
        doc='rotational Nusselt law of the oil-filled airgap (correlations.AIRGAP_NUSSELT): '
            'Becker and Kaye (1962), or Tachibana, Fukui and Mitsumura (1960)')
    torque_constant_Nm_A: float = positive('per A RMS phase current')
    max_continuous_current_A: float = positive(
        "continuous rating, A RMS (datasheet): the estimator's margin-current search starts there")
    peak_current_A: float = positive(
        'peak rating, A RMS (datasheet): the loss tables cover 1.5 times it')
    max_speed_rpm: float = positive(
        'top speed (datasheet): the loss tables cover 1.5 times it, and are extrapolated above')
    frame: Frame = spec(doc='the housing over the stack and the end spaces')
    stator: Stator = spec(doc='the laminated stator core')
    winding: Winding = spec(doc='slot winding and end windings')
    rotor: Rotor = spec(doc='rotor and shaft')
    end_spaces: EndSpaces = spec(doc='the oil-filled spaces between the stack and the end caps')
    bearings: Bearings = spec(doc='the two shaft bearings, in the end caps')
    electromagnetic: Electromagnetic = spec(doc=(
        "rotor eddy losses and PWM ripple: the magnets', sleeve's and core's electrical data "
        'and the drive'))
    loss_map: Optional[LossMap] = spec(default=None, doc=(
        'losses from an electromagnetic FEA instead of the analytical laws; null: analytical'))

    def check(self, key: str) -> None:
        """Check that the parts fit together."""
        p = f'{key}.' if key else ''
        if abs(self.stator.outer_radius_m - self.frame.inner_radius_m) > 1e-9:
            raise ConfigError(f'{p}stator.outer_radius_m = {self.stator.outer_radius_m!r}: '
                              f'must equal {p}frame.inner_radius_m = '
                              f'{self.frame.inner_radius_m!r} (the fit is a contact gap)')
        check_below(key + '.rotor' if key else 'rotor', 'outer_radius_m',
                    self.rotor.outer_radius_m, 'stator bore radius', self.stator.bore_radius_m)
        check_below(key or 'motor', 'stack_length_m', self.stack_length_m, 'frame.length_m',
                    self.frame.length_m)
        if self.max_continuous_current_A > self.peak_current_A:
            raise ConfigError(f'{p}max_continuous_current_A = {self.max_continuous_current_A!r}: '
                              f'must not exceed {p}peak_current_A = {self.peak_current_A!r}')
        check_below(key + '.end_spaces' if key else 'end_spaces', 'rotor_clearance_m',
                    self.end_spaces.rotor_clearance_m, 'the end space length ((frame.length_m - '
                    'stack_length_m) / 2)', 0.5 * (self.frame.length_m - self.stack_length_m))
        check_below(key or 'motor', 'stack_length_m', self.stack_length_m, 'rotor.shaft_length_m',
                    self.rotor.shaft_length_m)
        if not self.bearings.seat_radius_m < self.rotor.outer_radius_m:
            raise ConfigError(f'{p}bearings.seat_radius_m = {self.bearings.seat_radius_m!r}: '
                              f'must be below {p}rotor.outer_radius_m = '
                              f"{self.rotor.outer_radius_m!r} (the end cap's hub that holds the "
                              "bearing faces the rotor's end face out to its radius)")
        check_below(key + '.rotor' if key else 'rotor', 'core_inner_radius_m',
                    self.rotor.core_inner_radius_m, 'bearings.seat_radius_m',
                    self.bearings.seat_radius_m + 1e-12)
        # the winding against its slot, its resistance and the torque constant (the model
        # package reads this module: imported here)
        from .model.winding import check_winding
        check_winding(self, key or 'motor')


@dataclass(frozen=True, kw_only=True)
class Shell:
    """Solid shell of a hydraulic component, lumped: heat capacity and two convective areas."""

    mass_kg: float = positive('times the specific heat: the heat capacity')
    specific_heat_J_kgK: float = positive('of the shell material')
    oil_htc_W_m2K: float = positive('oil side')
    oil_area_m2: float = positive(
        "oil side: the pump's is shared by case and ports (60/20/20 %, est.); the actuator's "
        'is per chamber')
    air_htc_W_m2K: float = positive('air side, convection plus radiation')
    air_area_m2: float = positive('outer surface, to ambient')

    @property
    def capacity_J_K(self) -> float:
        """Heat capacity (J/K)."""
        return self.mass_kg * self.specific_heat_J_kgK


@dataclass(frozen=True, kw_only=True)
class Pump:
    """Bidirectional axial piston pump without shaft seal (case drains through the motor)."""

    displacement_m3_rev: float = positive('geometric displacement per shaft revolution')
    internal_leak_coeff_m3: float = spec(0.0, None, doc='laminar Q = C dp / mu, port to port')
    external_leak_coeff_m3: float = spec(0.0, None, doc='laminar Q = C dp / mu, port to case')
    leak_gap_height_m: float = positive(
        'height h of the equivalent gap of both leakage paths (width b = 12 C l / h^3): with '
        'its length it sets the gap Reynolds number and where the laminar law turns into the '
        'orifice law', default=1.0e-5)
    leak_gap_length_m: float = positive('length l of that gap along the flow', default=2.0e-3)
    leak_discharge_coeff: float = fraction(
        'C_d of the orifice law Q = C_d b h sqrt(2 dp / rho) the leakage tends to at high gap '
        'Reynolds numbers', default=0.61)
    viscous_friction_coeff: float = spec(0.0, None, doc='C_v of T_loss = C_v mu D w')
    pressure_friction_coeff: float = spec(0.0, None, doc='C_f of T_loss = C_f D dp')
    coulomb_torque_Nm: float = spec(0.0, None, doc='T_c')
    friction_to_case_fraction: float = spec(0.0, 1.0, doc='rest heats the shell')
    extra_loss_W: float = spec(0.0, 1000.0, default=0.0, doc=(
        'constant heat into the case oil that the friction law lacks (a shaft seal, say); '
        'fit it from bench logs'))
    port_volume_m3: float = positive('each port (inlet/outlet)')
    case_volume_m3: float = positive(
        "oil in the pump case: the external leakage fills it, the motor's cooling flow drains it")
    shell: Shell = spec(doc='the pump body (reference rig: aluminium)')


@dataclass(frozen=True, kw_only=True)
class Actuator:
    """Double-rod (balanced) cylinder."""

    bore_m: float = positive('cylinder bore diameter')
    rod_m: float = positive(
        'rod diameter, both sides: the flow is pi (bore^2 - rod^2) / 4 times the rod speed')
    half_stroke_m: float = positive('travel each side of centre')
    dead_volume_m3: float = positive('each chamber at centre stroke minus the swept part')
    shell: Shell = spec(doc='the cylinder body (reference rig: steel)')

    @property
    def area_m2(self) -> float:
        """Annular piston area (m^2)."""
        return 0.25 * 3.141592653589793 * (self.bore_m ** 2 - self.rod_m ** 2)

    def check(self, key: str) -> None:
        """Check the rod fits the bore."""
        check_below(key, 'rod_m', self.rod_m, 'bore_m', self.bore_m)


@dataclass(frozen=True, kw_only=True)
class Accumulator:
    """Gas-charged accumulator holding the low-pressure side (the pump case drains to it)."""

    oil_volume_m3: float = positive('oil held in the accumulator')
    pressure_Pa: float = positive(
        'working pressure of the low-pressure side (also the low side of a differential sensor)')
    precharge_Pa: float = positive(
        'gas precharge (datasheet); the model does not use it: the low side is at pressure_Pa')
    shell: Shell = spec(doc='the accumulator body (reference rig: steel)')


@dataclass(frozen=True, kw_only=True)
class Lines:
    """The two pump-actuator lines (identical)."""

    length_m: float = positive('each line, pump to actuator')
    bore_m: float = positive('inner diameter')
    wall_m: float = positive('wall thickness')
    wall_density_kg_m3: float = positive('of the tube wall, for its heat capacity')
    wall_specific_heat_J_kgK: float = positive('of the tube wall')
    air_htc_W_m2K: float = positive('outside, natural convection plus radiation')


@dataclass(frozen=True, kw_only=True)
class Hydraulics:
    """Hydraulic circuit of the EHA."""

    pump: Pump = spec(doc='the pump, its two ports and its case')
    actuator: Actuator = spec(doc='the cylinder and its two chambers')
    accumulator: Accumulator = spec(doc='the low-pressure side')
    lines: Lines = spec(doc='the two lines between the pump ports and the chambers')
    substep_s: float = spec(1e-4, 10.0, default=0.05, doc=(
        'longest sub-step of the oil volumes inside a model step: their flows, volumes and '
        'pressure work swing within a duty cycle, and a step mean misplaces that heat'))


@dataclass(frozen=True, kw_only=True)
class Fluid:
    """Hydraulic oil."""

    grade: str = spec(choices=OIL_GRADE_NAMES, doc='oil grade')
    oil_limit_C: float = spec(0.0, 300.0, doc='highest oil temperature allowed in service')
