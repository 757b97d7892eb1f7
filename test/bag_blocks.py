"""
The sample bag's topics, and its blocks read with and without prefetching compared.

Apart from test_bag, which imports rclpy: that starts threads, and a process
that runs threads never forks its reading process. A fresh process that
imports only this module forks it, as a command does.
"""

from pathlib import Path

import numpy as np
import pytest
from wet_eha_thermal.bag.reader import BagError, iter_column_blocks
from wet_eha_thermal.interface import FLOAT64, FLUID_PRESSURE, TEMPERATURE

SPECS = {'/f': FLOAT64, '/p': FLUID_PRESSURE, '/t': TEMPERATURE}


def blocks_and_state(blocks):
    """Return every block of ``blocks`` with the attributes seen after each, then at the end."""
    out = [(block, (blocks.message_count, blocks.truncated, blocks.problem)) for block in blocks]
    return out, (blocks.message_count, blocks.truncated, blocks.problem)


def assert_prefetched_blocks_are_the_same(path, tmp_path):
    """Read ``path`` and a cut copy with and without prefetching: the same blocks and state."""
    path, tmp_path = Path(path), Path(tmp_path)     # (strings from a fresh process)
    whole = path.read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(whole[:int(len(whole) * 0.6)])
    for source in (path, cut):
        progress = []
        direct, end = blocks_and_state(iter_column_blocks(source, SPECS, max_block_s=0.05))
        fetched = iter_column_blocks(source, SPECS, max_block_s=0.05, prefetch=True,
                                     on_progress=lambda done, size: progress.append(done))
        assert fetched.prefetch
        ahead, ahead_end = blocks_and_state(fetched)
        assert len(direct) > 3 and len(ahead) == len(direct) and ahead_end == end
        assert end[1] == (source == cut)
        for (a, state_a), (b, state_b) in zip(direct, ahead):
            assert state_a == state_b
            for topic in SPECS:
                assert np.array_equal(a[topic].log_time_ns, b[topic].log_time_ns)
                for name, values in a[topic].values.items():
                    assert np.array_equal(values, b[topic].values[name])
        # once per block, then at the end: never backwards, up to the file's size at most
        assert len(progress) == len(direct) + 1 and progress == sorted(progress)
        assert 0 < progress[-1] <= source.stat().st_size
    # an error in the reading process is raised in the caller, as without prefetching
    with pytest.raises(BagError, match='expected sensor_msgs/msg/Temperature'):
        list(iter_column_blocks(path, {'/p': TEMPERATURE}, prefetch=True))
