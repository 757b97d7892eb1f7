"""
Lumped-parameter thermal network with named nodes.

A network is built once (nodes, boundaries, links, heat sources), then driven:
coefficient values (conductances, advective capacity rates, heat capacities)
may change between steps, the topology may not.

- Node: a temperature with a heat capacity C (J/K). ``C = 0`` makes it an
  algebraic node (a surface or a junction of a Mellor block); it is eliminated
  exactly (Kron reduction) so that only capacitive nodes are states.
- Boundary: a temperature imposed from outside (ambient, an oil inlet).
- Conductance link: heat flow G (T_a - T_b), G in W/K, negative values allowed
  (the Mellor T-equivalent has negative resistances that make the mean
  temperature exact).
- Advective link: a mass flow carrying enthalpy from an upstream node (or
  boundary) into a downstream node, upwind: the downstream node receives
  ``m_dot c_p (T_up - T_down)``. Chain links to model plug flow.
- Source: a heat input P (W) into one node.

With T the node temperatures (K), T_b the boundary temperatures and P the
source powers, the network reads ``C dT/dt = -K T + G_b T_b + E P``. After
eliminating the algebraic nodes the states x = T_d obey ``dx/dt = A x + B w``
with ``w = [T_b; P]``. A transient step is the exact zero-order-hold solution
(inputs held over the step), computed with one matrix exponential of the
reduced network, so it is stable and exact for the linear network at any step; the
time integral of the state over the step follows from the same exponential,
which makes step-averaged heat flows (and so energy balances) exact as well.
"""

from collections import OrderedDict
from dataclasses import dataclass
from functools import lru_cache
import os
import threading
from typing import Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import scipy.linalg
from scipy.linalg.lapack import dgbtrf, dgbtrs
import scipy.sparse
from scipy.sparse.csgraph import reverse_cuthill_mckee

from .compiled import jit

Ref = Union[str, int]


class NetworkError(ValueError):
    """A network that cannot be built or solved, with the reason."""


@dataclass
class Discretisation:
    """Exact zero-order-hold matrices of the reduced network for one step ``dt_s``."""

    dt_s: float
    Ad: np.ndarray  # x(t + dt) = Ad x + Bd w
    Bd: np.ndarray
    Mx: np.ndarray  # mean of x over the step = Mx x + Mw w
    Mw: np.ndarray


#: Reductions and discretisations kept by their exact inputs, the last few: the limits'
#: two probes of a tick (:mod:`~wet_eha_thermal.estimator.limits`) step copies of one model
#: from one state, whose coefficients come out the same to the bit (the copies share the
#: network's structure, :mod:`.snapshot`): the second takes the first's matrices instead of
#: computing them again (about 8 ms of reduction and exponential). Values are only read.
_MEMO: 'OrderedDict[tuple, list]' = OrderedDict()
_MEMO_SIZE = 2
#: the cold start's heating steps copies on a thread of its own (estimator/uncertainty.py):
#: an entry looked up on one thread must not be evicted by the other before it is moved
_MEMO_LOCK = threading.Lock()
# a child forked while the heating thread held it would wait on it for ever
os.register_at_fork(after_in_child=lambda: globals().update(_MEMO_LOCK=threading.Lock()))


