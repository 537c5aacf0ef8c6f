"""Where a phone heard in bursts can be: a posterior on a grid over the ground (the field world).

A phone that is not connected sends probe bursts tens of seconds to minutes apart (SPEC 1.1): a
person's data are a few to a few dozen bursts, each a handful of frames heard by one or more
vehicles, plus the vehicles that listened during a burst and heard none of it. Each burst says
little (one range with tens of percent of error) and the posterior bends along rings, with several
modes until bursts from different directions meet. So the estimate is the posterior itself, on a
grid of the ground, every burst's likelihood summed in with the transmit offset integrated out
(Gauss-Hermite), the 95 % radius read off the grid; no mode search, no Gaussian in between.

Motion: a trapped person (``max_speed_m_s`` 0) stands still. A person who may walk (speed bound
``v``) is where they are now, at most ``v`` (t_ref - t) from where they were when each burst was
sent: each burst's likelihood is blurred by a disc of that radius before it is summed in, which
holds whatever path they took (a bound, not a motion model: honest and wide; the time between
bursts makes a walker hard to locate, and the radius says so). Both hypotheses together with a
stated prior share of trapped people (``static_share``).

Per burst the likelihood depends on the person's position only through the horizontal distance to
where the vehicle heard it (its height fixed over flat ground), so it is tabulated once over
distance (:class:`BurstTable`) and read at every cell. The channel is a :class:`~.burst_models.BurstModel`:
:class:`~.burst_models.LogDistanceBursts` for the log-distance channel with per-frame shadowing (the field world
before the air-to-ground channel), :class:`~.burst_models.A2GBursts` for the air-to-ground channel of
``uavloc_gcs.a2g`` (``[channel] environment``: line of sight by elevation angle, one shadowing per
burst), the model the simulated world draws from.

Units close together share their shadowing. Probe bursts tens of seconds apart are heard hundreds of
metres apart, past the channel's shadowing decorrelation distance; frames elicited by an on-board
access point a second apart, or BLE beacons 2 s apart (uavloc_gcs/radios.py), are heard a few metres
apart and nearly share it: summed as if independent they overstated what they say (a person located
with 4 of 4 elicited looks had 1 outside its 95 % circle, docs/measurements/field-world.md). Under
the air-to-ground channel each unit's log-likelihood is therefore weighted by what it adds to the
one before it from the same vehicle: with rho = exp(-d / decorrelation_m) (d: the distance between
the two places the vehicle heard them; the channel's Gudmundson correlation), a chain of n units
whose shadowing (variance s2) is an AR(1) and whose fading (f2) is their own carries the
information of n (s2 + f2) / (s2 (1 + rho) / (1 - rho) + f2) independent ones; each weighs that
share (:func:`unit_weights`, line-of-sight variances; a composite likelihood). Units far apart
weigh 1.

That share is the chain's information about a quantity every unit sees alike (a transmit offset, a
range common to all). What places the person is how the units' ranges change with the bearing from
the person, and on an orbit the bearing turns by some 30 degrees between two beacons: the shadowing's
AR(1) has there about a quarter of the power it has at frequency zero, so the zero-frequency share
undervalued an orbit's units about threefold (one orbit's beacons: truth 2-8 m away inside 15-33 m
circles). With a reference point (the coarser grid's posterior mean) each unit weighs what the
chain carries at its own frequency, the bearing's turn from the previous unit of its vehicle:
(s2 + f2) / (S(omega) + f2), S(omega) = s2 (1 - rho^2) / (1 - 2 rho cos omega + rho^2) (a Whittle
approximation), never above 1. A straight pass far from the person turns the bearing little and
weighs as before (``BEARING_WEIGHTS``; False: the zero-frequency share everywhere).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..errors import EstimationError
from ..observations import SlotBatch
from .burst_models import BurstModel

BURST_GAP_S = 0.5  # slots of one vehicle farther apart than this belong to different bursts
# The phone's transmit offset is integrated on a regular grid of this step over +-TX_SPAN_SIGMA of its
# prior. Not Gauss-Hermite: with dozens of bursts the offset is known to a fraction of a dB, far
# narrower than 7 nodes 3.5 dB apart, and nodes that coarse forced the offset onto one of them: a
# demo's phone at +4.4 dB was placed 116 m from the truth with a 35 m radius (the positions that
# suited +3.5 dB won).
TX_STEP_DB = 0.75
TX_SPAN_SIGMA = 3.5
TABLE_STEP_M = 2.0  # horizontal-distance step of a burst's likelihood table
MAX_TABLES = 3000  # tables kept per estimator (about 100 MB at most)
COARSE_CELLS = 64  # cells along the longer side of the first grid
FINE_CELLS_PER_RADIUS = 10.0  # the last grid has its 95 % radius over at least this many cells
MIN_CELL_M = 0.5
SUPPORT_LOG = 25.0  # cells within this of the best log posterior are the support (wide: a coarse
# grid samples a sharp ridge between its cell centres far below its peak)
SUPPORT_PAD_CELLS = 3  # the next grid covers the support and this many of the coarser cells around it
EDGE_MASS = 1e-3  # a posterior with more than this within two cells of the grid's edge is cut: grow it
MAX_LEVELS = 4


@dataclass(frozen=True)
class Burst:
    """One vehicle's hearing of one burst: when, where the vehicle was (mean over the burst's
    slots; z = height above the person's ground), and the slots (mean RSSI, frames each); or a
    vehicle that listened during a heard burst and heard none of it (no slots)."""

    t_s: float
    vehicle: int
    xyz_m: tuple[float, float, float]
    rssi_dbm: tuple[float, ...] = ()
    counts: tuple[int, ...] = ()

    @property
    def silent(self) -> bool:
        return not self.rssi_dbm


def bursts_from_slots(slots: SlotBatch, *, gap_s: float = BURST_GAP_S) -> list[Burst]:
    """One person's slots grouped, per vehicle, into bursts (a new one after a gap over ``gap_s``).

    A phone that answers an access point does so under one address it keeps (its per-network
    address) while its probe bursts use addresses of their own: when a person has both, the
    addresses heard in more than one run (:func:`steady_addresses`) are grouped apart from the
    others, so a burst and the answers heard during it are two units, not one run of more frames
    than a burst sends. A phone with one address for everything is grouped as before."""
    out = []
    steady = steady_addresses(slots, gap_s)
    for v in np.unique(slots.vehicle):
        part = slots.take(slots.vehicle == v).sorted_by_time()
        pieces = [part]
        if len(steady):
            keep = np.isin(part.address, steady)
            if keep.any() and not keep.all():
                pieces = [part.take(keep), part.take(~keep)]
        for piece in pieces:
            t = piece.t_s
            starts = np.concatenate([[0], np.flatnonzero(np.diff(t) > gap_s) + 1, [len(t)]])
            for a, b in zip(starts[:-1], starts[1:]):
                w = np.maximum(piece.n_samples[a:b].astype(float), 1.0)
                xyz = np.average(piece.xyz_m[a:b], axis=0, weights=w)
                out.append(Burst(float(t[a]), int(v), tuple(float(c) for c in xyz),
                                 tuple(float(r) for r in piece.rssi_dbm[a:b]),
                                 tuple(int(c) for c in piece.n_samples[a:b])))
    return sorted(out, key=lambda b: (b.t_s, b.vehicle))


def steady_addresses(slots: SlotBatch, gap_s: float = BURST_GAP_S) -> np.ndarray:
    """The addresses heard in more than one run of slots (runs: a new one after a gap over
    ``gap_s``, all vehicles together): an address a phone keeps, not one of a single burst."""
    if len(slots) == 0:
        return np.zeros(0, dtype=np.int64)
    order = np.argsort(slots.t_s, kind="stable")
    t, address = slots.t_s[order], slots.address[order]
    run = np.concatenate([[0], np.cumsum(np.diff(t) > gap_s)])
    pairs = np.unique(np.column_stack([address, run]), axis=0)
    values, counts = np.unique(pairs[:, 0], return_counts=True)
    return values[counts > 1]


def missed_beacons(heard: Sequence[Burst], interval_s: float, tracks: dict, *, listen_gap_s: float = 1.0,
                   heard_until: dict | None = None) -> list[Burst]:
    """The advertising events of one BLE identity that a listening vehicle did not hear, as silent
    units. A beacon identity advertises on a fixed schedule (every ``interval_s``, each event late by
    at most 10 ms of advDelay), so between its first and last heard beacon every event is known; a
    vehicle whose track (``tracks``: vehicle -> (t (N,), xyz (N, 3))) was within ``listen_gap_s`` of
    an event and that heard nothing then was too far or shadowed. Left out, the heard beacons alone
    are the loud ones near the edge of hearing, and a person orbited 20 m up was placed 24 m off
    inside a 15 m circle (``uavloc bench low_orbit --ble --alt 20``). ``heard_until``: vehicle -> time
    through which its receiver has reported everything (later events are not yet known missed)."""
    if not heard or interval_s <= 0:
        return []
    times = np.array(sorted(b.t_s for b in heard))
    t0 = float(times[0])
    n = int(round((float(times[-1]) - t0) / interval_s))
    if n < 1:
        return []
    k = np.arange(n + 1)
    events = t0 + k * interval_s
    out = []
    for v, (tt, xyz) in tracks.items():
        tt = np.asarray(tt, float)
        if len(tt) == 0:
            continue
        mine = np.array([b.t_s for b in heard if b.vehicle == v])
        miss = ~np.isin(k, np.rint((mine - t0) / interval_s).astype(int)) if len(mine) else np.ones(len(k), bool)
        until = math.inf if heard_until is None else heard_until.get(v, math.inf)
        e = events[miss & (events + 1.0 <= until)]
        if len(e) == 0:
            continue
        order = np.argsort(tt)
        ts, xs = tt[order], np.asarray(xyz, float)[order]
        j = np.clip(np.searchsorted(ts, e), 1, len(ts) - 1)
        near = np.minimum(np.abs(ts[j] - e), np.abs(ts[j - 1] - e))
        e = e[near <= listen_gap_s]
        for t in e:
            pos = [float(np.interp(t, ts, xs[:, c])) for c in range(3)]
            out.append(Burst(float(t), int(v), (pos[0], pos[1], pos[2])))
    return out


# False: every unit weighs 1 (the estimator before issue 39; a named variant for comparison)
WEIGH_UNITS = True
LOGLIK_FLOOR = -1e30  # a table's log-likelihood floor: finite in float32, summed over thousands of units too
# False: every unit weighs the chain's zero-frequency share (the estimator before 2026-11-29)
BEARING_WEIGHTS = True


def unit_weight(rho: float, shared_db2: float = 1.0, own_db2: float = 0.0, omega: float = 0.0) -> float:
    """What one unit adds to a chain whose shared part correlates as ``rho`` (unit_weights), at the
    frequency ``omega`` [rad per unit] of what is estimated; at most 1."""
    # 1 - 2 rho cos(omega) + rho^2, written so that rho -> 1 at omega = 0 (the same place again) is
    # the zero-frequency limit, an unbounded spectrum: a unit heard where the last one was adds nothing
    den = (1.0 - rho) ** 2 + 2.0 * rho * (1.0 - math.cos(omega))
    spectrum = shared_db2 * (1.0 - rho) * (1.0 + rho) / den if den > 1e-15 else math.inf
    return min(1.0, (shared_db2 + own_db2) / (spectrum + own_db2))


def unit_weights(bursts: Sequence[Burst], decorrelation_m: float | None,
                 shared_and_own_db2: tuple[float, float] = (1.0, 0.0), about_xy_m=None) -> np.ndarray:
    """Each unit's weight in the summed log-likelihood (module docstring), rho = exp(-d /
    decorrelation_m), d the distance from where the same vehicle heard (or listened for) its
    previous unit; 1 for a vehicle's first unit and without a decorrelation distance. A unit's
    error is a shared part (shadowing, variance s2, correlated as rho) and its own (fading, f2): the
    chain's information per unit is that of (s2 + f2) / (s2 (1 + rho) / (1 - rho) + f2) independent
    units (the long-run variance of an AR(1) plus white noise); with no own part, (1 - rho) / (1 + rho).
    ``about_xy_m``: a reference position of the person; each unit then weighs the chain's share at
    the turn of the bearing from there since the vehicle's previous unit (module docstring)."""
    w = np.ones(len(bursts))
    if not (WEIGH_UNITS and decorrelation_m) or len(bursts) < 2:
        return w
    last: dict[int, np.ndarray] = {}
    for i in np.argsort([b.t_s for b in bursts], kind="stable"):
        b = bursts[int(i)]
        here = np.asarray(b.xyz_m, float)
        prev = last.get(b.vehicle)
        if prev is not None:
            rho = math.exp(-float(np.linalg.norm(here - prev)) / float(decorrelation_m))
            omega = 0.0
            if about_xy_m is not None and BEARING_WEIGHTS:
                a = math.atan2(here[1] - about_xy_m[1], here[0] - about_xy_m[0])
                b0 = math.atan2(prev[1] - about_xy_m[1], prev[0] - about_xy_m[0])
                omega = abs((a - b0 + math.pi) % (2.0 * math.pi) - math.pi)
            w[int(i)] = unit_weight(rho, *shared_and_own_db2, omega=omega)
        last[b.vehicle] = here
    return w


