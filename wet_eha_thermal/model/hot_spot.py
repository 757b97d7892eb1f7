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
  as a contact h on its four sides), in radial bands that are the network's
  winding layers, solved once at configuration load by finite volumes for
  unit generation in each band and for each wall at unit temperature
  (:func:`slot_section_field`). At run time the walls are the network's iron
  (yoke at the slot bottom, teeth at the tips and, along the flanks, the
  tooth's radial profile plus the drop its lateral heat makes) and each
  band's generation is the heat its layer sends out within the section (its
  loss less what it stores and what it passes along the stack); the field is
  anchored at the network's slice mean (its layers' volume mean). Exact for
  this section when each wall is isothermal over each band.
- end winding: each layer's radial profile (a hollow cylinder with uniform
  generation, exact through its two surface temperatures and its mean) plus
  its axial one (a slab: a parabola through the two faces and the mean),
  superposed as in the cuboidal element with internal generation of Wrobel
  and Mellor (IEEE Trans. Magn. 46(8), 2010), which sums independent 1-D
  profiles in each direction; that sum slightly overestimates a 2-D peak
  (by about 8 % of the peak-over-mean in a square section).
"""

from dataclasses import dataclass
from functools import lru_cache
from typing import List, Tuple

import numpy as np
import scipy.sparse
import scipy.sparse.linalg
from scipy.spatial import ConvexHull

from .mellor import mellor_resistances


#: finite-volume cells of the slot section: radial (rounded up to a multiple of the
#: layers), across the slot (an odd count puts a column on the centre line; the peak is
#: sampled at the cell centres: within 0.2 K of the FE's peak at 45 A with 4 layers,
#: test_fem_check)
SLOT_CELLS = (32, 15)
#: the most dimensions :func:`hull_rows` takes a hull in: qhull's cost and its round-off
#: grow steeply with them (a six-layer slot's 13 fail), and above it every row is kept
HULL_MAX_DIMS = 6
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
    rows never win and are dropped (exactly), so that the peak costs less; in
    more than :data:`HULL_MAX_DIMS` dimensions every row is kept.

    >>> x = np.linspace(0.0, 1.0, 11)
    >>> hull_rows(np.stack([x, x * x], axis=1)).shape    # a convex curve: every point
    (11, 2)
    >>> hull_rows(np.stack([x, x], axis=1)).tolist()     # a segment: its ends
    [[0.0, 0.0], [1.0, 1.0]]
    """
    forms = np.ascontiguousarray(forms, dtype=float)
    return forms[_hull_keep(forms.shape, forms.tobytes())]


# every model built (the estimator's, each uncertainty copy's) asks for the same few hulls
# and slot fields: kept per process, by their inputs' exact values
@lru_cache(maxsize=256)
def _hull_keep(shape: Tuple[int, int], data: bytes) -> np.ndarray:
    """Return the indices of :func:`hull_rows`' rows, for forms given as their bytes."""
    forms = np.frombuffer(data).reshape(shape)
    centred = forms - forms.mean(axis=0)
    _, sv, vt = np.linalg.svd(centred, full_matrices=False)
    dims = int(np.sum(sv > 1e-9 * sv[0]))
    if dims == 0:
        keep = np.arange(1)
    elif dims > HULL_MAX_DIMS:
        keep = np.arange(shape[0])
    else:
        coords = centred @ vt[:dims].T
        if dims == 1:
            keep = np.unique([int(np.argmin(coords[:, 0])), int(np.argmax(coords[:, 0]))])
        else:
            keep = np.unique(ConvexHull(coords).vertices)
    keep.flags.writeable = False
    return keep


