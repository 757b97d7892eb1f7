"""
Rotor eddy-current losses of a surface-PM motor and the PWM ripple of its phase current.

The armature's current sheet at the stator bore has space harmonics (the
concentrated winding's MMF) and time harmonics (the inverter's PWM); every
component that does not turn with the rotor induces eddy currents in the
magnets, the retaining sleeve and a solid rotor core. The method is that of

- Z. Q. Zhu, K. Ng, N. Schofield, D. Howe, "Improved analytical modelling of
  rotor eddy current loss in brushless machines equipped with surface-mounted
  permanent magnets", IEE Proc. Electr. Power Appl. 151(6), 2004, 641-650, and
- D. Ishak, Z. Q. Zhu, D. Howe, "Eddy-current loss in the rotor magnets of
  permanent-magnet brushless machines having a fractional number of slots per
  pole", IEEE Trans. Magn. 41(9), 2005, 2462-2469:

a 2-D polar field of each harmonic of the current sheet, computed without the
eddy currents' own field (resistance-limited), the eddy current density
J = -sigma dA/dt in each magnet piece less its mean (a piece carries no net
axial current), and the time-averaged J^2 / sigma. Only the abstracts of those
papers could be read here; the equations below are derived in this module's
docstrings, and the method's parts are checked against an independent finite
element solution and closed forms in ``test/test_rotor_losses.py``.

Geometry (radii from the configuration): rotor core (iron, or a solid
conductor through a surface impedance) to the magnets' inner radius; magnets
(relative permeability mu_m) to the sleeve; the sleeve; the oil gap; the
smooth stator bore (iron of infinite permeability) carrying the current
sheet. Slotting of the bore is neglected except for the slot-opening factor
of the current sheet, and so is the no-load loss from the slots' permeance
harmonics.

Corrections past the resistance-limited field, each derived or cited where it
is applied: the sleeve as a thin conducting sheet whose own current reacts on
the field (exact for a sleeve thin against its skin depth and the wavelength),
the classical slab factor for the magnet pieces' skin effect, and end factors
for the finite axial length (the thin-plate stream function of the pieces and
of the sleeve, Russell and Norsworthy 1958).

SI units: radii and lengths in m, speed in rad/s, current in A RMS, frequency
in Hz or rad/s as named, losses in W for the whole motor.
"""

from dataclasses import dataclass
import math
from typing import Dict, Optional

import numpy as np

from .losses import copper_ac_factor
from .stator_harmonics import pwm_current_harmonics, winding_coefficients, winding_harmonics
from .validity import check, ValidityLog
from .winding import winding_layout

MU0 = 4.0e-7 * math.pi

#: Space harmonics whose field at the sleeve's outer radius is below this share of their
#: bore value (squared, i.e. of their loss) are dropped.
SPACE_HARMONIC_CUTOFF = 1.0e-5
#: Rotor-frame frequency grid of the tabulated field transfer (rad/s, log-spaced).
_TRANSFER_OMEGA = (2.0 * math.pi * 1.0, 2.0 * math.pi * 5.0e6, 160)


# --------------------------------------------------------------- layered field
def _layer_solve(nu, radii, mu_r, beta0, sheets, particular=None):
    """
    Solve the 2-D polar field A_z = Re{A(r) e^(j nu theta)} of concentric layers.

    Layer i spans radii[i]..radii[i+1] with relative permeability mu_r[i] and
    A_i(r) = a_i (r / r_{i+1})^nu + b_i (r_i / r)^nu + c_i r (c_i the particular
    solution of a radial magnetisation, when given). Inner boundary:
    (1/mu_0) dA/dr = beta0 A (beta0 = 0: iron of infinite permeability); the
    outer radius is the bore (iron beyond). ``sheets`` maps an interface index
    (1..N) to the current sheet there, in units of mu0 K: the jump of
    (1/mu_r) dA/dr across it. Vectorised over the harmonics (``nu`` and
    ``beta0`` of shape (B,)); returns (a, b) of shape (B, N) for each sheet
    list entry stacked on the last axis: (B, N, S).
    """
    nu = np.asarray(nu, float)
    beta0 = np.broadcast_to(np.asarray(beta0, complex), nu.shape)
    radii = np.asarray(radii, float)
    n = len(mu_r)
    nb = nu.size
    q = (radii[:-1, None] / radii[1:, None]) ** nu[None, :]            # (N, B)
    c = np.zeros((n, nb)) if particular is None else particular
    mat = np.zeros((nb, 2 * n, 2 * n), complex)
    rhs = np.zeros((nb, 2 * n, len(sheets)), complex)
    r0 = radii[0]
    # inner boundary
    mat[:, 0, 0] = nu * q[0] / r0 / mu_r[0] - beta0 * q[0]
    mat[:, 0, 1] = -nu / r0 / mu_r[0] - beta0
    rhs[:, 0, :] = (-c[0] / mu_r[0] + beta0 * c[0] * r0)[:, None]
    for i in range(1, n):
        r = radii[i]
        row = 2 * i - 1
        mat[:, row, 2 * i - 2] = 1.0
        mat[:, row, 2 * i - 1] = q[i - 1]
        mat[:, row, 2 * i] = -q[i]
        mat[:, row, 2 * i + 1] = -1.0
        rhs[:, row, :] = ((c[i] - c[i - 1]) * r)[:, None]
        row += 1
        mat[:, row, 2 * i - 2] = nu / r / mu_r[i - 1]
        mat[:, row, 2 * i - 1] = -nu * q[i - 1] / r / mu_r[i - 1]
        mat[:, row, 2 * i] = -nu * q[i] / r / mu_r[i]
        mat[:, row, 2 * i + 1] = nu / r / mu_r[i]
        rhs[:, row, :] = (c[i] / mu_r[i] - c[i - 1] / mu_r[i - 1])[:, None]
    rn = radii[-1]
    mat[:, -1, -2] = nu / rn / mu_r[-1]
    mat[:, -1, -1] = -nu * q[-1] / rn / mu_r[-1]
    rhs[:, -1, :] = (-c[-1] / mu_r[-1])[:, None]
    for s, (where, value) in enumerate(sheets):
        rhs[:, 2 * where if where < n else -1, s] += value
    sol = np.linalg.solve(mat, rhs)
    return sol[:, 0::2, :], sol[:, 1::2, :]


