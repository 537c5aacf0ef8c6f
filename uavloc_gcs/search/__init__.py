"""The adaptive search loop's decisions: who is located, when to replan, where to look next.

Pure (no sockets, files or clocks): the daemon and the experiment harness drive the same
:class:`SearchPolicy` with slots and times they supply.
"""

from .policy import PersonStatus, SearchPlan, SearchPolicy, VehicleTask

__all__ = ["PersonStatus", "SearchPlan", "SearchPolicy", "VehicleTask"]
