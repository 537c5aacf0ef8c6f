"""Probability of detection (POD): how likely a search was to hear a phone, cell by cell.

Search-and-rescue practice grades a search by its POD per area (Koopman's search theory). Here a
phone counts as *detected k times* when at least k of its probe bursts are heard. Three pieces:

- :class:`~.burst_timing.BurstTiming`: when phones send, as the scenario's ``[emission]`` keys describe them
  (the model of ``sim_link/world/emission.py``, SPEC 1.1): a stationary renewal process per phone
  whose gaps are log-normal with a median and 90th percentile drawn log-linearly by a phone
  quantile u ~ U(0, 1), at least the longest burst plus a quiet second, with a long silence
  (log-uniform in ``long_silence_min_s``..``max_s``) replacing a gap with probability
  ``long_silence_per_gap``. A search starts at a random moment of every phone's life, so the
  process is taken in steady state (the phone is in a long silence with the probability the
  silences' share of time gives).
- :func:`p_burst_heard`: whether one burst sent at a given geometry is heard: each of its K frames
  (the scenario's frames-per-burst law, the estimator's :func:`~uavloc_gcs.search.phones.frames_prior`
  per phone) reaches a radio the receiver listens on with the channel share and is heard when its
  RSSI exceeds ``channel.receiver_sensitivity_dbm`` under i.i.d. shadowing (fully shared within a
  burst with ``simulation.correlated_shadowing``), with a per-phone transmit offset
  N(0, ``simulation.tx_power_spread_db``^2). Without a sensitivity (the paper) a burst is heard
  exactly within ``fleet.comm_range_m``.
- :func:`pod_from_tracks`: the POD of every cell of a grid from tracks as flown. For each cell
  centre and each phone type (transmit offset, frames per burst: a small quadrature) the tracks
  give *looks*: runs of track samples where the burst could be heard, each with an effective
  window w = integral of p_burst_heard dt (a window in which every burst is heard, the thinning of
  the burst process). Looks closer in time than ``MERGE_GAPS`` mean gaps of the phone add up into
  one window; farther apart they are independent given the phone's silence state. The long
  silences are the strongest dependence between looks (a phone silent for an hour is missed by
  every pass in that hour), so they are not averaged away: for every phone quantile u a fixed set of
  steady-state silence timelines (:data:`SILENCE_DRAWS`) removes the silent part of every window,
  and the counts of the remaining windows combine as independent. The POD is the average over
  phone quantiles, types and silence timelines.

Continuous emission (the paper): a phone sends every slot, so any window longer than a slot hears
it; each look (a run of samples within range, separated by more than ``CONTINUOUS_LOOK_GAP_S``)
counts once.

Cells and positions are local metres of ``scenario.frame`` (launch point = (0, 0)), as elsewhere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..a2g import A2GChannel
from ..errors import ConfigError
from . import pod_a2g
from .burst_timing import BurstTiming, _overlap
from .phones import FRAMES_LOG_SIGMA, N_QUANTILES, channel_share, frames_prior


N_TX = 5  # Gauss-Hermite nodes of the per-phone transmit offset
N_FRAMES = 4  # per-phone median frames per burst (log-uniform midpoints)
MERGE_GAPS = 2.0  # looks closer than this many mean gaps (of the phone) are one window
P_EPS = 1e-3  # a look is a run of samples where the best phone's burst is heard with more than this
TRACK_STEP_M = 25.0  # tracks are resampled to at most this many metres ...
TRACK_STEP_S = 2.5  # ... and seconds between samples (a burst is heard over ~500 m of flight)
CONTINUOUS_LOOK_GAP_S = 10.0  # continuous world: in-range runs farther apart are separate looks
DEFAULT_CELLS = 1200  # grid_for's default cell size gives about this many cells over the area


def _ndtr(x):
    from scipy.special import ndtr

    return ndtr(x)


# ---------------------------------------------------------------------------------------------
# Whether a burst is heard


@dataclass(frozen=True)
class _Hearing:
    """Phone types (transmit offset x frames median) with weights, and the per-type probability of
    hearing one burst tabulated over 3-D distance."""

    d_grid: np.ndarray  # (G,) 3-D distance [m]
    table: np.ndarray  # (G, T)
    weights: np.ndarray  # (T,)
    max_range_m: float  # beyond this no type's burst is heard with more than P_EPS
    elicit: np.ndarray | None = None  # (G, T) heard elicited frames per second (None: no elicitation)
    # heights [m] of an air-to-ground table (channel.environment, .pod_a2g): then d_grid is the
    # horizontal distance and table / elicit are (G, Z, T); None: tables over 3-D distance
    z_grid: np.ndarray | None = None
    reach_by_z: np.ndarray | None = None  # (Z,) the 3-D reach of vehicles at or below each height [m]

    def reach_m(self, max_height_m: float) -> float:
        """The 3-D distance beyond which nothing is heard from vehicles at most ``max_height_m`` above
        the phones (``max_range_m`` for 3-D tables)."""
        if self.reach_by_z is None:
            return self.max_range_m
        j = int(np.clip(np.ceil(max_height_m / (self.z_grid[1] - self.z_grid[0])), 0, len(self.z_grid) - 1))
        return float(self.reach_by_z[j])

    def p_at(self, horizontal_m, height_m) -> np.ndarray:
        """(..., T) per type at a horizontal distance and height (air-to-ground tables only)."""
        return pod_a2g.lookup(self.table32, horizontal_m, height_m)

    def rate_at(self, horizontal_m, height_m) -> np.ndarray:
        """(..., T) heard elicited frames per second per type (air-to-ground tables only)."""
        if self.elicit is None:
            return np.zeros(np.shape(horizontal_m) + (self.table.shape[-1],), np.float32)
        return pod_a2g.lookup(self.elicit, horizontal_m, height_m)

    def p(self, d3_m) -> np.ndarray:
        """(..., T) per type (the table's nearest distance, 1 m away at most)."""
        step = self.d_grid[1] - self.d_grid[0]
        i = np.minimum(np.rint(np.asarray(d3_m, float) / step).astype(np.int32), len(self.d_grid) - 1)
        return self.table32[i]

    def rate(self, d3_m) -> np.ndarray:
        """(..., T) heard elicited frames per second per type (zeros without elicitation)."""
        step = self.d_grid[1] - self.d_grid[0]
        i = np.minimum(np.rint(np.asarray(d3_m, float) / step).astype(np.int32), len(self.d_grid) - 1)
        if self.elicit is None:
            return np.zeros(i.shape + (self.table.shape[1],), np.float32)
        return self.elicit[i]

    @property
    def table32(self) -> np.ndarray:
        t = self.__dict__.get("_t32")
        if t is None:
            t = self.table.astype(np.float32)
            object.__setattr__(self, "_t32", t)
        return t


def _frames_nodes(sc, frames_median):
    """Frame counts K (n,) and weights for one phone of median ``frames_median`` (None: the
    population, the estimator's frames prior)."""
    em = sc.emission
    if frames_median is None:
        p = np.asarray(frames_prior(sc).p, float)
        return np.arange(1, len(p) + 1, dtype=float), p / p.sum()
    z, w = np.polynomial.hermite_e.hermegauss(15)
    k = np.clip(np.rint(frames_median * np.exp(FRAMES_LOG_SIGMA * z)), 1, em.frames_per_burst_max)
    return k, w / w.sum()


def p_burst_heard(sc, horizontal_m, altitude_m, *, tx_offset_db=0.0, frames_median=None):
    """P(a burst sent with the vehicle ``horizontal_m`` away on the ground and ``altitude_m`` above
    the phone is heard), vectorised over the broadcast of both. ``tx_offset_db`` is the phone's
    transmit offset (None: averaged over the scenario's spread); ``frames_median`` its median frames
    per burst (None: the population's frames prior). Continuous emission: the probability a slot's
    frames are heard (1 within the paper's gate)."""
    h = np.asarray(horizontal_m, float)
    z = np.asarray(altitude_m, float)
    d3 = np.sqrt(h * h + z * z)
    ch = sc.channel
    sens = ch.receiver_sensitivity_dbm
    if sens is None:  # the paper's exact gate
        share = 1.0 if sc.emission.model == "continuous" else float(channel_share(sc) > 0)
        out = (d3 <= sc.fleet.comm_range_m) * share
        return out.astype(float)
    if tx_offset_db is None:
        spread = sc.simulation.tx_power_spread_db
        x, w = np.polynomial.hermite_e.hermegauss(N_TX if spread > 0 else 1)
        w = w / w.sum()
        return sum(wi * p_burst_heard(sc, h, z, tx_offset_db=spread * xi, frames_median=frames_median)
                   for xi, wi in zip(x, w))
    a2g = A2GChannel.from_scenario(sc)
    if a2g is not None:  # the air-to-ground channel: the state by elevation, shadowing per burst
        ks, wk = _frames_nodes(sc, frames_median)
        return pod_a2g.burst_heard(a2g, h, z, tx_offset_db=tx_offset_db, ks=ks, weights=wk,
                                   channel_share=channel_share(sc))
    mu = ch.reference_power_dbm - 10.0 * ch.path_loss_exponent * np.log10(
        np.maximum(d3, 1e-3) / ch.reference_distance_m) + tx_offset_db
    q = _ndtr((mu - sens) / ch.shadowing_sigma_db)  # one frame above the sensitivity
    if sc.emission.model == "continuous":  # a slot of samples_per_slot samples
        return 1.0 - (1.0 - q) ** ch.samples_per_slot
    c = channel_share(sc)
    ks, wk = _frames_nodes(sc, frames_median)
    if sc.simulation.correlated_shadowing:  # the frames of a burst share their shadowing
        return q * sum(wi * (1.0 - (1.0 - c) ** k) for k, wi in zip(ks, wk))
    miss = 1.0 - c * q
    return sum(wi * (1.0 - miss**k) for k, wi in zip(ks, wk))


_HEARING_CACHE: dict = {}


def _hearing(sc) -> _Hearing:
    key = (repr(sc.channel), repr(sc.emission), repr(sc.simulation), sc.fleet.comm_range_m)
    if key not in _HEARING_CACHE:
        if len(_HEARING_CACHE) > 8:
            _HEARING_CACHE.clear()
        _HEARING_CACHE[key] = _hearing_table(sc)
    return _HEARING_CACHE[key]


def _hearing_table(sc) -> _Hearing:
    em, channel, simulation = sc.emission, sc.channel, sc.simulation
    spread = simulation.tx_power_spread_db
    if channel.receiver_sensitivity_dbm is None:
        tx, wtx = np.zeros(1), np.ones(1)
    else:
        tx, wtx = np.polynomial.hermite_e.hermegauss(N_TX if spread > 0 else 1)
        tx, wtx = spread * tx, wtx / wtx.sum()
    if em.model == "continuous" or channel.receiver_sensitivity_dbm is None:
        med, wm = [None], np.ones(1)
    else:
        lo, hi = math.log(em.frames_per_burst_median_min), math.log(em.frames_per_burst_median_max)
        med = list(np.exp(lo + (hi - lo) * (np.arange(N_FRAMES) + 0.5) / N_FRAMES))
        wm = np.full(N_FRAMES, 1.0 / N_FRAMES)
    step = 2.0
    d = np.arange(0.0, 5000.0 + step, step)
    cols, weights, rates = [], [], []
    elicit = elicited_stream(sc)
    a2g = A2GChannel.from_scenario(sc)
    if a2g is not None:  # tables over (horizontal distance, height): the elevation decides line of sight
        types = [_frames_nodes(sc, m) for m in med]
        h, z, table, reach, el, reach_z = pod_a2g.tables(
            a2g, tx, types, channel_share(sc), P_EPS, em.elicitation_rate_hz if elicit else 0.0,
            elicitation_range_m(sc))
        weights = np.array([wt * wmm for wt in wtx for wmm in wm])
        return _Hearing(h, table, weights, reach, el, z, reach_z)
    for t, wt in zip(tx, wtx):
        for m, wmm in zip(med, wm):
            cols.append(p_burst_heard(sc, d, 0.0, tx_offset_db=float(t), frames_median=m))
            weights.append(wt * wmm)
            if elicit:
                rates.append(elicited_rate_hz(sc, d, tx_offset_db=float(t)))
    table = np.column_stack(cols)
    reach = d[np.max(table, axis=1) > P_EPS]
    max_range = float(reach.max()) + step if len(reach) else 0.0
    keep = d <= max_range + step
    el = np.column_stack(rates)[keep].astype(np.float32) if elicit else None
    return _Hearing(d[keep], table[keep], np.asarray(weights), max_range, el)


def elicited_stream(sc) -> bool:
    """Whether the POD counts elicited frames as detections: only for a stream every phone sends
    from the moment it is within reach (``emission.elicitation_join = "in-reach"``, every phone:
    what a beacon's advertising is, ``radios.ble_view``). A mimicked network (``"scan"``) is joined
    at one of the phone's bursts sent within reach, a burst the POD already counts, and only by
    the ``emission.mimicry_share`` of phones: the stream that follows places a phone already
    detected, so the POD counts bursts only (it may understate what the access point adds, never
    overstate it)."""
    em = sc.emission
    return (em.model != "continuous" and em.elicitation_rate_hz > 0 and sc.channel.receiver_sensitivity_dbm is not None
            and em.elicitation_join == "in-reach" and em.mimicry_share >= 1.0)


def elicitation_range_m(sc) -> float:
    """3-D distance within which a phone hears the on-board access point and answers: where one
    frame of a phone with no transmit offset is heard with probability 1/2 (a symmetric link; as
    sim_link's World.elicitation_range_m)."""
    ch = sc.channel
    if ch.receiver_sensitivity_dbm is None:
        return float(sc.fleet.comm_range_m)
    a2g = A2GChannel.from_scenario(sc)
    if a2g is not None:  # a frame in line of sight (as sim_link's World.hearing_range_m)
        return float(a2g.state_range_m(0))
    margin = ch.reference_power_dbm - ch.receiver_sensitivity_dbm
    return float(ch.reference_distance_m * 10.0 ** (margin / (10.0 * ch.path_loss_exponent)))


def elicited_rate_hz(sc, d3_m, *, tx_offset_db=0.0, height_m=None) -> np.ndarray:
    """Elicited frames heard per second from a phone at 3-D distance ``d3_m``: the phone answers
    at ``emission.elicitation_rate_hz`` within :func:`elicitation_range_m`, on the access point's
    (listened) channel, each frame heard above the sensitivity. Under an air-to-ground environment
    hearing depends on the elevation: give the vehicle's ``height_m`` above the phone."""
    ch = sc.channel
    d = np.asarray(d3_m, float)
    a2g = A2GChannel.from_scenario(sc)
    if a2g is not None:
        if height_m is None:
            raise ValueError("elicited_rate_hz: under channel.environment the rate depends on the "
                             "elevation; pass height_m (the vehicle's height above the phone)")
        z = np.asarray(height_m, float)
        q = a2g.frame_heard_probability(np.sqrt(np.maximum(d * d - z * z, 0.0)), z, tx_offset_db)
        return sc.emission.elicitation_rate_hz * q * (d <= elicitation_range_m(sc))
    mu = ch.reference_power_dbm - 10.0 * ch.path_loss_exponent * np.log10(
        np.maximum(d, 1e-3) / ch.reference_distance_m) + tx_offset_db
    q = _ndtr((mu - ch.receiver_sensitivity_dbm) / ch.shadowing_sigma_db)
    return sc.emission.elicitation_rate_hz * q * (d <= elicitation_range_m(sc))


# ---------------------------------------------------------------------------------------------
# The grid


@dataclass
class PodGrid:
    """Square cells over the search area (centres in local metres) and their POD: ``pod1`` = P(at
    least one burst heard), ``pod2`` = P(at least two), 0 outside the area."""

    x_m: np.ndarray  # (C,) cell centres
    y_m: np.ndarray
    cell_m: float
    inside: np.ndarray  # (C,) bool
    pod1: np.ndarray = field(default=None)
    pod2: np.ndarray = field(default=None)
    shape: tuple = ()  # (rows, cols) of the regular grid (x varies along cols)

    def __post_init__(self):
        n = len(self.x_m)
        self.pod1 = np.zeros(n) if self.pod1 is None else np.asarray(self.pod1, float)
        self.pod2 = np.zeros(n) if self.pod2 is None else np.asarray(self.pod2, float)

    def overall(self, k: int = 1) -> float:
        """Area-weighted POD over the cells inside the area (all cells have the same size)."""
        pod = self.pod1 if k == 1 else self.pod2
        return float(np.mean(pod[self.inside])) if np.any(self.inside) else 0.0

    def with_pod(self, pod1, pod2) -> "PodGrid":
        return PodGrid(self.x_m, self.y_m, self.cell_m, self.inside, pod1, pod2, self.shape)

    def to_geojson(self, origin) -> dict:
        """A FeatureCollection of the cells inside the area: square polygons (lon/lat) with
        ``pod1``/``pod2`` properties. ``origin``: the scenario or its LocalFrame."""
        frame = getattr(origin, "frame", origin)
        h = self.cell_m / 2.0
        feats = []
        for i in np.flatnonzero(self.inside):
            x, y = self.x_m[i], self.y_m[i]
            ring = np.array([[x - h, y - h], [x + h, y - h], [x + h, y + h], [x - h, y + h], [x - h, y - h]])
            ll = frame.to_wgs84_latlon(ring)
            feats.append({
                "type": "Feature",
                "geometry": {"type": "Polygon", "coordinates": [[[round(float(lon), 7), round(float(lat), 7)]
                                                                  for lat, lon in ll]]},
                "properties": {"pod1": round(float(self.pod1[i]), 4), "pod2": round(float(self.pod2[i]), 4),
                               "x_m": round(float(x), 1), "y_m": round(float(y), 1)},
            })
        return {"type": "FeatureCollection", "features": feats,
                "properties": {"cell_m": self.cell_m, "pod1_overall": round(self.overall(1), 4),
                               "pod2_overall": round(self.overall(2), 4)}}


def grid_for(sc, cell_m: float | None = None) -> PodGrid:
    """An empty (POD 0) grid of square cells over the scenario's area; the default cell size gives
    about :data:`DEFAULT_CELLS` cells."""
    import shapely

    xy = sc.area_xy_m()
    poly = shapely.Polygon(xy)
    if cell_m is None:
        cell_m = max(5.0, round(math.sqrt(poly.area / DEFAULT_CELLS)))
    if not cell_m > 0:
        raise ConfigError(f"a POD cell must be larger than 0 m, got {cell_m}", source=sc.source)
    x0, y0, x1, y1 = poly.bounds
    nx, ny = max(1, math.ceil((x1 - x0) / cell_m)), max(1, math.ceil((y1 - y0) / cell_m))
    cx = x0 + cell_m * (np.arange(nx) + 0.5) + ((x1 - x0) - nx * cell_m) / 2
    cy = y0 + cell_m * (np.arange(ny) + 0.5) + ((y1 - y0) - ny * cell_m) / 2
    gx, gy = np.meshgrid(cx, cy)
    x, y = gx.reshape(-1), gy.reshape(-1)
    inside = shapely.contains_xy(poly, x, y)
    return PodGrid(x, y, float(cell_m), inside, shape=(ny, nx))


# ---------------------------------------------------------------------------------------------
# POD from tracks


def _resample(t_s, xyz_m) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t_s, float).reshape(-1)
    xyz = np.asarray(xyz_m, float).reshape(-1, 3)
    if len(t) < 2:
        return t, xyz
    order = np.argsort(t, kind="stable")
    t, xyz = t[order], xyz[order]
    out_t = [t[:1]]
    for a in range(len(t) - 1):
        dt = t[a + 1] - t[a]
        dist = float(np.linalg.norm(xyz[a + 1] - xyz[a]))
        n = max(1, math.ceil(max(dist / TRACK_STEP_M, dt / TRACK_STEP_S)))
        if dt <= 0:
            continue
        out_t.append(t[a] + dt * np.arange(1, n + 1) / n)
    tt = np.concatenate(out_t)
    return tt, np.column_stack([np.interp(tt, t, xyz[:, c]) for c in range(3)])