def _layer_value(a, b, nu, radii, i, r):
    """Return A at radius ``r`` of layer ``i`` from its coefficients (broadcast)."""
    return a[:, i] * (r / radii[i + 1]) ** nu + b[:, i] * (radii[i] / r) ** nu


def _layer_integrals(a, b, nu, radii, i):
    """
    Return (int |A|^2 r dr, int A r dr) over layer ``i`` (closed forms).

    With x = r / r_i, X = r_{i+1} / r_i: int (r/r_{i+1})^(2 nu) r dr =
    r_i^2 (X^2 - X^-2nu) / (2 nu + 2), int (r_i/r)^(2 nu) r dr =
    r_i^2 (X^(2-2nu) - 1) / (2 - 2 nu) (r_i^2 ln X at nu = 1), and the cross
    term X^-nu r_i^2 (X^2 - 1) / 2.
    """
    ri, ro = radii[i], radii[i + 1]
    big = ro / ri
    q = big ** -nu
    uu = ri ** 2 * (big ** 2 - q ** 2) / (2.0 * nu + 2.0)
    vv = ri ** 2 * _power_integral(1.0 - 2.0 * nu, big)
    uv = q * (ro ** 2 - ri ** 2) / 2.0
    u1 = ri ** 2 * (big ** 2 - q) / (nu + 2.0)
    v1 = ri ** 2 * _power_integral(1.0 - nu, big)
    ai, bi = a[:, i], b[:, i]
    sq = np.abs(ai) ** 2 * uu + np.abs(bi) ** 2 * vv + 2.0 * np.real(ai * np.conj(bi)) * uv
    return sq, ai * u1 + bi * v1


def _power_integral(n, big):
    """Return the integral of x^n from 1 to ``big`` (ln big where n = -1)."""
    n = np.asarray(n, float)
    near = np.abs(n + 1.0) < 1e-9
    safe = np.where(near, 1.0, n + 1.0)
    return np.where(near, np.log(big), np.expm1(safe * np.log(big)) / safe)


# --------------------------------------------------------------- corrections
def slab_skin_factor(width_m, frequency_rad_s, resistivity_ohm_m, mu_r=1.0):
    """
    Return the skin-effect factor of the eddy loss in a conducting slab, <= 1.

    F = (3 / xi) (sinh xi - sin xi) / (cosh xi - cos xi), xi = width / delta,
    delta = sqrt(2 rho / (omega mu0 mu_r)): the loss of a slab of that width in
    a uniform alternating field parallel to its faces, divided by its
    resistance-limited value sigma omega^2 B^2 width^2 / 24 per volume (the
    classical result for a lamination, e.g. R. L. Stoll, "The analysis of eddy
    currents", Clarendon Press, 1974; G. Bertotti, "Hysteresis in magnetic
    materials", Academic Press, 1998; its thin limit is 1 - xi^4 / 630). Applied here to a
    magnet piece of circumferential width w in the radial field of a
    harmonic: the eddy currents of the piece run axially and cross its width
    as they would cross a lamination's thickness. Exact for a uniform field
    over a piece long radially and axially; for a piece 2.5 mm thick on iron
    and for a field that varies across the piece it is an approximation
    (flagged past xi = 1 by the callers).

    >>> round(float(slab_skin_factor(1e-3, 2 * np.pi * 50.0, 1.5e-6)), 6)   # thin: 1
    1.0
    >>> d = 1e-2 / 2.0    # two skin depths: F(2) = 1.5 (3.6269 - 0.9093) / (3.7622 + 0.4161)
    >>> w = 2 * 1.5e-6 / (MU0 * d ** 2)
    >>> round(float(slab_skin_factor(1e-2, w, 1.5e-6)), 4)
    0.9756
    """
    delta = np.sqrt(2.0 * resistivity_ohm_m
                    / (np.maximum(frequency_rad_s, 1e-300) * MU0 * mu_r))
    xi = np.minimum(np.asarray(width_m, float) / delta, 300.0)
    small = xi < 0.05
    xs = np.where(small, 1.0, xi)
    exact = 3.0 / xs * (np.sinh(xs) - np.sin(xs)) / (np.cosh(xs) - np.cos(xs))
    return np.where(small, 1.0 - xi ** 4 / 630.0, exact)


