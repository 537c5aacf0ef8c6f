"""uavloc ground-control service: localize people from phone RSSI heard by a UAV fleet.

Layering (dependencies point down only):
    cli                      -- argument parsing, printing, exit codes (the only place errors are formatted)
    service                  -- daemon, store, orchestration
    link                     -- MAVLink transports and protocol exchanges
    estimation, planning     -- pure numerical code
    scenario, geo, energy    -- the shared world model and its configuration
The core never imports ``sim_link`` (the simulator); only CLI commands that run simulations do, lazily.
"""

__version__ = "0.1.0"
