"""Code style check of the whole package with ament's flake8 configuration."""

import os
from pathlib import Path

from ament_flake8.main import main_with_errors
import pytest

PACKAGE_ROOT = Path(__file__).resolve().parents[1]

# Output of a colcon build in the package root, and of the tools.
NOT_OURS = ['build', 'install', 'log', 'out']


@pytest.mark.flake8
@pytest.mark.linter
@pytest.mark.slow     # the whole package, minutes on a busy machine
def test_flake8(monkeypatch):
    # ament_flake8 checks the current directory; make that the package root
    # whatever directory pytest was started from.
    monkeypatch.chdir(PACKAGE_ROOT)
    rc, errors = main_with_errors(argv=[os.curdir, '--exclude', *NOT_OURS])
    assert rc == 0, (
        'Found %d code style errors / warnings:\n' % len(errors) + '\n'.join(errors))