def sheet_end_factor(wavenumber_1_m, length_m):
    """
    Return the end factor of a thin conducting sheet in a travelling wave, <= 1.

    k_e = 1 - tanh(x) / x, x = k L / 2 (k the wave number along the
    circumference, L the axial length): the loss of a sheet of finite length
    without end rings over that of the infinitely long (2-D) sheet, the
    eddy currents closing at the ends (W. J. Russell and K. H. Norsworthy,
    "Eddy currents and wall losses in screened-rotor induction motors",
    Proc. IEE A 105, 1958; the paper itself could not be read here). Derived from the
    stream function
    psi of the sheet's current: laplacian(psi) = -sigma dB_r/dt with psi = 0
    at both ends gives psi proportional to 1 - cosh(k z) / cosh(k L / 2), whose
    loss integral is L (1 - tanh(x) / x) against L for the 2-D sheet.

    >>> round(float(sheet_end_factor(8 / 0.01775, 0.055)), 4)   # x = 12.39: 1 - 1/x
    0.9193
    """
    x = np.maximum(np.asarray(wavenumber_1_m, float) * length_m / 2.0, 1e-12)
    return np.where(x < 1e-4, x ** 2 / 3.0, 1.0 - np.tanh(x) / x)


def piece_end_factor(order, piece_angle_rad, width_m, length_m, modes: int = 63):
    """
    Return the end factor of a magnet piece's eddy loss (finite length against 2-D), <= 1.

    Thin-plate (resistance-limited) stream function of a rectangular piece of
    width w and length L in a field sin(nu theta - omega t) over its angle
    beta: laplacian(psi) = s(x) with psi = 0 on the edges (no current leaves
    the piece), s expanded in sin(m pi x / w). Mode m of wave number
    k_m = m pi / w carries the 2-D loss share a_m = |s_m|^2 / k_m^2 and the
    end factor 1 - tanh(k_m L / 2) / (k_m L / 2) of :func:`sheet_end_factor`
    (the same derivation in x and z); the factor is sum a_m e_m / sum a_m,
    averaged over the two time phases of the wave. For a uniform field
    (nu beta -> 0) it is the torsion series of a rectangular bar,
    1 - (192 w / (pi^5 L)) sum_odd tanh(m pi L / (2 w)) / m^5 (Prandtl's
    membrane analogy; Timoshenko and Goodier, "Theory of elasticity",
    3rd ed., 1970, sec. 109). The piece's radial profile is taken as uniform.

    >>> round(float(piece_end_factor(1, 1e-6, 0.010, 0.055)[0]), 4)  # 1 - 0.6274 x 0.1818 x 1.0044
    0.8854
    """
    order = np.atleast_1d(np.asarray(order, float))
    m = np.arange(1, modes + 1, dtype=float)
    km = m * np.pi                               # over the unit width
    theta = order[:, None] * piece_angle_rad     # phase change across the piece
    # s(x) = cos(theta x + phi) on x in [0, 1]; its sine coefficients for phi = 0, pi/2
    cc, ss = _sine_coefficients(theta, km)
    weight = (np.abs(cc) ** 2 + np.abs(ss) ** 2) / km ** 2
    x = km * (length_m / width_m) / 2.0
    end = 1.0 - np.tanh(x) / x
    total = np.sum(weight, axis=1)
    return np.where(total > 0, np.sum(weight * end, axis=1) / np.where(total > 0, total, 1),
                    1.0)


def _sine_coefficients(theta, km):
    """Return int_0^1 cos(theta x) sin(k x) dx and int_0^1 sin(theta x) sin(k x) dx."""
    # products to sums: cos(t x) sin(k x) = [sin((k+t)x) + sin((k-t)x)] / 2
    def int_sin(w):
        w_safe = np.where(np.abs(w) < 1e-9, 1.0, w)
        return np.where(np.abs(w) < 1e-9, 0.0, (1.0 - np.cos(w_safe)) / w_safe)

    def int_cos(w):
        w_safe = np.where(np.abs(w) < 1e-9, 1.0, w)
        return np.where(np.abs(w) < 1e-9, 1.0, np.sin(w_safe) / w_safe)

    cos_part = 0.5 * (int_sin(km + theta) + int_sin(km - theta))
    sin_part = 0.5 * (int_cos(km - theta) - int_cos(km + theta))
    return cos_part, sin_part