def _looks(cx, cy, tracks, hearing: _Hearing, ground=None):
    """Per cell: looks (t0, t1, w[T]) over all tracks. Returns padded arrays t0, t1 (C, L), w (C, L, T)
    and a validity mask (C, L). ``ground`` (C,): each cell's ground above the launch point [m] (the
    tracks' heights are above the launch point); None: flat."""
    C, T = len(cx), hearing.table.shape[-1]
    if hearing.z_grid is not None:
        T = 2 * T  # air-to-ground: each type's integral of p, then of p^2 (pod_a2g.heard_12)
    g = np.zeros(C) if ground is None else np.asarray(ground, float)
    per_cell = [[] for _ in range(C)]
    top = max((float(np.max(x[:, 2])) for _, x in tracks if len(x)), default=0.0) - float(np.min(g, initial=0.0))
    reach_m = hearing.reach_m(top)
    for t_s, xyz_m in tracks:
        t, xyz = _resample(t_s, xyz_m)
        if len(t) < 2:
            continue
        # each sample stands for the time to the midpoints of its neighbours
        dt = np.diff(np.concatenate([[t[0]], 0.5 * (t[1:] + t[:-1]), [t[-1]]]))
        for a in range(0, C, 64):
            sl = slice(a, min(C, a + 64))
            dx = xyz[None, :, 0] - cx[sl, None]
            dy = xyz[None, :, 1] - cy[sl, None]
            dz = xyz[None, :, 2] - g[sl, None]
            d3 = np.sqrt(dx * dx + dy * dy + dz * dz)
            near = d3 <= reach_m
            rows, cols = np.nonzero(near)  # row-major: runs of consecutive samples per cell
            if len(rows) == 0:
                continue
            start = np.ones(len(rows), bool)
            start[1:] = (rows[1:] != rows[:-1]) | (cols[1:] != cols[:-1] + 1)
            first = np.flatnonzero(start)
            last = np.append(first[1:], len(rows)) - 1
            if hearing.z_grid is None:
                pr = hearing.p(d3[rows, cols])
            else:  # air-to-ground: the sample's own height above the cell's ground
                pr = hearing.p_at(np.hypot(dx[rows, cols], dy[rows, cols]), dz[rows, cols])
                pr = np.concatenate([pr, pr * pr], axis=-1)
            w = np.add.reduceat(pr * dt[cols, None], first, axis=0)  # (R, T)
            for r, a0, a1, ww in zip(rows[first], t[cols[first]], t[cols[last]], w):
                per_cell[a + r].append((a0, a1, ww))
    L = max(1, max((len(c) for c in per_cell), default=1))
    t0 = np.zeros((C, L))
    t1 = np.zeros((C, L))
    w = np.zeros((C, L, T))
    valid = np.zeros((C, L), bool)
    for i, looks in enumerate(per_cell):
        looks.sort(key=lambda r: r[0])
        for j, (a, b, ww) in enumerate(looks):
            t0[i, j], t1[i, j], w[i, j], valid[i, j] = a, b, ww, True
    return t0, t1, w, valid


