"""Code style check of the whole package with ament's flake8 configuration."""

from pathlib import Path
import subprocess
import sys

import pytest

PACKAGE_ROOT = Path(__file__).resolve().parents[1]

# Output of a colcon build in the package root, and of the tools.
NOT_OURS = ['build', 'install', 'log', 'out']


@pytest.mark.flake8
@pytest.mark.linter
@pytest.mark.slow     # the whole package, minutes on a busy machine
def test_flake8():
    # In a process of its own: flake8 forks its workers, and a test process runs threads
    # (DDS, pytest's watchdog) that a fork would copy in whatever state they are (a run
    # in-process, after the ROS tests, once hung with its workers idle). ament_flake8 checks
    # the current directory: the package root, whatever directory pytest was started from.
    done = subprocess.run([sys.executable, '-m', 'ament_flake8.main', '--exclude', *NOT_OURS],
                          cwd=PACKAGE_ROOT, capture_output=True, text=True)
    assert done.returncode == 0, f'code style errors / warnings:\n{done.stdout}{done.stderr}'
