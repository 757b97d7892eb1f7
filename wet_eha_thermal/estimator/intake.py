"""
The estimator's intake: the inputs' samples, their checks, sensor health and the clock.

Samples of the inputs arrive one by one, at any rate and in any
interleaving: current, speed, position and either the absolute pressures of
both ports and the accumulator or one differential pressure
(``estimator.pressure_inputs``). ``push`` only appends to the input's
preallocated buffer (the live node's per-sample work); the checks run
vectorised when the stepping screens the buffers (:meth:`Intake.screen`);
``add_many`` checks arrays at once (a replay).

Sensor health: a non-finite or out-of-range value, a stamp going backwards, a
stamp the model already stepped past (late) or one more than ``max_future_s``
ahead of the receiving clock (future) is rejected and counted; a rejected
sample never moves its input's last stamp. Each input keeps at most
``buffer_samples`` samples the model has not stepped past; more are dropped
and counted (overflow). An input with no sample for its ``timeout_s`` is
stale; it then takes its fallback (the last good value held; an input never
seen takes its resting value: no current, no speed, accumulator pressure,
mid-stroke). A silence of every input at once is a data gap: counted, timed,
and told in the notices.

The receiving clock is what the stepping is given; with none ever given there
is no future check. A reading more than ``clock_jump_s`` behind the latest is
a jump (:meth:`Intake.observe_clock` says so; the estimator then re-starts its
time, :meth:`Intake.restart` the intake's part).
"""

from dataclasses import dataclass
import math
from typing import Dict, List, Optional, Tuple

import numpy as np

from ..config import Config
from ..interface import DIFFERENTIAL_INPUTS, INPUTS
from ..model.compiled import jit
from ..model.eha import SampleBlock

#: why ``check_samples`` rejected a sample (ACCEPTED: it did not)
ACCEPTED, NON_FINITE, OUT_OF_RANGE, FUTURE, BACKWARDS, LATE = range(6)


def sensor_inputs(cfg: Config) -> Tuple[str, ...]:
    """Return the estimator's inputs under configuration ``cfg``."""
    return DIFFERENTIAL_INPUTS if cfg.estimator.pressure_inputs == 'differential' else INPUTS


def sensor_signal(samples: SampleBlock, name: str) -> np.ndarray:
    """Return what input ``name`` reads from the model's ``samples`` (dp_Pa: p_A - p_B)."""
    if name == 'dp_Pa':
        return samples.p_a_Pa - samples.p_b_Pa
    return getattr(samples, name)


@dataclass
class ChannelHealth:
    """Counters and state of one input."""

    received: int = 0
    accepted: int = 0
    non_finite: int = 0
    out_of_range: int = 0
    backwards: int = 0
    late: int = 0            # arrived after the model had stepped past its stamp
    future: int = 0          # stamped more than max_future_s ahead of the receiving clock
    overflow: int = 0        # dropped: the input's buffer was full
    discarded: int = 0       # accepted, then dropped at a jump of the receiving clock
    stale_events: int = 0    # times the input went stale
    stale: bool = False
    stale_since_s: Optional[float] = None
    last_stamp_s: Optional[float] = None
    last_value: Optional[float] = None
    heard_s: Optional[float] = None   # the receiving clock when a sample was last accepted

    @property
    def rejected(self) -> int:
        """Return the number of samples not used."""
        return (self.non_finite + self.out_of_range + self.backwards + self.late + self.future
                + self.overflow)


@dataclass
class DataGaps:
    """Silences of every input at once (all stale): how many, how long, the open one."""

    count: int = 0
    total_s: float = 0.0
    longest_s: float = 0.0
    open_since_s: Optional[float] = None
    last: Optional[Tuple[float, float]] = None     # (start, end) of the last closed gap (s)


