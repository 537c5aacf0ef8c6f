"""How simulated phones transmit: the paper's continuous emitter or Wi-Fi probe-request bursts.

``continuous`` (the paper) needs nothing from this module: every phone sends
``channel.samples_per_slot`` frames in every slot under its stable emitter id (see :mod:`.world`).

``probe-bursts`` (the field world, SPEC 1.1) is a renewal process per phone:

- the gap between bursts is log-normal per phone. A phone quantile u ~ U(0, 1) places its median
  gap log-linearly between :data:`GAP_MEDIAN_MIN_S` and :data:`GAP_MEDIAN_MAX_S` and its 90th
  percentile between :data:`GAP_P90_MIN_S` and :data:`GAP_P90_MAX_S` (frequent probers are also the
  regular ones); with probability :data:`LONG_SILENCE_PER_GAP` a gap is a long silence, log-uniform
  in [:data:`LONG_SILENCE_MIN_S`, :data:`LONG_SILENCE_MAX_S`]. Gaps are at least the longest burst
  plus :data:`MIN_QUIET_S`, so bursts never overlap;
- a burst carries n = round(m exp(:data:`FRAMES_LOG_SIGMA` z)) frames, clipped to
  [1, :data:`FRAMES_PER_BURST_MAX`], where the phone's median m is log-uniform in
  [:data:`FRAMES_MEDIAN_MIN`, :data:`FRAMES_MEDIAN_MAX`]; it lasts n x :data:`FRAME_SPACING_S`, frame
  times uniform within; each frame reaches one of the receiver's radios on 1, 6 or 11 with the
  shares :data:`CHANNEL_WEIGHTS` (channels ascending over the burst, a sweep);
- identity: each phone's model is drawn from :data:`CATALOGUE` by population share. The content
  fingerprint is a hash of the model (same-model phones collide). A randomizing model uses a new
  random, locally administered unicast address for every burst -- recent iPhones for every
  ``frames_per_address`` frames, i.e. several per burst -- and restarts its 802.11 sequence number
  at 0 with each; the others keep one address and a running sequence number;
- an elicited frame (an on-board access point that imitates a known network) is sent under the
  phone's per-network address: phones bind one random address to each saved network.

Sources and fit (docs/science/world.md has the tables):

- within a burst (frames, spacing, channels, addresses per burst) and the rate of long silences:
  fitted with ``python -m sim_link.world.calibrate`` to the labelled per-device captures of 11 phones
  (Pixel 3A, Galaxy M31/S7/S21 Ultra/J6, Redmi Note 9S, Honor 9, iPhone 6/XR/11/12) captured on
  channels 1/6/11, as published in the Politecnico di Milano MAC de-randomization lab datasets
  (github.com/amanzargari/Network-Measurement-Lab-MAC_De-randomization, Data/). No data ships.
- the gaps between bursts: the per-phone medians 20-135 s and 90th percentiles 60-270 s of 11 modern
  phones (iOS 15-16, Android 13) that SPEC 1.1 and uavloc issue 24 report -- those captures were not
  available here, so the constants reproduce the published per-phone figures (both ends of both
  ranges exactly), not raw frames. The lab captures above, with older phones and unknown screen
  states, spread wider (medians 8-270 s, p90 78-738 s); a scenario can set those instead.
- assumptions, stated as such: the catalogue's population shares; long silences up to 90 min (the
  lab captures' longest is 48 min, SPEC 1.1 reports one of 85 min).

Everything is drawn from per-phone random streams in fixed chunks of :data:`CHUNK_BURSTS` bursts,
so a phone's bursts do not depend on when or how often the world is asked about them.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass

import numpy as np

# -- gaps: fitted to the published per-phone figures (SPEC 1.1, issue 24; module docstring) --
GAP_MEDIAN_MIN_S = 20.0  # the most frequent prober's median gap between bursts
GAP_MEDIAN_MAX_S = 135.0  # the least frequent prober's median gap
GAP_P90_MIN_S = 60.0  # 90th percentile of the gap, most frequent prober
GAP_P90_MAX_S = 270.0  # 90th percentile, least frequent prober
# -- fitted to the lab captures with ``python -m sim_link.world.calibrate`` (module docstring) --
LONG_SILENCE_PER_GAP = 0.0094  # 6 gaps of 30-48 min among 641 within-session gaps
LONG_SILENCE_MIN_S = 1800.0
LONG_SILENCE_MAX_S = 5400.0  # assumption: SPEC 1.1's 85-minute silence lies inside
FRAMES_MEDIAN_MIN = 4  # per-phone median frames per burst: 4 (iPhone XR) ...
FRAMES_MEDIAN_MAX = 27  # ... to 27 (Galaxy J6)
FRAMES_PER_BURST_MAX = 80  # SPEC 1.1's "~80"; the captures' largest burst had 71
FRAMES_LOG_SIGMA = 0.41  # burst-to-burst spread of one phone's frame count (median over phones)
FRAME_SPACING_S = 0.040  # median time between frames of a burst (per phone 25-97 ms)
MIN_QUIET_S = 1.0  # shortest quiet time between the end of one burst and the next
# Share of frames heard by the sniffer on 1, 6 and 11 (adjacent channels leak into them).
CHANNEL_WEIGHTS = {1: 0.349, 6: 0.254, 11: 0.398}
# z of the 90th percentile of a standard normal
_Z90 = 1.2815515655446004


@dataclass(frozen=True)
class PhoneModel:
    """One model/OS of the catalogue: population share and address behaviour."""

    name: str
    share: float
    randomizes: bool  # random, locally administered addresses
    frames_per_address: int = 0  # a new address every this many frames; 0: one per burst

    @property
    def fingerprint(self) -> int:
        """Content hash of the model's probe requests: nonzero, 32 bits (what the RSSI message
        carries, dialect.rssi.wire_fingerprint), same for same-model phones."""
        h = int.from_bytes(hashlib.blake2b(self.name.encode(), digest_size=4).digest(), "big")
        return h or 1


# Shares are a plausible current handset mix (assumption). Address behaviour from the lab
# captures: iPhone 11/12 change address every 1-2 frames (one per channel visit, two copies each),
# iPhone 6/XR and the Androids once per burst; SPEC 1.1: one iPhone used 465 addresses in 53 min.
CATALOGUE = (
    PhoneModel("Apple iPhone 11, iOS 16", 0.12, True, 2),
    PhoneModel("Apple iPhone 12, iOS 16", 0.12, True, 2),
    PhoneModel("Apple iPhone 13, iOS 17", 0.12, True, 2),
    PhoneModel("Apple iPhone 14, iOS 17", 0.10, True, 2),
    PhoneModel("Samsung Galaxy S21, Android 13", 0.10, True),
    PhoneModel("Samsung Galaxy A52, Android 13", 0.10, True),
    PhoneModel("Oppo A74, Android 13", 0.06, True),
    PhoneModel("Google Pixel 7, Android 14", 0.06, True),
    PhoneModel("Xiaomi Redmi Note 10, Android 12", 0.08, True),
    PhoneModel("Huawei P30, EMUI 10 (global address)", 0.04, False),
    PhoneModel("Android 8 phone (global address)", 0.10, False),
)

CHUNK_BURSTS = 64
LOOKAHEAD_S = 1800.0  # when the table must grow, every phone is drawn this far ahead (fewer re-sorts)
SEQ_MODULO = 4096  # 802.11 sequence numbers are 12 bits
_LOCAL_BIT = 1 << 41  # locally administered bit of the first octet (48-bit address, first octet high)
_MULTICAST_BIT = 1 << 40


@dataclass(frozen=True)
class BurstParams:
    """The renewal process's parameters (defaults: the fit above)."""

    gap_median_min_s: float = GAP_MEDIAN_MIN_S
    gap_median_max_s: float = GAP_MEDIAN_MAX_S
    gap_p90_min_s: float = GAP_P90_MIN_S
    gap_p90_max_s: float = GAP_P90_MAX_S
    long_silence_per_gap: float = LONG_SILENCE_PER_GAP
    long_silence_min_s: float = LONG_SILENCE_MIN_S
    long_silence_max_s: float = LONG_SILENCE_MAX_S
    frames_median_min: int = FRAMES_MEDIAN_MIN
    frames_median_max: int = FRAMES_MEDIAN_MAX
    frames_max: int = FRAMES_PER_BURST_MAX
    frame_spacing_s: float = FRAME_SPACING_S

    @staticmethod
    def from_scenario(sc) -> "BurstParams":
        em = sc.emission
        return BurstParams(
            em.burst_gap_median_min_s, em.burst_gap_median_max_s, em.burst_gap_p90_min_s, em.burst_gap_p90_max_s,
            em.long_silence_per_gap, em.long_silence_min_s, em.long_silence_max_s,
            em.frames_per_burst_median_min, em.frames_per_burst_median_max, em.frames_per_burst_max,
            em.frame_spacing_s,
        )

    def gap_quantiles_s(self, u) -> tuple[np.ndarray, np.ndarray]:
        """Median and 90th percentile of the gap [s] of phones at quantile(s) u in [0, 1]."""
        u = np.asarray(u, dtype=float)
        med = self.gap_median_min_s * (self.gap_median_max_s / self.gap_median_min_s) ** u
        p90 = self.gap_p90_min_s * (self.gap_p90_max_s / self.gap_p90_min_s) ** u
        return med, p90


