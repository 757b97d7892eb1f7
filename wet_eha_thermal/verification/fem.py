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

Contacts (frame fit, slot liner, rotor fits, cap joint) are thin layers: the
nodes on the two sides are distinct and joined by h (T_a - T_b) per area.
Oil and ambient links are read from the built network at its operating
point, link by link (h x area as the network has it, spread uniformly over the
surface that stands for the link's node), as are the losses (each source's
power spread uniformly over its part's volume in its slice). The model is
built from node names (``part.sI``, ``part.sI.outer``, ``part.fJ``), so that
it follows the network's builder as long as those names keep their meaning.
"""

from dataclasses import dataclass, field, replace
import math
import re
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from skfem import asm, Basis, BilinearForm, ElementTriP1, FacetBasis, LinearForm, MeshTri

from ..model.motor import MotorInputs, WetMotor

_TOL = 1e-9
#: h (W/(m^2 K)) of a contact that is perfect (the bearing ring to the cap)
PERFECT_HTC = 1e7
SIDES = ('inner', 'outer', 'front', 'rear')


@dataclass(frozen=True)
class Block:
    """
    A rectangle of the (a, b) grid of one material: (r, z) in r-z, (r, theta) in 2-D.

    ``k`` the effective conductivities along a and b (W/(m K)), already scaled
    by ``frac``, the volume share of the material in the block (a continuum
    sharing its cells with another, or a sector of an annulus); sources are
    spread by that share; ``slice_no`` the network slice it belongs to (1-based).
    Blocks of one ``group`` share their nodes (perfect
    contact); different groups meet only through declared contacts.
    """

    part: str
    group: str
    a: Tuple[float, float]
    b: Tuple[float, float]
    k: Tuple[float, float]
    frac: float = 1.0
    slice_no: int = 1


@dataclass
class _Link:
    """A Robin term: h over facets, to a fixed temperature or a lumped node."""

    name: str
    b: np.ndarray        # int h v dA (W/K per unit nodal temperature)
    G: float             # its sum: the link's conductance (W/K)
    target: object       # a float (K) or a lumped node's index
    M: sp.csr_matrix = field(repr=False, default=None)


class GridFE:
    """
    Steady conduction on a structured grid of blocks, P1 triangles (scikit-fem).

    ``axisymmetric``: (a, b) = (r, z), every integral carries 2 pi r (areas in
    m^2, conductances in W/K); otherwise (a, b) = (r, theta) mapped to the
    plane, per metre of length (isotropic blocks only).
    """

    def __init__(self, blocks: Sequence[Block], h_m: float, axisymmetric: bool) -> None:
        self.blocks = list(blocks)
        self.axisymmetric = axisymmetric
        self.h_m = h_m
        a_max = max(blk.a[1] for blk in self.blocks)
        self.u = _grid_lines([blk.a for blk in self.blocks], h_m)
        self.v = _grid_lines([blk.b for blk in self.blocks],
                             h_m if axisymmetric else h_m / a_max)
        nu, nv = self.u.size, self.v.size
        self._nv = nv
        groups = sorted({blk.group for blk in self.blocks})
        self.node_of = {g: np.full(nu * nv, -1) for g in groups}
        self._cells = []
        for blk in self.blocks:
            if not axisymmetric and blk.k[0] != blk.k[1]:
                raise ValueError(f'{blk.part}: the planar model takes isotropic blocks only')
            ia = np.flatnonzero((self.u[:-1] >= blk.a[0] - _TOL) & (self.u[1:] <= blk.a[1] + _TOL))
            jb = np.flatnonzero((self.v[:-1] >= blk.b[0] - _TOL) & (self.v[1:] <= blk.b[1] + _TOL))
            I, J = np.meshgrid(ia, jb, indexing='ij')
            self._cells.append((I.ravel(), J.ravel()))
            for di in (0, 1):
                for dj in (0, 1):
                    self.node_of[blk.group][(I + di) * nv + J + dj] = 0
        offset = 0
        grid_of = []
        for g in groups:
            used = np.flatnonzero(self.node_of[g] >= 0)
            self.node_of[g][used] = np.arange(offset, offset + used.size)
            grid_of.append(used)
            offset += used.size
        self.n = offset
        grid = np.concatenate(grid_of)
        a, b = self.u[grid // nv], self.v[grid % nv]
        p = np.vstack([a, b]) if axisymmetric else np.vstack([a * np.cos(b), a * np.sin(b)])
        tris, owner, rows = [], [], []
        for k, (blk, (I, J)) in enumerate(zip(self.blocks, self._cells)):
            nd = self.node_of[blk.group]
            n00, n10 = nd[I * nv + J], nd[(I + 1) * nv + J]
            n11, n01 = nd[(I + 1) * nv + J + 1], nd[I * nv + J + 1]
            tris += [np.vstack([n00, n10, n11]), np.vstack([n00, n11, n01])]
            owner += [np.full(I.size, k)] * 2
            rows += [I, I]
        self.mesh = MeshTri(p, np.hstack(tris))
        self.owner = np.concatenate(owner)
        self.row = np.concatenate(rows)     # grid interval along a of each element
        self.elem = ElementTriP1()
        f = np.sort(self.mesh.facets, axis=0)
        self._facet_keys = f[0] * self.n + f[1]
        self._facet_order = np.argsort(self._facet_keys)
        self.nodes: List[str] = []          # lumped unknowns after the n field nodes
        self._node_rows: List[Tuple[int, int, float]] = []    # (row, col, value)
        self._node_rhs: Dict[int, float] = {}
        self.links: List[_Link] = []
        self.contacts: List[Tuple[str, sp.csr_matrix, sp.csr_matrix]] = []
        self._basis: Dict[int, Basis] = {}
        self.K = self._stiffness()
        self.f = np.zeros(self.n)

    # -------------------------------------------------------------- geometry
    def weight(self, w):
        """Return the integration weight: 2 pi r in r-z, 1 in the plane."""
        return 2 * np.pi * w.x[0] if self.axisymmetric else 1.0

    def basis(self, k: int) -> Basis:
        """Return the (cached) basis over the elements of block ``k``."""
        if k not in self._basis:
            self._basis[k] = Basis(self.mesh, self.elem, elements=np.flatnonzero(self.owner == k),
                                   intorder=3)
        return self._basis[k]

    def blocks_of(self, part: str, slice_: Optional[int] = None) -> List[int]:
        """Return the indices of the blocks of ``part`` (in slice ``slice_``, if given)."""
        return [k for k, blk in enumerate(self.blocks) if blk.part == part
                and (slice_ is None or blk.slice_no == slice_)]

    def face(self, blocks: Sequence[int], side: str,
             box: Optional[Tuple[Tuple[float, float], Tuple[float, float]]] = None):
        """
        Return the edges of the ``side`` of ``blocks`` (grid node pairs, and group per edge).

        ``side`` is one of ``SIDES`` (inner/outer: a = a1/a2, front/rear: b = b1/b2);
        ``box`` keeps the edges whose midpoints lie in ((a1, a2), (b1, b2)).
        """
        nv, out = self._nv, []
        for k in blocks:
            blk = self.blocks[k]
            if side in ('inner', 'outer'):
                i = int(np.argmin(abs(self.u - blk.a[side == 'outer'])))
                js = np.flatnonzero((self.v[:-1] >= blk.b[0] - _TOL)
                                    & (self.v[1:] <= blk.b[1] + _TOL))
                g0, g1 = i * nv + js, i * nv + js + 1
            else:
                j = int(np.argmin(abs(self.v - blk.b[side == 'rear'])))
                i_s = np.flatnonzero((self.u[:-1] >= blk.a[0] - _TOL)
                                     & (self.u[1:] <= blk.a[1] + _TOL))
                g0, g1 = i_s * nv + j, (i_s + 1) * nv + j
            if box is not None:
                am = 0.5 * (self.u[g0 // nv] + self.u[g1 // nv])
                bm = 0.5 * (self.v[g0 % nv] + self.v[g1 % nv])
                keep = ((am >= box[0][0] - _TOL) & (am <= box[0][1] + _TOL)
                        & (bm >= box[1][0] - _TOL) & (bm <= box[1][1] + _TOL))
                g0, g1 = g0[keep], g1[keep]
            out.append((g0, g1, blk.group))
        return out

    def _facets(self, edges) -> np.ndarray:
        ids = []
        for g0, g1, group in edges:
            d0, d1 = self.node_of[group][g0], self.node_of[group][g1]
            keys = np.minimum(d0, d1) * self.n + np.maximum(d0, d1)
            pos = np.searchsorted(self._facet_keys[self._facet_order], keys)
            ids.append(self._facet_order[pos])
        return np.concatenate(ids) if ids else np.zeros(0, dtype=int)

    def _surface(self, facets: np.ndarray, h: float):
        """Return (int h u v dA, int h v dA) over ``facets`` (matrix, vector)."""
        fb = FacetBasis(self.mesh, self.elem, facets=facets, intorder=3)
        wt = self.weight
        M = asm(BilinearForm(lambda u, v, w: h * u * v * wt(w)), fb)
        b = asm(LinearForm(lambda v, w: h * v * wt(w)), fb)
        return M.tocsr(), b

    def area(self, edges) -> float:
        """Return the size of the edges of :meth:`face`: m^2 in r-z, m per m in the plane."""
        return float(self._surface(self._facets(edges), 1.0)[1].sum())

    def _jump(self, grid_nodes: np.ndarray, group_a: str, group_b: str) -> sp.csr_matrix:
        """Return J with (J T)_a = T_a - T_b at the A-side nodes of ``grid_nodes``."""
        da, db = self.node_of[group_a][grid_nodes], self.node_of[group_b][grid_nodes]
        if np.any(db < 0):
            raise ValueError(f'contact {group_a}-{group_b}: no {group_b} node opposite')
        rows = np.concatenate([da, da])
        cols = np.concatenate([da, db])
        vals = np.concatenate([np.ones(da.size), -np.ones(da.size)])
        return sp.coo_matrix((vals, (rows, cols)), shape=(self.n, self.n)).tocsr()

    # -------------------------------------------------------------- assembly
    def _stiffness(self) -> sp.csr_matrix:
        K = sp.csr_matrix((self.n, self.n))
        for k, blk in enumerate(self.blocks):
            ka, kb = blk.k
            wt = self.weight
            K = K + asm(BilinearForm(lambda u, v, w: (ka * u.grad[0] * v.grad[0]
                                                      + kb * u.grad[1] * v.grad[1]) * wt(w)),
                        self.basis(k))
        return K

    def add_contact(self, name: str, edges_a, group_b: str, h: float) -> None:
        """Join the edges ``edges_a`` (of :meth:`face`) to group ``group_b`` by h (W/(m^2 K))."""
        M, _ = self._surface(self._facets(edges_a), h)
        grid_nodes = np.unique(np.concatenate([np.concatenate([g0, g1])
                                               for g0, g1, _ in edges_a]))
        J = self._jump(grid_nodes, edges_a[0][2], group_b)
        self.K = self.K + J.T @ M @ J
        self.contacts.append((name, M, J))

    def add_volume_coupling(self, k_a: int, group_b: str, g_W_m3K: float) -> None:
        """Couple block ``k_a`` to the coincident nodes of group ``group_b``: g (T_a - T_b)."""
        M = asm(BilinearForm(lambda u, v, w: g_W_m3K * u * v * self.weight(w)), self.basis(k_a))
        I, J_ = self._cells[k_a]
        nv = self._nv
        grid_nodes = np.unique(np.concatenate([(I + di) * nv + J_ + dj
                                               for di in (0, 1) for dj in (0, 1)]))
        J = self._jump(grid_nodes, self.blocks[k_a].group, group_b)
        self.K = self.K + J.T @ M.tocsr() @ J

    def contact_flow(self, name: str, T: np.ndarray) -> float:
        """Return the heat (W) through contact ``name``, from its A side to its B side."""
        return float(sum((M @ (J @ T[:self.n])).sum() for nm, M, J in self.contacts
                         if nm == name))

    def node(self, name: str) -> int:
        """Return the index of lumped unknown ``name``, adding it if new."""
        if name not in self.nodes:
            self.nodes.append(name)
        return self.n + self.nodes.index(name)

    def add_link(self, name: str, edges, G_W_K: float, target) -> None:
        """
        Add a Robin link of conductance ``G_W_K`` spread uniformly over ``edges``.

        ``target`` is a temperature (K) or the name of a lumped unknown.
        """
        facets = self._facets(edges)
        if facets.size == 0:
            raise ValueError(f'link {name}: no surface found for it')
        _, b1 = self._surface(facets, 1.0)
        h = G_W_K / b1.sum()
        M, b = self._surface(facets, h)
        tgt = self.node(target) if isinstance(target, str) else float(target)
        self.links.append(_Link(name, b, float(b.sum()), tgt, M))

    def add_advection(self, upstream, downstream: str, rate_W_K: float) -> None:
        """Carry enthalpy m c_p (T_up - T_down) into ``downstream`` (a node; up: node or K)."""
        d = self.node(downstream)
        self._node_rows.append((d, d, rate_W_K))
        if isinstance(upstream, str):
            self._node_rows.append((d, self.node(upstream), -rate_W_K))
        else:
            self._node_rhs[d] = self._node_rhs.get(d, 0.0) + rate_W_K * float(upstream)

    def add_source(self, blocks: Sequence[int], power_W: float) -> None:
        """Spread ``power_W`` uniformly over the material volume of ``blocks``."""
        vol = sum(self.blocks[k].frac * self.volume(k) for k in blocks)
        for k in blocks:
            q = power_W * self.blocks[k].frac / vol
            self.f += asm(LinearForm(lambda v, w: q * v * self.weight(w)), self.basis(k))

    def add_node_source(self, name: str, power_W: float) -> None:
        """Heat lumped unknown ``name`` by ``power_W``."""
        d = self.node(name)
        self._node_rhs[d] = self._node_rhs.get(d, 0.0) + power_W

    def volume(self, k: int) -> float:
        """Return the geometric volume of block ``k`` (m^3; m^2 per m in the plane)."""
        return float(self._mean_weights(k).sum())

    def _mean_weights(self, k: int) -> np.ndarray:
        return asm(LinearForm(lambda v, w: v * self.weight(w)), self.basis(k))

    # ----------------------------------------------------------------- solve
    def solve(self) -> np.ndarray:
        """Solve the steady state; return [field nodes; lumped unknowns] in K."""
        n, m = self.n, len(self.nodes)
        K = self.K
        rhs = np.concatenate([self.f, np.zeros(m)])
        rows, cols, vals = [], [], []
        for lk in self.links:
            K = K + lk.M
            if isinstance(lk.target, int):
                nz = np.flatnonzero(lk.b)
                t = np.full(nz.size, lk.target)
                rows += [nz, t, [lk.target]]
                cols += [t, nz, [lk.target]]
                vals += [-lk.b[nz], -lk.b[nz], [lk.G]]
            else:
                rhs[:n] += lk.b * lk.target
        for r, c, v in self._node_rows:
            rows.append([r])
            cols.append([c])
            vals.append([v])
        for d, v in self._node_rhs.items():
            rhs[d] += v
        K = sp.bmat([[K, None], [None, sp.csr_matrix((m, m))]]) if m else K
        if rows:
            K = K + sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows),
                                                          np.concatenate(cols))),
                                  shape=(n + m, n + m))
        self.T = spla.spsolve(sp.csc_matrix(K), rhs)
        return self.T

    # --------------------------------------------------------------- results
    def mean(self, blocks: Sequence[int], T: Optional[np.ndarray] = None) -> float:
        """Return the material-volume mean temperature (K) over ``blocks``."""
        T = self.T if T is None else T
        num = den = 0.0
        for k in blocks:
            wts = self._mean_weights(k) * self.blocks[k].frac
            num += float(wts @ T[:self.n])
            den += float(wts.sum())
        return num / den

    def peak(self, blocks: Sequence[int], T: Optional[np.ndarray] = None) -> float:
        """Return the highest nodal temperature (K) of ``blocks``."""
        T = self.T if T is None else T
        els = np.flatnonzero(np.isin(self.owner, blocks))
        return float(T[np.unique(self.mesh.t[:, els])].max())

    def link_flow(self, lk: _Link, T: Optional[np.ndarray] = None) -> float:
        """Return the heat (W) leaving the solid through link ``lk``."""
        T = self.T if T is None else T
        t = T[lk.target] if isinstance(lk.target, int) else lk.target
        return float(lk.b @ T[:self.n] - lk.G * t)


def _grid_lines(ranges: Sequence[Tuple[float, float]], h: float) -> np.ndarray:
    """Return grid lines through every range end, no farther apart than ``h``."""
    ends = np.unique(np.round(np.array(ranges).ravel(), 12))
    lines = [ends[:1]]
    for x0, x1 in zip(ends[:-1], ends[1:]):
        n = max(1, math.ceil((x1 - x0) / h - 1e-9))
        lines.append(np.linspace(x0, x1, n + 1)[1:])
    return np.concatenate(lines)


# ------------------------------------------------------------------ the mesh check
def annulus_exact(r_m, r_in_m: float, r_out_m: float, k_W_mK: float, q_W_m3: float,
                  h_W_m2K: float):
    """
    Return the temperature rise (K) of a hollow cylinder with uniform generation.

    Adiabatic at ``r_in_m``, cooled at ``r_out_m`` by h to a sink at 0:
    T(r) = q (ro^2 - ri^2) / (2 ro h) + q (ro^2 - r^2) / (4 k) + q ri^2 ln(r / ro) / (2 k)
    (dT/dr = 0 at ri; -k dT/dr = h T at ro).

    At the adiabatic wall: 18.056 + 40.625 - 16.219 K.

    >>> round(float(annulus_exact(0.02, 0.02, 0.045, 1.0, 1e5, 100.0)), 3)
    42.462
    """
    r, ri, ro = np.asarray(r_m, dtype=float), r_in_m, r_out_m
    return (q_W_m3 * (ro ** 2 - ri ** 2) / (2 * ro * h_W_m2K)
            + q_W_m3 * (ro ** 2 - r ** 2) / (4 * k_W_mK)
            + q_W_m3 * ri ** 2 * np.log(r / ro) / (2 * k_W_mK))


def annulus_check(h_m: float, axisymmetric: bool = False, r_in_m: float = 0.02,
                  r_out_m: float = 0.045, k_W_mK: float = 1.0, q_W_m3: float = 1e5,
                  h_W_m2K: float = 100.0) -> Dict[str, float]:
    """
    Solve the annulus of :func:`annulus_exact` on a grid of size ``h_m``; return FE and exact.

    In the plane a 30 degree sector (its sides adiabatic, as the slot pitch's),
    in r-z a 10 mm long cylinder with adiabatic ends. Returns the mean and
    peak rises (K), FE and exact.
    """
    b = (0.0, 0.01) if axisymmetric else (0.0, np.pi / 6)
    fe = GridFE([Block('annulus', 'annulus', (r_in_m, r_out_m), b, (k_W_mK, k_W_mK))],
                h_m, axisymmetric)
    fe.add_source([0], q_W_m3 * fe.volume(0))
    fe.add_link('cooled', fe.face([0], 'outer'), h_W_m2K * fe.area(fe.face([0], 'outer')), 0.0)
    T = fe.solve()
    r = np.linspace(r_in_m, r_out_m, 20001)
    exact = annulus_exact(r, r_in_m, r_out_m, k_W_mK, q_W_m3, h_W_m2K)
    mean = np.trapezoid(exact * r, r) / np.trapezoid(r, r)
    return {'mean_fe': fe.mean([0], T), 'mean_exact': float(mean),
            'peak_fe': float(T.max()), 'peak_exact': float(exact[0])}


# ------------------------------------------------------------------ operating points
RPM = np.pi / 30.0


def map_inputs(maps, rpm: float, amps: float) -> MotorInputs:
    """Return the inputs of a map point of ``config.MapsJob`` ``maps`` (speed r/min, A)."""
    return MotorInputs(current_sq_mean_A2=amps ** 2, speed_rad_s=rpm * RPM,
                       oil_inlet_K=maps.oil_inlet_C + 273.15,
                       oil_flow_m3_s=maps.oil_flow_L_min / 60000.0,
                       ambient_K=maps.ambient_C + 273.15, case_pressure_Pa=maps.case_pressure_Pa)


def source_names(motor: WetMotor) -> List[str]:
    """Return the node of each source of ``motor.power_W``, in order."""
    return list(motor.net._source_nodes)


def _split_name(name: str) -> Tuple[str, Optional[int], Optional[str]]:
    """Split a node name into (part, slice, side): 'yoke.s2.outer', 'teeth.f0', 'magnet.s1'."""
    m = re.fullmatch(r'(.+)\.s(\d+)(?:\.(outer|inner))?', name)
    if m:
        return m.group(1), int(m.group(2)), m.group(3)
    m = re.fullmatch(r'(.+)\.f(\d+)', name)
    if m:
        j = int(m.group(2))
        return m.group(1), max(j, 1), 'front' if j == 0 else 'rear'
    return name, None, None


# ------------------------------------------------------------------ 2-D slot pitch
@dataclass(frozen=True)
class SlotProblem:
    """
    The 2-D problem of one operating point: losses of the whole machine per metre of stack.

    Copper, yoke and teeth losses (W/m); h (W/(m^2 K)) of the frame barrel to
    ambient and of the bore to the airgap oil; the ambient and oil temperatures (K).
    """

    copper_W_m: float
    yoke_W_m: float
    teeth_W_m: float
    h_ambient_W_m2K: float
    h_bore_W_m2K: float
    ambient_K: float
    oil_K: float


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


def slot_pitch(c, prob: SlotProblem, h_m: float) -> Tuple[GridFE, Dict[str, float]]:
    """
    Solve one slot pitch of motor config ``c`` (2-D, per metre); return the model and results.

    Radial-sided tooth of angular share ``tooth_fraction`` (the network's
    annulus share), centred on the pitch's sides; the tooth tips close the slot
    over the whole pitch from the bore to ``tooth_tip_depth_m`` (the network
    joins the slot's inner liner to the bore); the liner a thin layer on the
    slot's four sides; the frame fit a thin layer. Results: winding mean and
    peak, teeth (tips included), yoke and frame means (K); the heat (W/m, whole
    machine) through the bore, the frame barrel and the slot sides.
    """
    fr, st, wd = c.frame, c.stator, c.winding
    pitch = 2 * np.pi / c.slots
    half = 0.5 * st.tooth_fraction * pitch
    r_tip = st.bore_radius_m + st.tooth_tip_depth_m
    k_fe, k_w = st.material.k_radial_W_mK, wd.k_radial_W_mK
    blocks = [Block('frame', 'frame', (fr.inner_radius_m, fr.outer_radius_m), (0, pitch),
                    (fr.material.k_radial_W_mK,) * 2),
              Block('yoke', 'stator', (st.yoke_inner_radius_m, st.outer_radius_m), (0, pitch),
                    (k_fe, k_fe)),
              Block('teeth', 'stator', (st.bore_radius_m, r_tip), (0, pitch), (k_fe, k_fe)),
              Block('teeth', 'stator', (r_tip, st.yoke_inner_radius_m), (0, half), (k_fe, k_fe)),
              Block('teeth', 'stator', (r_tip, st.yoke_inner_radius_m), (pitch - half, pitch),
                    (k_fe, k_fe)),
              Block('winding', 'winding', (r_tip, st.yoke_inner_radius_m), (half, pitch - half),
                    (k_w, k_w))]
    fe = GridFE(blocks, h_m, axisymmetric=False)
    liner = wd.liner_conductivity_W_mK / wd.liner_thickness_m
    fe.add_contact('frame fit', fe.face([0], 'inner'), 'stator',
                   st.contact_gap_conductivity_W_mK / st.frame_contact_gap_m)
    fe.add_contact('slot bottom', fe.face([5], 'outer'), 'stator', liner)
    fe.add_contact('slot top', fe.face([5], 'inner'), 'stator', liner)
    fe.add_contact('slot sides', fe.face([5], 'front') + fe.face([5], 'rear'), 'stator', liner)
    fe.add_source([5], prob.copper_W_m / c.slots)
    fe.add_source([1], prob.yoke_W_m / c.slots)
    fe.add_source([2, 3, 4], prob.teeth_W_m / c.slots)
    outer, bore = fe.face([0], 'outer'), fe.face([2], 'inner')
    fe.add_link('frame', outer, prob.h_ambient_W_m2K * fe.area(outer), prob.ambient_K)
    fe.add_link('bore', bore, prob.h_bore_W_m2K * fe.area(bore), prob.oil_K)
    T = fe.solve()
    return fe, {'winding_mean': fe.mean([5], T), 'winding_peak': fe.peak([5], T),
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
    for k, nm in enumerate(source_names(m)):
        P[k] = {'winding.s1': prob.copper_W_m, 'yoke.s1': prob.yoke_W_m,
                'teeth.s1': prob.teeth_W_m}.get(nm, 0.0) * L
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
    t = {p: float(T[net.index(p + '.s1')]) for p in ('winding', 'teeth', 'yoke', 'frame')}
    t.update({'bore_W_m': float(flows[m.gap_links_stator].sum()) / L,
              'frame_W_m': float(flows[frame_links].sum()) / L})
    t['winding_mean'] = t.pop('winding')
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
    for i in np.unique(fe.row[np.isin(fe.owner, [3, 4, 5])]):
        means, area = [], 0.0
        for blocks in ([5], [3, 4]):
            els = np.flatnonzero(np.isin(fe.owner, blocks) & (fe.row == i))
            wts = asm(LinearForm(lambda v, w: v), Basis(fe.mesh, fe.elem, elements=els))
            means.append(float(wts @ T[:fe.n]) / wts.sum())
            area += wts.sum()
        integral += (means[0] - means[1]) * area
    return q / integral


# ------------------------------------------------------------------ r-z motor
ROTOR_PARTS = ('sleeve', 'magnet', 'rotor_core', 'shaft', 'bearing')


def _oil_nodes(net) -> List[str]:
    """Return the lumped oil nodes: every node an advection link feeds."""
    return [d for _, d in net._advections]


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
    :func:`slot_pitch`). Each bearing is a ring in the cap's bore, shaft to cap,
    whose conductivity gives the network's bearing conductance.
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
    t_cap, oh = es.cap_thickness_m, wd.end_overhang_m
    tf = st.tooth_fraction
    sf = 1.0 - tf

    def ks(mat, f=1.0):
        return (f * mat.k_radial_W_mK, f * mat.k_axial_W_mK)
    k_wind = (sf * wd.k_radial_W_mK, sf * wd.k_axial_W_mK)
    stack = [('frame', 'frame', (fr.inner_radius_m, fr.outer_radius_m), ks(fr.material), 1.0),
             ('yoke', 'stator', (st.yoke_inner_radius_m, st.outer_radius_m), ks(st.material),
              1.0),
             ('teeth', 'tip', (st.bore_radius_m, r_tip), ks(st.material), 1.0),
             ('teeth', 'stator', (r_tip, st.yoke_inner_radius_m), ks(st.material, tf), tf),
             ('winding', 'winding', (r_tip, st.yoke_inner_radius_m), k_wind, sf),
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
            Block(f'end_winding_{side}', 'winding', (r_tip, st.yoke_inner_radius_m),
                  span(0.0, oh), k_wind, sf),
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
    c, net = motor.cfg, motor.net
    st, wd, ro = c.stator, c.winding, c.rotor
    fe = GridFE(rz_blocks(motor), h_m, axisymmetric=True)
    liner = wd.liner_conductivity_W_mK / wd.liner_thickness_m * (1 - st.tooth_fraction)
    every = fe.blocks_of
    contacts = [('frame fit', every('frame'), 'inner', 'stator',
                 st.contact_gap_conductivity_W_mK / st.frame_contact_gap_m, None),
                ('slot bottom', every('winding'), 'outer', 'stator', liner, None),
                ('slot top', every('winding'), 'inner', 'tip', liner, None),
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
    names = net.node_names + net.boundary_names
    Tb = motor.boundaries(u)
    bvals = dict(zip(net.boundary_names, Tb))
    oil = _oil_nodes(net)
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
        part, sl, side = _split_name(solid)
        if side is None:
            raise ValueError(f'link {a}-{b}: the FE model has no surface for node {solid}')
        box = end_space_box(c, other[len('end_oil_'):]) if other.startswith('end_oil_') else None
        fe.add_link(f'{solid}|{other}', fe.face(fe.blocks_of(part, sl), side, box), G[k],
                    other if other in oil else bvals[other])
        fe.network_links.append(k)
    for up, down in net._advections:
        rate = net.advection_rate[net._advections.index((up, down))]
        fe.add_advection(up if up in oil else bvals[up], down, rate)
    for nm, P in zip(source_names(motor), motor.power_W):
        if nm in oil:
            fe.add_node_source(nm, P)
            continue
        part, sl, _ = _split_name(nm)
        blocks = fe.blocks_of(part, sl)
        if not blocks:
            raise ValueError(f'source at {nm}: the FE model has no part {part!r}')
        fe.add_source(blocks, P)
    fe.solve()
    return fe


# ------------------------------------------------------------------ comparisons
TEMPERATURES = ('winding_mean', 'winding_hotspot', 'magnet', 'yoke', 'teeth', 'frame',
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
    (conductor-length mean; hottest winding block; hottest magnet slice; frame
    volume mean over the stack); yoke, teeth, rotor core and shaft the volume
    means of their stack slices. Heat paths: the sum over the links of each path.
    """
    T, net = motor.T, motor.net
    out = {k: v - 273.15 for k, v in motor.outputs(T).items()}
    for part in ('yoke', 'teeth', 'rotor_core', 'shaft'):
        cyl = motor.parts[part]
        out[part] = float(np.dot([T[net.index(m)] for m in cyl.mean], cyl.volume_m3)
                          / np.sum(cyl.volume_m3)) - 273.15
    names = net.node_names + net.boundary_names
    flows = net.link_heat_flows(T, motor.boundaries(u))
    oil, bounds = _oil_nodes(net), set(net.boundary_names)
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
    by the network's conductor-length shares; hot spot: the hottest of those
    block means (``winding_peak``: the hottest point of the winding continua);
    magnet: the hottest magnet slice mean; the other parts their stack means;
    the oil outlets the lumped oil unknowns.
    """
    def block_mean(node):
        part, sl, _ = _split_name(node)
        return fe.mean(fe.blocks_of(part, sl))
    wind = np.array([block_mean(m) for m in motor.copper_nodes])
    share = np.asarray(motor.copper_share)
    out = {'winding_mean': float(wind @ share / share.sum()),
           'winding_hotspot': float(wind.max()),
           'winding_peak': max(fe.peak(fe.blocks_of(p)) for p in
                               {_split_name(m)[0] for m in motor.copper_nodes}),
           'magnet': max(fe.mean([k]) for k in fe.blocks_of('magnet'))}
    for part in ('yoke', 'teeth', 'frame', 'rotor_core', 'shaft'):
        out[part] = fe.mean(fe.blocks_of(part))
    out['airgap_oil_outlet'] = fe.T[fe.node(motor.gap[-1])]
    out['motor_oil_outlet'] = fe.T[fe.node(motor.oil_nodes[-1])]
    out = {k: float(v) - 273.15 for k, v in out.items()}
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
