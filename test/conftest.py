"""Fixtures shared by the tests."""

import pytest
import rclpy
from rclpy.context import Context
from wet_eha_thermal.config import load_config
from wet_eha_thermal.simulation import compile_model


@pytest.fixture(scope='session', autouse=True)
def compiled_model():
    """
    Compile the model's kernels into numba's cache before the first test.

    On a fresh clone the first model step compiles for about half a minute;
    a test that gives a node or a subprocess a few seconds to start would
    otherwise time out on that alone.
    """
    compile_model(load_config())


@pytest.fixture(scope='module')
def context(request):
    """Return an rclpy context on the test module's own ROS domain (its ``DOMAIN_ID``)."""
    ctx = Context()
    rclpy.init(context=ctx, domain_id=request.module.DOMAIN_ID)
    yield ctx
    rclpy.try_shutdown(context=ctx)
