"""
The simulated rig without ROS: a duty in, the rig's sensor signals and thermocouples out.

The kinetic model turns the duty into the estimator's input signals, in
blocks of ``block_s`` (``BLOCK_S`` by default); a "truth" thermal model
(:class:`~wet_eha_thermal.model.eha.EHAModel`) is stepped with the same,
noise-free samples every block, and its temperatures, through a first-order
sensor lag, are the thermocouples. The truth model may run with other
parameters than the estimator's configuration (a rig that differs from
its handbook values, for calibration tests). Seeded Gaussian noise (1 sigma):
current 0.05 A (an RMS reading, so its magnitude is kept), speed 2 rad/s,
pressures 20 kPa, position 10 um, thermocouples 0.2 K, ambient 0.05 K.
By default each thermocouple reads the model output it is named after
(``THERMOCOUPLES``); with ``point_thermocouples`` the winding and frame
thermocouples read one point, at mid-stack, of the truth's axial profile
instead of the means the estimator publishes, as a bonded thermocouple does.

A rig whose ``current_limit_A`` is set plays a drive that honours a current
limit (:meth:`~wet_eha_thermal.model.kinetics.KineticModel.sample_limited`:
the load yields where the duty asks for more current); it counts the samples
it clamped, the first one's duty time and the largest cut. The truth model
heats with the clamped current, and the rig keeps the truth's peak
hot-spot. Which limit the drive applies, the estimator's or its own
fallback, :class:`DriveLimit` decides.

The ROS node (:mod:`wet_eha_thermal.ros.sim_rig_node`) publishes these
blocks in real time; :func:`write_rig_bag` writes them straight to a bag,
as the recorder would have recorded the rig, for replays and tests;
:func:`~wet_eha_thermal.calibration.logs.log_from_rig` averages them straight
into a calibration's log.
"""

import math
import os
from typing import Callable, Dict, Iterator, Optional, Sequence, Tuple

import numpy as np

# the rig's kinetics see its truth model as a duty simulation's see its model: one feedback
from .simulation import feedback
from ..config import Config
from ..estimator.intake import sensor_inputs, sensor_signal
from ..interface import (AMBIENT_TOPIC, DriveLimits, INPUT_TOPICS, INPUT_TYPES, LimitStatus,
                         MEASURED_PREFIX, PRESSURE_INPUTS, SENSOR, TEMPERATURE, THERMOCOUPLES)
from ..model.duty import Duty
from ..model.eha import EHAModel
from ..model.kinetics import KineticModel, ThermalFeedback
from ..units import C_TO_K

#: Length of one kinetics block and one truth-model step (s).
BLOCK_S = 0.02
#: Sensor noise, 1 sigma, in the units of each input.
NOISE_SIGMA = {'current_A': 0.05, 'speed_rad_s': 2.0, 'p_a_Pa': 20.0e3, 'p_b_Pa': 20.0e3,
               'p_acc_Pa': 20.0e3, 'dp_Pa': 20.0e3, 'position_m': 10.0e-6}
THERMOCOUPLE_SIGMA_K = 0.2
AMBIENT_SIGMA_K = 0.05
#: Where the point thermocouples sit, as a fraction of the stack length from the oil inlet.
POINT_THERMOCOUPLE_Z = 0.5


class DriveLimit:
    """
    The current limit the simulated drive applies: the estimator's, or its own fallback.

    :meth:`take` keeps the binding limit of the last limits message (the
    ``data`` of a Float64MultiArray on ``<prefix>/drive/limits``,
    :class:`~wet_eha_thermal.interface.DriveLimits`).
    :meth:`applied` says what the drive carries at most now: that limit
    while its stamp is at most ``watchdog_s`` old, else (or before any)
    ``fallback_A``; one whose status code is not OK is applied up to
    ``fallback_A`` only.
    """

    def __init__(self, watchdog_s: float, fallback_A: float) -> None:
        self.watchdog_s = watchdog_s
        self.fallback_A = fallback_A
        self.value_A: Optional[float] = None        # the last message's binding limit
        self.stamp_ns = 0
        self.status = LimitStatus.OK                # the last message's status code
        self.received = 0
        self.rejected = 0
        self.missed = 0                             # gaps in the sequence
        self.sequence = 0

    def take(self, data: Sequence[float]) -> None:
        """
        Take one limits message; a malformed one is counted and left to the watchdog.

        Malformed: not the layout (version, count), or a limit NaN or negative
        (+inf is no limit within that horizon).
        """
        try:
            limits = DriveLimits.from_data(data)
        except ValueError:
            self.rejected += 1
            return
        self.received += 1
        if limits.sequence > self.sequence + 1 and self.sequence:
            self.missed += limits.sequence - self.sequence - 1
        self.sequence = limits.sequence
        self.value_A = limits.binding_A
        self.stamp_ns = limits.stamp_ns
        self.status = limits.status

    def applied(self, now_ns: int) -> Tuple[float, str]:
        """Return the limit to carry at ``now_ns`` (the rig's clock, ns) and whose it is."""
        if self.value_A is None:
            return self.fallback_A, 'fallback: no limit yet'
        age_s = (now_ns - self.stamp_ns) * 1e-9
        if age_s > self.watchdog_s:
            return self.fallback_A, f'fallback: the last limit is {age_s:.1f} s old'
        if self.status != LimitStatus.OK:
            return min(self.value_A, self.fallback_A), \
                f'estimator fallback: {self.status.name.lower()}'
        return self.value_A, 'estimator'


