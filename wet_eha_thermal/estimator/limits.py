"""
Thermal current limits for the drive: the largest RMS phase current, now and for a while.

At each limit tick (every ``estimator.limits.period_s`` of sample time) the
outlook copies the model; from that copy :func:`limit_steps` finds, for each
horizon H of ``horizons_s``, the largest constant RMS current I that keeps
every limited quantity q (winding hot-spot, magnet, oil) at or below its
limit over (0, H], at its estimate plus ``k_sigma`` times its present
uncertainty, with the recent speed and pressure duty held. The search stops
at the motor's peak rating (``motor.peak_current_A``): a limit there means
no temperature binds. The continuous limit, the steady margin, is the
outlook's (:mod:`.outlook`).

How: over one probe step of dt = ``period_s`` the coupled model is affine in
its state and, through the copper's R(T), bilinear in I^2:

    x' = (A + I^2 K) x + c0 + I^2 c1

Two steps of copies of the model from the tick's state, at I = 0 and at the
peak rating, give the four terms: A and K from the model's own linearisation
(:meth:`~..model.eha.EHAModel.linearize`, composed by the filter's
:func:`~.kalman.coupled_transition`), c0 and c1 from where the copies
ended. The state at every power of two of dt and at H follows from powers of
the augmented matrix [[A + I^2 K, c0 + I^2 c1], [0, 1]] by squaring (a
dozen 81 x 81 products for 600 s), and a search on a fixed grid of I^2
(:meth:`LimitProblem.solve`), started at the last tick's answer, finds
where the worst quantity meets its limit.

What it leaves out (``test/test_limits.py`` measures it against the model
itself): the coefficients that move with temperature (convection,
viscosities, friction) stay as they are at the tick, or for a horizon of
minutes as they are half-way along it; the held duty has the
recent root-mean-square speed and the pressures (the high side as its RMS)
but no motion, so no flow work; a peak between two checked times of a
horizon is not seen.

The uncertainty at the horizon: with a propagated uncertainty
(:mod:`.uncertainty`) a quantity's 1 sigma grows with its rise above
ambient, about in proportion (``relative``: sigma per K of rise, at the
tick). Holding T + k f (T - T_amb) <= T_lim is holding T below
(T_lim + k f T_amb) / (1 + k f): the ceiling is that, or the limit less k
times the tick's sigma if lower (:func:`ceiling_K`). Without a relative
figure (a quantity less than a few K above ambient, or the constant
uncertainty) the tick's sigma stands.
"""

from dataclasses import dataclass, field
import math
from typing import Dict, Generator, List, NamedTuple, Optional, Sequence, Tuple

import numpy as np

from .correction import filter_layout
from .kalman import copper_gain, coupled_transition
from ..interface import limits_frame_id, limits_reason, LimitStatus
from ..model import snapshot
from ..model.eha import EHAModel, SampleBlock
from ..model.quantities import PEAK
from ..units import C_TO_K

#: names of the limits, as in the drive's message: the steady one, then each horizon
CONTINUOUS = 'continuous'
#: what a limit at the search's top (the motor's peak rating) is bound by
RATING = 'rating'
#: what a limit capped at the conservative value is bound by
FALLBACK = 'fallback'
#: a longer horizon is solved again, linearised at the middle of its path (s)
RELINEARISE_AFTER_S = 120.0
#: I^2 tolerance of the search (A^2): 0.04 A at 25 A, a tenth of the model's own spread
TOL_A2 = 2.0
#: a tick whose every state is within this (K) of a linearised tick's, on the same held duty
#: and ambient, takes that tick's linearisations: a fifth of the model's own threshold (its
#: airgap oil's 0.5 K) within which it steps on held coefficients; the limits then stay
#: within a cell of the search's grid of linearising every tick (test/test_limits.py)
REUSE_TOL_K = 0.1


def horizon_name(horizon_s: float) -> str:
    """Return the name of a horizon's limit: ``'10s'`` for 10 s."""
    return f'{horizon_s:g}s'


