"""
The uncertainty of every estimate, propagated from the configuration's stated sigmas.

First order, as the GUM does it (JCGM 100:2008, 5.1.2): the variance of a
temperature T is sum_j (dT/dp_j s_j)^2 over the uncertain parameters p_j of
the ``uncertainty`` section, each with its stated 1 sigma s_j. The
sensitivities dT/dp_j s_j are finite differences of whole models: one copy
of the model per parameter, built with that parameter moved by one sigma
(:func:`~..model.uncertainty.parameter_perturbations`), stepped on the
estimator's own duty beside an unperturbed copy stepped the same way; the
difference of their outputs is that parameter's contribution. Whole copies
carry the sensitivity along the run exactly as the model carries heat (no
linearisation about a state), so the result starts at zero at ambient,
where no parameter moves anything, and grows with the heat. The structural
part is the same difference for the copies of
:func:`~..model.uncertainty.structural_perturbations` (finer axial slices;
each other law the configuration can select, taken as one sigma), plus
``rise_fraction`` of each temperature's rise above ambient.

Cost and time: the copies step once per ``copy_period_s`` of sample time,
one model step over the period's duty (the estimator's steps, as their
means: the current as the RMS; a silence the estimator held, a step of its
own), so 31 copies of the reference rig cost about 31 model steps per
period. They are worked in the background between estimates
(:meth:`Propagation.work`) and any still pending when the next period ends
are stepped there and then, so the uncertainty depends on the samples
alone: a replay gives the live sigmas bit for bit. The sigmas published
during a period are those of the copies at its start (one period late).

The limits carry the sigma to their horizons as a figure per K of rise
(:meth:`Propagation.relative`): the copies' own once a quantity has risen
``MIN_RISE_K`` above ambient at a period's end, and the last they gave while
it cools. Before that, on a cold start, the copies give no figure (they all
sit at ambient), yet the limits ask what ten minutes at a high current would
do: the copies are then heated once, from where they stand, at the
continuous rating on the held duty for the longest horizon, on a thread of
their own, and their figures stand until the copies' own.

With the live correction on, the filter (:mod:`.correction`) takes the
parameter part as process noise: at each period, the covariance of the
change of the parameter sensitivities over it (:attr:`Propagation.growth`).
"""

import functools
import math
import threading
import time
from typing import Dict, Iterable, List, Optional

import numpy as np

from ..config import Config
from ..model import snapshot
from ..model.eha import EHAModel, SampleBlock
from ..model.uncertainty import parameter_perturbations, structural_perturbations

#: the copies' duty: the estimator's grid samples averaged over about this long (s)
SAMPLE_S = 0.02
#: a quantity's sigma per K of rise is taken once it has risen this much above ambient (K)
MIN_RISE_K = 5.0
#: the cold start's heating (:class:`Heating`): the horizon in HEATING_STEPS equal exact
#: steps, doubled (up to HEATING_MAX_STEPS) until the unperturbed copy's rise of every
#: limited quantity agrees within HEATING_RISE_TOL with twice as many. A long step holds
#: the oil's viscosity, and with it the pump's leakage and friction heat and the loop's
#: flows, at the step's start: on a loaded pump 4 steps of 150 s put the sigma per K of
#: rise 30 % (1000 rad/s, 10 MPa) to 67 % (500 rad/s, 15 MPa) under that of 120 steps
#: (benchmarks/heated_relative.py)
HEATING_STEPS = 4
HEATING_MAX_STEPS = 64
HEATING_RISE_TOL = 0.01
#: sample time (s) per step of the heating from its start to the first tick that takes its
#: figures (2 s for 4 steps; the step count is known a moment after the start): the limits
#: are the fallback meanwhile; a heating not ended by then is waited for
HEATING_WAIT_PER_STEP_S = 0.5


@functools.lru_cache(maxsize=64)
def _groups(n: int, groups: int) -> tuple:
    """
    Return ``n`` samples in ``groups`` nearly equal groups: (starts, ends, counts, n - ends).

    The same few splits every step (a 20 ms step's grid in one group): kept
    rather than made again, read only.
    """
    ends = np.linspace(0, n, groups + 1).round().astype(int)[1:]
    starts = np.concatenate([[0], ends[:-1]])
    out = starts, ends, (ends - starts).astype(float), n - ends
    for a in out:
        a.flags.writeable = False
    return out


