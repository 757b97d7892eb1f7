"""
Where the live estimator's CPU goes above what rclpy costs: its session, part by part.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_session.py [--seconds 30]
     [--skip-s 15] [--budget-ms 2.0]

The estimator node's work on its four 1 kHz per-message inputs without DDS
(``bench_estimator.py`` measures the node with it): stage 6 signals as
sensor_msgs/FluidPressure bytes, decoded (:mod:`wet_eha_thermal.inputs`) and
taken by an :class:`~wet_eha_thermal.estimator.session.EstimatorSession` made
as the node makes it (the outlook in the background, ``--budget-ms`` of it
after each step), its outputs built into messages
(:mod:`wet_eha_thermal.messages`) and not sent. The samples are paced at real
time (stamped with the wall clock and taken as received at their stamps, a
sleep every 5 ms): the background's budget is wall time, and the limits, the
forecast and the uncertainty's copies are work per second of samples, so only
a paced run does what a live node does. After ``--skip-s`` (the first
limits, forecast and copies' period), the process CPU over ``--seconds`` of
samples is printed in % of one core, with the CPU of each part
(``time.process_time`` around the calls; a part inside another is in both)
and the time in the garbage collector.
"""

import argparse
import collections
import functools
import gc
import time

import numpy as np
from wet_eha_thermal import messages
from wet_eha_thermal.bag import cdr
from wet_eha_thermal.config import load_config
from wet_eha_thermal.estimator import core, outlook, uncertainty
from wet_eha_thermal.estimator.intake import sensor_inputs, sensor_signal
from wet_eha_thermal.estimator.session import EstimatorSession
from wet_eha_thermal.estimator.warmup import compile_estimator
from wet_eha_thermal.inputs import decoders, FLUID_PRESSURE, Inputs, InputSignal, SI_UNIT
from wet_eha_thermal.model.duty import stage_duty
from wet_eha_thermal.model.kinetics import KineticModel, ThermalFeedback
from wet_eha_thermal.model.oil import get_oil

#: (class, method, what it is), timed while measuring
PARTS = (
    (EstimatorSession, 'step', 'a step and all after it (the rest is per-message work)'),
    (core.Estimator, 'advance', 'the model steps with the intake around them'),
    (core.Estimator, '_step', 'the model steps'),
    (uncertainty.Propagation, 'record', "the copies' duty, recorded at each step"),
    (outlook.Outlook, 'tick', 'the limit ticks: the model saved'),
    (outlook.Outlook, 'record', "the forecast's duty window"),
    (core.Estimator, 'prepare', "the model's deferred re-discretisation"),
    (uncertainty.Propagation, 'work', "the uncertainty's copies"),
    (outlook.Outlook, '_work_on', "the drive's current limits"),
    (outlook.Outlook, '_forecast_step', 'the forecast'),
    (outlook.Outlook, '_margin_step', 'the continuous limit'),
)


class Meter:
    """CPU seconds and calls of the timed parts, counted while ``on``."""

    def __init__(self) -> None:
        self.on = False
        self.cpu = collections.Counter()
        self.calls = collections.Counter()
        self._gc_start = 0.0
        gc.callbacks.append(self._gc)

    def wrap(self, cls, name: str) -> None:
        """Replace ``cls.name`` by a timed call."""
        func = getattr(cls, name)
        label = f'{cls.__name__}.{name}'

        @functools.wraps(func)
        def timed(*args, **kwargs):
            if not self.on:
                return func(*args, **kwargs)
            start = time.process_time()
            try:
                return func(*args, **kwargs)
            finally:
                self.cpu[label] += time.process_time() - start
                self.calls[label] += 1
        setattr(cls, name, timed)

    def _gc(self, phase: str, info) -> None:
        if phase == 'start':
            self._gc_start = time.process_time()
        elif self.on:
            self.cpu['gc'] += time.process_time() - self._gc_start
            self.calls['gc'] += 1


def main() -> None:
    """Feed the session at real time and print its CPU by part."""
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument('--seconds', type=float, default=30.0)
    ap.add_argument('--skip-s', type=float, default=15.0)
    ap.add_argument('--budget-ms', type=float, default=2.0)
    args = ap.parse_args()
    cfg = load_config(overrides={'estimator.pressure_inputs': 'differential'})
    compile_estimator(cfg)
    inputs = sensor_inputs(cfg)
    n = int(round((args.seconds + args.skip_s) * 1000))
    t = np.arange(1, n + 1) * 1e-3
    kin = KineticModel(cfg, get_oil(cfg.fluid.grade))
    s = kin.sample(stage_duty(cfg, 6), t, ThermalFeedback.uniform())
    x = np.column_stack([sensor_signal(s, k) for k in inputs])
    decs = decoders(Inputs(**{k: InputSignal(topic=f'/eha/{k}', message_type=FLUID_PRESSURE,
                                             unit=SI_UNIT[k]) for k in inputs}), inputs)
    meter = Meter()
    for cls, name, _ in PARTS:
        meter.wrap(cls, name)
    built = messages.OutputMessages()

    def publish(out) -> None:
        start = time.process_time()
        built.build(out)
        if meter.on:
            meter.cpu['messages'] += time.process_time() - start
            meter.calls['messages'] += 1

    session = EstimatorSession(cfg, outlook='background', publish=publish,
                               budget_s=args.budget_ms * 1e-3)
    gc.collect()
    gc.freeze()                        # as the node does once its model is built
    t0 = time.time() + 0.05
    ns = ((t0 + t) * 1e9).astype(np.int64)
    msgs = [cdr.encode_stamped(ns, 'eha', np.column_stack([x[:, k], np.zeros(n)]))
            for k in range(len(inputs))]
    skip = int(round(args.skip_s * 1000))
    wall0 = time.perf_counter()
    for i in range(n):
        if i == skip:
            meter.on = True
            cpu0 = time.process_time()
        if i % 5 == 0:
            ahead = wall0 + i * 1e-3 - time.perf_counter()
            if ahead > 0.0:
                time.sleep(ahead)
        for dec, m in zip(decs, msgs):
            stamp_ns, values = dec.decode(m[i])
            for channel, value in zip(dec.channels, values):
                # received at its stamp: a starved run does the same work, only later
                session.take(channel, stamp_ns * 1e-9, value, stamp_ns * 1e-9)
    cpu = time.process_time() - cpu0
    print(f'{len(inputs)} inputs at 1 kHz, stage 6, {args.seconds:g} s of samples after '
          f'{args.skip_s:g} s, background budget {args.budget_ms:g} ms a step: '
          f'{100 * cpu / args.seconds:.1f} % of one core')
    what = {f'{cls.__name__}.{name}': text for cls, name, text in PARTS}
    what.update(messages='the estimates built into messages', gc='the garbage collector')
    for label, used in meter.cpu.most_common():
        print(f'  {label:<30} {100 * used / args.seconds:5.2f} %  {meter.calls[label]:6d} calls '
              f'{1e3 * used / meter.calls[label]:8.3f} ms each  {what[label]}')
    st = session.status()
    print(f'  limits published {st.limits_published} ({st.limits_fallback} fallback); '
          f'step {1e3 * meter.cpu["Estimator._step"] / max(meter.calls["Estimator._step"], 1):.2f}'
          f' ms; per-message work (all but the steps) '
          f'{100 * (cpu - meter.cpu["EstimatorSession.step"]) / args.seconds:.2f} %')


if __name__ == '__main__':
    main()