class SimulatedRig:
    """The reference rig playing a duty: sensor blocks, thermocouples, the truth model."""

    def __init__(self, cfg: Config, duty: Duty, rate_Hz: float = 1000.0, noise: bool = True,
                 seed: int = 1, ambient_C: float = 20.0,
                 thermocouple_lag_s: float = 1.0, block_s: float = BLOCK_S,
                 point_thermocouples: bool = False) -> None:
        self.cfg = cfg
        self.point_thermocouples = point_thermocouples
        self.block_s = block_s
        self.duty = duty
        self.inputs = sensor_inputs(cfg)      # three pressures or one differential
        self.n_block = max(1, int(round(rate_Hz * block_s)))
        self.period_s = block_s / self.n_block   # exact: a block is a whole number of samples
        self.noise = noise
        self.thermocouple_sigma_K = THERMOCOUPLE_SIGMA_K if noise else 0.0
        self.ambient_C = ambient_C
        self.rng = np.random.default_rng(seed)
        self.truth = EHAModel(cfg)
        self.kin = KineticModel(cfg, self.truth.oil, self.truth.log)
        amb_K = ambient_C + C_TO_K
        first = self.kin.sample(duty, np.array([0.0]), ThermalFeedback.uniform(amb_K))
        self.truth.initialise(amb_K, first)
        self.tc_lag_K = {name: amb_K for name in THERMOCOUPLES}
        self.tc_alpha = 1.0 - math.exp(-block_s / thermocouple_lag_s) \
            if thermocouple_lag_s > 0.0 else 1.0
        self.blocks = 0
        #: the phase current the drive may carry (A RMS); None: the duty's, unlimited
        self.current_limit_A: Optional[float] = None
        self.clamped_samples = 0
        self.first_clamp_s = math.nan        # duty time of the first clamped sample
        self.largest_cut_A = 0.0             # demanded minus carried current, largest
        self.peak_hotspot_K = self.truth.outputs()['winding_hotspot']

    def next_block(self) -> Dict[str, np.ndarray]:
        """
        Return the next block's samples: ``t_s`` (duty time) and one array per input.

        Steps the truth model over the block and the thermocouple lags.
        """
        first = 1 + self.blocks * self.n_block
        t = (first + np.arange(self.n_block)) * self.period_s
        if self.current_limit_A is None:
            s = self.kin.sample(self.duty, t, feedback(self.truth))
        else:
            s, demanded = self.kin.sample_limited(self.duty, t, feedback(self.truth),
                                                  self.current_limit_A)
            self._count_clamp(t, demanded - s.current_A)
        self.truth.step(s, self.ambient_C + C_TO_K)
        out = self.truth.outputs()
        self.peak_hotspot_K = max(self.peak_hotspot_K, out['winding_hotspot'])
        seen = {name: out[quantity] for name, quantity in THERMOCOUPLES.items()}
        if self.point_thermocouples:
            seen.update(self._at_mid_stack())
        for name, value in seen.items():
            self.tc_lag_K[name] += self.tc_alpha * (value - self.tc_lag_K[name])
        block = {'t_s': t}
        for name in self.inputs:
            v = sensor_signal(s, name)
            if self.noise:
                v = v + self.rng.normal(0.0, NOISE_SIGMA[name], v.size)
                if name == 'current_A':
                    np.abs(v, out=v)       # an RMS reading is never negative
            block[name] = v
        self.blocks += 1
        return block

    def _count_clamp(self, t_s: np.ndarray, cut_A: np.ndarray) -> None:
        """Count the block's clamped samples (a cut > 0) and keep the first and the largest."""
        clamped = np.flatnonzero(cut_A > 0.0)
        if not clamped.size:
            return
        if not self.clamped_samples:
            self.first_clamp_s = float(t_s[clamped[0]])
        self.clamped_samples += int(clamped.size)
        self.largest_cut_A = max(self.largest_cut_A, float(np.max(cut_A)))

    def _at_mid_stack(self) -> Dict[str, float]:
        """Return the truth's slot copper and frame (K) at ``POINT_THERMOCOUPLE_Z``."""
        motor = self.truth.motor
        n = self.cfg.motor.slices
        centres = (np.arange(n) + 0.5) / n          # slice centres, stack fractions
        return {'winding': float(np.interp(POINT_THERMOCOUPLE_Z, centres,
                                           motor.winding_slices_K())),
                'frame': float(np.interp(POINT_THERMOCOUPLE_Z, centres,
                                         motor.T[motor.idx_frame]))}

    def thermocouples_C(self) -> Dict[str, float]:
        """Return the thermocouple readings now (degC, lagged, with noise)."""
        sigma = self.thermocouple_sigma_K
        noise = self.rng.normal(0.0, sigma, len(THERMOCOUPLES)) if sigma else \
            np.zeros(len(THERMOCOUPLES))
        return {name: self.tc_lag_K[name] - C_TO_K + float(e)
                for name, e in zip(THERMOCOUPLES, noise)}

    def ambient_reading_C(self) -> float:
        """Return an ambient reading (degC, with noise)."""
        sigma = AMBIENT_SIGMA_K if self.noise else 0.0
        return self.ambient_C + (float(self.rng.normal(0.0, sigma)) if sigma else 0.0)

    def run(self, seconds: float, thermocouple_rate_Hz: float = 10.0) -> Iterator[
            Tuple[int, int, Dict[str, np.ndarray], Optional[Dict[str, float]],
                  Optional[float]]]:
        """
        Play ``seconds`` of the duty: yield (k, blocks, block, thermocouples, ambient) per block.

        Thermocouple readings (degC) come with every block that starts a
        ``1 / thermocouple_rate_Hz`` period, an ambient reading once a
        second, else None; ``blocks`` is the total count.
        """
        n_blocks = int(round(seconds / self.block_s))
        tc_every = max(1, int(round(1.0 / (thermocouple_rate_Hz * self.block_s))))
        amb_every = max(1, int(round(1.0 / self.block_s)))
        for k in range(n_blocks):
            block = self.next_block()
            tcs = self.thermocouples_C() if k % tc_every == 0 else None
            amb = self.ambient_reading_C() if k % amb_every == 0 else None
            yield k, n_blocks, block, tcs, amb