def _elicited(cx, cy, tracks, hearing: _Hearing, reach_m: float, ground=None):
    """Elicited detections per cell and type: every run of a track within ``reach_m`` (where the
    phone hears the access point) is one detection with probability 1 - exp(-m), m its elicited
    frames expected to be heard. Returns P(none) and P(exactly one), (C, T) each."""
    C, T = len(cx), hearing.table.shape[-1]
    g = np.zeros(C) if ground is None else np.asarray(ground, float)
    el0 = np.ones((C, T))
    el1 = np.zeros((C, T))
    for t_s, xyz_m in tracks:
        t, xyz = _resample(t_s, xyz_m)
        if len(t) < 2:
            continue
        dt = np.diff(np.concatenate([[t[0]], 0.5 * (t[1:] + t[:-1]), [t[-1]]]))
        hxy = np.hypot(xyz[None, :, 0] - cx[:, None], xyz[None, :, 1] - cy[:, None])
        dz = xyz[None, :, 2] - g[:, None]
        d3 = np.sqrt((xyz[None, :, 0] - cx[:, None]) ** 2 + (xyz[None, :, 1] - cy[:, None]) ** 2
                     + (xyz[None, :, 2] - g[:, None]) ** 2)
        rows, cols = np.nonzero(d3 <= reach_m)
        if len(rows) == 0:
            continue
        start = np.ones(len(rows), bool)
        start[1:] = (rows[1:] != rows[:-1]) | (cols[1:] != cols[:-1] + 1)
        first = np.flatnonzero(start)
        rate = hearing.rate(d3[rows, cols]) if hearing.z_grid is None else hearing.rate_at(hxy[rows, cols], dz[rows, cols])
        m = np.add.reduceat(rate * dt[cols, None], first, axis=0)  # (R, T)
        pe = 1.0 - np.exp(-m)
        for r, p in zip(rows[first], pe):
            el0[r], el1[r] = el0[r] * (1.0 - p), el1[r] * (1.0 - p) + el0[r] * p
    return el0.astype(np.float32), el1.astype(np.float32)