@lru_cache(maxsize=32)
def slot_section_field(r_inner_m: float, r_outer_m: float, angle_rad: float, k_W_mK: float,
                       h_wall_W_m2K: float, bands: int = 1, cells: Tuple[int, int] = SLOT_CELLS
                       ) -> Tuple[np.ndarray, np.ndarray]:
    """
    Return the slot section's temperature at its cell centres, and its mean, per input.

    The section: r_inner < r < r_outer, 0 < theta < angle, conductivity k, each
    side joined to its wall by h, in ``bands`` radial bands of equal depth (the
    network's layers; band 1 at r_outer, the slot bottom). Columns (inputs):
    each band's generation (per W/m^3), then the bottom wall (r_outer) and the
    top wall (r_inner) at unit temperature, then each band's stretch of both
    flanks at unit temperature (K per K). Finite volumes, second order, radial
    cells a multiple of the bands; the rows of the walls' columns sum to 1.
    Returns (cells x (2 bands + 2), 2 bands + 2): field and area-weighted mean, read-only
    (kept per process for the same arguments).

    >>> field, mean = slot_section_field(0.02, 0.038, 0.3, 0.9, 1e9, bands=2)
    >>> bool(np.allclose(field[:, 2:].sum(axis=1), 1.0)), round(float(mean[2:].sum()), 12)
    (True, 1.0)
    """
    nt = cells[1]
    nr = bands * -(-cells[0] // bands)
    dr = (r_outer_m - r_inner_m) / nr
    dt = angle_rad / nt
    r = r_inner_m + (np.arange(nr) + 0.5) * dr
    band = bands - 1 - np.arange(nr) // (nr // bands)     # each radial row's band
    area = np.repeat(r * dr * dt, nt)               # cells' areas, radial index major
    idx = np.arange(nr * nt).reshape(nr, nt)
    rows, cols, vals = [], [], []
    diag = np.zeros(nr * nt)
    rhs = np.zeros((nr * nt, 2 * bands + 2))
    rhs[np.arange(nr * nt), np.repeat(band, nt)] = area

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
        wall(idx[i, [0, nt - 1]], g_flank, bands + 2 + band[i])
    for i in range(nr - 1):
        r_face = r_inner_m + (i + 1) * dr
        for j in range(nt):
            link(idx[i, j], idx[i + 1, j], k_W_mK * r_face * dt / dr)
    for i, r_wall, column in ((nr - 1, r_outer_m, bands), (0, r_inner_m, bands + 1)):
        g_wall = 1.0 / (dr / 2.0 / (k_W_mK * r_wall * dt) + 1.0 / (h_wall_W_m2K * r_wall * dt))
        wall(idx[i], g_wall, column)
    K = scipy.sparse.coo_matrix((vals, (rows, cols)), shape=(nr * nt,) * 2).tocsc()
    K = K + scipy.sparse.diags(diag)
    field = scipy.sparse.linalg.splu(K.tocsc()).solve(rhs)
    mean = area @ field / area.sum()
    field.flags.writeable = mean.flags.writeable = False     # cached: shared by every caller
    return field, mean


def slot_peak_forms(motor) -> List[PeakForms]:
    """
    Return the peak forms of each slot slice of a built :class:`~.motor.WetMotor`.

    Over the slice's layer means and radial junctions, the teeth slice's mean
    and the yoke's and teeth's surfaces (the slot bottom and top walls); each
    layer is a band of the section with its own generation and flank
    temperature (within 0.2 K of the 2-D FE's peak at 10 000 r/min and 45 A with 4
    layers: test_fem_check). The state that stands for the peak is the middle layer.
    """
    c = motor.cfg
    st, wd = c.stator, c.winding
    r_tip, r_yoke = motor.slot_radii_m
    slot_frac = 1.0 - st.tooth_fraction
    L = len(motor.winding_layers)
    field, mean = slot_section_field(r_tip, r_yoke, slot_frac * 2.0 * np.pi / c.slots,
                                     wd.k_radial_W_mK,
                                     wd.liner_conductivity_W_mK / wd.liner_thickness_m, L)
    # the section is symmetric about the slot's centre line and so are its inputs: the
    # peak is in one half
    nt = SLOT_CELLS[1]
    half = np.arange(field.shape[0]).reshape(-1, nt)[:, :(nt + 1) // 2].ravel()
    rel = field[half] - mean                # each point less the mean, per input
    r_lat, r_tooth = motor.slot_lateral_R   # each layer's
    radii = motor.layer_radii_m
    volume = slot_frac * np.pi * (radii[:-1] ** 2 - radii[1:] ** 2) * motor.dz
    R6 = np.array([mellor_resistances(r_out, r_in, motor.dz, wd.k_radial_W_mK,
                                      wd.k_axial_W_mK, slot_frac).R6
                   for r_out, r_in in zip(radii[:-1], radii[1:])])
    # the inputs as forms over (layer means, their radial junctions jr, teeth mean, yoke
    # inner, teeth inner). A layer's generation: what leaves it within the section,
    # radially (mean -> jr) and to the teeth (its loss less what it stores and what it
    # passes along the stack). Its flank: the tooth's surface at the layer's radius,
    # the teeth block's own radial profile there (exact for a hollow cylinder with
    # uniform generation, through its mean and surfaces; the tooth is cooler at the tip
    # than its mean) plus the drop across the tooth's half width that the layer's
    # lateral heat makes
    eye = np.eye(L)
    gen = np.hstack([eye * (1.0 / R6 + 1.0 / r_lat), -eye / R6,
                     np.full((L, 1), -1.0 / r_lat), np.zeros((L, 2))]) / volume[:, None]
    walls = np.hstack([np.zeros((2, 2 * L + 1)), np.eye(2)])
    r_mid = 0.5 * (radii[:-1] + radii[1:])
    prof = cylinder_profile(r_yoke, st.bore_radius_m, r_mid)   # over (outer - m, inner - m)
    ratio = r_tooth / r_lat
    flank = np.hstack([eye * ratio, np.zeros((L, L)), (1.0 - prof.sum(axis=1) - ratio)[:, None],
                       prof])
    forms = hull_rows(rel @ np.vstack([gen, walls, flank]))
    forms[:, :L] += motor.layer_share       # anchored at the network's slice mean
    out = []
    for i in range(c.slices):
        layers = tuple(w.mean[i] for w in motor.winding_layers)
        out.append(PeakForms(layers + tuple(f'{m}.jr' for m in layers)
                             + (f'teeth.s{i + 1}', f'yoke.s{i + 1}.inner',
                                f'teeth.s{i + 1}.inner'), (forms,), layers[L // 2]))
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


def end_winding_peak_forms(motor, side: str) -> List[PeakForms]:
    """
    Return the peak forms of one end winding's layers: their radial and axial profiles superposed.

    Each over the layer's mean, its outer and inner surfaces and its two faces.
    """
    radii = motor.layer_radii_m
    axial = slab_profile(np.linspace(0.0, 1.0, END_POINTS))
    # T_m + g_r + g_z: the radial part carries the mean, the axial one sums to zero
    forms_z = np.zeros((END_POINTS, 5))
    forms_z[:, 3:5] = axial
    forms_z[:, 0] = -axial.sum(axis=1)
    forms_z = hull_rows(forms_z)
    out = []
    for j, ew in enumerate(motor.end_winding[side]):
        r_out, r_in = radii[j], radii[j + 1]
        radial = cylinder_profile(r_out, r_in, np.linspace(r_in, r_out, END_POINTS))
        forms_r = np.zeros((END_POINTS, 5))
        forms_r[:, 1:3] = radial
        forms_r[:, 0] = 1.0 - radial.sum(axis=1)
        out.append(PeakForms((ew.mean[0], ew.outer[0], ew.inner[0], ew.faces[0], ew.faces[1]),
                             (hull_rows(forms_r), forms_z), ew.mean[0]))
    return out