# --------------------------------------------------------------- the rotor model
@dataclass(frozen=True)
class RotorGeometry:
    """The rotor's radii and materials as the loss model uses them (from ``config.Motor``)."""

    core_radius_m: float          # magnets' inner radius
    magnet_outer_radius_m: float
    sleeve_outer_radius_m: float
    bore_radius_m: float
    length_m: float
    pole_pairs: int
    slots: int
    pole_arc: float
    pieces_per_pole: int
    pieces_axial: int
    magnet_resistivity_ohm_m: float
    magnet_mu_r: float
    magnet_remanence_T: float
    sleeve_resistivity_ohm_m: float
    solid_core: bool
    core_resistivity_ohm_m: float
    core_mu_r: float
    slot_opening_m: float

    @classmethod
    def from_motor(cls, motor) -> 'RotorGeometry':
        """Take the geometry from a ``config.Motor``."""
        rot, em = motor.rotor, motor.electromagnetic
        r_mag = rot.outer_radius_m - rot.sleeve_thickness_m
        return cls(core_radius_m=r_mag - rot.magnet_thickness_m,
                   magnet_outer_radius_m=r_mag, sleeve_outer_radius_m=rot.outer_radius_m,
                   bore_radius_m=motor.stator.bore_radius_m, length_m=motor.stack_length_m,
                   pole_pairs=motor.pole_pairs, slots=motor.slots,
                   pole_arc=em.pole_arc_fraction, pieces_per_pole=em.magnet_pieces_per_pole,
                   pieces_axial=em.magnet_pieces_axial,
                   magnet_resistivity_ohm_m=em.magnet_resistivity_ohm_m,
                   magnet_mu_r=em.magnet_relative_permeability,
                   magnet_remanence_T=em.magnet_remanence_T,
                   sleeve_resistivity_ohm_m=em.sleeve_resistivity_ohm_m,
                   solid_core=em.rotor_core == 'solid',
                   core_resistivity_ohm_m=em.core_resistivity_ohm_m,
                   core_mu_r=em.core_relative_permeability,
                   slot_opening_m=em.slot_opening_m)

    @property
    def radii(self):
        """Layer radii: core, magnet outer, sleeve middle, sleeve outer, bore."""
        mid = 0.5 * (self.magnet_outer_radius_m + self.sleeve_outer_radius_m)
        return np.array([self.core_radius_m, self.magnet_outer_radius_m, mid,
                         self.sleeve_outer_radius_m, self.bore_radius_m])

    @property
    def mu_r(self):
        """Relative permeability of each layer: magnet, sleeve (two halves), gap."""
        return (self.magnet_mu_r, 1.0, 1.0, 1.0)

    @property
    def piece_angle_rad(self) -> float:
        """Angle spanned by one magnet piece."""
        return self.pole_arc * np.pi / self.pole_pairs / self.pieces_per_pole

    @property
    def piece_width_m(self) -> float:
        """Circumferential width of a piece at the magnets' mean radius."""
        return self.piece_angle_rad * 0.5 * (self.core_radius_m + self.magnet_outer_radius_m)


def magnet_fundamental_field_T(geo: RotorGeometry) -> float:
    """
    Return the peak fundamental radial flux density of the magnets at the bore (T).

    Radially magnetised magnets of pole-arc fraction alpha_p: the remanence's
    fundamental is (4 / pi) B_rem sin(alpha_p pi / 2); in the magnet layer
    A = f(r) sin(p theta) has the particular solution f = p B_p r / (p^2 - 1)
    (laplacian A = -curl B_rem), the other layers are free, the rotor core and
    the stator iron of infinite permeability; B_r = p A / r at the bore (the
    polar solution of Z. Q. Zhu, D. Howe, E. Bolte, B. Ackermann, "Instantaneous
    magnetic field distribution in brushless permanent magnet dc motors, part
    I", IEEE Trans. Magn. 29(1), 1993, for a slotless stator). Needs p > 1.
    """
    p = geo.pole_pairs
    b_p = 4.0 / np.pi * geo.magnet_remanence_T * np.sin(geo.pole_arc * np.pi / 2.0)
    part = np.zeros((4, 1))
    part[0, 0] = p * b_p / (p * p - 1.0)
    a, b = _layer_solve(np.array([float(p)]), geo.radii, geo.mu_r, 0.0, [(4, 0.0)],
                        particular=part)
    a_bore = a[0, -1, 0] + b[0, -1, 0] * (geo.radii[-2] / geo.radii[-1]) ** p
    return float(abs(p * a_bore / geo.radii[-1]))


