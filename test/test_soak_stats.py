"""
The soak benchmark's figures: the slope and its standard error, live's output parsed, /proc read.

``benchmarks/soak_live.py`` itself runs the live twin for minutes: it is not
tested here, only the functions it takes its figures from.
"""

import doctest
import os
from pathlib import Path
import sys
import time

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'benchmarks'))
import numpy as np  # noqa: E402
import procfs  # noqa: E402 (the benchmark's helpers)
import pytest  # noqa: E402
import soak_stats  # noqa: E402
from soak_stats import linear_fit, parse_status_line, parse_summary  # noqa: E402

# the end of a 60 s `live` run on the shared machine (2026-11-26), as it printed it
SUMMARY = """\
t  60.0/60 s | winding hot-spot   21.9 mean   21.8 | magnet   27.3 | oil   28.8 degC | margin \
19.5 A | limit: beyond horizon | alerts OK | stale: none

Live twin summary
  run             60.0 s of duty after 6.0 s of start-up (duration reached); stage 6 on the \
simulated rig at 1000 Hz, noise on, ROS domain 114
  estimates       2902 received, 48.5 per s over 59.9 s (60.0 s of sample time)
  peak estimates  winding hotspot 21.9, winding mean 21.8, magnet 27.3, oil 29.6 degC
  at the end      winding hotspot 21.9, winding mean 21.8, magnet 27.3, oil 28.8 degC (1 sigma \
0.5 K)
  margin, limits  margin current 19.5 A RMS; time to limit: beyond horizon
  alerts raised   0
  stale events    6 (during the duty): current_A 1, speed_rad_s 1, p_a_Pa 1, p_b_Pa 1, \
p_acc_Pa 1, position_m 1; inputs on fallback at the end: none
  samples         the rig published 59141 per input; the estimator received 58322 of them on \
its worst input (98.62 %), rejected 13111
  rig             exited cleanly (exit status 0)
  estimator       exited cleanly (exit status 0)
  recorder        did not exit cleanly (killed by SIGKILL; sent SIGINT, SIGTERM, SIGKILL)
  rig figures     60.8 s, 59141 samples x 6 topics (931 skipped), tick interval p50/p99/max \
1.000/3.262/201.7 ms, CPU 36.0 % of a core
  recording       /tmp/soak: a/bag: 396857 messages on 31 topics, 14.0 MiB
"""


def test_the_module_examples_run():
    assert doctest.testmod(soak_stats).failed == 0


def test_fit_agrees_with_numpy_polyfit_and_its_covariance():
    # an independent least squares: numpy's polyfit scales its covariance by SSR / (n - 2)
    rng = np.random.default_rng(1)
    t = np.sort(rng.uniform(0.0, 3600.0, 40))
    y = 300.0 + 2e-3 * t + rng.normal(0.0, 0.5, t.size)
    fit = linear_fit(t, y)
    (slope, intercept), cov = np.polyfit(t, y, 1, cov=True)
    assert fit.slope == pytest.approx(slope, rel=1e-9)
    assert fit.intercept == pytest.approx(intercept, rel=1e-9)
    assert fit.stderr == pytest.approx(np.sqrt(cov[0, 0]), rel=1e-9)
    assert fit.n == 40


def test_standard_error_is_the_spread_of_slopes_over_repeated_noise():
    # 2000 series with independent noise of 1 MB on a 13 MB/h line, sampled every 5 s for an
    # hour: the slopes' spread must match the mean standard error (the spread of 2000 slopes
    # is known to about 1.6 %, 1/sqrt(2 * 2000); 6 % is four times that) and centre on 13
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 3600.0, 5.0)
    truth = 13.0 / 3600.0
    fits = [linear_fit(t, 100.0 + truth * t + rng.normal(0.0, 1.0, t.size)) for _ in range(2000)]
    slopes = np.array([f.slope for f in fits])
    mean_se = np.mean([f.stderr for f in fits])
    assert np.std(slopes, ddof=1) == pytest.approx(mean_se, rel=0.06)
    assert abs(slopes.mean() - truth) < 4.0 * mean_se / np.sqrt(len(fits))
    # and the textbook value, sigma / sqrt(Sxx), for sigma = 1
    assert mean_se == pytest.approx(1.0 / np.sqrt(np.sum((t - t.mean()) ** 2)), rel=0.01)


def test_fit_of_too_few_points():
    assert np.isnan(linear_fit([], []).slope)
    assert np.isnan(linear_fit([1.0], [2.0]).slope)
    assert np.isnan(linear_fit([1.0, 1.0, 1.0], [2.0, 3.0, 4.0]).slope)
    two = linear_fit([0.0, 2.0], [1.0, 5.0])
    assert two.slope == 2.0 and np.isnan(two.stderr)


def test_summary_parsed():
    s = parse_summary(SUMMARY)
    assert (s['duty_s'], s['start_s'], s['stopped_by']) == (60.0, 6.0, 'duration reached')
    assert (s['estimates'], s['estimate_rate_Hz'], s['alerts_raised']) == (2902, 48.5, 0)
    assert (s['published'], s['received'], s['lost'], s['rejected']) == (
        59141, 58322, 59141 - 58322, 13111)
    assert s['stale_events'] == 6 and s['stale_since'] == 'during the duty'
    assert s['stale_per_input'] == dict.fromkeys(
        ('current_A', 'speed_rad_s', 'p_a_Pa', 'p_b_Pa', 'p_acc_Pa', 'position_m'), 1)
    assert s['fallback_at_end'] == 'none'
    assert (s['recording'], s['recording_messages'], s['recording_topics'],
            s['recording_MiB']) == ('/tmp/soak: a/bag', 396857, 31, 14.0)
    assert s['exits'] == {'rig': 'exited cleanly (exit status 0)',
                          'estimator': 'exited cleanly (exit status 0)',
                          'recorder': 'did not exit cleanly (killed by SIGKILL; sent SIGINT, '
                                      'SIGTERM, SIGKILL)'}


