"""Every YAML file shipped under config/ and docs/ loads with today's code (so none can rot)."""

from pathlib import Path

import pytest
from wet_eha_thermal.config import load_config
from wet_eha_thermal.inputs import load_inputs
import yaml

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted(p for folder in ('config', 'docs') for p in (ROOT / folder).rglob('*.y*ml'))


def _load(path: Path) -> None:
    """Load ``path`` as what it is: node parameters, inputs, or a thermal configuration."""
    data = yaml.safe_load(path.read_text())
    params = (data.get('/**') or {}).get('ros__parameters')
    if params is not None:
        # a node's parameters: the files they name load (relative names from config/)
        if params.get('config_file'):
            load_config(ROOT / 'config' / params['config_file'])
        load_inputs(params.get('inputs_file') or None)
    elif path.name.endswith('.inputs.yaml'):
        load_inputs(str(path))
    else:
        load_config(path)


def test_the_shipped_files_are_found():
    names = {p.relative_to(ROOT).as_posix() for p in SHIPPED}
    assert {'config/reference_eha.yaml', 'docs/calibration-truth/calibrated.yaml',
            'config/ros2_control_rig.inputs.yaml', 'config/estimator.params.yaml'} <= names


@pytest.mark.parametrize('path', SHIPPED, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_shipped_yaml_loads(path):
    _load(path)