def fundamental_sheet_per_amp(motor) -> float:
    """
    Return the fundamental current sheet's peak (A/m) per A RMS of phase current.

    The torque of a current sheet K_1 cos(p theta - omega t) at the bore radius
    R in the magnets' radial field B_1 cos(p theta - omega t) there is
    T = pi R^2 L B_1 K_1 (Lorentz force K B_r on the sheet, averaged around the
    bore), so with T = k_t I: K_1 / I = k_t / (pi R^2 L B_1), from the torque
    constant and the magnet field (:func:`magnet_fundamental_field_T`); no
    turns count is needed. The turns per phase it implies are in
    :func:`implied_turns_per_phase`.
    """
    geo = RotorGeometry.from_motor(motor)
    b1 = magnet_fundamental_field_T(geo)
    return motor.torque_constant_Nm_A / (np.pi * geo.bore_radius_m ** 2 * geo.length_m * b1)


def implied_turns_per_phase(motor) -> float:
    """
    Return the series turns per phase that the fundamental current sheet implies.

    A balanced winding of m phases, N series turns per phase and fundamental
    winding factor k_w1 makes K_1 = m sqrt(2) k_w1 N I / (pi R) (the standard
    MMF fundamental, e.g. Hendershot and Miller, "Design of brushless
    permanent-magnet machines", 2010), hence N = pi R K_1 / (m sqrt(2) k_w1 I);
    k_w1 of the tooth-coil winding from the star of slots (0.866 for 12/8).
    A consistency check of :func:`fundamental_sheet_per_amp`: a plausible whole
    number means the torque constant, the remanence and the geometry agree.
    """
    geo = RotorGeometry.from_motor(motor)
    coeff, coils = winding_coefficients(motor.slots, motor.pole_pairs, [motor.pole_pairs],
                                        motor.winding.phases)
    kw1 = abs(coeff[0, 0]) / (2.0 * coils[0])
    k1 = fundamental_sheet_per_amp(motor)
    return np.pi * geo.bore_radius_m * k1 / (motor.winding.phases * np.sqrt(2.0) * kw1)


def _space_orders(geo: RotorGeometry, phases: int):
    """Return the armature's space harmonics kept: (order, direction, sheet per fundamental)."""
    ratio = geo.sleeve_outer_radius_m / geo.bore_radius_m
    top = int(np.ceil(np.log(SPACE_HARMONIC_CUTOFF) / (2.0 * np.log(ratio))))
    top = max(top, 4 * geo.pole_pairs)
    nu, d, amp = winding_harmonics(geo.slots, geo.pole_pairs, phases, top)
    # current spread evenly over the slot opening instead of a line
    arg = nu * geo.slot_opening_m / (2.0 * geo.bore_radius_m)
    arg1 = geo.pole_pairs * geo.slot_opening_m / (2.0 * geo.bore_radius_m)
    amp = amp * np.abs(np.sinc(arg / np.pi) / np.sinc(arg1 / np.pi))
    return nu.astype(float), d, amp


def harmonic_losses(geo: RotorGeometry, order, omega_rotor_rad_s, sleeve_reaction=True):
    """
    Return the magnet, sleeve and core losses (W) of unit-amplitude sheet harmonics.

    Each harmonic is a current sheet K = 1 A/m x cos(nu theta - omega_r t) at the
    bore in the rotor's frame (``omega_rotor_rad_s`` >= 0 the frequency the
    rotor sees). Its field comes from :func:`_layer_solve`; then, per metre of
    stack, with sigma the conductivities:

    - magnets: eddy current J = -sigma dA/dt less the mean over each piece of
      angle beta (a piece carries no net current: Zhu et al. 2004, Ishak et al.
      2005). Time-averaged, per piece: sigma omega_r^2 beta / 2
      [int |A|^2 r dr - s^2 |A_bar|^2 int r dr], s = sin(nu beta/2) / (nu beta/2),
      A_bar the r-weighted mean of A over the thickness (independent of the
      piece's position); times 2 p x pieces per pole, the slab skin factor
      (:func:`slab_skin_factor`, width over the skin depth at omega_r) and the
      piece end factor (:func:`piece_end_factor`).
    - sleeve: continuous, sigma omega_r^2 pi int |A|^2 r dr over its thickness
      (no mean to remove: the harmonic integrates to zero around the rotor),
      times the end factor (:func:`sheet_end_factor`). With
      ``sleeve_reaction`` the sleeve is a thin sheet at its mean radius whose
      current K_e = j omega_r sigma t A (e^(-j omega t) phasors) adds its field:
      A = A_applied / (1 - j omega_r sigma t Z), Z the field there per unit sheet
      there, which also shields the magnets and the core. Exact for a sleeve
      thin against its skin depth and the wavelength; without it, the result is
      resistance-limited (the limit sigma t -> 0).
    - solid core (``geo.solid_core``): a conducting half-space at the magnets'
      inner radius, A ~ exp(gamma (r - r_0)), gamma = sqrt(k^2 - j omega mu sigma),
      k = nu / r_0, so (1/mu) dA/dr = (gamma / mu_core) A there (surface impedance;
      curvature neglected, valid where the skin depth is small against r_0 and
      the wavelength); loss per area sigma omega^2 |A(r_0)|^2 / (4 Re gamma).
      A laminated core is iron of infinite permeability without loss.

    Returns a dict of arrays 'magnet', 'sleeve', 'core' (W, whole stack) and
    'xi_magnet' (piece width / skin depth), 'sleeve_reaction' (|omega sigma t Z|),
    'core_delta_k' (skin depth x wave number of the core).
    """
    nu = np.atleast_1d(np.asarray(order, float))
    w = np.broadcast_to(np.asarray(omega_rotor_rad_s, float), nu.shape).copy()
    gamma, beta0 = _core_surface(geo, nu, w)
    a, b = _layer_solve(nu, geo.radii, geo.mu_r, beta0, [(4, MU0), (2, MU0)])
    a_tot, b_tot, reaction = _with_sleeve_reaction(geo, nu, w, a, b, sleeve_reaction)
    magnet, xi = _magnet_loss(geo, nu, w, a_tot, b_tot)
    core, core_dk = _core_loss(geo, nu, w, a_tot, b_tot, gamma)
    return {'magnet': np.real(magnet), 'sleeve': np.real(_sleeve_loss(geo, nu, w, a_tot, b_tot)),
            'core': np.real(core),
            'xi_magnet': xi, 'sleeve_reaction': np.abs(reaction), 'core_delta_k': core_dk}


