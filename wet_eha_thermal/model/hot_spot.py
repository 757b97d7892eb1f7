"""
The peak temperature inside the slot winding and the end windings (docs/model.md, Hot spot).

A Mellor block's node is the block's mean temperature, not its peak: in a
slot of uniform generation q cooled through its two teeth the peak is
q w^2 / (24 k) above the mean, a gap that grows as I^2. The hot spot is
therefore rebuilt from the network's own temperatures, once per output,
as the maximum over points of the block of a temperature that is linear in
a few node temperatures (:class:`PeakForms`):

- slot slice: the steady 2-D conduction field of the configured slot section
  (an annular sector between the teeth, conductivity k_radial, the slot liner
  as a contact h on its four sides), solved once at configuration load by
  finite volumes for unit generation and for each wall at unit temperature
  (:func:`slot_section_field`). At run time the walls are the network's iron
  surfaces (yoke at the slot bottom, teeth at the tips and, from the lateral
  link's heat flow, at the tooth flanks) and the generation is the heat the
  slice sends out through those walls (its loss less what it stores and what
  it passes along the stack); the field is anchored at the network's slice
  mean. Exact for this section when each wall is isothermal.
- end winding: the block's radial profile (a hollow cylinder with uniform
  generation, exact through its two surface temperatures and its mean) plus
  its axial one (a slab: a parabola through the two faces and the mean),
  superposed as in the cuboidal element with internal generation of Wrobel
  and Mellor (IEEE Trans. Magn. 46(8), 2010), which sums independent 1-D
  profiles in each direction; that sum slightly overestimates a 2-D peak
  (by about 8 % of the peak-over-mean in a square section).
"""

from dataclasses import dataclass
from typing import List, Tuple

import numpy as np
import scipy.sparse
import scipy.sparse.linalg
from scipy.spatial import ConvexHull

from .mellor import mellor_resistances

#: finite-volume cells of the slot section: radial, across the slot (an odd count puts a
#: column on the centre line; the peak is sampled at the cell centres: within 0.4 K of
#: the FE's peak at 45 A, test_fem_check; 24 x 11 moves it by 0.05 K)
SLOT_CELLS = (32, 15)
#: points of each end-winding direction at which its profile is sampled
END_POINTS = 33


@dataclass(frozen=True)
class PeakForms:
    """
    A block's peak: sum over its parts of max_p part[p] . T[values], each form a row.

    ``values`` the node names whose temperatures the forms weigh; ``parts`` the
    forms of each direction whose peaks add (one part for a 2-D field);
    ``state`` the block's mean node, the state that stands for the peak in a
    filter's row.
    """

    values: Tuple[str, ...]
    parts: Tuple[np.ndarray, ...]
    state: str


def hull_rows(forms: np.ndarray) -> np.ndarray:
    """
    Return the rows of ``forms`` that can be the largest for some values: its hull's vertices.

    The largest of linear forms of any values is at a vertex of the convex hull
    of the forms (taken as points, in the affine space they span): the other
    rows never win and are dropped (exactly), so that the peak costs less.

    >>> x = np.linspace(0.0, 1.0, 11)
    >>> hull_rows(np.stack([x, x * x], axis=1)).shape    # a convex curve: every point
    (11, 2)
    >>> hull_rows(np.stack([x, x], axis=1)).tolist()     # a segment: its ends
    [[0.0, 0.0], [1.0, 1.0]]
    """
    centred = forms - forms.mean(axis=0)
    _, sv, vt = np.linalg.svd(centred, full_matrices=False)
    dims = int(np.sum(sv > 1e-9 * sv[0]))
    if dims == 0:
        return forms[:1]
    coords = centred @ vt[:dims].T
    if dims == 1:
        keep = [int(np.argmin(coords[:, 0])), int(np.argmax(coords[:, 0]))]
    else:
        keep = ConvexHull(coords).vertices
    return forms[np.sort(np.unique(keep))]