class ThermalNetwork:
    """Named thermal network: build it, then solve steady states or step it in time."""

    def __init__(self) -> None:
        self.node_names: List[str] = []
        self.boundary_names: List[str] = []
        self._kind: Dict[str, Tuple[str, int]] = {}
        self._capacity: List[float] = []
        self._links: List[Tuple[str, str]] = []
        self._link_g: List[float] = []
        self._advections: List[Tuple[str, str]] = []
        self._source_nodes: List[str] = []
        self.link_names: List[Optional[str]] = []
        self._frozen = False
        self.refresh_rtol = 0.0
        # hold_changes: new coefficients wait for apply_changes() (or the step after the
        # next) instead of dropping the cached matrices at once; see apply_changes
        self.hold_changes = False
        self.changes_pending = False
        self.discretise_count = 0       # exponentials computed: the expensive part of a step
        self.last_disc: Optional[Discretisation] = None   # used by the last step_temperatures

    # ----------------------------------------------------------------- build
    def add_node(self, name: str, capacity_J_K: float = 0.0) -> str:
        """Add a node; ``capacity_J_K = 0`` makes it algebraic (no thermal mass)."""
        self._check_new(name)
        if not capacity_J_K >= 0.0:
            raise NetworkError(f'node {name!r}: heat capacity {capacity_J_K} J/K must be >= 0')
        self._kind[name] = ('n', len(self.node_names))
        self.node_names.append(name)
        self._capacity.append(float(capacity_J_K))
        return name

    def add_boundary(self, name: str) -> str:
        """Add a fixed-temperature boundary (an input of the network)."""
        self._check_new(name)
        self._kind[name] = ('b', len(self.boundary_names))
        self.boundary_names.append(name)
        return name

    def add_conductance(self, a: str, b: str, conductance_W_K: float = 0.0,
                        name: Optional[str] = None) -> int:
        """Link ``a`` and ``b`` by a conductance (W/K, may be negative); return its id."""
        self._check_open()
        self._require(a)
        self._require(b)
        if a == b:
            raise NetworkError(f'conductance from {a!r} to itself')
        if self._kind[a][0] == 'b' and self._kind[b][0] == 'b':
            raise NetworkError(f'conductance between two boundaries {a!r} and {b!r}')
        if not np.isfinite(conductance_W_K):
            raise NetworkError(f'conductance {a!r}-{b!r}: {conductance_W_K} W/K is not finite')
        self._links.append((a, b))
        self._link_g.append(float(conductance_W_K))
        self.link_names.append(name)
        return len(self._links) - 1

    def add_resistance(self, a: str, b: str, resistance_K_W: float,
                       name: Optional[str] = None) -> int:
        """Link ``a`` and ``b`` by a thermal resistance (K/W, may be negative, not zero)."""
        if resistance_K_W == 0.0:
            raise NetworkError(f'resistance {a!r}-{b!r} is zero: merge the two nodes instead')
        return self.add_conductance(a, b, 1.0 / resistance_K_W, name)

    def add_advection(self, upstream: str, downstream: str) -> int:
        """Carry enthalpy from ``upstream`` into node ``downstream``; return the link id."""
        self._check_open()
        self._require(upstream)
        self._require(downstream)
        if self._kind[downstream][0] != 'n':
            raise NetworkError(f'advection into boundary {downstream!r}: the outlet of a '
                               'chain needs no link')
        self._advections.append((upstream, downstream))
        return len(self._advections) - 1

    def add_source(self, node: str) -> int:
        """Declare a heat input into ``node``; return its index in the power vector."""
        self._check_open()
        self._require(node)
        if self._kind[node][0] != 'n':
            raise NetworkError(f'heat source on boundary {node!r}')
        self._source_nodes.append(node)
        return len(self._source_nodes) - 1

    def _check_new(self, name: str) -> None:
        self._check_open()
        if name in self._kind:
            raise NetworkError(f'name {name!r} is used twice')

    def _check_open(self) -> None:
        if self._frozen:
            raise NetworkError('the network topology is fixed once it has been solved')

    def _require(self, name: str) -> None:
        if name not in self._kind:
            raise NetworkError(f'unknown node or boundary {name!r}')

    # --------------------------------------------------------------- compile
    def freeze(self) -> 'ThermalNetwork':
        """Fix the topology and precompute index arrays (done on first use)."""
        if self._frozen:
            return self
        self._frozen = True
        n = len(self.node_names)
        self.n = n
        self.nb = len(self.boundary_names)
        self.ns = len(self._source_nodes)
        self.capacity = np.array(self._capacity)
        self.conductance = np.array(self._link_g)
        self.advection_rate = np.zeros(len(self._advections))
        # link endpoints: node-node pairs and node-boundary pairs
        nn, nb_ = [], []
        for k, (a, b) in enumerate(self._links):
            ka, ia = self._kind[a]
            kb, ib = self._kind[b]
            if ka == 'n' and kb == 'n':
                nn.append((k, ia, ib))
            else:
                node, bnd = (ia, ib) if ka == 'n' else (ib, ia)
                nb_.append((k, node, bnd))
        self._nn = np.array(nn, dtype=int).reshape(-1, 3)
        self._nbl = np.array(nb_, dtype=int).reshape(-1, 3)
        adv_n, adv_b = [], []
        for k, (u, d) in enumerate(self._advections):
            ku, iu = self._kind[u]
            idn = self._kind[d][1]
            (adv_n if ku == 'n' else adv_b).append((k, iu, idn))
        self._adv_n = np.array(adv_n, dtype=int).reshape(-1, 3)
        self._adv_b = np.array(adv_b, dtype=int).reshape(-1, 3)
        self._src = np.array([self._kind[s][1] for s in self._source_nodes], dtype=int)
        # scatter indices of K, G_b, E in node order, and in the order [states;
        # algebraic nodes] that makes the Kron reduction work on plain slices (capacities
        # may change, but never to or from zero, so the split is fixed from here on)
        self._d = np.flatnonzero(self.capacity > 0.0)
        self._a = np.flatnonzero(self.capacity == 0.0)
        position = np.empty(n, dtype=int)
        position[np.concatenate([self._d, self._a])] = np.arange(n)
        self._scatter = self._scatter_indices(np.arange(n))
        self._scatter_reduced = self._scatter_indices(position)
        self._band = self._algebraic_band()
        self._blocks = self._reduction_blocks()
        # link ends in the vector [T; T_b], for heat flows
        flat = {nm: (i if k == 'n' else n + i) for nm, (k, i) in self._kind.items()}
        self._ends = np.array([[flat[a], flat[b]] for a, b in self._links],
                              dtype=int).reshape(-1, 2)
        self._disc: Optional[Discretisation] = None
        self._reduced: Optional[tuple] = None
        self._used = None
        return self

    def index(self, name: str) -> int:
        """Return the index of node ``name`` in the full temperature vector."""
        kind = self._kind.get(name)
        if kind is None or kind[0] != 'n':
            close = [s for s in self.node_names if s.startswith(name.split('.')[0])][:8]
            raise KeyError(f'no node named {name!r}' + (f'; nodes like it: {close}' if close
                                                        else ''))
        return kind[1]

    def link_id(self, a: str, b: str) -> int:
        """Return the id of the conductance link joining ``a`` and ``b`` (either order)."""
        for k, ends in enumerate(self._links):
            if ends in ((a, b), (b, a)):
                return k
        raise KeyError(f'no conductance link between {a!r} and {b!r}')

    def boundary_index(self, name: str) -> int:
        """Return the index of boundary ``name`` in the boundary-temperature vector."""
        kind = self._kind.get(name)
        if kind is None or kind[0] != 'b':
            raise KeyError(f'no boundary named {name!r}; boundaries: {self.boundary_names}')
        return kind[1]

    @property
    def dynamic(self) -> np.ndarray:
        """Return the indices of the nodes with heat capacity (the states), in state order."""
        return self.freeze()._d

    @property
    def state_names(self) -> List[str]:
        """Return the names of the states, in state order."""
        return [self.node_names[i] for i in self.dynamic]

    # ---------------------------------------------------------- coefficients
    def set_conductances(self, ids, values_W_K) -> None:
        """Set conductance values (W/K) of links ``ids``."""
        self.freeze()
        self.conductance[ids] = values_W_K
        self._mark_changed()

    def set_advection_rates(self, ids, rates_W_K) -> None:
        """Set the capacity rates ``m_dot c_p`` (W/K, >= 0) of advective links ``ids``."""
        self.freeze()
        rates = np.asarray(rates_W_K, dtype=float)
        if np.any(rates < 0.0):
            raise NetworkError('advective capacity rate must be >= 0: reverse the link to '
                               'reverse the flow')
        self.advection_rate[ids] = rates
        self._mark_changed()

    def set_capacities(self, names_or_idx: Sequence[Ref], capacities_J_K) -> None:
        """Change heat capacities of capacitive nodes (must stay > 0)."""
        self.freeze()
        idx = [self.index(r) if isinstance(r, str) else r for r in names_or_idx]
        c = np.asarray(capacities_J_K, dtype=float)
        if np.any(c <= 0.0) or np.any(self.capacity[idx] <= 0.0):
            raise NetworkError('only capacitive nodes may change capacity, and it stays > 0')
        self.capacity[idx] = c
        self._mark_changed()

    def _mark_changed(self) -> None:
        """Drop cached matrices when a coefficient moved by more than ``refresh_rtol``."""
        if self._used is None:
            return
        if self.refresh_rtol > 0.0:
            moved = False
            for now, then in zip((self.conductance, self.advection_rate, self.capacity),
                                 self._used):
                if np.any(np.abs(now - then) > self.refresh_rtol * np.abs(then)):
                    moved = True
                    break
            if not moved:
                return
        if self.hold_changes:
            self.changes_pending = True
            return
        self._drop_cache()

    def use_new_coefficients(self) -> None:
        """Put the present coefficients into use, however little they moved (``refresh_rtol``)."""
        self._drop_cache()

    def _drop_cache(self) -> None:
        self._used = None
        self._reduced = None
        self._disc = None
        self.changes_pending = False

    def apply_changes(self, dt_s: Optional[float] = None) -> bool:
        """
        Put held coefficient changes into use; with ``dt_s``, also discretise for that step.

        With ``hold_changes`` the solver keeps stepping (and reporting heat
        flows) with the coefficients of the last discretisation until this is
        called, so that the expensive re-discretisation can be done at a
        convenient time, e.g. right after an estimate has been published.
        Returns whether anything changed.
        """
        if not self.changes_pending:
            return False
        self._drop_cache()
        if dt_s is not None:
            self.discretise(dt_s)
        return True

    # -------------------------------------------------------------- matrices
    def _scatter_indices(self, position: np.ndarray) -> tuple:
        """Return flat indices of K, G_b and E's rows with node i placed at ``position[i]``."""
        n, nb = self.n, max(self.nb, 1)
        i, j = position[self._nn[:, 1]], position[self._nn[:, 2]]
        bi = position[self._nbl[:, 1]]
        au, ad = position[self._adv_n[:, 1]], position[self._adv_n[:, 2]]
        bd = position[self._adv_b[:, 2]]
        k_idx = np.concatenate([i * n + i, j * n + j, i * n + j, j * n + i, bi * n + bi,
                                ad * n + ad, ad * n + au, bd * n + bd])
        gb_idx = np.concatenate([bi * nb + self._nbl[:, 2], bd * nb + self._adv_b[:, 1]])
        return k_idx, gb_idx, position[self._src]

    def matrices(self, reduced_order: bool = False) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """
        Assemble K (n x n), G_b (n x nb), E (n x ns) of ``C dT/dt = -K T + G_b T_b + E P``.

        Rows and columns follow the node order, or with ``reduced_order`` the
        states first and then the algebraic nodes.
        """
        self.freeze()
        n, nb = self.n, max(self.nb, 1)
        k_idx, gb_idx, src = self._scatter_reduced if reduced_order else self._scatter
        k_val, w_val = self._entry_values()
        K = np.bincount(k_idx, weights=k_val, minlength=n * n).reshape(n, n)
        Gb = np.bincount(gb_idx, weights=w_val,
                         minlength=n * nb).reshape(n, nb)[:, :self.nb]
        E = np.zeros((n, self.ns))
        E[src, np.arange(self.ns)] = 1.0
        return K, Gb, E

    def _algebraic_band(self) -> tuple:
        """
        Order the algebraic nodes for a narrow band (reverse Cuthill-McKee) and index it.

        Each algebraic node links to a few neighbours of its own part (the
        surfaces of a Mellor block, a slice's neighbours): in that order the
        block is banded (half-width 2 in the reference motor), and its LU costs
        a fraction of a dense one. Returns (order, half-width, the block's
        entries as rows and columns of K's algebraic block, their places in
        LAPACK's band storage).
        """
        m, na = self._d.size, self._a.size
        if not na:
            return None
        k_idx = self._scatter_reduced[0]
        return _band(self.n, m, na, k_idx.dtype.str, k_idx.tobytes())

    def _reduction_blocks(self) -> Optional[tuple]:
        """
        Return where each entry of K, G_b and E goes in the blocks that the reduction reads.

        :meth:`_reduce` needs K's state block, its state-to-algebraic block,
        the band of its algebraic block, and the right-hand side of the
        algebraic solve (K's algebraic-to-state block beside W's algebraic
        rows, in the band's order). Each is summed by ``np.bincount`` straight
        from the coefficients, in their order, as :meth:`matrices` sums the
        whole of K: the same entries added in the same order, so the same
        values to the bit, without filling and reading a dense n x n matrix.
        """
        if not self._a.size:
            return None
        k_idx, gb_idx, src = self._scatter_reduced
        order = self._band[0]
        return _blocks(self.n, self._d.size, self.nb, self.ns, self._band[1],
                       *(a.dtype.str for a in (k_idx, gb_idx, src, order)),
                       *(a.tobytes() for a in (k_idx, gb_idx, src, order)))

    def algebraic_map(self) -> Tuple[np.ndarray, np.ndarray]:
        """Return the algebraic nodes and their temperatures' sensitivity to the states (K/K)."""
        a, out_x = self._reduce()[3:5]
        return a, out_x

    def _reduce(self) -> tuple:
        """Eliminate algebraic nodes: return A, B and the algebraic-node output maps."""
        self.freeze()
        if self._reduced is not None:
            return self._reduced
        memo = self._memo((self.conductance, self.advection_rate, self.capacity))
        if memo[1] is not None:
            self._used = (self.conductance.copy(), self.advection_rate.copy(),
                          self.capacity.copy())
            self._reduced = memo[1]
            return self._reduced
        d, a = self._d, self._a
        m = d.size
        if a.size:
            half = self._band[1]
            # K is made of the conductances and advection rates: finite when they are
            if not (np.isfinite(self.conductance).all()
                    and np.isfinite(self.advection_rate).all()):
                raise NetworkError('algebraic nodes cannot be eliminated: a coefficient is '
                                   'not finite')
            K_dd, K_da, W_d, band, rhs = self._reduction_matrices()
            lu, piv, info = dgbtrf(band, half, half)
            pivots = lu[2 * half]                    # U's diagonal
            # the band holds every entry of K's algebraic block: its largest is the block's
            if info != 0 or np.any(np.abs(pivots) < 1e-14 * np.abs(band).max()):
                raise NetworkError('algebraic nodes form a group with no path to a capacity '
                                   'or a boundary: their temperature is undefined')
            # the solve costs per column, and most of them are zero (sources heat states,
            # a state touches a few algebraic nodes): those solve to zero
            cols = np.flatnonzero(rhs.any(axis=0))
            solved, info = dgbtrs(lu, half, half, rhs[:, cols], piv)
            if info != 0:
                raise NetworkError(f'algebraic nodes cannot be eliminated (gbtrs info {info})')
            # back in node order (the band's row i is node order[i])
            sol = np.zeros_like(rhs)
            sol[:, cols] = solved[self._blocks[5]]
            # T_a = out_x x + out_w w (in C order, as the step's kernel takes them)
            out_x = np.ascontiguousarray(-sol[:, :m])
            out_w = np.ascontiguousarray(sol[:, m:])
            K_red = K_dd - K_da @ sol[:, :m]
            W_red = W_d - K_da @ out_w
        else:
            K, Gb, E = self.matrices(reduced_order=True)
            W = np.hstack([Gb, E])  # input map of w = [T_b; P]
            out_x = np.zeros((0, m))
            out_w = np.zeros((0, W.shape[1]))
            K_red, W_red = K, W
        cap = self.capacity[d][:, None]
        A = -K_red / cap
        B = W_red / cap
        self._used = (self.conductance.copy(), self.advection_rate.copy(), self.capacity.copy())
        # the step's kernels take the maps by their nonzeros: out_x is about 9 % full, out_w
        # 0.5 % (an algebraic node sees a few states and inputs), and the dense products
        # were most of the step's memory traffic
        self._reduced = memo[1] = (A, B, d, a, out_x, out_w, (_by_rows(out_x), _by_rows(out_w)))
        return self._reduced

    def _entry_values(self) -> Tuple[np.ndarray, np.ndarray]:
        """Return the values of K's entries and of G_b's, in the scatter indices' order."""
        g, c = self.conductance, self.advection_rate
        g_nn = g[self._nn[:, 0]]
        g_nb = g[self._nbl[:, 0]]
        c_n = c[self._adv_n[:, 0]]
        c_b = c[self._adv_b[:, 0]]
        return (np.concatenate([g_nn, g_nn, -g_nn, -g_nn, g_nb, c_n, -c_n, c_b]),
                np.concatenate([g_nb, c_b]))

    def _reduction_matrices(self) -> tuple:
        """
        Return K's state block, its state-to-algebraic block, W's state rows, the band, the rhs.

        As :meth:`matrices` (reduced order) would give them, sliced as
        :meth:`_reduce` uses them: ``K[:m, :m]``, ``K[:m, m:]``, ``W[:m]``
        with ``W = [G_b E]``, K's algebraic block in LAPACK's band storage,
        and ``[K[m:, :m] W[m:]]`` with its rows in the band's order.
        """
        m, na, nw = self._d.size, self._a.size, self.nb + self.ns
        half = self._band[1]
        k_sel, k_bins, w_sel, w_bins, e_places = self._blocks[:5]
        k_val, w_val = self._entry_values()
        sizes = (m * m, m * na, (3 * half + 1) * na, na * (m + nw))
        K_dd, K_da, band, rhs = (np.bincount(bins, weights=k_val[sel], minlength=size)
                                 for sel, bins, size in zip(k_sel, k_bins, sizes))
        W_d = np.bincount(w_bins[0], weights=w_val[w_sel[0]], minlength=m * nw)
        rhs += np.bincount(w_bins[1], weights=w_val[w_sel[1]], minlength=na * (m + nw))
        W_d[e_places[0]] = 1.0
        rhs[e_places[1]] = 1.0
        return (K_dd.reshape(m, m), K_da.reshape(m, na), W_d.reshape(m, nw),
                band.reshape(3 * half + 1, na), rhs.reshape(na, m + nw))

    def _memo(self, coefficients: tuple) -> list:
        """
        Return the :data:`_MEMO` entry of ``coefficients``: [structure, reduced, discs by dt].

        Keyed by the coefficients' bytes (conductances, advection rates,
        capacities) and the structure's identity (the entry holds the
        structure, so that identity is not reused while it lives): equal
        inputs, so the same matrices to the bit.
        """
        key = (id(self._scatter_reduced),) + tuple(c.tobytes() for c in coefficients)
        with _MEMO_LOCK:
            entry = _MEMO.get(key)
            if entry is None or entry[0] is not self._scatter_reduced:
                entry = _MEMO[key] = [self._scatter_reduced, None, {}]
                while len(_MEMO) > _MEMO_SIZE:
                    _MEMO.popitem(last=False)
            else:
                _MEMO.move_to_end(key)
        return entry

    def state_space(self) -> Tuple[np.ndarray, np.ndarray]:
        """Return (A, B) of the reduced network ``dx/dt = A x + B [T_b; P]``."""
        A, B = self._reduce()[:2]
        return A, B

    def discretise(self, dt_s: float) -> Discretisation:
        """Return the exact zero-order-hold matrices of a step, cached while coefficients hold."""
        if not dt_s > 0.0:
            raise NetworkError(f'time step {dt_s} s must be > 0')
        self.freeze()
        # steps taken from sample times differ in the last bits: within 1 ppm they are
        # one step (the state moves by 1e-6 of a step's change at most), discretised
        # at the step rounded to 1 ns, so that the matrices do not depend on which of
        # them came first (apply_changes may discretise ahead of a step)
        if self._disc is not None and abs(self._disc.dt_s - dt_s) <= 1e-6 * dt_s:
            return self._disc        # (dropped with the reduced matrices it was made of)
        A, B = self._reduce()[:2]
        dt_s = round(dt_s, 9) or dt_s
        discs = self._memo(self._used)[2]     # the coefficients A and B were made of
        if dt_s in discs:
            self._disc = discs[dt_s]
            return self._disc
        self.discretise_count += 1
        # Ad = e^{A dt}; F1 = int_0^dt e^{As} ds = A^-1 (Ad - I) and
        # F2 = int_0^dt (dt - s) e^{As} ds = A^-1 (F1 - dt I) (by parts). A is
        # invertible when every node has a path to a boundary; this costs one
        # exponential of the reduced matrix and one LU, a third of Van Loan's 3m x 3m.
        eye = np.eye(A.shape[0])
        Ad = scipy.linalg.expm(A * dt_s)
        try:
            lu = scipy.linalg.lu_factor(A)
        except (ValueError, scipy.linalg.LinAlgError) as exc:
            raise NetworkError(f'a group of nodes has no path to a boundary: {exc}') from exc
        F1 = scipy.linalg.lu_solve(lu, Ad - eye, check_finite=False)
        F2 = scipy.linalg.lu_solve(lu, F1 - dt_s * eye, check_finite=False)
        # all in C order (lu_solve returns Fortran's): the kernels that take them compile once
        self._disc = discs[dt_s] = Discretisation(
            dt_s, Ad, F1 @ B, np.ascontiguousarray(F1) / dt_s, (F2 @ B) / dt_s)
        return self._disc

    # ---------------------------------------------------------------- solve
    def inputs(self, boundary_K, power_W) -> np.ndarray:
        """Stack boundary temperatures (K) and source powers (W) into the input vector w."""
        self.freeze()
        tb = np.asarray(boundary_K, dtype=float).reshape(-1)
        p = np.asarray(power_W, dtype=float).reshape(-1)
        if tb.size != self.nb or p.size != self.ns:
            raise NetworkError(f'expected {self.nb} boundary temperatures and {self.ns} '
                               f'source powers, got {tb.size} and {p.size}')
        return np.concatenate([tb, p])

    def steady_state(self, boundary_K, power_W) -> np.ndarray:
        """Return the full steady-state temperature vector (K) for fixed inputs."""
        w = self.inputs(boundary_K, power_W)
        K, Gb, E = self.matrices()
        rhs = np.hstack([Gb, E]) @ w
        try:
            T = scipy.linalg.solve(K, rhs, check_finite=True)
        except (ValueError, scipy.linalg.LinAlgError) as exc:
            raise NetworkError(f'no steady state: {exc} (is every node connected to a '
                               'boundary?)') from exc
        return T

    def step(self, x: np.ndarray, dt_s: float, boundary_K, power_W,
             mean: bool = False):
        """
        Advance the states ``x`` (K) by ``dt_s`` with inputs held over the step.

        Returns the new states, and with ``mean=True`` also the mean of the
        states over the step (for exact step-averaged heat flows).
        """
        disc = self.discretise(dt_s)
        w = self.inputs(boundary_K, power_W)
        x_new = disc.Ad @ x + disc.Bd @ w
        if mean:
            return x_new, disc.Mx @ x + disc.Mw @ w
        return x_new

    def step_temperatures(self, x: np.ndarray, dt_s: float, boundary_K, power_W) -> tuple:
        """
        Advance as ``step(..., mean=True)`` and return the node temperatures too.

        Returns the new states, the full node-temperature vector (K) at the
        end of the step and the one averaged over the step: one input vector
        and one lookup of the matrices serve all three.
        """
        disc = self.discretise(dt_s)
        self.last_disc = disc         # the matrices of this step, for a state estimator
        _, _, d, a, _, _, (out_x, out_w) = self._reduce()
        return zoh_step(disc.Ad, disc.Bd, disc.Mx, disc.Mw, out_x, out_w, d, a, x,
                        self.inputs(boundary_K, power_W))

    def temperatures(self, x: np.ndarray, boundary_K, power_W) -> np.ndarray:
        """Return the full node-temperature vector (K) from states and inputs."""
        return self._full_temperatures(x, self.inputs(boundary_K, power_W))

    def _full_temperatures(self, x: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Return the full node-temperature vector (K) from states and the input vector."""
        _, _, d, a, _, _, (out_x, out_w) = self._reduce()
        return full_temperatures(d, a, out_x, out_w, x, w)

    def initial_state(self, T_full: np.ndarray) -> np.ndarray:
        """Pick the states out of a full temperature vector."""
        return np.asarray(T_full, dtype=float)[self.dynamic].copy()

    def coefficients_in_use(self) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """
        Return (conductances, advection rates, capacities) that the solver uses now.

        They differ from the last values set by at most ``refresh_rtol``
        (relative) while a cached discretisation is kept; heat flows computed
        with them make energy balances of the stepped network exact.
        """
        self.freeze()
        if self._used is not None:
            return self._used
        return self.conductance, self.advection_rate, self.capacity

    def link_heat_flows(self, T_full: np.ndarray, boundary_K, ids=None) -> np.ndarray:
        """
        Return the heat flow (W) through each conductance link, positive from end 1 to end 2.

        With ``ids`` (an index array of link ids) only those links, in that order.
        """
        tb = np.asarray(boundary_K, dtype=float).reshape(-1)
        values = np.concatenate([T_full, tb])
        g = self.coefficients_in_use()[0]
        if ids is None:
            return g * (values[self._ends[:, 0]] - values[self._ends[:, 1]])
        ends = self._ends[ids]
        return g[ids] * (values[ends[:, 0]] - values[ends[:, 1]])

    def link_ends(self, ids) -> np.ndarray:
        """Return the two ends of each conductance link ``ids`` as indices into [T; T_b]."""
        self.freeze()
        return self._ends[ids].copy()

    def heat_flow(self, T_full: np.ndarray, boundary_K, a: str, b: str) -> float:
        """Return the heat flow (W) from ``a`` to ``b`` through the link joining them."""
        k = self.link_id(a, b)
        flow = float(self.link_heat_flows(T_full, boundary_K)[k])
        return flow if self._links[k][0] == a else -flow


def _by_rows(M: np.ndarray) -> tuple:
    """Return ``M``'s nonzeros in row order: (rows, columns, values), each C-contiguous."""
    # np.nonzero's index arrays are strided views, and a pickled model's or an empty map's
    # contiguous: the step's kernels compiled a second signature for the other layout.
    # The flat indices of a C-ordered M are in row order, as np.nonzero's
    flat = np.flatnonzero(M)
    rows, cols = np.divmod(flat, M.shape[1])
    return rows, cols, M.ravel()[flat]


@jit
def sparse_product(M, v, n):
    """
    Return ``M @ v`` (``n`` rows) for ``M`` given by :func:`_by_rows`.

    Each row's products summed in column order; numpy style, so that it is
    fast without numba too.
    """
    rows, cols, values = M
    return np.bincount(rows, values * v[cols], n)


@jit
def full_temperatures(dynamic, algebraic, out_x, out_w, x, w):
    """
    Return the temperatures (K) of all nodes from the states ``x`` (K) and the inputs ``w``.

    ``dynamic`` and ``algebraic`` index the nodes with and without heat
    capacity; an algebraic node's temperature is ``out_x x + out_w w`` (the
    maps by rows, :func:`_by_rows`).
    """
    return _scatter_temperatures(dynamic, algebraic, out_x, x,
                                 sparse_product(out_w, w, algebraic.size))


@jit
def _scatter_temperatures(dynamic, algebraic, out_x, x, from_inputs):
    """Return all node temperatures (K): the states ``x``, and ``out_x x + from_inputs``."""
    T = np.empty(dynamic.size + algebraic.size)
    T[dynamic] = x
    if algebraic.size:
        T[algebraic] = sparse_product(out_x, x, algebraic.size) + from_inputs
    return T


@jit
def zoh_step(Ad, Bd, Mx, Mw, out_x, out_w, dynamic, algebraic, x, w):
    """
    Return one exact zero-order-hold step: new states, node temperatures at its end, and mean.

    ``Ad``, ``Bd``, ``Mx``, ``Mw``: the step's :class:`Discretisation`;
    ``out_x``, ``out_w``: the algebraic nodes' output map by rows
    (:func:`_by_rows`); ``x`` the states (K) at the start, ``w`` the inputs
    held over the step (boundary K, source W). Returns (states K at the end,
    all node temperatures K at the end, all node temperatures K averaged over
    the step). One compiled call: a step of a few small matrix products costs
    less than their calls from Python.
    """
    x_new = Ad @ x + Bd @ w
    x_mean = Mx @ x + Mw @ w
    from_inputs = sparse_product(out_w, w, algebraic.size)   # the inputs' share, once
    return (x_new, _scatter_temperatures(dynamic, algebraic, out_x, x_new, from_inputs),
            _scatter_temperatures(dynamic, algebraic, out_x, x_mean, from_inputs))


# every model built (the estimator's, each uncertainty copy's, a calibration's runs) has
# one of a few topologies: their band orders are kept per process, by the exact indices
@lru_cache(maxsize=64)
def _band(n: int, m: int, na: int, dtype: str, k_idx_bytes: bytes) -> tuple:
    """Return :meth:`ThermalNetwork._algebraic_band` of K's scatter indices (given as bytes)."""
    k_idx = np.frombuffer(k_idx_bytes, dtype=dtype)
    i, j = np.divmod(k_idx, n)
    inside = (i >= m) & (j >= m)
    i, j = np.unique(np.stack([i[inside] - m, j[inside] - m]), axis=1)   # once each
    pattern = scipy.sparse.csr_matrix((np.ones(i.size), (i, j)), shape=(na, na))
    order = reverse_cuthill_mckee(pattern + pattern.T, symmetric_mode=True)
    rank = np.empty(na, dtype=int)
    rank[order] = np.arange(na)
    pi, pj = rank[i], rank[j]
    half = max(int(np.abs(pi - pj).max()), 0)
    # LAPACK's gbtrf storage of a band with kl = ku = half: A[r, c] at row 2 half + r - c
    out = order, half, (i + m, j + m), (2 * half + pi - pj, pj)
    for a in (order, *out[2], *out[3]):
        a.flags.writeable = False           # shared by every network of this topology
    return out


@lru_cache(maxsize=64)
def _blocks(n: int, m: int, nb: int, ns: int, half: int, k_dtype: str, gb_dtype: str,
            src_dtype: str, order_dtype: str, k_idx_bytes: bytes, gb_idx_bytes: bytes,
            src_bytes: bytes, order_bytes: bytes) -> tuple:
    """
    Return :meth:`ThermalNetwork._reduction_blocks` of the scatter indices (given as bytes).

    For K's entries (in :meth:`ThermalNetwork.matrices`' order) and for G_b's:
    which of them fall in each block (ascending, so that each block sums them
    in their order) and their flat places in it; for E's ones, their flat
    places in W's state rows and in the right-hand side; and each algebraic
    node's row in the band's order.
    """
    k_idx = np.frombuffer(k_idx_bytes, dtype=k_dtype)
    gb_idx = np.frombuffer(gb_idx_bytes, dtype=gb_dtype)
    src = np.frombuffer(src_bytes, dtype=src_dtype)
    order = np.frombuffer(order_bytes, dtype=order_dtype)
    na, nw, nbs = n - m, nb + ns, max(nb, 1)
    rank = np.empty(na, dtype=int)
    rank[order] = np.arange(na)
    i, j = np.divmod(k_idx, n)
    blocks = ((i < m) & (j < m), (i < m) & (j >= m), (i >= m) & (j >= m), (i >= m) & (j < m))
    k_sel = tuple(np.flatnonzero(b) for b in blocks)
    dd, da, aa, ad = k_sel
    k_bins = (i[dd] * m + j[dd], i[da] * na + j[da] - m,
              (2 * half + rank[i[aa] - m] - rank[j[aa] - m]) * na + rank[j[aa] - m],
              rank[i[ad] - m] * (m + nw) + j[ad])
    # G_b's rows are n x max(nb, 1) in the scatter, its first nb columns in W
    r, col = np.divmod(gb_idx, nbs)
    w_sel = (np.flatnonzero(r < m), np.flatnonzero(r >= m))
    w_bins = (r[w_sel[0]] * nw + col[w_sel[0]],
              rank[r[w_sel[1]] - m] * (m + nw) + m + col[w_sel[1]])
    k = np.arange(ns)
    state = src < m
    e_places = (src[state] * nw + nb + k[state],
                rank[src[~state] - m] * (m + nw) + m + nb + k[~state])
    out = (k_sel, k_bins, w_sel, w_bins, e_places, rank)
    for a in (*k_sel, *k_bins, *w_sel, *w_bins, *e_places, rank):
        a.flags.writeable = False           # shared by every network of this topology
    return out