def write_rig_bag(path: os.PathLike, rig: SimulatedRig, seconds: float, *,
                  start_ns: int = 1_700_000_000 * 10**9, thermocouple_rate_Hz: float = 10.0,
                  metadata: Optional[Dict[str, Dict[str, str]]] = None,
                  on_progress: Optional[Callable[[float], None]] = None) -> int:
    """
    Write ``seconds`` of the rig's topics to a bag, as the recorder records them; return the count.

    Log times are the samples' times from ``start_ns``; pressures carry the
    same stamp in their header. Thermocouples and ambient come at
    ``thermocouple_rate_Hz`` and 1 Hz.
    """
    from ..bag import cdr
    from ..bag.rosbag2 import offered_profiles
    from ..bag.writer import BagWriter, offered_qos

    def temperature(value_C: float, sigma_K: float, ns: int) -> bytes:
        return cdr.encode_stamped(np.array([ns]), '', [[value_C, sigma_K ** 2 if rig.noise
                                                        else 0.0]])[0]

    count = 0
    with BagWriter(path, metadata=metadata) as bag:
        for name in rig.inputs:
            bag.add_topic(INPUT_TOPICS[name], INPUT_TYPES[name], offered_profiles(SENSOR, 100))
        for tc in THERMOCOUPLES:
            bag.add_topic(f'{MEASURED_PREFIX}/{tc}', TEMPERATURE,
                          offered_qos(depth=10))
        bag.add_topic(AMBIENT_TOPIC, TEMPERATURE,
                      offered_qos(depth=10))
        for k, n_blocks, block, tcs, amb in rig.run(seconds, thermocouple_rate_Hz):
            stamps_ns = (start_ns + np.round(block['t_s'] * 1e9)).astype(np.int64)
            cols = [(INPUT_TOPICS[n],
                     cdr.encode_stamped(stamps_ns, '', np.column_stack(
                         [block[n], np.zeros_like(block[n])]))
                     if n in PRESSURE_INPUTS
                     else [cdr.encode_float64(v) for v in block[n].tolist()])
                    for n in rig.inputs]
            stamps = stamps_ns.tolist()
            for j, ns in enumerate(stamps):
                for topic, data in cols:
                    bag.write(topic, data[j], ns)
            count += len(stamps) * len(cols)
            ns = stamps[-1]
            if tcs is not None:
                for tc, value in tcs.items():
                    bag.write(f'{MEASURED_PREFIX}/{tc}',
                              temperature(value, THERMOCOUPLE_SIGMA_K, ns), ns)
                    count += 1
            if amb is not None:
                bag.write(AMBIENT_TOPIC, temperature(amb, AMBIENT_SIGMA_K, ns), ns)
                count += 1
            if on_progress is not None and k % 500 == 0:
                on_progress((k + 1) / n_blocks)
    return count