def slot_section_field(r_inner_m: float, r_outer_m: float, angle_rad: float, k_W_mK: float,
                       h_wall_W_m2K: float, cells: Tuple[int, int] = SLOT_CELLS
                       ) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return the slot section's temperature at its cell centres, and its mean, per input.

    The section: r_inner < r < r_outer, 0 < theta < angle, conductivity k, each
    side joined to its wall by h. Columns (inputs): generation (per W/m^3),
    then the bottom wall (r_outer), the top wall (r_inner) and both flanks at
    unit temperature (K per K). Finite volumes, second order; the rows of the
    walls' columns sum to 1. Returns (cells x 4, 4): field and area-weighted mean.

    >>> field, mean = slot_section_field(0.02, 0.038, 0.3, 0.9, 1e9)
    >>> bool(np.allclose(field[:, 1:].sum(axis=1), 1.0)), round(float(mean[1:].sum()), 12)
    (True, 1.0)
    """
    nr, nt = cells
    dr = (r_outer_m - r_inner_m) / nr
    dt = angle_rad / nt
    r = r_inner_m + (np.arange(nr) + 0.5) * dr
    area = np.repeat(r * dr * dt, nt)               # cell areas, radial index major
    idx = np.arange(nr * nt).reshape(nr, nt)
    rows, cols, vals = [], [], []
    diag = np.zeros(nr * nt)
    rhs = np.zeros((nr * nt, 4))
    rhs[:, 0] = area

    def link(a, b, g):
        rows.extend([a, b])
        cols.extend([b, a])
        vals.extend([-g, -g])
        diag[a] += g
        diag[b] += g

    def wall(cells_, g, column):
        diag[cells_] += g
        rhs[cells_, column] += g

    for i in range(nr):
        g_t = k_W_mK * dr / (r[i] * dt)              # across theta, between columns
        for j in range(nt - 1):
            link(idx[i, j], idx[i, j + 1], g_t)
        # the flanks: half a cell of copper in series with the liner
        g_flank = 1.0 / (r[i] * dt / 2.0 / (k_W_mK * dr) + 1.0 / (h_wall_W_m2K * dr))
        wall(idx[i, [0, nt - 1]], g_flank, 3)
    for i in range(nr - 1):
        r_face = r_inner_m + (i + 1) * dr
        for j in range(nt):
            link(idx[i, j], idx[i + 1, j], k_W_mK * r_face * dt / dr)
    for i, r_wall, column in ((nr - 1, r_outer_m, 1), (0, r_inner_m, 2)):
        g_wall = 1.0 / (dr / 2.0 / (k_W_mK * r_wall * dt) + 1.0 / (h_wall_W_m2K * r_wall * dt))
        wall(idx[i], g_wall, column)
    K = scipy.sparse.coo_matrix((vals, (rows, cols)), shape=(nr * nt,) * 2).tocsc()
    K = K + scipy.sparse.diags(diag)
    field = scipy.sparse.linalg.splu(K.tocsc()).solve(rhs)
    return field, area @ field / area.sum()


def slot_peak_forms(motor) -> List[PeakForms]:
    """
    Return the peak forms of each slot slice of a built :class:`~.motor.WetMotor`.

    Over the slice's mean, its radial junction ``jr``, the teeth slice's mean
    and the yoke's and teeth's surfaces (the slot bottom and top walls).
    """
    c = motor.cfg
    st, wd = c.stator, c.winding
    r_tip, r_yoke = motor.slot_radii_m
    slot_frac = 1.0 - st.tooth_fraction
    field, mean = slot_section_field(r_tip, r_yoke, slot_frac * 2.0 * np.pi / c.slots,
                                     wd.k_radial_W_mK,
                                     wd.liner_conductivity_W_mK / wd.liner_thickness_m)
    # the section is symmetric about the slot's centre line and so are its inputs: the
    # peak is in one half
    nr, nt = SLOT_CELLS
    half = np.arange(nr * nt).reshape(nr, nt)[:, :(nt + 1) // 2].ravel()
    rel = field[half] - mean                # each point less the mean, per input
    R6 = mellor_resistances(r_yoke, r_tip, motor.dz, wd.k_radial_W_mK, wd.k_axial_W_mK,
                            slot_frac).R6
    r_lat, r_tooth = motor.slot_lateral_R
    volume = slot_frac * np.pi * (r_yoke ** 2 - r_tip ** 2) * motor.dz
    # the inputs as forms over (mean, jr, teeth mean, yoke inner, teeth inner):
    # generation: what leaves the slice's section, radially (mean -> jr) and to the teeth
    q = np.array([1.0 / R6 + 1.0 / r_lat, -1.0 / R6, -1.0 / r_lat, 0.0, 0.0]) / volume
    flank = np.array([r_tooth / r_lat, 0.0, 1.0 - r_tooth / r_lat, 0.0, 0.0])
    inputs = np.stack([q, np.eye(5)[3], np.eye(5)[4], flank])       # 4 x 5
    forms = hull_rows(rel @ inputs)
    forms[:, 0] += 1.0                      # anchored at the network's mean
    out = []
    for i in range(c.slices):
        s = f'winding.s{i + 1}'
        out.append(PeakForms((s, f'{s}.jr', f'teeth.s{i + 1}', f'yoke.s{i + 1}.inner',
                              f'teeth.s{i + 1}.inner'), (forms,), s))
    return out


def cylinder_profile(r_outer_m: float, r_inner_m: float, r_m: np.ndarray) -> np.ndarray:
    """
    Return T(r) - T_mean of a hollow cylinder with uniform generation, per surface rise.

    T(r) = T_m + A (r^2 - <r^2>) + B (ln r - <ln r>) (the general radial solution
    with uniform generation), A and B fixed by the outer and inner surfaces:
    rows ``r_m``, columns the forms over (T_outer - T_m, T_inner - T_m).

    >>> p = cylinder_profile(2.0, 1.0, np.array([2.0, 1.0]))
    >>> bool(np.allclose(p, np.eye(2)))
    True
    """
    r1, r2 = r_outer_m, r_inner_m
    area = r1 ** 2 - r2 ** 2
    m_sq = 0.5 * (r1 ** 2 + r2 ** 2)
    m_ln = (r1 ** 2 * np.log(r1) - r2 ** 2 * np.log(r2)) / area - 0.5
    basis = lambda r: np.stack([r ** 2 - m_sq, np.log(r) - m_ln], axis=-1)  # noqa: E731
    return basis(np.asarray(r_m, float)) @ np.linalg.inv(basis(np.array([r1, r2])))


def slab_profile(x: np.ndarray) -> np.ndarray:
    """
    Return T(x) - T_mean of a slab with uniform generation, x in [0, 1], per face rise.

    The parabola through the faces' rises a, b over the mean: a (1 - 4x + 3x^2)
    + b (-2x + 3x^2); columns the forms over (T_a - T_m, T_b - T_m).

    >>> slab_profile(np.array([0.0, 1.0])).tolist()
    [[1.0, 0.0], [0.0, 1.0]]
    """
    x = np.asarray(x, float)
    return np.stack([1.0 - 4.0 * x + 3.0 * x ** 2, -2.0 * x + 3.0 * x ** 2], axis=-1)


def end_winding_peak_forms(motor, side: str) -> PeakForms:
    """
    Return the peak forms of one end winding: its radial and axial profiles superposed.

    Over the block's mean, its outer and inner surfaces and its two faces.
    """
    r_tip, r_yoke = motor.slot_radii_m
    ew = motor.end_winding[side]
    radial = cylinder_profile(r_yoke, r_tip, np.linspace(r_tip, r_yoke, END_POINTS))
    axial = slab_profile(np.linspace(0.0, 1.0, END_POINTS))
    # T_m + g_r + g_z: the radial part carries the mean, the axial one sums to zero
    forms_r = np.zeros((END_POINTS, 5))
    forms_r[:, 1:3] = radial
    forms_r[:, 0] = 1.0 - radial.sum(axis=1)
    forms_z = np.zeros((END_POINTS, 5))
    forms_z[:, 3:5] = axial
    forms_z[:, 0] = -axial.sum(axis=1)
    return PeakForms((ew.mean[0], ew.outer[0], ew.inner[0], ew.faces[0], ew.faces[1]),
                     (hull_rows(forms_r), hull_rows(forms_z)), ew.mean[0])
