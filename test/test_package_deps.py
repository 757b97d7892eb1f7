"""
The package's dependencies are declared where each kind of install looks for them.

Every module the package and its launch file import is the standard
library's, the package's own, a rosdep key in package.xml (an apt-installed
ROS 2 Jazzy: rosdep install), or in requirements-no-ros.txt (what rosdep
lacks, pip-installed beside /opt/ros); and requirements.txt, the venv path,
takes that file in whole plus the PyPI ROS wheels, which the no-ROS file
never names.
"""

import ast
from pathlib import Path
import re
import sys
import xml.etree.ElementTree as ET

ROOT = Path(__file__).resolve().parents[1]
#: import name -> rosdep key, where they differ from each other
ROSDEP_KEY = {'numpy': 'python3-numpy', 'scipy': 'python3-scipy', 'yaml': 'python3-yaml',
              'matplotlib': 'python3-matplotlib', 'zstandard': 'python3-zstandard',
              'lz4': 'python3-lz4'}
#: import name -> pip name, of what rosdep has no key for
PIP_NAME = {'mcap': 'mcap', 'mcap_ros2': 'mcap-ros2-support', 'numba': 'numba',
            'dask': 'dask', 'distributed': 'dask', 'foxglove': 'foxglove-sdk',
            'skfem': 'scikit-fem'}


def imported(paths):
    """Return the top-level names of every module imported by the files ``paths``."""
    names = set()
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names.update(a.name.split('.')[0] for a in node.names)
            elif isinstance(node, ast.ImportFrom) and not node.level:
                names.add(node.module.split('.')[0])
    return names - set(sys.stdlib_module_names) - {'wet_eha_thermal'}


def pip_names(path):
    """Return the distribution names a requirements file lists (its -r lines aside)."""
    out = set()
    for line in path.read_text().splitlines():
        line = line.split('#')[0].strip()
        if line and not line.startswith('-'):
            out.add(re.split(r'[\[<>=~!; ]', line)[0].lower())
    return out


def test_every_import_has_a_rosdep_key_or_a_pip_line():
    keys = {e.text for e in ET.parse(ROOT / 'package.xml').getroot()
            if e.tag in ('exec_depend', 'depend')}
    no_ros = pip_names(ROOT / 'requirements-no-ros.txt')
    code = list((ROOT / 'wet_eha_thermal').rglob('*.py')) + list((ROOT / 'launch').glob('*.py'))
    missing = []
    for name in sorted(imported(code)):
        if name in PIP_NAME:
            if PIP_NAME[name] not in no_ros:
                missing.append(f'{name}: {PIP_NAME[name]} not in requirements-no-ros.txt')
        elif ROSDEP_KEY.get(name, name) not in keys:
            missing.append(f'{name}: no <exec_depend>{ROSDEP_KEY.get(name, name)}'
                           '</exec_depend> in package.xml')
    assert not missing, missing


def test_the_venv_file_takes_the_no_ros_file_and_only_it_has_no_ros_wheels():
    text = (ROOT / 'requirements.txt').read_text()
    assert '-r requirements-no-ros.txt' in text.splitlines()
    assert not any(n.startswith('ros-') for n in pip_names(ROOT / 'requirements-no-ros.txt'))
    assert any(n.startswith('ros-jazzy-rclpy') for n in pip_names(ROOT / 'requirements.txt'))
    # nothing listed twice with two different pins
    assert not pip_names(ROOT / 'requirements.txt') & pip_names(ROOT / 'requirements-no-ros.txt')
