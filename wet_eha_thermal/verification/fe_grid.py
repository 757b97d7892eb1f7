"""
Steady conduction on a structured grid of material blocks, P1 triangles (scikit-fem).

The grid's lines pass through every material boundary; blocks of one group
share their nodes, different groups meet only through declared thin-layer
contacts (the nodes on the two sides are distinct and joined by
h (T_a - T_b) per area). Robin links lead to fixed temperatures or to lumped
unknowns (oil nodes, with their advection). :func:`annulus_check` checks the
mesh against an exact solution.
"""

from dataclasses import dataclass, field
import math
import re
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from skfem import asm, Basis, BilinearForm, ElementTriP1, FacetBasis, LinearForm, MeshTri

_TOL = 1e-9
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
        """
        Return the indices of the blocks of ``part`` (in slice ``slice_``, if given).

        A part's radial layers (``winding.l1``, ``winding.l2``, ...) are its blocks too.
        """
        return [k for k, blk in enumerate(self.blocks)
                if (blk.part == part or re.fullmatch(rf'{re.escape(part)}\.l\d+', blk.part))
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
        # a surface is where its group ends: a face another block of the group covers is inside
        facets = facets[self.mesh.f2t[1, facets] < 0]
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
