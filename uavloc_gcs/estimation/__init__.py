"""Localization of phones from RSSI slots: pure functions over numpy (SPEC §2.2, §3.1-3.2).

- :class:`ChannelModel` -- the calibrated log-distance channel;
- :func:`estimate_emitter` / :func:`estimate_all` -- MAP position + velocity with honest radii;
- :class:`Estimate` (with ``predict``) and :class:`Candidate` (the mirror image);
- :func:`access_radius_m` -- how far off a follow-up pass may go and still meet the accuracy;
- :func:`crb_position_rmse_m` -- the (Bayesian) Cramer-Rao bound used by the benchmark.
"""

from .estimate import Candidate, Estimate, estimate_all, estimate_emitter
from .model import ChannelModel, airborne_slots, radius_of_probability

__all__ = ["ChannelModel", "Candidate", "Estimate", "estimate_emitter", "estimate_all", "radius_of_probability",
           "airborne_slots"]

from .access import access_radius_m  # noqa: E402  (needs Estimate)
from .crb import data_information, position_rmse_bound_m, prior_information  # noqa: E402

from .evidence import Silence, silence_from_track  # noqa: E402

__all__ += ["Silence", "silence_from_track", "access_radius_m", "data_information", "prior_information", "position_rmse_bound_m"]