class SampleBuffer:
    """
    One input's samples in preallocated arrays.

    ``t[lo:hi]``, ``v[lo:hi]``: accepted samples the model has not stepped
    past, stamps strictly increasing; ``t[hi:top]``: pushed, not yet checked.
    """

    __slots__ = ('t', 'v', 'lo', 'hi', 'top', 'size')

    def __init__(self, capacity: int) -> None:
        self.t = np.empty(capacity)
        self.v = np.empty(capacity)
        self.lo = self.hi = self.top = 0
        self.size = capacity

    def room(self, n: int = 1) -> int:
        """Make room at the end (moving the kept samples to the front); return up to ``n``."""
        if self.top + n > self.size and self.lo:
            k = self.top - self.lo
            self.t[:k] = self.t[self.lo:self.top]
            self.v[:k] = self.v[self.lo:self.top]
            self.hi -= self.lo
            self.top = k
            self.lo = 0
        return min(n, self.size - self.top)

    def stamps(self) -> np.ndarray:
        """Return a view of the accepted stamps."""
        return self.t[self.lo:self.hi]

    def clear(self) -> int:
        """Drop everything; return how many accepted samples there were."""
        n = self.hi - self.lo
        self.lo = self.hi = self.top = 0
        return n


class Intake:
    """Each input's buffer and health, the receiving clock and the data gaps."""

    def __init__(self, cfg: Config, resolution_s: float) -> None:
        s = cfg.estimator
        self.settings = s
        self.inputs = sensor_inputs(cfg)
        self.differential = self.inputs == DIFFERENTIAL_INPUTS
        self.channel_cfg = {name: getattr(s.channels, name) for name in self.inputs}
        self.health = {name: ChannelHealth() for name in self.inputs}
        self.buffers = {name: SampleBuffer(s.buffer_samples) for name in self.inputs}
        #: each input's last sample the model stepped past: (stamp s, value), None before
        self.prev: Dict[str, Optional[tuple]] = dict.fromkeys(self.inputs)
        p_acc = cfg.hydraulics.accumulator.pressure_Pa
        self.rest = {'current_A': 0.0, 'speed_rad_s': 0.0, 'p_a_Pa': p_acc, 'p_b_Pa': p_acc,
                     'p_acc_Pa': p_acc, 'dp_Pa': 0.0, 'position_m': 0.0}
        self.eps_base = resolution_s
        #: stamps this close (s) count as equal
        self.eps = resolution_s
        #: the receiving clock's latest reading (s), None while none was given
        self.clock_s: Optional[float] = None
        self.clock_jumps = 0
        self.last_clock_jump: Optional[Tuple[float, float]] = None   # (from, to) s
        self.gaps = DataGaps()
        # a silence of every input longer than the longest timeout is a data gap
        self._gap_after_s = max(c.timeout_s for c in self.channel_cfg.values())
        self._last_sample_s: Optional[float] = None   # latest accepted stamp of any input
        #: what happened to the time base since the stepping last took these (texts)
        self.notices: List[str] = []

    def resolve(self, t_s: float) -> None:
        """Set the stamp resolution for stamps near ``t_s``."""
        # stamps since the epoch are only resolved to ~0.2 us: equal means within a few ulps
        self.eps = max(self.eps_base, 8.0 * float(np.spacing(abs(t_s))))

    def push(self, channel: str, stamp_s: float, value: float) -> bool:
        """
        Append one sample (SI units) unchecked; it is checked at the next :meth:`screen`.

        The live path's whole per-sample work. Returns False (and counts an
        overflow) when the input's buffer is full.
        """
        buf = self.buffers[channel]          # KeyError names an unknown channel
        if buf.top == buf.size and not buf.room():
            h = self.health[channel]
            h.received += 1
            h.overflow += 1
            return False
        top = buf.top                        # after room(), which may have moved the samples
        buf.t[top] = stamp_s
        buf.v[top] = value
        buf.top = top + 1
        return True

    def push_many(self, channel: str, stamps_s: np.ndarray, values: np.ndarray) -> bool:
        """
        Append a block of samples (SI units) unchecked, as :meth:`push` appends one.

        A batched message's work. Returns False when none found room; those
        that did not are counted (overflow).
        """
        buf = self.buffers[channel]
        n = len(stamps_s)
        room = buf.room(n)
        if room < n:
            h = self.health[channel]
            h.received += n - room
            h.overflow += n - room
        if not room:
            return False
        top = buf.top
        buf.t[top:top + room] = stamps_s[:room]
        buf.v[top:top + room] = values[:room]
        buf.top = top + room
        return True

    def latest_allowed(self) -> float:
        """Return the latest stamp a sample may carry now (the future guard)."""
        return self.clock_s + self.settings.max_future_s if self.clock_s is not None \
            else math.inf

    def add_many(self, channel: str, stamps_s: np.ndarray, values: np.ndarray,
                 now_s: Optional[float], model_s: float) -> int:
        """
        Take many samples of one input at once, checked; return how many were accepted.

        The same checks, vectorised, for replaying logs. ``now_s``: the
        receiving clock (s) for the future check, one reading for all or one
        per sample (a log's receive times); unlike ``advance``'s it is not
        taken as the clock (a replay feeds one input's block after another's,
        so these readings go back between calls). ``model_s``: a stamp at or
        before it is late (the model stepped past it).
        """
        buf = self.buffers[channel]
        if buf.top > buf.hi:
            self._screen(channel, model_s)
        t = np.asarray(stamps_s, dtype=float)
        v = np.asarray(values, dtype=float)
        latest = self.latest_allowed() if now_s is None \
            else np.asarray(now_s, dtype=float) + self.settings.max_future_s
        return self._accept(channel, t, v, latest, model_s)

    def screen(self, model_s: float) -> None:
        """Check every input's pushed samples, keeping the accepted (``model_s``: late before)."""
        for name in self.inputs:
            buf = self.buffers[name]
            if buf.top > buf.hi:
                self._screen(name, model_s)

    def _screen(self, channel: str, model_s: float) -> None:
        """Check the pushed samples of ``channel``, keeping the accepted."""
        buf = self.buffers[channel]
        t = buf.t[buf.hi:buf.top].copy()
        v = buf.v[buf.hi:buf.top].copy()
        buf.top = buf.hi
        self._accept(channel, t, v, self.latest_allowed(), model_s)

    def _accept(self, channel: str, t: np.ndarray, v: np.ndarray, latest,
                model_s: float) -> int:
        """Count and keep the acceptable samples of ``t``, ``v`` (``latest``: future guard)."""
        h = self.health[channel]
        c = self.channel_cfg[channel]
        buf = self.buffers[channel]
        h.received += t.size
        code = check_samples(t, v, c.low, c.high, np.broadcast_to(latest, t.shape),
                             h.last_stamp_s if h.last_stamp_s is not None else -math.inf,
                             model_s)
        counts = np.bincount(code, minlength=6).tolist()
        h.non_finite += counts[NON_FINITE]
        h.out_of_range += counts[OUT_OF_RANGE]
        h.future += counts[FUTURE]
        h.backwards += counts[BACKWARDS]
        h.late += counts[LATE]
        ok = code == ACCEPTED
        n = int(np.count_nonzero(ok))
        if not n:
            return 0
        ts, vs = t[ok], v[ok]
        room = buf.room(n)
        if room < n:                      # full: the newest are dropped
            h.overflow += n - room
            ts, vs, n = ts[:room], vs[:room], room
            if not n:
                return 0
        h.accepted += n
        h.last_stamp_s, h.last_value, h.heard_s = float(ts[-1]), float(vs[-1]), self.clock_s
        self._heard(float(ts[0]), h.last_stamp_s)
        buf.t[buf.hi:buf.hi + n] = ts
        buf.v[buf.hi:buf.hi + n] = vs
        buf.hi += n
        buf.top = buf.hi
        return n

    # ------------------------------------------------------------- the clock
    def observe_clock(self, now_s: float) -> bool:
        """Take a reading of the receiving clock; return True for a jump back (not taken)."""
        if not (math.isfinite(now_s) and now_s > 0.0):    # no clock reads that
            return False
        if self.clock_s is not None and now_s < self.clock_s - self.settings.clock_jump_s:
            return True
        self.clock_s = now_s if self.clock_s is None else max(self.clock_s, now_s)
        return False

    def restart(self, now_s: float, delta_s: float) -> None:
        """
        Take a jump of the receiving clock to ``now_s`` (the model's time moves by ``delta_s``).

        The buffered samples are discarded and counted per input
        (``discarded``); every input's last stamp is forgotten, so the new
        clock's samples are not taken for stamps going backwards; the last
        samples stepped past move by ``delta_s``; the open data gap closes.
        """
        self.clock_jumps += 1
        self.last_clock_jump = (float(self.clock_s) if self.clock_s is not None else math.nan,
                                float(now_s))
        self.clock_s = now_s
        for name in self.inputs:
            h = self.health[name]
            h.discarded += self.buffers[name].clear()
            h.last_stamp_s = h.heard_s = None
            h.stale_since_s = None
            if self.prev[name] is not None:
                self.prev[name] = (self.prev[name][0] + delta_s, self.prev[name][1])
        self._last_sample_s = None
        self.gaps.open_since_s = None
        self.notices.append(
            f'receiving clock jumped from {self.last_clock_jump[0]:.3f} s to {now_s:.3f} s: '
            'model time re-started there, thermal state kept')

    # --------------------------------------------------------------- health
    def reference_time(self, now_s: Optional[float]) -> Optional[float]:
        """Return the latest of the inputs' last stamps and the clock ``now_s`` (None: none)."""
        stamps = [h.last_stamp_s for h in self.health.values() if h.last_stamp_s is not None]
        if now_s is not None and math.isfinite(now_s) and now_s > 0.0:
            stamps.append(now_s)
        return max(stamps) if stamps else None

    def update_staleness(self, ref: float) -> List[str]:
        """
        Mark the inputs stale whose last stamp is older than their timeout; return them.

        With a receiving clock, an input still arriving (a sample accepted
        within its timeout) whose stamps lag the clock by at most
        ``max_lag_s`` stays fresh and is waited for: a busy receiver delivers
        a source-stamped sample late, and stepping past it would lose it.
        """
        stale = []
        lag_s = self.settings.max_lag_s
        for name, h in self.health.items():
            limit = self.channel_cfg[name].timeout_s
            is_stale = h.last_stamp_s is None or (
                ref - h.last_stamp_s > limit
                and not (h.heard_s is not None and self.clock_s - h.heard_s <= limit
                         and ref - h.last_stamp_s <= lag_s))
            if is_stale and not h.stale and h.last_stamp_s is not None:
                h.stale_events += 1
                h.stale_since_s = h.last_stamp_s + limit
            if not is_stale:
                h.stale_since_s = None
            h.stale = is_stale
            if is_stale:
                stale.append(name)
        return stale

    def _heard(self, first_s: float, last_s: float) -> None:
        """Note accepted samples stamped ``first_s`` .. ``last_s``; close a data gap they end."""
        prev = self._last_sample_s
        if prev is not None and first_s - prev > self._gap_after_s:
            g = self.gaps
            length = first_s - prev
            g.count += 1
            g.total_s += length
            g.longest_s = max(g.longest_s, length)
            g.last = (prev, first_s)
            self.notices.append(
                f'data gap: no input sample for {length:.1f} s (from {prev:.3f} s to '
                f'{first_s:.3f} s); the model ran on the held inputs')
        if prev is None or last_s > prev:
            self._last_sample_s = last_s
        self.gaps.open_since_s = None

    def track_gap(self, stale: List[str]) -> None:
        """Open a data gap when every input is stale (it closes with the next sample)."""
        if len(stale) == len(self.inputs) and self.gaps.open_since_s is None:
            self.gaps.open_since_s = self._last_sample_s

    def model_inputs(self, values: Dict[str, np.ndarray]) -> Dict[str, np.ndarray]:
        """
        Return the model's six inputs from the sensors' (the same arrays with port pressures).

        A differential pressure is split with its low side at the accumulator
        pressure: in a closed-circuit EHA the low port is fed from the
        accumulator through its check valve.
        """
        if not self.differential:
            return values
        p_a, p_b, p_acc = split_differential(values['dp_Pa'], self.rest['p_acc_Pa'])
        return {**values, 'p_a_Pa': p_a, 'p_b_Pa': p_b, 'p_acc_Pa': p_acc}

    # -------------------------------------------------------------- buffers
    def first_stamps(self) -> List[float]:
        """Return the first buffered stamp of each input that has one."""
        return [float(b.t[b.lo]) for b in self.buffers.values() if b.hi > b.lo]

    def stamps_in(self, lo_s: float, hi_s: float) -> np.ndarray:
        """Return the buffered stamps of every input in (``lo_s``, ``hi_s``], input by input."""
        stamps = []
        for b in self.buffers.values():
            a, z = np.searchsorted(b.stamps(), [lo_s, hi_s], side='right')
            stamps.append(b.t[b.lo + a:b.lo + z])
        return np.concatenate(stamps)

    def until(self, name: str, t: float) -> Tuple[np.ndarray, np.ndarray]:
        """Return the buffered stamps and values of ``name`` at or before ``t`` (views)."""
        k = self.count_until(name, t)
        buf = self.buffers[name]
        return buf.t[buf.lo:buf.lo + k], buf.v[buf.lo:buf.lo + k]

    def count_until(self, name: str, t: float) -> int:
        """Return how many buffered samples of ``name`` are stamped at or before ``t``."""
        return int(np.searchsorted(self.buffers[name].stamps(), t + self.eps, side='right'))

    def value_at(self, name: str, t: float) -> float:
        """Return the last value at or before ``t`` (fallback: last good, else at rest)."""
        k = self.count_until(name, t)
        if k:
            buf = self.buffers[name]
            return float(buf.v[buf.lo + k - 1])
        if self.prev[name] is not None:
            return self.prev[name][1]
        h = self.health[name]
        return h.last_value if h.last_value is not None else self.rest[name]

    def drop_until(self, name: str, t: float) -> None:
        """Drop the samples of ``name`` at or before ``t`` (the model stepped past them)."""
        k = self.count_until(name, t)
        if k:
            buf = self.buffers[name]
            j = buf.lo + k - 1
            self.prev[name] = (float(buf.t[j]), float(buf.v[j]))
            buf.lo += k