def _core_surface(geo: RotorGeometry, nu, w):
    """Return the solid core's gamma and its surface condition (gamma / mu_core); 0 laminated."""
    if not geo.solid_core:
        return None, np.zeros(nu.shape, complex)
    sig_c = 1.0 / geo.core_resistivity_ohm_m
    gamma = np.sqrt((nu / geo.radii[0]) ** 2 - 1j * w * MU0 * geo.core_mu_r * sig_c + 0j)
    return gamma, gamma / geo.core_mu_r


def _with_sleeve_reaction(geo: RotorGeometry, nu, w, a, b, sleeve_reaction: bool):
    """Return the field coefficients with the sleeve sheet's own field added, and |..| of it."""
    radii = geo.radii
    sig_s = 1.0 / geo.sleeve_resistivity_ohm_m
    t = radii[3] - radii[1]
    # applied field at the sleeve's middle, and the sleeve sheet's own field there
    a_app = _layer_value(a[..., 0], b[..., 0], nu, radii, 1, radii[2])
    z_self = _layer_value(a[..., 1], b[..., 1], nu, radii, 1, radii[2])
    reaction = w * sig_s * t * z_self
    if sleeve_reaction:
        k_e = 1j * w * sig_s * t * a_app / (1.0 - 1j * reaction)
    else:
        k_e = np.zeros_like(a_app)
    return a[..., 0] + k_e[:, None] * a[..., 1], b[..., 0] + k_e[:, None] * b[..., 1], reaction


def _magnet_loss(geo: RotorGeometry, nu, w, a_tot, b_tot):
    """Return the magnets' loss (W, complex dtype) and their width over the skin depth."""
    radii = geo.radii
    sig_m = 1.0 / geo.magnet_resistivity_ohm_m
    sq_m, lin_m = _layer_integrals(a_tot, b_tot, nu, radii, 0)
    area_m = (radii[1] ** 2 - radii[0] ** 2) / 2.0
    beta = geo.piece_angle_rad
    s = np.sinc(nu * beta / 2.0 / np.pi)
    per_piece = sig_m * w ** 2 * beta / 2.0 * (sq_m - s ** 2 * np.abs(lin_m) ** 2 / area_m)
    pieces = 2 * geo.pole_pairs * geo.pieces_per_pole
    xi = geo.piece_width_m / np.sqrt(2.0 * geo.magnet_resistivity_ohm_m
                                     / (np.maximum(w, 1e-300) * MU0 * geo.magnet_mu_r))
    magnet = (pieces * per_piece * geo.length_m
              * slab_skin_factor(geo.piece_width_m, w, geo.magnet_resistivity_ohm_m,
                                 geo.magnet_mu_r)
              * piece_end_factor(nu, beta, geo.piece_width_m,
                                 geo.length_m / geo.pieces_axial))
    return magnet, xi


def _sleeve_loss(geo: RotorGeometry, nu, w, a_tot, b_tot):
    """Return the sleeve's loss (W): its two layers' integrals of |A|^2, end factor."""
    radii = geo.radii
    sig_s = 1.0 / geo.sleeve_resistivity_ohm_m
    sq_s = _layer_integrals(a_tot, b_tot, nu, radii, 1)[0] \
        + _layer_integrals(a_tot, b_tot, nu, radii, 2)[0]
    return (sig_s * w ** 2 * np.pi * sq_s * geo.length_m
            * sheet_end_factor(nu / radii[2], geo.length_m))


