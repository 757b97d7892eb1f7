"""
CPU of the estimator's input path in one process, without DDS: per-message against batched.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_inputs.py [--seconds 20]
     [--rate-Hz 1000] [--batched-rate-Hz 4000] [--block-ms 10]

What the node does with each message's bytes once rclpy hands them over
(:mod:`wet_eha_thermal.inputs` decodes, the estimator takes and steps; the
forecast's and the limits' slow work, the same for both and bounded by the
node's budget of wall time, left out), fed as fast as it goes:
``--seconds`` of four inputs (current, speed, one differential pressure,
position; stage 6 signals) as per-message stamped samples at ``--rate-Hz``
(sensor_msgs/FluidPressure bytes, the header's stamp: a Float64's arrival
stamp cannot be played faster than real time), and the same signals at
``--batched-rate-Hz`` in ``--block-ms`` blocks of one Float64MultiArray. The
figures: process CPU time per second of data, in % of one core, for each,
alternating three times in this one run (median). What rclpy costs to
receive the messages is not in it: ``bench_estimator.py`` measures that
against a bare subscriber.
"""

import argparse
import statistics
import time

import numpy as np
from wet_eha_thermal.bag import cdr
from wet_eha_thermal.config import load_config
from wet_eha_thermal.estimator.intake import sensor_inputs, sensor_signal
from wet_eha_thermal.estimator.session import EstimatorSession
from wet_eha_thermal.inputs import (BATCH, decoders, encode_batch, FLUID_PRESSURE, Inputs,
                                    InputSignal, SI_UNIT)
from wet_eha_thermal.model.duty import stage_duty
from wet_eha_thermal.model.kinetics import KineticModel, ThermalFeedback
from wet_eha_thermal.model.oil import get_oil
from wet_eha_thermal.model.warmup import compile_model

T0_S = 1_790_000_000.0


def signals(cfg, inputs, rate_Hz, seconds):
    """Return the stamps (s) and one column per input of stage 6 at ``rate_Hz``."""
    duty = stage_duty(cfg, 6)
    t = np.arange(1, int(round(seconds * rate_Hz)) + 1) / rate_Hz
    s = KineticModel(cfg, get_oil(cfg.fluid.grade)).sample(duty, t, ThermalFeedback.uniform())
    return T0_S + t, np.column_stack([sensor_signal(s, k) for k in inputs])


def per_message(cfg, inputs, rate_Hz, seconds) -> float:
    """Return CPU s per s of data: a stamped message per sample and input."""
    spec = Inputs(**{k: InputSignal(topic=f'/eha/{k}', message_type=FLUID_PRESSURE,
                                    unit=SI_UNIT[k]) for k in inputs})
    decs = decoders(spec, inputs)
    t, x = signals(cfg, inputs, rate_Hz, seconds)
    msgs = [cdr.encode_stamped((t * 1e9).astype(np.int64), 'eha',
                               np.column_stack([x[:, k], np.zeros(t.size)]))
            for k in range(len(inputs))]
    est = EstimatorSession(cfg, outlook='background')
    cpu = time.process_time()
    for i in range(t.size):
        now = t[i]
        for dec, m in zip(decs, msgs):
            ns, values = dec.decode(m[i])
            for channel, value in zip(dec.channels, values):
                est.take(channel, ns * 1e-9, value, now)
    return (time.process_time() - cpu) / seconds


def batched(cfg, inputs, rate_Hz, block_ms, seconds) -> float:
    """Return CPU s per s of data: one block of every input per ``block_ms``."""
    spec = Inputs(**{k: InputSignal(topic='/eha/daq', message_type=BATCH, column=j,
                                    columns=len(inputs), unit=SI_UNIT[k])
                     for j, k in enumerate(inputs)})
    dec, = decoders(spec, inputs)
    t, x = signals(cfg, inputs, rate_Hz, seconds)
    n = int(round(block_ms * 1e-3 * rate_Hz))
    blocks = [encode_batch(t[i], 1.0 / rate_Hz, x[i:i + n]) for i in range(0, t.size, n)]
    est = EstimatorSession(cfg, outlook='background')
    cpu = time.process_time()
    for b, i in zip(blocks, range(0, t.size, n)):
        now = t[min(i + n, t.size) - 1]
        stamps, values = dec.decode_batch(b)
        for k, channel in enumerate(dec.channels):
            est.take_many(channel, stamps, values[:, k], now)
    return (time.process_time() - cpu) / seconds


def main() -> None:
    """Run both paths three times, alternating; print the medians and their ratio."""
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--seconds', type=float, default=20.0)
    p.add_argument('--rate-Hz', type=float, default=1000.0)
    p.add_argument('--batched-rate-Hz', type=float, default=4000.0)
    p.add_argument('--block-ms', type=float, default=10.0)
    args = p.parse_args()
    cfg = load_config(overrides={'estimator.pressure_inputs': 'differential'})
    compile_model(cfg)
    inputs = sensor_inputs(cfg)
    one, many = [], []
    for _ in range(3):
        one.append(per_message(cfg, inputs, args.rate_Hz, args.seconds))
        many.append(batched(cfg, inputs, args.batched_rate_Hz, args.block_ms, args.seconds))
    a, b = statistics.median(one), statistics.median(many)
    print(f'{len(inputs)} inputs, {args.seconds:g} s of data, three runs each, median:')
    print(f'  per-message at {args.rate_Hz:g} Hz ({len(inputs) * args.rate_Hz:.0f} samples/s): '
          f'{100 * a:.1f} % of one core ({", ".join(f"{100 * v:.1f}" for v in one)})')
    print(f'  batched at {args.batched_rate_Hz:g} Hz in {args.block_ms:g} ms blocks '
          f'({len(inputs) * args.batched_rate_Hz:.0f} samples/s): {100 * b:.1f} % '
          f'({", ".join(f"{100 * v:.1f}" for v in many)})')
    print(f'  ratio batched / per-message: {b / a:.2f}')


if __name__ == '__main__':
    main()