def _merge(t0, t1, w, valid, gap_s: float):
    """Looks closer in time than ``gap_s`` add up into one window (per cell, looks sorted by t0)."""
    C, L = t0.shape
    if L == 1:
        return t0, t1, w, valid
    end = np.where(valid, t1, -np.inf)
    run_end = np.maximum.accumulate(end, axis=1)
    new = np.ones((C, L), bool)
    new[:, 1:] = t0[:, 1:] - run_end[:, :-1] > gap_s
    new &= valid
    gid = np.cumsum(new, axis=1) - 1  # cluster index per look
    gid = np.where(valid, gid, L)  # invalid looks go to a dump slot
    m0 = np.full((C, L + 1), np.inf)
    m1 = np.full((C, L + 1), -np.inf)
    mw = np.zeros((C, L + 1, w.shape[2]))
    rows = np.repeat(np.arange(C), L)
    g = gid.reshape(-1)
    np.minimum.at(m0, (rows, g), t0.reshape(-1))
    np.maximum.at(m1, (rows, g), t1.reshape(-1))
    np.add.at(mw, (rows, g), w.reshape(C * L, -1))
    mv = np.isfinite(m0[:, :L])
    return np.where(mv, m0[:, :L], 0.0), np.where(mv, m1[:, :L], 0.0), mw[:, :L], mv


