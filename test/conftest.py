"""Fixtures shared by the tests."""

import os
from pathlib import Path
import subprocess

import pytest
import rclpy
from rclpy.context import Context
from wet_eha_thermal import interface
from wet_eha_thermal.config import default_config_path, load_config
from wet_eha_thermal.model.duty import stage_duty
from wet_eha_thermal.model.warmup import compile_model
from wet_eha_thermal.offline.simulated_rig import SimulatedRig, write_rig_bag
import yaml


# These start ROS nodes that find each other by discovery, and time them. One xdist worker
# runs them one after another, as a serial run does: never two at once on the cores' slack.
# Each has a domain of its own (test/ros_domains.py).
ROS_GRAPH_MODULES = ('test_estimator_node.py', 'test_live.py', 'test_player.py',
                     'test_recorder.py', 'test_sim_rig_limit.py', 'test_namespaces.py',
                     'test_managed_estimator.py')


class ModuleScopes:
    """pytest-xdist's scheduler hook, registered only when xdist runs (``-p no:xdist`` works)."""

    @staticmethod
    def pytest_xdist_make_scheduler(config, log):
        """Send a test module whole to one worker (module fixtures run once), ROS ones together."""
        from xdist.scheduler import LoadScopeScheduling

        class ModuleScheduling(LoadScopeScheduling):
            def _split_scope(self, nodeid):
                module = nodeid.split('::', 1)[0]
                return 'ros graph' if Path(module).name in ROS_GRAPH_MODULES else module

        return ModuleScheduling(config, log)


def pytest_configure(config):
    """Register the xdist scheduler hook when xdist is loaded."""
    if config.pluginmanager.hasplugin('xdist'):
        config.pluginmanager.register(ModuleScopes())


def pytest_collection_modifyitems(config, items):
    """Mark the tests of the ROS graph modules ``ros`` (one list: ROS_GRAPH_MODULES)."""
    for item in items:
        if item.path.name in ROS_GRAPH_MODULES:
            item.add_marker(pytest.mark.ros)


@pytest.fixture(scope='session', autouse=True)
def compiled_model():
    """
    Compile the model's kernels into numba's cache before the first test.

    On a fresh clone the first model step compiles for about half a minute;
    a test that gives a node or a subprocess a few seconds to start would
    otherwise time out on that alone.
    """
    compile_model(load_config())


@pytest.fixture(scope='session')
def cfg():
    """
    Return the reference configuration (frozen: the tests share one), copies once a minute.

    The uncertainty's copies step over each ``uncertainty.copy_period_s``;
    tests drive estimators in long steps through long silences, where 31
    copies every 10 s of sample time cost several times the model (a live
    node at 0.02 s steps spends a fifth of its time on them). The sigma's
    own tests (test_uncertainty.py) and the nodes run the shipped 10 s.
    """
    return load_config(overrides={'uncertainty.copy_period_s': 60.0})


@pytest.fixture(scope='module', autouse=True)
def ros_domain_env(request):
    """
    Set ``ROS_DOMAIN_ID`` to the module's ``DOMAIN_ID`` while a ROS module runs.

    Its subprocesses and the nodes its code starts without a context then
    join its domain; at import a module would set it for all the others.
    """
    domain = getattr(request.module, 'DOMAIN_ID', None)
    if domain is None:
        yield
        return
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv('ROS_DOMAIN_ID', str(domain))
        yield


@pytest.fixture(scope='module')
def context(request):
    """Return an rclpy context on the test module's own ROS domain (its ``DOMAIN_ID``)."""
    ctx = Context()
    rclpy.init(context=ctx, domain_id=request.module.DOMAIN_ID)
    yield ctx
    rclpy.try_shutdown(context=ctx)


@pytest.fixture(scope='session')
def record_rig_log():
    """
    Return ``record(path, seconds, stage=6, seed=1, rig_cfg=None, **rig)``: a simulated-rig log.

    The log holds the topics the recorder writes (one differential pressure)
    and stores the reference configuration with ``pressure_inputs:
    differential``. The rig runs on ``rig_cfg`` (default: that
    configuration), with the :class:`SimulatedRig` options ``rig``.
    """
    data = yaml.safe_load(default_config_path().read_text())
    data['estimator']['pressure_inputs'] = 'differential'
    meta = {interface.CONFIG_METADATA: {interface.CONFIG_METADATA_KEY: yaml.safe_dump(data)}}
    nominal = load_config(overrides={'estimator.pressure_inputs': 'differential'})

    def record(path, seconds, stage=6, seed=1, rig_cfg=None, **rig):
        cfg = rig_cfg or nominal
        write_rig_bag(path, SimulatedRig(cfg, stage_duty(cfg, stage), seed=seed, **rig),
                      seconds, metadata=meta)
        return path
    return record


@pytest.fixture
def small_fs(tmp_path):
    """Mount a 3 MiB tmpfs (root only); unmount it afterwards: a disk that fills up for real."""
    if os.geteuid() != 0:
        pytest.skip('mounting a tmpfs needs root')
    mount = tmp_path / 'small'
    mount.mkdir()
    done = subprocess.run(['mount', '-t', 'tmpfs', '-o', 'size=3m', 'tmpfs', str(mount)],
                          capture_output=True, text=True)
    if done.returncode:
        pytest.skip(f'mount -t tmpfs failed: {done.stderr.strip()}')
    try:
        yield mount
    finally:
        subprocess.run(['umount', '--lazy', str(mount)], check=True)  # even with a file open