class Propagation:
    """The sensitivity copies of the model, stepped each period; the sigmas they give."""

    def __init__(self, cfg: Config, names: List[str]) -> None:
        u = cfg.uncertainty
        s = cfg.estimator
        self.settings = u
        self.names = list(names)
        self.period_steps = max(1, int(round(u.copy_period_s / s.step_s)))
        self.params = parameter_perturbations(cfg)
        self.structural = structural_perturbations(cfg)
        self._cfgs = [cfg] + [p.cfg for p in self.params] + [p.cfg for p in self.structural]
        # built now, with the estimator: at its first sample they would stall a live node
        # for the seconds their construction takes
        self.models: List[EHAModel] = []
        for c in self._cfgs:
            m = EHAModel(c, coefficient_filter_s=s.coefficient_filter_s)
            m.circuit.keep_transition = False
            m.motor.check_rotor_validity = False     # the copies' validity is not reported
            m.oil_substep_s = u.copy_substep_s
            self.models.append(m)
        self._samples: List[np.ndarray] = []  # this period's step means, a row per group
        self._held: List[bool] = []           # whether each of them is a held block's
        self._job: Optional[List[SampleBlock]] = None   # the waiting period, in segments
        self._last_s = 0.0                    # the last step's end (model time s)
        self._pending = False                 # a period stepped (or being) but not taken
        self._next = 0                        # next copy the job steps
        self._ambient_K = math.nan
        self._rise_fraction = u.structural.rise_fraction
        n, q = len(self._cfgs), len(self.names)
        self._y = np.zeros((n, q))            # each copy's outputs at the job's end (K)
        self._x: List[Optional[np.ndarray]] = [None] * n
        #: each quantity's variance from the copies (K^2), at the last period's end
        self.variance_K2 = np.zeros(q)
        #: the parameter sensitivities of the states at the last period's end (params x n, K)
        self.sensitivity_K: Optional[np.ndarray] = None
        #: the covariance of their change over the last period (K^2; None: no change yet)
        self.growth: Optional[np.ndarray] = None
        self.periods = 0
        self._known: Dict[str, float] = {}   # each quantity's last sigma per K of rise
        self._heated: Optional[Dict[str, float]] = None   # the cold start's figures
        self._heating: Optional[Heating] = None
        #: sample time (s) per heating step from its start to the first tick that takes them
        self.heating_wait_per_step_s = HEATING_WAIT_PER_STEP_S
        #: sample time (s) from the last heating's start to the tick that took its figures
        self.heated_after_s: Optional[float] = None
        #: why the last heating gave no figures (None: it did, or none has ended)
        self.heating_error: Optional[str] = None
        self.work_s = 0.0                     # CPU time spent stepping copies (s)

    @property
    def copies(self) -> int:
        """Return how many models are stepped: the unperturbed one and the perturbed ones."""
        return len(self._cfgs)

    def start(self, ambient_K: float, first: SampleBlock) -> None:
        """Start the copies where the estimator's model starts."""
        for m in self.models:
            m.initialise(ambient_K, first)
        self._samples, self._held = [], []
        self._job = None
        self._pending = False
        self._last_s = float(first.t_s[-1])
        self._known, self._heated, self._heating = {}, None, None
        self.heated_after_s = self.heating_error = None

    def record(self, since_start_s: float, block: SampleBlock, steps_before: int,
               steps_after: int, ambient_K: float) -> bool:
        """
        Add a step's (or a held block's) duty; at a period's end, start stepping the copies.

        ``since_start_s`` the step's end in model time, ``block`` its inputs
        (one sample for a held block); the step took the step count from
        ``steps_before`` to ``steps_after``. At a period's end the copies of
        the period before are finished (if the background has not) and their
        sigmas taken: returns True then. The sigmas change there only, at a
        step fixed by the sample times.
        """
        n = block.current_A.size
        span = since_start_s - self._last_s
        self._last_s = since_start_s
        # the grid's samples, in groups of about SAMPLE_S: a bidirectional duty's speed and
        # pressures alternate within a long step, and their means would cancel the pump's heat
        per = max(1, int(round(SAMPLE_S * n / span))) if span > 0.0 else n
        starts, ends, count, left = _groups(n, max(1, n // per))

        def means(x):
            return np.add.reduceat(x, starts) / count

        rows = np.empty((ends.size, 7))
        rows[:, 0] = self._last_s - span * left / n
        rows[:, 1] = np.sqrt(means(block.current_A ** 2))
        for j, x in enumerate((block.speed_rad_s, block.p_a_Pa, block.p_b_Pa, block.p_acc_Pa)):
            rows[:, 2 + j] = means(x)
        rows[:, 6] = block.position_m[ends - 1]
        held = steps_after - steps_before > 1
        if held and self._held and self._held[-1] \
                and np.array_equal(self._samples[-1][0, 1:], rows[0, 1:]):
            self._samples[-1] = rows      # the same silence, held longer: one step crosses it
        else:
            self._samples.append(rows)
            self._held.append(held)
        p = self.period_steps
        if steps_after // p == steps_before // p:
            return False
        taken, self._pending = self._pending, True
        self.finish()
        if taken:
            self._take()
        self._open(ambient_K)
        return taken

    def _open(self, ambient_K: float) -> None:
        """Make the duty recorded since the last period the copies' job."""
        # contiguous rows: the kernels of the estimator's own steps, not strided variants
        # that numba would load (or compile) at the first period's end, inside a callback
        # a held block (a silence crossed) is a segment of its own: the copies cross it in
        # one exact step, as the estimator did, not in oil sub-steps over all of it
        segments, run = [], []
        for rows, held in zip(self._samples, self._held):
            if held:
                segments += [run, [rows]] if run else [[rows]]
                run = []
            else:
                run.append(rows)
        if run:
            segments.append(run)
        self._job = [SampleBlock(*(np.ascontiguousarray(c) for c in np.concatenate(seg).T))
                     for seg in segments]
        self._samples, self._held = [], []
        self._next = 0
        self._ambient_K = ambient_K

    def warm_up(self, ambient_K: float) -> None:
        """
        Step every copy over the duty recorded so far, as a period's end would.

        For :mod:`.warmup`, whose record ends before a period does: the kernels
        of the copies' steps are then compiled (or loaded) before a live node
        listens, not at its first period's end.
        """
        self._open(ambient_K)
        self.finish()

    def work(self, budget_s: float) -> None:
        """Step copies of the waiting period for about ``budget_s`` of wall time (at least one)."""
        deadline = time.perf_counter() + budget_s
        while self._job is not None:
            self._step_next()
            if time.perf_counter() >= deadline:
                break

    def finish(self) -> None:
        """Step every copy the waiting period still has."""
        while self._job is not None:
            self._step_next()

    def _step_next(self) -> None:
        """Step the next copy over the waiting period."""
        t0 = time.process_time()
        k = self._next
        m = self.models[k]
        for block in self._job:
            m.step(block, self._ambient_K, max_substep_s=float(block.t_s[-1] - m.time_s))
        out = m.outputs()
        self._y[k] = [out[n] for n in self.names]
        if k <= len(self.params):
            self._x[k] = m.state
        self._next += 1
        self.work_s += time.process_time() - t0
        if self._next == len(self.models):
            self._job = None

    def _take(self) -> None:
        """Form the variances and the parameter sensitivities from the copies' outputs."""
        self.variance_K2, rise = self._variance(self._y, self._ambient_K)
        self._known.update(self._per_rise(self.variance_K2, rise))
        x0 = self._x[0]
        S = np.array([x - x0 for x in self._x[1:len(self.params) + 1]])
        if self.sensitivity_K is not None:
            dS = S - self.sensitivity_K
            self.growth = dS.T @ dS
        self.sensitivity_K = S
        self.periods += 1

    def _variance(self, y: np.ndarray, ambient_K: float):
        """Return each quantity's variance (K^2) from the copies' outputs ``y``, and rise (K)."""
        d = y[1:] - y[0]
        rise = np.maximum(y[0] - ambient_K, 0.0)
        return np.sum(d * d, axis=0) + (self._rise_fraction * rise) ** 2, rise

    def _per_rise(self, variance_K2: np.ndarray, rise_K: np.ndarray) -> Dict[str, float]:
        """Return the sigma per K of rise of each quantity risen at least MIN_RISE_K."""
        return {n: float(math.sqrt(variance_K2[i]) / rise_K[i])
                for i, n in enumerate(self.names) if rise_K[i] >= MIN_RISE_K}

    def sigma_K(self) -> np.ndarray:
        """Return each quantity's 1 sigma (K) at the last period's end, in ``names`` order."""
        return np.sqrt(self.variance_K2)

    def relative(self, held, ambient_K: float, stamp_s: float,
                 needed: Iterable[str]) -> Optional[Dict[str, float]]:
        """
        Return each quantity's 1 sigma per K of rise for the limits' horizons; None: pending.

        The copies' figure from the last period at whose end the quantity
        stood ``MIN_RISE_K`` above ambient (the unperturbed copy's rise then).
        Until the copies have given one for every quantity of ``needed`` (the
        limited ones), those of a cold start fill in: the first such call (a
        tick at ``stamp_s``, sample time) starts heating the copies on
        ``held`` (:class:`~.limits.HeldDuty`) at ``ambient_K`` on a thread of
        its own (:class:`Heating`); the calls of the next
        ``heating_wait_per_step_s`` of sample time per step of the heating
        return None, and the first after that waits for the heating if it has
        not ended. The figures so depend on the samples alone, and a live
        node's steps go on meanwhile. A heating that fails
        (:attr:`heating_error`) gives None until the copies' own figures.
        """
        if self._heated is None and any(q not in self._known for q in needed):
            if self.heating_error is not None:
                return None
            if self._heating is None:
                self.finish()            # the copies in step with each other
                self._heating = Heating(self.models, self.names, held, ambient_K,
                                        self._cfgs[0], stamp_s, needed)
            since_s = stamp_s - self._heating.stamp_s
            # the step count is waited for only once the fewest steps' wait has passed
            wait_s = self.heating_wait_per_step_s
            if since_s < wait_s * HEATING_STEPS or since_s < wait_s * self._heating.steps():
                return None
            heating, self._heating = self._heating, None
            try:
                self._heated = self.per_rise(*heating.result())
            except Exception as exc:  # noqa: B902 - any failure of a copy's step
                # (a held duty that takes the oil past the model's range within the
                # horizon): no figures, so the limits stay the fallback until the copies'
                # own; the estimates go on
                self.heating_error = f'{type(exc).__name__}: {exc}'
                return None
            self.heated_after_s = since_s
        return {**(self._heated or {}), **self._known}

    def per_rise(self, y: np.ndarray, ambient_K: float) -> Dict[str, float]:
        """Return the sigma per K of rise the copies' outputs ``y`` (K, a row each) give."""
        return self._per_rise(*self._variance(y, ambient_K))


class Heating:
    """
    The uncertainty's copies heated once at the continuous rating, on a thread of their own.

    Each copy is saved (:mod:`~..model.snapshot`) on the caller's thread,
    then, on the heating's, loaded and stepped on the held duty at
    ``motor.max_continuous_current_A`` over the longest horizon of
    ``estimator.limits`` in equal exact steps: the copies themselves do not
    move. How many steps: ``steps``, or (None) the fewest of HEATING_STEPS,
    twice that... up to HEATING_MAX_STEPS with which the unperturbed copy's
    rise of each quantity of ``needed`` (of those risen MIN_RISE_K) agrees
    within HEATING_RISE_TOL with twice as many steps. The reference rig's 31
    copies: about 80 ms on the caller's thread, then about 0.15 s of CPU per
    step on the heating's.
    """

    def __init__(self, models: List[EHAModel], names: List[str], held, ambient_K: float,
                 cfg: Config, stamp_s: float, needed: Iterable[str] = (),
                 steps: Optional[int] = None) -> None:
        self.stamp_s = stamp_s
        saved = [snapshot.save(m) for m in models]
        self._out: List[object] = []
        self._steps: List[int] = []
        self._counted = threading.Event()
        self._thread = threading.Thread(
            target=self._run, name='uncertainty heating', daemon=True,
            args=(saved, names, [names.index(q) for q in needed], held, ambient_K, cfg,
                  steps))
        self._thread.start()

    def _run(self, saved, names, needed, held, ambient_K, cfg, steps) -> None:
        try:
            heat = functools.partial(_heated, names=names, held=held, ambient_K=ambient_K,
                                     current_A=cfg.motor.max_continuous_current_A,
                                     horizon_s=max(cfg.estimator.limits.horizons_s))
            if steps is None:
                steps, first = _step_count(heat, saved[0], needed, ambient_K)
            else:
                first = heat(saved[0], steps)
            self._steps.append(steps)
            self._counted.set()
            y = np.array([first] + [heat(snap, steps) for snap in saved[1:]])
            self._out.append((y, ambient_K))
        except BaseException as exc:  # noqa: B902 - handed to result()
            self._out.append(exc)
        finally:
            self._counted.set()

    def steps(self) -> int:
        """Wait for the step count; return it (0 if the heating failed before it was known)."""
        self._counted.wait()
        return self._steps[0] if self._steps else 0

    def result(self):
        """Wait for the heating; return the copies' outputs (K) and the ambient (K)."""
        self._thread.join()
        out = self._out[0]
        if isinstance(out, BaseException):
            raise out
        return out


def _heated(snap: bytes, steps: int, names: List[str], held, ambient_K: float,
            current_A: float, horizon_s: float) -> np.ndarray:
    """Return a saved copy's outputs (K, ``names``) after ``horizon_s`` in ``steps`` steps."""
    dt = horizon_s / steps
    c = snapshot.copy(snap)
    c.hold_from(held.block(c.time_s, current_A))
    for _ in range(steps):
        c.step(held.block(c.time_s + dt, current_A), ambient_K, max_substep_s=dt)
    out = c.outputs()
    return np.array([out[n] for n in names])


def _step_count(heat, snap: bytes, needed: List[int], ambient_K: float):
    """Return the heating's step count (:class:`Heating`) and the copy's outputs with it."""
    steps, y = HEATING_STEPS, heat(snap, HEATING_STEPS)
    while steps < HEATING_MAX_STEPS:
        finer = heat(snap, 2 * steps)
        rise, finer_rise = y[needed] - ambient_K, finer[needed] - ambient_K
        risen = finer_rise >= MIN_RISE_K        # (the others give no figure)
        if np.all(np.abs(rise - finer_rise)[risen] <= HEATING_RISE_TOL * finer_rise[risen]):
            break
        steps, y = 2 * steps, finer
    return steps, y