def pod_from_tracks(sc, tracks, grid: PodGrid | None = None, *, coarse: bool = False) -> PodGrid:
    """POD of every cell of ``grid`` (default :func:`grid_for`) from ``tracks`` as flown: a list of
    (times (N,) [s], positions (N, 3) [m, local, z = height above the launch point; over terrain
    each cell's people stand on the DEM's ground there]). See the module
    docstring for the model. ``coarse``: every second phone quantile and silence timeline (4x
    faster, for comparing plans)."""
    grid = grid_for(sc) if grid is None else grid
    idx = np.flatnonzero(grid.inside)
    pod1 = np.zeros(len(grid.x_m))
    pod2 = np.zeros(len(grid.x_m))
    tracks = [(np.asarray(t, float), np.asarray(x, float)) for t, x in tracks if len(t)]
    if len(idx) == 0 or not tracks:
        return grid.with_pod(pod1, pod2)
    hearing = _hearing(sc)
    ground = None
    if sc.dem is not None:  # heights are above the launch point; each cell's people on its own ground
        xy = np.column_stack([grid.x_m[idx], grid.y_m[idx]])
        ground = sc.dem.height_xy(xy, clamp=True) - sc.dem.height_at(0.0, 0.0, clamp=True)
    t0, t1, w, valid = _looks(grid.x_m[idx], grid.y_m[idx], tracks, hearing, ground)
    bt = BurstTiming.from_scenario(sc)
    if bt.continuous:
        p1, p2 = _continuous_pod(t0, t1, w, valid, hearing, sc.channel.slot_s)
    else:
        start = min(float(t[0]) for t, _ in tracks)
        horizon = max(float(t[-1]) for t, _ in tracks) - start + 1.0
        el = None
        if hearing.elicit is not None:
            el = _elicited(grid.x_m[idx], grid.y_m[idx], tracks, hearing, elicitation_range_m(sc), ground)
        p1, p2 = _burst_pod(bt, t0 - start, t1 - start, w, valid, hearing.weights, horizon, 2 if coarse else 1, el,
                            uneven=hearing.z_grid is not None)
    pod1[idx], pod2[idx] = p1, p2
    return grid.with_pod(pod1, pod2)