@dataclass(frozen=True)
class Frames:
    """Frames sent, one row each, in time order (ties by person). ``burst`` counts the phone's bursts
    from 0 (-1 for an elicited frame); ``seq`` is the 802.11 sequence number (-1 if not modelled)."""

    person: np.ndarray  # (F,) int
    t_s: np.ndarray  # (F,)
    channel: np.ndarray  # (F,) int
    address: np.ndarray  # (F,) int64
    seq: np.ndarray  # (F,) int
    burst: np.ndarray  # (F,) int

    def __len__(self) -> int:
        return len(self.t_s)

    def take(self, index) -> "Frames":
        return Frames(self.person[index], self.t_s[index], self.channel[index], self.address[index],
                      self.seq[index], self.burst[index])

    @staticmethod
    def concat(parts: "list[Frames]") -> "Frames":
        return Frames(*(np.concatenate([getattr(p, f) for p in parts])
                        for f in ("person", "t_s", "channel", "address", "seq", "burst")))


def random_local_addresses(rng: np.random.Generator, n: int) -> np.ndarray:
    """n random 48-bit unicast, locally administered addresses (int64)."""
    a = rng.integers(0, 1 << 48, size=n, dtype=np.int64)
    return (a | _LOCAL_BIT) & ~np.int64(_MULTICAST_BIT)


