"""Software-in-the-loop world and fake vehicles for tests, demos and experiments.

``sim_link`` may import the uavloc core; the core never imports ``sim_link``.
"""