def _continuous_pod(t0, t1, w, valid, hearing, slot_s):
    """The paper's emitter sends every slot: a look (in-range runs closer than
    CONTINUOUS_LOOK_GAP_S merged) with w seconds of hearing probability holds w / slot_s heard slots
    on average, so it is heard with 1 - exp(-w / slot_s) (1 for any look that passes the gate)."""
    t0, t1, w, valid = _merge(t0, t1, w, valid, CONTINUOUS_LOOK_GAP_S)
    p = (1.0 - np.exp(-w[..., 0] / slot_s)) * valid
    q0, q1 = np.ones(len(t0)), np.zeros(len(t0))
    for j in range(t0.shape[1]):
        q0, q1 = q0 * (1 - p[:, j]), q1 * (1 - p[:, j]) + q0 * p[:, j]
    return 1 - q0, 1 - q0 - q1


def _burst_pod(bt: BurstTiming, t0, t1, w, valid, type_w, horizon, stride: int = 1, elicited=None,
               uneven: bool = False):
    """P(>= 1), P(>= 2) bursts heard per cell. ``uneven``: ``w`` holds each type's integral of p and
    then of p^2 (air-to-ground), and a look is T_eff seconds of bursts heard with p_bar each
    (:func:`.pod_a2g.heard_12`); otherwise a look is a window of w seconds in which every burst is
    heard (thinning)."""
    C = len(t0)
    type_w = np.asarray(type_w, np.float32)
    sil_all = bt.silences(horizon)
    gaps = bt.mean_active_gap_s()
    p1 = np.zeros(C)
    p2 = np.zeros(C)
    nt = len(type_w)
    # elicited detections (:func:`_elicited`), independent of the burst process and its silences
    el0, el1 = elicited if elicited is not None else (np.ones((C, nt), np.float32), np.zeros((C, nt), np.float32))
    quantiles = range(stride // 2, N_QUANTILES, stride)
    for iu in quantiles:
        m0, m1, mw, mv = _merge(t0, t1, w, valid, MERGE_GAPS * gaps[iu])
        sil = sil_all[iu][::stride]  # (D, M, 2)
        span = np.maximum(m1 - m0, 1e-9)
        alive = 1.0 - _overlap(m0, np.maximum(m1, m0 + 1e-9), sil) / span  # (D, C, L)
        alive = np.where(mv[None], alive, 0.0).astype(np.float32)
        if uneven:  # air-to-ground: a look is t_eff seconds of bursts heard with p_bar each (pod_a2g)
            w1, w2 = mw[..., :nt], mw[..., nt:]
            p_bar = np.where(w1 > 0, w2 / np.maximum(w1, 1e-300), 0.0).astype(np.float32)
            win = np.where(p_bar > 0, w1 / np.maximum(p_bar, 1e-30), 0.0).astype(np.float32)  # (C, L, T)

            def chances(x, cj=None, j=None):
                a1, b1 = pod_a2g.heard_12(bt, x, p_bar if cj is None else p_bar[cj, j], iu)
                return a1, a1 - b1
        else:
            win = mw.astype(np.float32)  # (C, L, T)

            def chances(x, cj=None, j=None):
                return bt.p_active_12(x, iu)
        # A look outside every long silence (alive 1: almost all of them, silences are rare) has the
        # same hearing chances in every silence draw: computed once, and only the looks a silence cut
        # short per draw. The same numbers as forming all (D, C, L, T) at once, 20-40x faster and with
        # a fraction of the memory (a field demo's final summary took 266 s and 1.4 GB).
        full1, full2 = chances(win)  # (C, L, T)
        D, T = alive.shape[0], win.shape[2]
        q0 = np.ones((D, C, T), np.float32)
        q1 = np.zeros_like(q0)
        for j in range(win.shape[1]):
            a1 = np.broadcast_to(full1[None, :, j], (D, C, T)).copy()
            a2 = np.broadcast_to(full2[None, :, j], (D, C, T)).copy()
            dj, cj = np.nonzero((alive[:, :, j] != np.float32(1.0)) & mv[None, :, j])  # (no look: window 0 already)
            if len(dj):
                a1[dj, cj], a2[dj, cj] = chances(alive[dj, cj, j][:, None] * win[cj, j], cj, j)
            e0, e1 = 1.0 - a1, a1 - a2
            q0, q1 = q0 * e0, q1 * e0 + q0 * e1
        q0, q1 = q0 * el0[None], q1 * el0[None] + q0 * el1[None]
        p1 += ((1.0 - q0) @ type_w).mean(axis=0)
        p2 += ((1.0 - q0 - q1) @ type_w).mean(axis=0)
    return p1 / len(quantiles), p2 / len(quantiles)
