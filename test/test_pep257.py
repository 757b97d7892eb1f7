"""Docstring style check of the whole package with ament's pep257 convention."""

from pathlib import Path

from ament_pep257.main import main
import pytest

PACKAGE_ROOT = Path(__file__).resolve().parents[1]

# Output of a colcon build in the package root, and of the tools.
NOT_OURS = ['build', 'install', 'log', 'out']


@pytest.mark.linter
@pytest.mark.pep257
@pytest.mark.slow     # the whole package, minutes on a busy machine
def test_pep257(monkeypatch):
    # ament_pep257 resolves its paths against the current directory; make
    # that the package root whatever directory pytest was started from.
    monkeypatch.chdir(PACKAGE_ROOT)
    rc = main(argv=['.', 'test', '--exclude', *NOT_OURS])
    assert rc == 0, 'Found docstring style errors / warnings (listed on stderr above)'