def step_statistics(block: SampleBlock) -> np.ndarray:
    """Return a step's mean squared speed, squared high-side pressure, low side, accumulator."""
    high = np.maximum(block.p_a_Pa, block.p_b_Pa)
    n = high.size
    # sums over the count: np.mean's arithmetic without its overhead on a step's samples
    return np.array([(block.speed_rad_s ** 2).sum() / n, (high ** 2).sum() / n,
                     np.minimum(block.p_a_Pa, block.p_b_Pa).sum() / n, block.p_acc_Pa.sum() / n])


@dataclass(frozen=True)
class HeldDuty:
    """The recent duty as the limits hold it: RMS speed (rad/s), pressures (Pa), position (m)."""

    speed_rad_s: float
    p_a_Pa: float
    p_b_Pa: float
    p_acc_Pa: float
    position_m: float

    @classmethod
    def from_statistics(cls, rows: np.ndarray, position_m: float) -> 'HeldDuty':
        """
        Hold the recent duty: its steps' :func:`step_statistics` (one row each), averaged.

        The pump's leakage and friction heat grow with the speed and the
        pressure difference (the leakage's throttling as its square): root
        mean squares keep them where plain means of an alternating load
        would cancel them. The high side goes to port A.
        """
        speed_sq, high_sq, low, acc = rows.mean(axis=0)
        return cls(speed_rad_s=math.sqrt(speed_sq), p_a_Pa=math.sqrt(high_sq), p_b_Pa=low,
                   p_acc_Pa=acc, position_m=position_m)

    def close_to(self, other: 'HeldDuty') -> bool:
        """
        Tell whether ``other`` is this duty within the model's own refresh thresholds.

        1 % of the speed, 0.1 MPa of each pressure (the case pressure's), and
        1 mm of the position: the coefficients a probe would take barely move.
        """
        return (abs(self.speed_rad_s - other.speed_rad_s) <= 0.01 * max(other.speed_rad_s, 5.0)
                and abs(self.p_a_Pa - other.p_a_Pa) <= 1e5
                and abs(self.p_b_Pa - other.p_b_Pa) <= 1e5
                and abs(self.p_acc_Pa - other.p_acc_Pa) <= 1e5
                and abs(self.position_m - other.position_m) <= 1e-3)

    def block(self, t_s: float, current_A: float) -> SampleBlock:
        """Return one held sample at ``t_s`` (model time) with ``current_A``."""
        return SampleBlock(*(np.array([v]) for v in (
            t_s, current_A, self.speed_rad_s, self.p_a_Pa, self.p_b_Pa, self.p_acc_Pa,
            self.position_m)))


@dataclass(frozen=True)
class CurrentLimits:
    """
    The limits of one tick, what the drive reads (docs/live.md#current-limits-for-the-drive).

    ``names``: ``continuous`` then each horizon (``'10s'``...); ``horizons_s``
    the same, +inf for the continuous one; ``limits_A`` the largest RMS phase
    current (A) for each; ``binds`` the quantity that sets each (``rating``:
    none, the motor's peak rating). ``binding_A`` is the one a drive with a
    single number applies: the shortest horizon's, refreshed every period.
    ``code`` is the drive's status (:class:`~wet_eha_thermal.interface.LimitStatus`):
    OK, or a fallback (then every limit is at most the configured
    conservative value); ``detail`` adds what the code cannot say (which
    inputs are stale...). The texts are made from the two.
    """

    stamp_s: float
    names: Tuple[str, ...]
    horizons_s: Tuple[float, ...]
    limits_A: Tuple[float, ...]
    binds: Tuple[str, ...]
    code: LimitStatus = LimitStatus.OK
    detail: str = ''

    @property
    def status(self) -> str:
        """Return ``ok`` or ``fallback``, as the reports write it."""
        return 'ok' if self.code == LimitStatus.OK else 'fallback'

    @property
    def reason(self) -> str:
        """Return why these limits fell back, in words ('' when they did not)."""
        return limits_reason(self.code, self.detail)

    @property
    def frame_id(self) -> str:
        """Return the text of the JointState's header.frame_id: ``ok`` or ``fallback: <why>``."""
        return limits_frame_id(self.code, self.detail)

    @property
    def binding_A(self) -> float:
        """Return the shortest horizon's limit (A RMS): the one a simple drive applies."""
        return self.limits_A[int(np.argmin(self.horizons_s))]

    def fallback(self, current_A: float, code: LimitStatus, detail: str) -> 'CurrentLimits':
        """Return these limits capped at the conservative ``current_A``, with why."""
        return CurrentLimits(
            stamp_s=self.stamp_s, names=self.names, horizons_s=self.horizons_s,
            limits_A=tuple(min(v, current_A) for v in self.limits_A),
            binds=tuple(FALLBACK if v > current_A else b
                        for v, b in zip(self.limits_A, self.binds)),
            code=code, detail=detail)