@jit
def split_differential(dp, p_acc):
    """Return the port pressures A and B and the accumulator's (Pa) from a differential one."""
    return p_acc + np.maximum(dp, 0.0), p_acc - np.minimum(dp, 0.0), np.full(dp.shape, p_acc)


@jit
def check_samples(t, v, low, high, latest, last_s, model_s):
    """
    Return why each sample of one input is rejected (ACCEPTED, NON_FINITE, ...), in order.

    Non-finite stamp or value; value outside [``low``, ``high``]; stamp after
    its ``latest`` (the future guard); stamp not after the latest accepted so
    far (``last_s`` before these: backwards); stamp at or before ``model_s``
    (the model stepped past it: late). One compiled loop for a batch.
    """
    code = np.empty(t.size, dtype=np.int64)
    for i in range(t.size):
        if not (np.isfinite(t[i]) and np.isfinite(v[i])):
            code[i] = NON_FINITE
        elif not low <= v[i] <= high:
            code[i] = OUT_OF_RANGE
        elif t[i] > latest[i]:
            code[i] = FUTURE
        elif t[i] <= last_s:
            code[i] = BACKWARDS
        elif t[i] <= model_s:
            code[i] = LATE
        else:
            code[i] = ACCEPTED
            last_s = t[i]
    return code
