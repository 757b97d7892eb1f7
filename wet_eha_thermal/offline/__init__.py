"""
The offline tools: replay, campaigns, duty-cycle simulation, its report, the simulated rig, maps.

They run without a ROS graph, in sample time. They may import the estimator, the model,
``bag``, ``config`` and ``interface``; never ``ros``. One tool imports another only where a
comment at the import says why.
"""