@dataclass(frozen=True)
class BurstTable:
    """A burst's log-likelihood over horizontal distance (rows: transmit-offset nodes)."""

    step_m: float
    loglik: np.ndarray  # (N_tx, N_d)
    slope: np.ndarray = field(init=False, repr=False, compare=False)  # (N_tx, N_d - 1): next - this

    def __post_init__(self) -> None:
        object.__setattr__(self, "slope", np.diff(self.loglik, axis=1))

    def at(self, horizontal_m: np.ndarray) -> np.ndarray:
        """(N_tx, ...) by linear interpolation (constant beyond the table's end). The search's
        hottest line: one gather of each row and of its slopes (np.take along the distance is
        twice as fast as fancy indexing there), the same float32 values as a + f (b - a)."""
        x = np.clip(np.asarray(horizontal_m, float) / self.step_m, 0.0, self.loglik.shape[1] - 1.000001)
        i = x.astype(np.int64)
        f = (x - i).astype(np.float32)
        return np.take(self.loglik, i, axis=1) + f * np.take(self.slope, i, axis=1)


def tx_nodes(sigma_db: float) -> tuple[np.ndarray, np.ndarray]:
    """Nodes [dB] and log weights of a N(0, sigma^2) transmit offset on a regular grid
    (TX_STEP_DB, over +-TX_SPAN_SIGMA sigma)."""
    n = int(math.ceil(TX_SPAN_SIGMA * sigma_db / TX_STEP_DB))
    x = np.arange(-n, n + 1) * TX_STEP_DB
    lw = -0.5 * (x / sigma_db) ** 2
    return x, lw - np.log(np.sum(np.exp(lw)))


