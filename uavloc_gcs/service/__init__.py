"""The ground-control service: the store, the daemon's orchestration, the live view, the results.

Layering: the service sits on top of the link layer, the estimator/planner (search policy) and
the file formats; only the CLI starts it. It never imports the simulator.
"""
