"""
Offline replay of recorded runs through the estimator: no ROS graph, sample time, full speed.

A bag (rosbag2-style MCAP: ours, or ``ros2 bag record -s mcap`` with the same
message types) is read in blocks of decoded columns
(:func:`~wet_eha_thermal.bag.reader.iter_column_blocks`), so memory stays flat
however long the log. By job:

- :mod:`.plan`: the configuration and which topic feeds which input
  (:func:`plan_replay`, :class:`ReplayOptions`);
- :mod:`.run`: the blocks through an estimator session, as the live node's
  (:func:`replay`, :class:`ReplayResult`);
- :mod:`.outputs`: ``estimates.csv`` and ``estimates.mcap`` at ``output_rate_Hz``
  (the MCAP the live node's messages), ``limits.csv`` (one row per tick);
- :mod:`.report`: the plots and ``report.md`` (:func:`write_report`).

Outputs go to one folder, each written under a ``.partial`` name and renamed
when complete.
"""

from .outputs import write_csv, write_limits_csv, write_mcap, write_outputs
from .plan import (BagError, choose_config, parse_mapping, plan_replay, ReplayError,
                   ReplayOptions, ReplayPlan, Samples)
from .report import error_stats, PLOTTED_ESTIMATES, thermocouple_errors, write_report
from .run import OUTPUT_ESTIMATES, replay, ReplayResult

__all__ = ['BagError', 'choose_config', 'error_stats', 'OUTPUT_ESTIMATES', 'parse_mapping',
           'plan_replay', 'PLOTTED_ESTIMATES', 'replay', 'ReplayError', 'ReplayOptions',
           'ReplayPlan', 'ReplayResult', 'Samples', 'thermocouple_errors', 'write_csv',
           'write_limits_csv', 'write_mcap', 'write_outputs', 'write_report']