def burst_table(model: BurstModel, burst: Burst, frames_pmf: np.ndarray, extent_m: float,
                nodes_db: np.ndarray) -> BurstTable:
    n = int(math.ceil(extent_m / TABLE_STEP_M)) + 2
    h = np.arange(n) * TABLE_STEP_M
    tx = np.asarray(nodes_db, float)[:, None]
    z = float(burst.xyz_m[2])
    if burst.silent:
        ll = model.silent_loglik(frames_pmf, h[None, :], z, tx)
    else:
        ll = model.heard_loglik(np.asarray(burst.rssi_dbm), np.asarray(burst.counts), frames_pmf, h[None, :], z, tx)
    # float32 holds down to -3.4e38: the models' floor of log 0 (-1e300) became -inf there, and two
    # -inf neighbours interpolated to NaN ("the bursts leave no place for the person on the grid",
    # an elicited look of `uavloc bench low_orbit --elicitation 2 --runs 12`, run 7)
    ll = np.maximum(ll, LOGLIK_FLOOR)
    return BurstTable(TABLE_STEP_M, np.broadcast_to(ll, (len(nodes_db), n)).astype(np.float32))


@dataclass(frozen=True)
class Grid:
    """A regular grid of cell centres: x0 + (i + 0.5) cell, y0 + (j + 0.5) cell."""

    x0: float
    y0: float
    cell_m: float
    nx: int
    ny: int

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        x = self.x0 + (np.arange(self.nx) + 0.5) * self.cell_m
        y = self.y0 + (np.arange(self.ny) + 0.5) * self.cell_m
        return np.meshgrid(x, y)  # (ny, nx) each