def current_limits(stamp_s: float, horizons_s: Sequence[float], continuous: Tuple[float, str],
                   per_horizon: Sequence[Tuple[float, str]], code: LimitStatus = LimitStatus.OK,
                   detail: str = '') -> CurrentLimits:
    """Return a tick's :class:`CurrentLimits`: the continuous (A, binds), then each horizon's."""
    both = [continuous] + list(per_horizon)
    return CurrentLimits(stamp_s=stamp_s,
                         names=(CONTINUOUS,) + tuple(horizon_name(h) for h in horizons_s),
                         horizons_s=(math.inf,) + tuple(float(h) for h in horizons_s),
                         limits_A=tuple(float(v) for v, _ in both),
                         binds=tuple(b for _, b in both), code=code, detail=detail)


def fallback_limits(stamp_s: float, horizons_s: Sequence[float], current_A: float,
                    code: LimitStatus, detail: str) -> CurrentLimits:
    """Return the conservative limits for a tick with nothing better (``code``: why)."""
    return current_limits(stamp_s, horizons_s, (current_A, FALLBACK),
                          [(current_A, FALLBACK)] * len(horizons_s), code, detail)


class LimitProblem:
    """
    The tick's affine-bilinear model and the search for each limit on it.

    ``A``, ``K``, ``c0``, ``c1``: the probe step's terms (module docstring);
    ``x0`` the tick's state (K); ``rows``: the states each limited quantity is
    the hottest of; ``ceiling_K`` each quantity's limit minus k sigma (K).
    """

    def __init__(self, A, K, c0, c1, peaks: Dict[str, tuple], x0, rows: Dict[str, np.ndarray],
                 ceiling_K: Dict[str, float]) -> None:
        self.A, self.K, self.c0, self.c1, self.x0 = A, K, c0, c1, x0
        self.rows, self.ceiling_K, self.peaks = rows, ceiling_K, peaks
        self.n = x0.size

    def _excess(self, X: np.ndarray) -> Tuple[float, str]:
        """Return the largest excess over its ceiling (K) among states ``X`` (n x k), and whose."""
        worst = {q: float(np.max(X[idx])) - self.ceiling_K[q] for q, idx in self.rows.items()
                 if q not in self.peaks}
        for q, (L, c, parts) in self.peaks.items():
            # a peak: per block, the sum over its parts of each part's largest form
            tops = np.maximum.reduceat(L @ X + c[:, None], parts[:, 0], axis=0)
            blocks = np.zeros((parts[-1, 1] + 1, X.shape[1]))
            np.add.at(blocks, parts[:, 1], tops)
            worst[q] = float(blocks.max()) - self.ceiling_K[q]
        q = max(worst, key=worst.get)
        return worst[q], q

    def trajectory(self, i_sq: float, steps: int) -> np.ndarray:
        """Return the states (n x k) after 1, 2, 4, ... probe steps and after ``steps``."""
        n = self.n
        M = np.zeros((n + 1, n + 1))
        M[:n, :n] = self.A + i_sq * self.K
        M[:n, n] = self.c0 + i_sq * self.c1
        M[n, n] = 1.0
        v = np.append(self.x0, 1.0)
        out, at = [], v
        power, k = M, steps
        while k:
            if k & 1:
                at = power @ at
            k >>= 1
            out.append(power @ v)
            if k:
                power = power @ power
        out.append(at)
        ks = [2 ** j for j in range(len(out) - 1)] + [steps]
        keep = [j for j, s in enumerate(ks) if s <= steps]
        return np.array(out)[keep, :n].T

    def horizon_excess(self, i_sq: float, steps: int) -> Tuple[float, str]:
        """Return the worst excess (K) over (0, ``steps`` dt] at ``i_sq`` (A^2), and whose."""
        X = self.trajectory(i_sq, steps)
        if not np.isfinite(X).all():
            return math.inf, ''
        return self._excess(X)

    def solve(self, excess, top_A: float, guess_A: Optional[float] = None) -> Tuple[float, str]:
        """
        Return the largest current (A) in [0, ``top_A``] whose ``excess`` is <= 0, and what binds.

        ``excess(i_sq)`` -> (K, quantity) grows with I^2. 0 A when even no
        current is too much, ``top_A`` (bound by the rating) when it is not.
        Otherwise the search finds the cell of a fixed grid of I^2 (spacing
        2 ``TOL_A2``, ``top_A`` squared its last point) whose lower end is
        within the limit and whose upper end is not, and returns the cell's
        middle, within ``TOL_A2`` of the root, bound by what exceeds at its
        upper end. The answer does not depend on where the search starts:
        ``guess_A`` (the last tick's answer, which moves little from tick to
        tick) only spares evaluations, two when the root stayed in its cell.
        """
        cell = 2.0 * TOL_A2
        top = top_A ** 2
        last = max(1, math.ceil(top / cell))        # the grid's points: k cell, then top
        seen: Dict[int, Tuple[float, str]] = {}
        lo = hi = None        # the highest point seen within the limit, the lowest past it

        def at(k: int) -> float:
            return top if k >= last else k * cell

        def visit(k: int) -> None:
            nonlocal lo, hi
            if k in seen:
                return
            e, q = excess(at(k))
            seen[k] = (min(e, 1e6), q)        # a runaway: large, but a number to interpolate
            if e <= 0.0:
                lo = k if lo is None else max(lo, k)
            else:
                hi = k if hi is None else min(hi, k)

        def crossing(a: int, b: int) -> float:
            """Return where the line through points a and b crosses zero (grid units)."""
            ea, eb = seen[a][0], seen[b][0]
            return a - ea * (b - a) / (eb - ea) if eb > ea else math.nan

        if guess_A is None:
            start = (0, last)
        else:
            k = min(max(int(guess_A ** 2 // cell), 0), last - 1)
            start = (last,) if guess_A >= top_A else (k, k + 1)
        for k in start:
            visit(k)
        width = 2 * last + 2      # the last round's bracket: none yet, so interpolate first
        while True:
            if lo is None and hi == 0:
                return 0.0, seen[0][1]
            if hi is None and lo == last:
                return top_A, RATING
            if lo is not None and hi is not None:
                if hi - lo == 1:
                    return math.sqrt(0.5 * (at(lo) + at(hi))), seen[hi][1]
                # inside the bracket: the two points around the line's crossing, or the
                # middle when the last round did not halve the bracket
                r = crossing(lo, hi) if hi - lo <= width // 2 else math.nan
                width = hi - lo
                low, high = lo + 1, hi - 1
            else:
                # beyond every point seen: the line through the two nearest (from one
                # point, its neighbour), or halfway to the end when it does not slope up
                pts = sorted(seen)
                if lo is None:
                    a, b = pts[:2] if len(pts) > 1 else (pts[0], pts[0])
                    low, high = 0, a - 1
                    r = crossing(a, b) if a != b else high
                else:
                    a, b = pts[-2:] if len(pts) > 1 else (pts[0], pts[0])
                    low, high = b + 1, last
                    r = crossing(a, b) if a != b else low
            if not math.isfinite(r):
                r = 0.5 * (low + high)
            for k in dict.fromkeys(min(max(int(math.floor(r)) + j, low), high)
                                   for j in (0, 1)):
                # a point beyond the bracket as it now stands would tell nothing new
                if (lo is None or k > lo) and (hi is None or k < hi):
                    visit(k)


def probe(model: EHAModel, held: HeldDuty, current_A: float, dt_s: float, ambient_K: float,
          layout, alpha_copper: float) -> Tuple[np.ndarray, np.ndarray]:
    """
    Step ``model`` (a copy: it is changed) by ``dt_s`` on the held duty; return (Phi, state).

    Phi is the step's transition with the copper's R(T) feedback at
    ``current_A`` (:func:`~.kalman.coupled_transition`), the state the one at
    the step's end (K). The coefficients are those of the step's start, not
    the estimator's filtered ones: a probe of a state moved by hand
    (:meth:`~..model.eha.EHAModel.correct`) takes that state's.
    """
    model.defer_refresh = False
    model.circuit.keep_transition = True
    model.motor.check_rotor_validity = False     # the peak current's bins: a copy's log
    model.step(held.block(model.time_s + dt_s, current_A), ambient_K, max_substep_s=dt_s,
               exact_coefficients=True)
    lin = model.linearize()
    n = model.state.size
    Phi = coupled_transition(lin.motor, lin.circuit,
                             copper_gain(lin.copper_K, lin.copper_power_W, alpha_copper),
                             layout, n)
    return Phi, model.state


def linearise(saved: bytes, shift_K: Optional[np.ndarray], held: HeldDuty, dt_s: float,
              ambient_K: float, peak_A: float, layout, alpha_copper: float,
              peaks: Sequence[str] = ()) -> tuple:
    """
    Return (A, K, c0, c1, forms) of one probe step from the saved model ``saved``.

    ``saved``: :func:`~..model.snapshot.save`'s bytes, or plain pickled ones.
    ``forms``: each of the ``peaks`` outputs as :func:`peak_forms` at the start.

    Its state moved first by ``shift_K`` (K; None: as it is), the held duty
    taken as its last sample (:meth:`~..model.eha.EHAModel.hold_from`: no
    jump of the pressures), a step at no current and one at ``peak_A``
    (module docstring).
    """
    cold, hot = snapshot.copy(saved), snapshot.copy(saved)
    for m in (cold, hot):
        m.hold_from(held.block(m.time_s, 0.0))
        if shift_K is not None:
            m.correct(shift_K)
    x_start = cold.state
    forms = {name: peak_forms(cold, name) for name in peaks}
    A, x_cold = probe(cold, held, 0.0, dt_s, ambient_K, layout, alpha_copper)
    Phi, x_hot = probe(hot, held, peak_A, dt_s, ambient_K, layout, alpha_copper)
    i2 = peak_A ** 2
    c0 = x_cold - A @ x_start
    return A, (Phi - A) / i2, c0, (x_hot - Phi @ x_start - c0) / i2, forms


def peak_forms(model: EHAModel, name: str) -> tuple:
    """
    Return the peak output ``name`` as linear forms of the model's state, at its present point.

    (forms R x n, constants R, parts P x 2: each part's first form and its block):
    the peak is the largest over blocks of the sum over a block's parts of the
    largest form of the part (:class:`~..model.hot_spot.PeakForms`). A value on
    an algebraic node is its sensitivity to the motor's states plus a constant,
    what the rest (boundaries) gives it now.
    """
    q, mo = model.quantities, model.motor
    a, out_x = mo.net.algebraic_map()
    row_of = {int(k): i for i, k in enumerate(a)}
    state_of = {s: i for i, s in enumerate(q.state_names)}
    n, m = model.state.size, mo.x.size
    forms, consts, parts = [], [], []
    for b, p in enumerate(q.outputs[name].peaks):
        V, c = np.zeros((len(p.values), n)), np.zeros(len(p.values))
        for k, v in enumerate(p.values):
            if v in state_of:
                V[k, state_of[v]] = 1.0
            else:
                i = mo.net.index(v)
                V[k, :m] = out_x[row_of[i]]
                c[k] = mo.T[i] - out_x[row_of[i]] @ mo.x
        for f in p.parts:
            parts.append((sum(len(g) for g in forms), b))
            forms.append(f @ V)
            consts.append(f @ c)
    return np.concatenate(forms), np.concatenate(consts), np.array(parts)


class Probing(NamedTuple):
    """What the probes of a model need of it, the same at every tick (:func:`probing`)."""

    layout: object                 # the couplings (:func:`~.correction.filter_layout`)
    rows: Dict[str, np.ndarray]    # the states each limited quantity is the hottest of
    alpha_copper: float            # the copper's temperature coefficient (1/K)
    peaks: Tuple[str, ...] = ()    # the limited quantities that are peaks (:func:`peak_forms`)


def probing(model: EHAModel, limited: Sequence[str]) -> Probing:
    """Return the :class:`Probing` of ``model`` for the ``limited`` quantities."""
    q = model.quantities
    return Probing(filter_layout(model), {name: q.state_indices(name) for name in limited},
                   model.cfg.motor.winding.copper_tempco_1_K,
                   tuple(name for name in limited if q.outputs[name].kind == PEAK))


@dataclass(eq=False)
class Linearised:
    """
    A tick's linearisations, for it and the ticks after it whose state stays close (:meth:`fits`).

    ``saved``, ``x0`` (K), ``held``, ``ambient_K``, ``ceilings`` (K): the tick's
    (:func:`limit_steps`). Each is computed when a tick first needs it, from
    this tick's saved model alone: a live node that gave the tick up and a
    replay that worked it reuse the same bits.
    """

    saved: bytes
    x0: np.ndarray
    held: HeldDuty
    ambient_K: float
    ceilings: Dict[str, float]
    terms: Optional[tuple] = None       # :func:`linearise` at x0
    mids: Dict[float, tuple] = field(default_factory=dict)   # by horizon: (state K, terms)

    @classmethod
    def for_tick(cls, kept: Optional['Linearised'], saved: bytes, x0: np.ndarray,
                 held: HeldDuty, ambient_K: float, ceilings: Dict[str, float]) -> 'Linearised':
        """Return ``kept`` if it :meth:`fits` this tick, else this tick's own."""
        if kept is not None and kept.fits(x0, held, ambient_K):
            return kept
        return cls(saved, x0, held, ambient_K, ceilings)

    def fits(self, x0: np.ndarray, held: HeldDuty, ambient_K: float) -> bool:
        """Tell whether a tick at state ``x0`` (K) may take these linearisations."""
        return (ambient_K == self.ambient_K and held.close_to(self.held)
                and float(np.max(np.abs(x0 - self.x0))) <= REUSE_TOL_K)

    def linearise(self, shift_K: Optional[np.ndarray], dt_s: float, peak_A: float,
                  setup: 'Probing') -> tuple:
        """Return :func:`linearise` of this tick's model moved by ``shift_K``."""
        return linearise(self.saved, shift_K, self.held, dt_s, self.ambient_K, peak_A,
                         setup.layout, setup.alpha_copper, setup.peaks)

    def first(self, dt_s: float, peak_A: float, setup: 'Probing') -> tuple:
        """Return the linearisation at this tick's state."""
        if self.terms is None:
            self.terms = self.linearise(None, dt_s, peak_A, setup)
        return self.terms

    def mid(self, horizon_s: float, steps: int, dt_s: float, peak_A: float, setup: 'Probing',
            guess_A: Optional[float]) -> tuple:
        """Return (state, terms) half-way along this tick's own first solution over a horizon."""
        if horizon_s not in self.mids:
            own = LimitProblem(*self.first(dt_s, peak_A, setup), self.x0, setup.rows,
                               self.ceilings)
            amps, _ = own.solve(lambda s: own.horizon_excess(s, steps), peak_A, guess_A)
            x_mid = own.trajectory(amps ** 2, steps // 2)[:, -1]
            self.mids[horizon_s] = (x_mid, self.linearise(x_mid - self.x0, dt_s, peak_A, setup))
        return self.mids[horizon_s]


def ceilings_K(limits_C: Dict[str, float], sigma_K: Dict[str, float], k_sigma: float,
               relative: Optional[Dict[str, float]], ambient_K: float) -> Dict[str, float]:
    """Return :func:`ceiling_K` of each limited quantity."""
    relative = relative or {}
    return {name: ceiling_K(lim, sigma_K[name], k_sigma, relative.get(name), ambient_K)
            for name, lim in limits_C.items()}


def ceiling_K(limit_C: float, sigma_K: float, k_sigma: float, relative: Optional[float],
              ambient_K: float) -> float:
    """
    Return the temperature (K) a quantity may reach so that it plus k sigma stays at its limit.

    ``sigma_K`` its 1 sigma now; ``relative`` (None: unknown) its 1 sigma per
    K of rise above ``ambient_K``, which carries the sigma to a hotter state
    (module docstring).
    """
    lim = limit_C + C_TO_K
    now = lim - k_sigma * sigma_K
    if relative is None:
        return now
    return min(now, (lim + k_sigma * relative * ambient_K) / (1.0 + k_sigma * relative))


def limit_steps(saved: bytes, x0: np.ndarray, setup: Probing, held: HeldDuty,
                ambient_K: float, sigma_K: Dict[str, float], limits_C: Dict[str, float],
                k_sigma: float, horizons_s: Sequence[float], dt_s: float, peak_A: float,
                relative: Optional[Dict[str, float]] = None,
                guesses: Optional[Dict[Tuple[float, int], float]] = None,
                kept: Optional[Linearised] = None
                ) -> Generator[None, None, List[Tuple[float, str]]]:
    """
    Compute a tick's limit for each horizon from the pickled model ``saved``, in slices.

    A generator: it yields between the linearisations and between the
    horizons, and returns (limit A RMS, what binds it) for each of
    ``horizons_s``. ``x0`` the model's state (K), ``setup`` its
    :class:`Probing`, ``sigma_K`` the tick's 1-sigma uncertainty of each
    limited quantity (K), ``limits_C`` their limits (degC), ``dt_s`` the
    probe step (s; each horizon a whole number of them), ``peak_A`` the
    search's top; ``relative`` each quantity's sigma per K of rise, where known
    (:func:`ceiling_K`). A horizon longer than ``RELINEARISE_AFTER_S`` is solved
    again on the linearisation at the middle of the first solution's path:
    over minutes the oil's viscosity, and with it the friction and the
    leakage heat, move far from the tick's. ``guesses``: where each search
    starts, by (horizon, 0 for the first solution or 1 for the second),
    updated with this tick's answers (an outlook keeps it from tick to tick:
    the answers do not depend on it, :meth:`LimitProblem.solve`). ``kept``: the
    :class:`Linearised` of the tick to take the linearisations of (this one's,
    or an earlier tick's that :meth:`~Linearised.fits` it; None: this one's).
    A tick that takes an earlier tick's takes its half-way linearisation too
    while its own half-way state is within ``REUSE_TOL_K`` of that tick's.
    """
    ceiling = ceilings_K(limits_C, sigma_K, k_sigma, relative, ambient_K)
    lin = kept if kept is not None else Linearised(saved, x0, held, ambient_K, ceiling)
    fit = (dt_s, peak_A, setup)
    guesses = {} if guesses is None else guesses
    problem = LimitProblem(*lin.first(*fit), x0, setup.rows, ceiling)
    out = []
    for h in horizons_s:
        yield
        steps = max(1, int(round(h / dt_s)))
        amps, binds = problem.solve(lambda s, n=steps: problem.horizon_excess(s, n), peak_A,
                                    guesses.get((h, 0)))
        guesses[(h, 0)] = amps
        if h > RELINEARISE_AFTER_S:
            yield
            x_mid = problem.trajectory(amps ** 2, steps // 2)[:, -1]
            if lin.saved is saved:            # this tick's own: x_mid is its half-way state
                if h not in lin.mids:
                    lin.mids[h] = (x_mid, lin.linearise(x_mid - x0, *fit))
                terms = lin.mids[h][1]
            else:
                at, terms = lin.mid(h, steps, *fit, amps)
                if float(np.max(np.abs(x_mid - at))) > REUSE_TOL_K:   # this tick's own, then
                    terms = Linearised(saved, x0, held, ambient_K, ceiling).linearise(
                        x_mid - x0, *fit)
            again = LimitProblem(*terms, x0, setup.rows, ceiling)
            amps, binds = again.solve(lambda s, n=steps: again.horizon_excess(s, n), peak_A,
                                      guesses.get((h, 1), amps))
            guesses[(h, 1)] = amps
        out.append((amps, binds))
    return out