def test_summary_without_stale_inputs_or_counts():
    text = ('Live twin summary\n'
            '  stale events    0 (at the last diagnostics); inputs on fallback at the end: '
            'current_A\n'
            '  samples         the estimator had received 1000 per input at its last '
            'diagnostics\n')
    s = parse_summary(text)
    assert (s['stale_events'], s['stale_per_input'], s['fallback_at_end']) == (0, {}, 'current_A')
    assert 'published' not in s and 'lost' not in s
    assert parse_summary('live died before its summary\n') == {}


def test_status_lines():
    assert parse_status_line(SUMMARY.splitlines()[0]) == {
        't_s': 60.0, 'hotspot_C': 21.9, 'stale': 'none'}
    assert parse_status_line('t   0.1/60 s | waiting for the first estimate ...') == {'t_s': 0.1}
    assert parse_status_line('start-up   5.8 s | waiting for eha_thermal_estimator') is None
    assert parse_status_line('  rig truth       winding hotspot 21.9 (-0.0)') is None
    line = ('t 125.0/3600 s | winding hot-spot    --- mean    --- | magnet    --- | oil    --- '
            'degC | margin pending | limit: pending | alerts OK | stale: current_A, speed_rad_s')
    assert parse_status_line(line) == {'t_s': 125.0, 'stale': 'current_A, speed_rad_s'}
    line += ' | REC ERROR: writing suspended since 09:13:51 (No space left on device)'
    assert parse_status_line(line) == {'t_s': 125.0, 'stale': 'current_A, speed_rad_s',
                                       'recorder': 'ERROR'}


def _fake_process(root: Path, pid: int, ppid: int, name: str, cmd: str, rss_kB: int,
                  utime: int, stime: int, start: int, cutime: int = 0) -> None:
    d = root / str(pid)
    d.mkdir()
    # fields 3.. of proc(5): state ppid pgrp session tty tpgid flags minflt cminflt majflt
    # cmajflt utime stime cutime cstime priority nice threads itrealvalue starttime vsize
    rest = ['S', ppid, pid, pid, 0, -1, 0, 0, 0, 0, 0, utime, stime, cutime, 0, 20, 0, 1, 0,
            start, 1000]
    (d / 'stat').write_text(f'{pid} ({name}) ' + ' '.join(map(str, rest)) + '\n')
    (d / 'status').write_text(f'Name:\t{name}\nVmPeak:\t  9 kB\nVmRSS:\t {rss_kB} kB\n')
    (d / 'cmdline').write_bytes(cmd.replace(' ', '\0').encode() + b'\0')


def test_proc_fields_of_a_fake_tree(tmp_path):
    tick = os.sysconf('SC_CLK_TCK')
    # a command name with spaces and parentheses, as a thread's name may be
    _fake_process(tmp_path, 10, 1, 'python3 (live) x', 'python -m wet_eha_thermal.cli live',
                  1000, 3 * tick, tick, 500, cutime=2 * tick)
    _fake_process(tmp_path, 11, 10, 'python3', 'python -m wet_eha_thermal.ros.sim_rig_node '
                  '--ros-args', 2048, tick, 0, 600)
    _fake_process(tmp_path, 12, 10, 'python3', 'python -m wet_eha_thermal.ros.recorder_node',
                  10, 0, 0, 601)
    _fake_process(tmp_path, 13, 99, 'python3', 'python -m wet_eha_thermal.ros.estimator_node',
                  10, 0, 0, 602)        # another session's estimator: not live's child
    _fake_process(tmp_path, 14, 11, 'python3', 'python -c fork server', 10, 5 * tick, 0, 603)
    (tmp_path / 'self').mkdir()
    # cpu user nice system idle iowait irq softirq steal guest guest_nice
    (tmp_path / 'stat').write_text(f'cpu  {50 * tick} {tick} {9 * tick} 7000 30 {tick} {tick} '
                                   f'{3 * tick} {20 * tick} 0\ncpu0 1 2 3 4 5 6 7 8 9 10\n')
    assert procfs.machine_cpu_seconds(tmp_path) == pytest.approx((62.0, 3.0))
    assert procfs.cpu_seconds(10, tmp_path) == pytest.approx(4.0)
    # its own 4 s, its ended children's 2, its child's 1 and grandchild's 5; not 13's
    assert procfs.tree_cpu_seconds(10, tmp_path) == pytest.approx(12.0)
    assert procfs.tree_cpu_seconds(11, tmp_path) == pytest.approx(6.0)
    assert procfs.rss_bytes(11, tmp_path) == 2048 * 1024
    assert procfs.start_ticks(11, tmp_path) == 600
    assert sorted(procfs.children(10, tmp_path)) == [11, 12]
    names = {'rig': 'sim_rig_node', 'estimator': 'estimator_node', 'recorder': 'recorder_node'}
    assert procfs.children_by_command(10, names, tmp_path) == {'rig': 11, 'recorder': 12}
    assert procfs.same_process(11, 600, tmp_path)
    assert not procfs.same_process(11, 599, tmp_path)       # the pid was reused
    assert not procfs.same_process(15, 600, tmp_path)       # ended


def test_cpu_time_of_this_process_is_what_python_counts():
    # the kernel's ticks against Python's own clock of this process's CPU
    end = time.process_time() + 0.3
    while time.process_time() < end:
        pass
    assert procfs.cpu_seconds(os.getpid()) == pytest.approx(time.process_time(), abs=0.05)
    assert procfs.rss_bytes(os.getpid()) > 10 * 2 ** 20