def is_locally_administered(address) -> np.ndarray:
    return (np.asarray(address, dtype=np.int64) & _LOCAL_BIT) != 0


class ProbeBursts:
    """The probe-request bursts of S phones (see the module docstring).

    ``rng_for(i)`` gives phone i's own random stream; ``traits_rng`` draws the phones' models,
    quantiles and fixed addresses.
    """

    def __init__(self, params: BurstParams, n_phones: int, traits_rng: np.random.Generator, rng_for):
        self.params = params
        n = int(n_phones)
        shares = np.array([m.share for m in CATALOGUE])
        self.model = traits_rng.choice(len(CATALOGUE), size=n, p=shares / shares.sum())
        self.gap_quantile = traits_rng.uniform(size=n)
        med, p90 = params.gap_quantiles_s(self.gap_quantile)
        self.gap_median_s = med
        self.gap_log_sigma = np.log(p90 / med) / _Z90
        lo, hi = np.log(params.frames_median_min), np.log(params.frames_median_max)
        self.frames_median = np.exp(traits_rng.uniform(lo, hi, size=n))
        self.randomizes = np.array([CATALOGUE[k].randomizes for k in self.model], dtype=bool)
        self.frames_per_address = np.array([CATALOGUE[k].frames_per_address for k in self.model], dtype=int)
        self.fingerprint = np.array([CATALOGUE[k].fingerprint for k in self.model], dtype=np.int64)
        # a global (vendor) address for non-randomizing phones: universally administered, unicast
        glob = traits_rng.integers(0, 1 << 48, size=n, dtype=np.int64) & ~np.int64(_LOCAL_BIT | _MULTICAST_BIT)
        self.network_address = random_local_addresses(traits_rng, n)  # per saved network, for elicited frames
        self.network_address[~self.randomizes] = glob[~self.randomizes]
        self.stable_address = glob
        self._rngs = [rng_for(i) for i in range(n)]
        self._next_start_s = np.zeros(n)  # start of the next burst to generate
        self._bursts = np.zeros(n, dtype=int)
        self._seq = np.zeros(n, dtype=int)
        self._first = np.ones(n, dtype=bool)
        self._frames: list[Frames | None] = [None] * n
        self._merged: Frames | None = None
        self.owner: dict[int, int] = {}
        for i in range(n):
            self.owner[int(self.network_address[i])] = i

    def __len__(self) -> int:
        return len(self._rngs)

    def frames(self, t_from_s: float, t_to_s: float) -> Frames:
        """All frames sent in [t_from_s, t_to_s) by every phone, in time order (ties by person)."""
        grown = False
        ahead = t_to_s + LOOKAHEAD_S if np.any(self._next_start_s < t_to_s) or self._merged is None else t_to_s
        for i in range(len(self)):
            while self._frames[i] is None or self._next_start_s[i] < ahead:
                chunk = self._chunk(i)
                self._frames[i] = chunk if self._frames[i] is None else Frames.concat([self._frames[i], chunk])
                grown = True
        if grown or self._merged is None:  # one table for all phones, re-sorted only when it grows
            parts = [f for f in self._frames if f is not None]
            merged = Frames.concat(parts) if parts else _empty_frames()
            self._merged = merged.take(np.lexsort((merged.person, merged.t_s)))
        a, b = np.searchsorted(self._merged.t_s, [t_from_s, t_to_s], side="left")
        return self._merged.take(slice(a, b))

    def _chunk(self, i: int) -> Frames:
        """The next CHUNK_BURSTS bursts of phone i, drawn in a fixed order from its own stream."""
        p, rng, nb = self.params, self._rngs[i], CHUNK_BURSTS
        gaps = np.exp(np.log(self.gap_median_s[i]) + self.gap_log_sigma[i] * rng.standard_normal(nb))
        silent = rng.uniform(size=nb) < p.long_silence_per_gap
        silence = np.exp(rng.uniform(np.log(p.long_silence_min_s), np.log(p.long_silence_max_s), size=nb))
        gaps = np.maximum(np.where(silent, silence, gaps), p.frames_max * p.frame_spacing_s + MIN_QUIET_S)
        if self._first[i]:
            start0 = self._steady_state_wait_s(i, rng)
            self._first[i] = False
        else:
            start0 = self._next_start_s[i]
        starts = start0 + np.concatenate([[0.0], np.cumsum(gaps[:-1])])
        self._next_start_s[i] = starts[-1] + gaps[-1]
        n = np.rint(self.frames_median[i] * np.exp(FRAMES_LOG_SIGMA * rng.standard_normal(nb)))
        n = np.clip(n, 1, p.frames_max).astype(int)
        duration = n * p.frame_spacing_s
        total = int(n.sum())
        burst_local = np.repeat(np.arange(nb), n)
        offset = rng.uniform(size=total)
        chans = np.array(list(CHANNEL_WEIGHTS))
        w = np.array(list(CHANNEL_WEIGHTS.values()))
        channel = rng.choice(chans, size=total, p=w / w.sum())
        by_time = np.lexsort((offset, burst_local))
        by_chan = np.lexsort((channel, burst_local))
        t = starts[burst_local] + duration[burst_local] * offset[by_time]
        channel = channel[by_chan]  # the sweep: channels ascending over the burst
        address, seq = self._addresses(i, rng, n)
        burst = self._bursts[i] + burst_local
        self._bursts[i] += nb
        return Frames(np.full(total, i), t, channel.astype(int), address.astype(np.int64), seq.astype(int), burst)

    def _steady_state_wait_s(self, i: int, rng: np.random.Generator) -> float:
        """Seconds from t = 0 to phone i's first burst, the phone having sent bursts long before
        (a disaster does not restart the phones). The gap under way at t = 0 is length-biased --
        a long gap is more likely to be the one in progress -- and t = 0 falls uniformly inside it.
        Length-biasing a log-normal(mu, s) gives log-normal(mu + s^2, s); a log-uniform silence on
        [a, b] gives uniform on [a, b]; the silence is the one under way with probability
        p E[silence] / (p E[silence] + (1 - p) E[gap]). With the fitted 0.94 % of gaps being 30-90
        min silences, about a quarter of the phones are silent at t = 0 (a cold start, the first
        burst within one ordinary gap, made the simulated scans hear 1.3-1.7x what the steady state
        gives: benchmarks/pod_world.py)."""
        p = self.params
        mu, s = math.log(self.gap_median_s[i]), float(self.gap_log_sigma[i])
        mean_gap = math.exp(mu + s * s / 2.0)
        a, b = p.long_silence_min_s, p.long_silence_max_s
        mean_silence = (b - a) / math.log(b / a)
        w_silence = p.long_silence_per_gap * mean_silence
        w_gap = (1.0 - p.long_silence_per_gap) * mean_gap
        if rng.uniform() * (w_silence + w_gap) < w_silence:
            under_way = rng.uniform(a, b)
        else:
            under_way = math.exp(mu + s * s + s * rng.standard_normal())
        return rng.uniform() * under_way

    def _addresses(self, i: int, rng: np.random.Generator, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Source address and 802.11 sequence number of every frame of bursts with n frames each."""
        total = int(n.sum())
        burst = np.repeat(np.arange(len(n)), n)
        within = np.arange(total) - np.repeat(np.concatenate([[0], np.cumsum(n)[:-1]]), n)  # index in burst
        if not self.randomizes[i]:  # one global address, a running sequence number
            seq = (self._seq[i] + np.arange(total)) % SEQ_MODULO
            self._seq[i] = (self._seq[i] + total) % SEQ_MODULO
            self.owner[int(self.stable_address[i])] = i
            return np.full(total, self.stable_address[i], dtype=np.int64), seq
        k = self.frames_per_address[i]
        if k <= 0:  # a new address per burst
            group = burst
        else:  # a new address every k frames of a burst
            group = np.cumsum((within == 0) | (within % k == 0)) - 1
        addr = random_local_addresses(rng, int(group[-1]) + 1)
        for a in addr.tolist():
            self.owner[a] = i
        first = np.concatenate([[0], np.nonzero(np.diff(group))[0] + 1])  # first frame of each address
        seq = (np.arange(total) - np.repeat(first, np.diff(np.append(first, total)))) % SEQ_MODULO
        return addr[group], seq


def _empty_frames() -> Frames:
    z = np.zeros(0, dtype=int)
    return Frames(z, np.zeros(0), z, np.zeros(0, dtype=np.int64), z, z)