@dataclass(frozen=True)
class GridPosterior:
    """The posterior over where the person is at ``t_ref_s`` on ``grid`` (probabilities sum to 1)."""

    grid: Grid
    p: np.ndarray  # (ny, nx)
    t_ref_s: float
    static_weight: float  # posterior probability that the person stands still
    max_speed_m_s: float

    @property
    def mean_xy_m(self) -> np.ndarray:
        x, y = self.grid.centres()
        return np.array([float(np.sum(self.p * x)), float(np.sum(self.p * y))])

    @property
    def map_xy_m(self) -> np.ndarray:
        x, y = self.grid.centres()
        k = int(np.argmax(self.p))
        return np.array([float(x.flat[k]), float(y.flat[k])])

    def covariance(self) -> np.ndarray:
        x, y = self.grid.centres()
        m = self.mean_xy_m
        dx, dy = x - m[0], y - m[1]
        c = np.array([[np.sum(self.p * dx * dx), np.sum(self.p * dx * dy)],
                      [np.sum(self.p * dx * dy), np.sum(self.p * dy * dy)]])
        return c + np.eye(2) * self.grid.cell_m ** 2 / 12.0  # the cells' own spread

    def radius_about(self, xy_m, prob: float = 0.95) -> float:
        """Smallest radius of a circle about ``xy_m`` holding ``prob`` of the posterior (a cell's
        half-diagonal added: the mass of a cell is anywhere in it)."""
        x, y = self.grid.centres()
        d = np.hypot(x - xy_m[0], y - xy_m[1]).ravel()
        order = np.argsort(d)
        c = np.cumsum(self.p.ravel()[order])
        k = min(int(np.searchsorted(c, prob)), len(c) - 1)
        return float(d[order[k]] + self.grid.cell_m * math.sqrt(0.5))

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` positions (n, 2) drawn from the posterior (uniform within their cell)."""
        k = rng.choice(self.p.size, size=n, p=self.p.ravel())
        j, i = np.unravel_index(k, self.p.shape)
        g = self.grid
        return np.column_stack([g.x0 + (i + rng.random(n)) * g.cell_m, g.y0 + (j + rng.random(n)) * g.cell_m])


def _edge_mass(p: np.ndarray, cells: int = 2) -> float:
    """Posterior mass within ``cells`` of the grid's edge."""
    inner = p[cells:-cells, cells:-cells].sum() if min(p.shape) > 2 * cells else 0.0
    return float(p.sum() - inner)


def _grown(grid: Grid, bound: Grid) -> Grid:
    """``grid`` twice as wide each way (its cell kept), within ``bound``'s extent."""
    w, h = grid.nx * grid.cell_m, grid.ny * grid.cell_m
    lo = np.maximum([grid.x0 - w / 2, grid.y0 - h / 2], [bound.x0, bound.y0])
    hi = np.minimum([grid.x0 + 1.5 * w, grid.y0 + 1.5 * h],
                    [bound.x0 + bound.nx * bound.cell_m, bound.y0 + bound.ny * bound.cell_m])
    cell = max(grid.cell_m, float(np.max(hi - lo)) / (2 * COARSE_CELLS))
    n = np.maximum(np.ceil((hi - lo) / cell).astype(int), 1)
    return Grid(float(lo[0]), float(lo[1]), cell, int(n[0]), int(n[1]))


def _disc_blur(p: np.ndarray, radius_cells: float) -> np.ndarray:
    """``p`` (..., ny, nx) convolved with a uniform disc of ``radius_cells`` (normalised), by FFT."""
    r = int(math.ceil(radius_cells))
    if r < 1:
        return p
    yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
    k = (xx * xx + yy * yy <= radius_cells * radius_cells).astype(float)
    k /= k.sum()
    from scipy.signal import fftconvolve

    ker = k.reshape((1,) * (p.ndim - 2) + k.shape)
    return np.maximum(fftconvolve(p, ker, mode="same", axes=(-2, -1)), 0.0)


@dataclass
class BurstGridEstimator:
    """The grid posterior of one person from their bursts (see the module docstring). Tables are
    cached per burst: a person fitted again with one more burst costs one more table."""

    model: BurstModel
    frames_pmf: np.ndarray  # over K = 0..Kmax frames sent per burst
    max_speed_m_s: float = 0.0
    static_share: float = 1.0  # prior probability of standing still (1 when max_speed_m_s is 0)
    area_xy_m: np.ndarray | None = None  # the search area (polygon); the person is within it + margin
    area_margin_m: float = 0.0
    # Prior probability that a burst linked to this person is someone else's (see OUTLIER_SHARE)
    outlier_share: float = 0.0
    _tables: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        self._nodes, self._log_w = tx_nodes(self.model.tx_sigma_db)

    def _table(self, b: Burst) -> BurstTable:
        """``b``'s table out to the model's reach (computed once per burst: beyond it every position
        is as unlikely as the table's last, a burst is not heard from there)."""
        t = self._tables.get(b)
        if t is None:
            if len(self._tables) >= MAX_TABLES:
                self._tables.clear()
            t = self._tables[b] = burst_table(self.model, b, self.frames_pmf, self.model.reach_m(b.xyz_m[2]),
                                              self._nodes)
        return t

    def posterior(self, bursts: Sequence[Burst], t_ref_s: float) -> GridPosterior:
        # a unit no place explains (more frames than a burst sends: a burst and an access point's
        # answers heard as one run) is left out: its table is at the floor everywhere, which in
        # float32 would swamp every other unit and leave the whole area as the posterior
        bursts = [b for b in bursts if b.silent or float(self._table(b).loglik.max()) > 0.5 * LOGLIK_FLOOR]
        heard = [b for b in bursts if not b.silent]
        if not heard:
            raise EstimationError("no heard burst to estimate from")
        vmax = float(self.max_speed_m_s)
        p_static = 1.0 if vmax <= 0 else float(self.static_share)
        grid = self._first_grid(heard, t_ref_s, vmax if p_static < 1.0 else 0.0)
        post = None
        first = grid
        for _ in range(MAX_LEVELS + 2):
            # each unit's weight at its bearing's turn about the coarser grid's mean (unit_weights)
            post = self._on(grid, bursts, t_ref_s, vmax, p_static, None if post is None else post.mean_xy_m)
            if grid is not first and _edge_mass(post.p) > EDGE_MASS:
                grid = _grown(grid, first)  # the support was undersampled: the mass runs off this grid
                continue
            r95 = post.radius_about(post.mean_xy_m)
            if grid.cell_m <= max(MIN_CELL_M, r95 / FINE_CELLS_PER_RADIUS) * 1.0001:
                break
            grid = self._refined(post, r95)
        return post

    def _first_grid(self, heard: list[Burst], t_ref_s: float, vmax: float) -> Grid:
        lo = np.array([-np.inf, -np.inf])
        hi = np.array([np.inf, np.inf])
        for b in heard:  # the person is within reach of every vehicle that heard them
            r = self.model.reach_m(b.xyz_m[2]) + vmax * max(t_ref_s - b.t_s, 0.0)
            c = np.array(b.xyz_m[:2])
            lo, hi = np.maximum(lo, c - r), np.minimum(hi, c + r)
        if np.any(hi <= lo):  # bursts too far apart for one place (a walker faster than the bound?)
            allc = np.array([b.xyz_m[:2] for b in heard])
            r = max(self.model.reach_m(b.xyz_m[2]) for b in heard)
            lo, hi = allc.min(axis=0) - r, allc.max(axis=0) + r
        if self.area_xy_m is not None:
            a = np.asarray(self.area_xy_m, float)
            lo = np.maximum(lo, a.min(axis=0) - self.area_margin_m)
            hi = np.minimum(hi, a.max(axis=0) + self.area_margin_m)
            if np.any(hi <= lo):
                raise EstimationError("the bursts put the person outside the search area")
        cell = max(float(np.max(hi - lo)) / COARSE_CELLS, MIN_CELL_M)
        n = np.maximum(np.ceil((hi - lo) / cell).astype(int), 1)
        return Grid(float(lo[0]), float(lo[1]), cell, int(n[0]), int(n[1]))

    def _refined(self, post: GridPosterior, r95: float) -> Grid:
        g = post.grid
        keep = post.p > post.p.max() * math.exp(-SUPPORT_LOG)
        j, i = np.nonzero(keep)
        pad = SUPPORT_PAD_CELLS
        lo = np.array([g.x0 + (i.min() - pad) * g.cell_m, g.y0 + (j.min() - pad) * g.cell_m])
        hi = np.array([g.x0 + (i.max() + 1 + pad) * g.cell_m, g.y0 + (j.max() + 1 + pad) * g.cell_m])
        cell = max(MIN_CELL_M, min(g.cell_m / 2.0, r95 / FINE_CELLS_PER_RADIUS))
        span = hi - lo
        if float(np.max(span)) / cell > 2 * COARSE_CELLS:  # never more than (2 x 64)^2 cells
            cell = float(np.max(span)) / (2 * COARSE_CELLS)
        n = np.maximum(np.ceil(span / cell).astype(int), 1)
        return Grid(float(lo[0]), float(lo[1]), cell, int(n[0]), int(n[1]))

    def _loglik(self, grid: Grid, bursts: Sequence[Burst], t_ref_s: float, vmax: float,
                about_xy_m=None) -> tuple[np.ndarray, np.ndarray]:
        """(static, walking) log-likelihood sums over (tx node, ny, nx); walking None when vmax 0."""
        x, y = grid.centres()
        still = np.zeros((len(self._nodes),) + x.shape, np.float32)
        walk = np.zeros_like(still) if vmax > 0 else None
        eps = float(self.outlier_share)
        weights = unit_weights(bursts, getattr(self.model, "decorrelation_m", None),
                               getattr(self.model, "shared_and_own_db2", (1.0, 0.0)), about_xy_m)
        for b, wb in zip(bursts, weights):
            if wb <= 0.0:
                continue
            ll = self._table(b).at(np.hypot(x - b.xyz_m[0], y - b.xyz_m[1]))  # (N_tx, ny, nx)
            if wb < 1.0:
                ll = ll * np.float32(wb)
            if eps > 0:  # or another phone's, somewhere on the grid: its likelihood averaged over it
                lw = self._log_w[:, None, None]
                m = float(np.max(ll))
                bg = m + math.log(float(np.sum(np.exp(ll + lw - m))) / ll[0].size)
                ll = np.logaddexp(math.log1p(-eps) + ll, math.log(eps) + bg)
            still += ll
            if walk is not None:
                age = max(t_ref_s - b.t_s, 0.0)
                m = ll.max(axis=(1, 2), keepdims=True)
                blurred = _disc_blur(np.exp(ll - m), vmax * age / grid.cell_m)
                walk += m + np.log(np.maximum(blurred, 1e-300))
        return still, walk

    def _on(self, grid: Grid, bursts: Sequence[Burst], t_ref_s: float, vmax: float, p_static: float,
            about_xy_m=None) -> GridPosterior:
        still, walk = self._loglik(grid, bursts, t_ref_s, vmax, about_xy_m)
        prior = self._area_prior(grid)
        lw = self._log_w[:, None, None]
        branches = []
        if p_static > 0:
            branches.append((math.log(p_static), still + lw))
        if walk is not None and p_static < 1:
            branches.append((math.log(1.0 - p_static), walk + lw))
        ref = max(float(np.max(b + prior)) for _, b in branches)
        masses, ps = [], []
        for log_prior, b in branches:
            q = np.exp(b + prior - ref).sum(axis=0)  # (ny, nx), the offset integrated out
            masses.append(math.exp(log_prior) * float(q.sum()))
            ps.append(math.exp(log_prior) * q)
        total = float(sum(masses))
        if not total > 0 or not math.isfinite(total):
            raise EstimationError("the bursts leave no place for the person on the grid")
        p = sum(ps) / total
        static_w = masses[0] / total if p_static > 0 else 0.0
        return GridPosterior(grid, p, float(t_ref_s), static_w, vmax)

    def _area_prior(self, grid: Grid) -> np.ndarray:
        if self.area_xy_m is None:
            return np.zeros((grid.ny, grid.nx))
        import shapely
        from shapely.geometry import Polygon

        poly = Polygon(np.asarray(self.area_xy_m, float)).buffer(self.area_margin_m)
        x, y = grid.centres()
        inside = shapely.contains_xy(poly, x.ravel(), y.ravel()).reshape(x.shape)
        return np.where(inside, 0.0, -np.inf)


@dataclass(frozen=True)
class GridSpec:
    """What a fit on the grid needs besides the data (hashable: the fitting worker keeps one
    estimator, with its tables, per spec)."""

    model: object  # a BurstModel (frozen dataclass)
    frames_pmf: tuple[float, ...]
    max_speed_m_s: float
    static_share: float
    area_xy_m: tuple[tuple[float, float], ...] | None
    area_margin_m: float
    outlier_share: float = 0.0

    def estimator(self) -> BurstGridEstimator:
        return BurstGridEstimator(self.model, np.asarray(self.frames_pmf, float), self.max_speed_m_s,
                                  self.static_share, None if self.area_xy_m is None else np.asarray(self.area_xy_m),
                                  self.area_margin_m, self.outlier_share)


_ESTIMATORS: dict = {}


def estimator_for(spec: GridSpec) -> BurstGridEstimator:
    """One estimator (and its table cache) per spec in this process."""
    est = _ESTIMATORS.get(spec)
    if est is None:
        if len(_ESTIMATORS) > 8:
            _ESTIMATORS.clear()
        est = _ESTIMATORS[spec] = spec.estimator()
    return est


def grid_estimate(emitter_id: int, bursts: Sequence[Burst], spec: GridSpec, t_ref_s: float):
    """An :class:`~.estimate.Estimate` of the grid posterior (position: the posterior mean; radius:
    the 95 % circle about it; no velocity: a walker is only bounded), the posterior itself attached
    (``GridEstimate.posterior``) for the look planner."""
    from .estimate import Estimate

    post = estimator_for(spec).posterior(bursts, t_ref_s)
    m = post.mean_xy_m
    r95 = post.radius_about(m)
    cov = np.zeros((4, 4))
    cov[:2, :2] = post.covariance()
    heard = [b for b in bursts if not b.silent]
    n_slots = sum(len(b.rssi_dbm) for b in heard)
    last = max(b.t_s for b in heard)
    est = Estimate(int(emitter_id), "ok", float(t_ref_s), m, np.zeros(2), cov, r95, math.nan, False, None,
                   n_slots, last, 0.0, r95, float(spec.max_speed_m_s), False)
    return GridEstimate(**{f.name: getattr(est, f.name) for f in est.__dataclass_fields__.values()},
                        posterior=post, bursts_heard=len(heard))


from .estimate import Estimate as _Estimate  # noqa: E402


@dataclass(frozen=True)
class GridEstimate(_Estimate):
    """An Estimate from the grid, with its posterior."""

    posterior: GridPosterior | None = field(default=None, repr=False)
    bursts_heard: int = 0
