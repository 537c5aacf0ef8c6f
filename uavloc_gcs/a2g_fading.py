"""Small-scale fading of one frame in dB, exactly (for :mod:`uavloc_gcs.a2g`).

A frame's power is the local mean times |h|^2 with E|h|^2 = 1: Rician with K factor ``K`` on a line
of sight (|h|^2 (K + 1) 2 is non-central chi-square with 2 degrees of freedom and non-centrality
2K), Rayleigh when blocked (|h|^2 exponential). In dB, F = 10 log10 |h|^2 has a skewed law: a long
tail of deep fades below, a short one above (Rayleigh: P(F > u) = exp(-10^(u/10))). A Gaussian in
dB with the same mean and spread would put too much weight on upward fades and make frames at the
hearing edge too easy to hear (a blocked 10-frame burst: about +20 % range), so the world draws the
exact law and the model integrates it: :class:`FadingLaw` tabulates, on a 0.01 dB grid, the
survival function and the log-density of the mean of n = 1..:data:`MEAN_N_MAX` frames (a sensor
reports the mean dBm of the frames it heard in one slot); beyond that the mean is taken as
Gaussian with the law's mean and spread / sqrt(n) (within 0.05 of the exact law's quantiles at n = 5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

STEP_DB = 0.01
LO_DB, HI_DB = -80.0, 20.0  # the grid: Rayleigh P(F < -80 dB) = 1e-8, P(F > 20 dB) = e^-100
MEAN_N_MAX = 4
_LOG_FLOOR = -700.0


@dataclass(frozen=True)
class FadingLaw:
    """The law of F = 10 log10 |h|^2 [dB] (see the module docstring)."""

    k_factor_db: float | None  # None: Rayleigh
    grid_db: np.ndarray
    sf: np.ndarray  # P(F > u)
    logpdf: tuple  # log density of the mean of n frames, n = 1..MEAN_N_MAX
    mean_db: float
    std_db: float

    def survival(self, u_db) -> np.ndarray:
        """P(F > u) (linear between grid points; 1 below the grid, 0 above)."""
        return _lookup(self.sf, u_db, 1.0, 0.0)

    def log_density(self, u_db, n: int = 1) -> np.ndarray:
        """log density [1/dB] of the mean of ``n`` independent frames' F at ``u_db``."""
        u = np.asarray(u_db, float)
        if n <= MEAN_N_MAX:
            return _lookup(self.logpdf[n - 1], u, _LOG_FLOOR, _LOG_FLOOR)
        s = self.std_db / math.sqrt(n)
        return -0.5 * ((u - self.mean_db) / s) ** 2 - math.log(s * math.sqrt(2.0 * math.pi))

    def sample(self, normals: np.ndarray) -> np.ndarray:
        """F [dB] from pairs of standard normals (..., 2): |a + s (n1 + i n2)|^2 with a^2 = K / (K + 1),
        2 s^2 = 1 / (K + 1) (Rayleigh: a = 0)."""
        k = 0.0 if self.k_factor_db is None else 10.0 ** (self.k_factor_db / 10.0)
        a, s = math.sqrt(k / (k + 1.0)), math.sqrt(0.5 / (k + 1.0))
        power = (a + s * normals[..., 0]) ** 2 + (s * normals[..., 1]) ** 2
        return 10.0 * np.log10(np.maximum(power, 1e-30))


def _lookup(table: np.ndarray, u_db, left: float, right: float) -> np.ndarray:
    """Linear interpolation on the uniform grid LO_DB + k STEP_DB (np.interp without the search)."""
    x = (np.asarray(u_db, float) - LO_DB) * (1.0 / STEP_DB)
    i = np.clip(x.astype(np.int64), 0, len(table) - 2)
    f = x - i
    out = table[i] + f * (table[i + 1] - table[i])
    return np.where(x < 0.0, left, np.where(x > len(table) - 1, right, out))


@lru_cache(maxsize=8)
def fading_law(k_factor_db: float | None) -> FadingLaw:
    """The tabulated law of Rician fading with K = ``k_factor_db`` [dB], or Rayleigh (None)."""
    from scipy.signal import fftconvolve

    u = np.arange(LO_DB, HI_DB + STEP_DB / 2, STEP_DB)
    p = 10.0 ** (u / 10.0)
    jac = p * math.log(10.0) / 10.0  # dp / du
    if k_factor_db is None:
        pdf = np.exp(-p) * jac
        sf = np.exp(-p)
    else:
        from scipy.stats import ncx2

        k = 10.0 ** (k_factor_db / 10.0)
        law = ncx2(df=2, nc=2.0 * k, scale=1.0 / (2.0 * (k + 1.0)))
        pdf = law.pdf(p) * jac
        sf = law.sf(p)
    pdf = pdf / (pdf.sum() * STEP_DB)
    mean = float(np.sum(u * pdf) * STEP_DB)
    std = math.sqrt(float(np.sum((u - mean) ** 2 * pdf) * STEP_DB))
    logpdfs = [np.log(np.maximum(pdf, 1e-300))]
    total = pdf
    for n in range(2, MEAN_N_MAX + 1):
        total = fftconvolve(total, pdf)[: ((n * (len(u) - 1)) + 1)] * STEP_DB  # the sum on n LO .. n HI
        sum_grid = n * LO_DB + STEP_DB * np.arange(len(total))
        dens = n * np.interp(n * u, sum_grid, np.clip(total, 0.0, None), left=0.0, right=0.0)
        logpdfs.append(np.log(np.maximum(dens / (dens.sum() * STEP_DB), 1e-300)))
    return FadingLaw(k_factor_db, u, np.clip(sf, 0.0, 1.0), tuple(logpdfs), mean, std)
