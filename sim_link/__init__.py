"""Software-in-the-loop world and fake vehicles for tests, demos and experiments.

Three parts, one per job:

* :mod:`sim_link.vehicles` -- fake autopilots (ArduPilot-like and PX4-like vehicles speaking
  MAVLink 2 over UDP, a fleet of them, link fault injection) and the companion-computer emulator
  that attaches to a real autopilot;
* :mod:`sim_link.world` -- the simulated world: people walking in the search area and the radio
  channel between their phones and the vehicles;
* :mod:`sim_link.experiments` -- the experiment harness: fast in-process missions, the paper's
  comparison and its RL baseline.

``sim_link`` may import the uavloc core; the core never imports ``sim_link``.
"""