def _core_loss(geo: RotorGeometry, nu, w, a_tot, b_tot, gamma):
    """Return the solid core's surface loss (W) and its skin depth x wave number (0 laminated)."""
    if not geo.solid_core:
        return np.zeros(nu.shape), np.zeros(nu.shape)
    radii = geo.radii
    r0 = radii[0]
    a_r0 = a_tot[:, 0] * (r0 / radii[1]) ** nu + b_tot[:, 0]
    core = (2.0 * np.pi * r0 * geo.length_m / geo.core_resistivity_ohm_m * w ** 2
            * np.abs(a_r0) ** 2 / (4.0 * np.real(gamma)))
    delta_c = np.sqrt(2.0 * geo.core_resistivity_ohm_m
                      / (np.maximum(w, 1e-300) * MU0 * geo.core_mu_r))
    return core, delta_c * nu / r0


# --------------------------------------------------------------- the losses at operating points
def _waves(motor, speed, current, geo, log=None):
    """
    Return every travelling wave of the current sheet at one operating point.

    Armature waves (fundamental current, the winding's space harmonics) and
    PWM waves (each current harmonic with each space harmonic, the direction
    reversed for a negative sequence). Returns a dict of arrays per wave:
    order, omega_r (rotor frame), sheet (peak A/m), group (0 armature, else m),
    n (PWM sideband, 0 for armature).
    """
    nu, d, amp = _space_orders(geo, motor.winding.phases)
    k1 = fundamental_sheet_per_amp(motor)
    speed = abs(float(speed))
    w1 = motor.pole_pairs * speed
    arm_omega = np.abs(nu * speed - d * w1)
    h = pwm_current_harmonics(motor, speed, current, log)
    wh, ih = h['omega_rad_s'], h['current_A']
    direction = d[None, :] * h['sequence'][:, None]
    pwm_omega = np.abs(nu[None, :] * speed - direction * wh[:, None])
    pwm_sheet = k1 * amp[None, :] * ih[:, None] / np.sqrt(2.0)
    hn = len(wh)
    return {'order': np.concatenate([nu, np.tile(nu, hn)]),
            'direction': np.concatenate([d, direction.ravel()]),
            'omega_r': np.concatenate([arm_omega, pwm_omega.ravel()]),
            'sheet': np.concatenate([k1 * amp * current, pwm_sheet.ravel()]),
            'group': np.concatenate([np.zeros(nu.size, int), np.repeat(h['m'], nu.size)]),
            'n': np.concatenate([np.zeros(nu.size, int), np.repeat(h['n'], nu.size)])}


def rotor_eddy_loss_breakdown(motor, speed_rad_s: float, current_A: float,
                              log: Optional[ValidityLog] = None) -> Dict[str, np.ndarray]:
    """
    Return the rotor eddy losses (W) of every wave at one operating point, evaluated directly.

    The waves of the armature's space harmonics and of the PWM current
    harmonics (:func:`~.stator_harmonics.pwm_current_harmonics`) through :func:`harmonic_losses`,
    times ``loss_factor``. Returns the arrays of :func:`_waves` plus 'magnet',
    'sleeve', 'core' per wave; sum them for the totals. Flags, on the waves
    that carry 1 % or more of the rotor loss: magnet piece width over skin
    depth past 1 (slab factor applied), the sleeve's reaction past 0.3 (thin
    sheet model applied), and a solid core's skin depth x wave number past 0.5
    (surface impedance without curvature).
    """
    geo = RotorGeometry.from_motor(motor)
    waves = _waves(motor, speed_rad_s, current_A, geo, log)
    res = harmonic_losses(geo, waves['order'], waves['omega_r'])
    scale = waves['sheet'] ** 2 * motor.electromagnetic.loss_factor
    out = dict(waves)
    for key in ('magnet', 'sleeve', 'core'):
        out[key] = res[key] * scale
    total = out['magnet'] + out['sleeve'] + out['core']
    big = total >= 0.01 * max(float(np.sum(total)), 1e-300)
    check(log, 'rotor eddy loss (magnets)', 'piece width / skin depth', res['xi_magnet'][big],
          0.0, 1.0, 'resistance-limited loss corrected by the slab factor (approximate)')
    check(log, 'rotor eddy loss (sleeve)', 'reaction omega sigma t |Z|',
          res['sleeve_reaction'][big], 0.0, 0.3,
          'thin-sheet reaction applied (3 % from the exact annulus in the tests)')
    if geo.solid_core:
        check(log, 'rotor eddy loss (solid core)', 'skin depth x wave number',
              res['core_delta_k'][big], 0.0, 0.5,
              'surface impedance without curvature; the core loss is approximate')
    return out


