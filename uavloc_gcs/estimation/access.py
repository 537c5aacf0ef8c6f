"""The planner's "edge access" radius (SPEC §2.3): how far from a person's predicted position a
straight pass may go and still bring the calibrated 95 % radius below the required accuracy.

For each horizontal offset rho (closest approach of the pass to the predicted position) and each
of ``headings`` pass directions, the Fisher information of the pass (slots every ``speed x slot_s``
metres along the chord inside the communication range, the person moving at the estimated
velocity) is added to the current information at the pass time, deflated by the estimate's
``inflation`` like the data were. The answer is the largest rho at which the requirement holds
for *every* heading (the heading of the follow-up pass is not known when the disk is planned).
Smaller offsets are not always better: right under the track the lateral position is
unobservable to first order, so the planner should aim for the disk's edge, as the paper's
"edge access" does. The 95 % radius is bounded by the isotropic circle of the largest
eigenvalue (conservative).
"""

from __future__ import annotations

import math

import numpy as np

from .estimate import Estimate
from .maneuver import state_noise
from .model import ChannelModel

CHORD_POINTS = 48
K95 = math.sqrt(-2.0 * math.log(0.05))  # 2.4477: isotropic 2-D 95 % circle in sigmas
REACH_WHOLE_CIRCLE = True  # the pass comes within range of the whole predicted 95 % circle (below)


def access_radius_m(
    estimate: Estimate,
    *,
    t_pass_s: float,
    altitude_m: float,
    speed_m_s: float,
    channel: ChannelModel,
    required_accuracy_m: float,
    comm_range_m: float,
    slot_s: float = 0.025,
    samples_per_slot: int = 10,
    headings: int = 8,
    offsets: int = 24,
) -> float:
    """Largest pass offset [m] guaranteeing radius95 <= required_accuracy_m; 0.0 if none does."""
    if not estimate.ok or comm_range_m <= altitude_m:
        return 0.0
    reach = math.sqrt(comm_range_m**2 - altitude_m**2)
    p, _ = estimate.predict(t_pass_s)
    v = estimate.velocity_m_s if estimate.model_motion else np.zeros(2)
    moving = estimate.model_motion
    dt = t_pass_s - estimate.t_ref_s
    a = np.eye(4)
    a[0, 2] = a[1, 3] = dt
    cov = a @ estimate.covariance @ a.T + state_noise(estimate.process_noise_m2_s3, dt) if moving \
        else estimate.covariance
    cov = cov if moving else cov[:2, :2] + np.eye(2) * (estimate.max_speed_m_s * abs(dt) / K95) ** 2
    cov = 0.5 * (cov + cov.T)
    info_now = np.linalg.pinv(cov, rcond=1e-12)

    rho = np.linspace(0.0, reach * 0.98, offsets)  # (O,)
    psi = np.linspace(0.0, 2.0 * np.pi, headings, endpoint=False)  # (H,)
    half = np.sqrt(np.maximum(reach**2 - rho**2, 0.0))  # chord half-length (O,)
    frac = np.linspace(-1.0, 1.0, CHORD_POINTS)
    along = half[:, None] * frac[None, :]  # (O, M)
    u = np.stack([np.cos(psi), np.sin(psi)], axis=1)  # (H, 2) heading
    n = np.stack([-np.sin(psi), np.cos(psi)], axis=1)  # (H, 2) left normal
    tau = along / speed_m_s  # (O, M) time from closest approach
    # vehicle ground point relative to the predicted person position at the pass time
    veh = rho[:, None, None, None] * n[None, :, None, :] + along[:, None, :, None] * u[None, :, None, :]
    person = tau[:, None, :, None] * v[None, None, None, :]
    g = person - veh  # (O, H, M, 2)
    d2 = np.sum(g * g, axis=-1) + altitude_m**2
    slots_per_point = np.maximum(2.0 * half / (speed_m_s * slot_s), 1.0) / CHORD_POINTS  # (O,)
    w = samples_per_slot / channel.log_range_sigma**2 * slots_per_point[:, None, None] / estimate.inflation
    grad = g / d2[..., None]  # d ln d / d p
    if moving:
        grad = np.concatenate([grad, tau[:, None, :, None] * grad], axis=-1)  # (O, H, M, 4)
    info = np.einsum("ohm,ohmi,ohmj->ohij", np.broadcast_to(w, d2.shape), grad, grad) + info_now
    post = np.linalg.inv(info)[..., :2, :2]
    lam_max = np.linalg.eigvalsh(post)[..., -1]
    r95 = K95 * np.sqrt(np.maximum(lam_max, 0.0))  # (O, H)
    ok = np.all(r95 <= required_accuracy_m, axis=1)
    if REACH_WHOLE_CIRCLE:
        # The Fisher information above assumes the person is where predicted. A pass must also
        # hear them anywhere in the predicted 95 % circle, or a pass at the edge of the range
        # (where a little information suffices) flies out of hearing of a person a few metres off:
        # measured in `uavloc bench looks` (SITL sparse scan), a static person fitted with
        # 0.28 m/s was looked at from 107 m of the prediction, 124 m of the truth, twice, unheard.
        r_pred = K95 * math.sqrt(max(float(np.linalg.eigvalsh(cov[:2, :2])[-1]), 0.0))
        ok &= rho <= reach * 0.98 - r_pred
    return float(rho[ok].max()) if ok.any() else 0.0
