"""Fixtures shared by the rclpy tests."""

import pytest
import rclpy
from rclpy.context import Context


@pytest.fixture(scope='module')
def context(request):
    """Return an rclpy context on the test module's own ROS domain (its ``DOMAIN_ID``)."""
    ctx = Context()
    rclpy.init(context=ctx, domain_id=request.module.DOMAIN_ID)
    yield ctx
    rclpy.try_shutdown(context=ctx)