def _transfer_table(geo: RotorGeometry, orders):
    """Return the log-frequency grid and the losses per unit sheet of each order on it."""
    lo, hi, num = _TRANSFER_OMEGA
    grid = np.geomspace(lo, hi, num)
    nu = np.repeat(orders, num)
    res = harmonic_losses(geo, nu, np.tile(grid, orders.size))
    return grid, {k: res[k].reshape(orders.size, num) for k in ('magnet', 'sleeve', 'core')}


def _interpolate(grid, table, index, omega):
    """Interpolate log(loss) linearly in log(omega); below the grid as omega^2 (no skin effect)."""
    lg = np.log(grid)
    step = lg[1] - lg[0]
    x = (np.log(np.maximum(omega, 1e-300)) - lg[0]) / step
    k = np.clip(np.floor(x).astype(int), 0, grid.size - 2)
    f = np.clip(x - k, 0.0, 1.0)
    lt = np.log(np.maximum(table, 1e-300))
    val = np.exp(lt[index, k] * (1.0 - f) + lt[index, k + 1] * f)
    below = omega < grid[0]
    return np.where(below, table[index, 0] * (omega / grid[0]) ** 2, val)


def rotor_eddy_loss_table(motor, speeds_rad_s, currents_A,
                          log: Optional[ValidityLog] = None) -> Dict[str, np.ndarray]:
    """
    Return the rotor eddy losses (W, whole motor) on a grid of |speed| x RMS current.

    For the integrator: tabulate once at model build, interpolate per step.
    Sums the waves of :func:`rotor_eddy_loss_breakdown` at every grid point,
    with the field transfer of each space order tabulated once against the
    rotor-frame frequency (160 points from 1 Hz to 5 MHz, log(loss)
    interpolated linearly in log(frequency); within 0.5 % of the direct sum,
    ``test/test_rotor_losses.py``). Armature losses scale as I^2 at a given
    speed; the PWM losses follow the modulation index (speed and current).

    Returns a dict of (n_speed, n_current) arrays: 'magnet_W', 'sleeve_W',
    'core_W' (loss_factor applied), 'ripple_rms_A'
    (:func:`~.stator_harmonics.pwm_ripple_current_rms_A`), 'ripple_ac_factor'
    (:func:`~.stator_harmonics.pwm_ripple_ac_factor`) and 'modulation_index'.
    Flags as :func:`rotor_eddy_loss_breakdown` at the grid's top speed and
    current, and the modulation index over the grid.
    """
    speeds = np.abs(np.asarray(speeds_rad_s, float))
    currents = np.asarray(currents_A, float)
    geo = RotorGeometry.from_motor(motor)
    nu, d, amp = _space_orders(geo, motor.winding.phases)
    k1 = fundamental_sheet_per_amp(motor)
    orders = np.unique(nu)
    index = np.searchsorted(orders, nu)
    grid, table = _transfer_table(geo, orders)
    h = pwm_current_harmonics(motor, speeds[:, None], currents[None, :], log)
    ih2 = h['current_A'] ** 2 / 2.0                                  # (S, C, H) RMS^2
    direction = d[None, :] * h['sequence'][:, None]                  # (H, V)
    wh = h['omega_rad_s'][:, 0, :]                                   # (S, H)
    w1 = motor.pole_pairs * speeds
    weight = (k1 * amp) ** 2
    out = {}
    for key in ('magnet', 'sleeve', 'core'):
        arm = np.sum(weight * _interpolate(grid, table[key], index,
                                           np.abs(nu * speeds[:, None]
                                                  - d * w1[:, None])), axis=1)   # (S,)
        pwm_omega = np.abs(nu * speeds[:, None, None] - direction[None] * wh[:, :, None])
        per_h = np.sum(weight * _interpolate(grid, table[key], index, pwm_omega), axis=2)
        total = arm[:, None] * currents[None, :] ** 2 + np.einsum('sch,sh->sc', ih2, per_h)
        out[key + '_W'] = total * motor.electromagnetic.loss_factor
    if not geo.solid_core:
        out['core_W'] = np.zeros_like(out['core_W'])     # not the interpolation's 1e-300
    out['ripple_rms_A'] = np.sqrt(np.sum(ih2, axis=-1))
    wdg, lay = motor.winding, winding_layout(motor)
    fr = copper_ac_factor(np.abs(wh) / (2.0 * np.pi), wdg.conductor_diameter_m,
                          lay.rows, lay.porosity, log=log)
    tot = np.sum(ih2, axis=-1)
    out['ripple_ac_factor'] = np.where(
        tot > 0, np.einsum('sch,sh->sc', ih2, fr) / np.where(tot > 0, tot, 1.0), 1.0)
    out['modulation_index'] = h['modulation_index']
    if log is not None and speeds.size and currents.size:
        rotor_eddy_loss_breakdown(motor, float(speeds.max()), float(currents.max()), log)
    return out
