"""``uavloc bench identity``: linking addresses into people on simulated worlds with known truth.

Worlds over ``--scenario`` (default ``field``: the paper's 1120 x 640 m area and fleet, the field
channel, eta 2.3, heard above -90 dBm, phones 3 dB apart in transmit power), heard by the
scenario's vehicles flying lawnmower lanes (100 m apart, at its speed and altitude) over equal
strips of the area's bounding box, back and forth, for ``--duration`` s:

- ``--world sim_link`` (default): :class:`sim_link.world.World` with the scenario's emission model,
  people and phone catalogue (11 models by population share, 14 % keeping a hardware address);
  truth from ``World.person_of``;
- ``--world own``: this module's generator, for a chosen fingerprint diversity: ``--people``
  phones walking at up to the speed bound (constant velocity, random heading and speed, reflected
  at the edges), each of one of ``--models`` equally common models (its fingerprint); bursts as a
  renewal process (per phone a median gap log-uniform in 20-135 s, the 90th percentile twice it,
  1-2 s long, a per-phone median of 5-40 frames), a new random locally administered address per
  burst except a ``--stable`` fraction that keeps its hardware address; a frame is heard when its
  RSSI (i.i.d. shadowing) exceeds the sensitivity (within ``fleet.comm_range_m`` without one);
  heard frames in 0.5 s slots.

Printed per density (and fingerprint diversity), means over ``--runs`` worlds: people heard, people
reported, bursts, bursts assigned to the wrong person (a burst whose linked person's majority truth
is another person), splits (extra people a true person was cut into), merges (extra true people
inside a reported person), the wrong bursts among people whose every link is sure (``w.sure``: how
far the flag can be trusted), people flagged uncertain, and the link time from scratch. Anchors
measured in the same run: ``addresses`` (no linking: every address a person) and ``fingerprint``
(every address of one fingerprint one person, which merges same-model people).
"""

from __future__ import annotations

from uavloc_gcs.cli._inputs import number, number_list
import argparse
import time
from dataclasses import dataclass

import numpy as np

from uavloc_gcs.estimation.identity import link
from uavloc_gcs.estimation.model import ChannelModel
from uavloc_gcs.observations import SlotBatch

LANE_SPACING_M = 100.0
SLOT_S = 0.5


@dataclass(frozen=True)
class Setting:
    """What a world takes from the scenario: area (bounding box, origin corner and size [m]),
    fleet, channel and the people's speed bound."""

    origin_m: tuple
    size_m: tuple
    vehicles: int
    speed_m_s: float
    altitude_m: float
    channel: ChannelModel
    max_speed_m_s: float
    tx_margin_db: float = 0.0  # how much louder or quieter than nominal a phone may be (2 x the spread)

    @staticmethod
    def from_scenario(sc) -> "Setting":
        xy = sc.area_xy_m()
        lo, hi = xy.min(axis=0), xy.max(axis=0)
        return Setting(tuple(lo), tuple(hi - lo), sc.fleet.vehicles, sc.fleet.speed_m_s, sc.fleet.altitude_m,
                       ChannelModel.from_scenario(sc), sc.people.max_speed_m_s,
                       2.0 * sc.simulation.tx_power_spread_db)

    @property
    def area_m2(self) -> float:
        return float(self.size_m[0] * self.size_m[1])


# examples/field.toml's, for tests that need no scenario file
FIELD = Setting((0.0, 0.0), (1120.0, 640.0), 4, 25.0, 100.0, ChannelModel(-40.0, 2.3, 4.0, 1.0, 150.0, -90.0), 1.5)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--runs", type=number(int, min=1), default=5, help="worlds per configuration (default 5)")
    parser.add_argument("--people", type=number_list(int, min=1, max=1000), default="10,20,50",
                        help="comma-separated people per world, 1-1000 each (default 10,20,50)")
    parser.add_argument("--models", type=number_list(int, min=1, max=1000), default="2,5,11",
                        help="comma-separated numbers of phone models, equally common (default 2,5,11; sim_link's "
                             "catalogue has 11)")
    parser.add_argument("--stable", type=number(float, min=0, max=1), default=0.14,
                        help="fraction of phones with a stable address (default 0.14, sim_link's catalogue)")
    parser.add_argument("--duration", type=number(float, above=0, unit="s"), default=1800.0, help="flight time [s] (default 1800)")
    parser.add_argument("--scenario", default="field",
                        help="scenario file, or a shipped one by name (default field: the burst world's channel)")
    parser.add_argument("--seed", type=number(int, min=0), default=0, help="seed (default 0)")
    parser.add_argument("--world", choices=("sim_link", "own"), default="sim_link",
                        help="sim_link: the scenario's simulated world (its emission model and phone catalogue; "
                             "--models and --stable do not apply); own: this module's generator (default sim_link)")


@dataclass(frozen=True)
class SimWorld:
    slots: SlotBatch
    truth: dict  # address -> person index
    setting: Setting

    def person_of(self, addresses) -> np.ndarray:
        return np.array([self.truth[int(a)] for a in np.asarray(addresses).reshape(-1)], dtype=np.int64)


def vehicle_tracks(st: Setting, duration_s: float, dt_s: float = 0.25) -> tuple[np.ndarray, np.ndarray]:
    """(T,) times and (V, T, 3) positions of vehicles flying lawnmower lanes over their strips of
    the area, back and forth."""
    t = np.arange(0.0, duration_s, dt_s)
    w, h = st.size_m
    strip = w / st.vehicles
    pos = np.zeros((st.vehicles, len(t), 3))
    for v in range(st.vehicles):
        xs = np.arange(v * strip + LANE_SPACING_M / 2, (v + 1) * strip, LANE_SPACING_M)
        pts = []
        for i, x in enumerate(xs):
            ys = (0.0, h) if i % 2 == 0 else (h, 0.0)
            pts += [(x, ys[0]), (x, ys[1])]
        pts = np.array(pts + pts[::-1])  # there and back: a closed loop
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        s = (st.speed_m_s * t) % cum[-1]
        pos[v, :, 0] = st.origin_m[0] + np.interp(s, cum, pts[:, 0])
        pos[v, :, 1] = st.origin_m[1] + np.interp(s, cum, pts[:, 1])
        pos[v, :, 2] = st.altitude_m
    return t, pos


def simulate(st: Setting, n_people: int, n_models: int, *, stable: float, duration_s: float,
             rng: np.random.Generator) -> SimWorld:
    """One world's heard slots and its truth (see the module docstring)."""
    start = rng.uniform([0, 0], st.size_m, size=(n_people, 2))
    heading = rng.uniform(0, 2 * np.pi, n_people)
    speed = rng.uniform(0, st.max_speed_m_s, n_people)
    vel = np.column_stack([np.cos(heading), np.sin(heading)]) * speed[:, None]
    fingerprints = rng.integers(1, 2**62, size=n_models)
    model = rng.integers(0, n_models, n_people)
    is_stable = rng.random(n_people) < stable
    hw_address = rng.integers(0, 2**46, n_people) & ~(0x02 << 40) & 0xFFFF_FFFF_FFFF  # U/L bit clear
    median_gap = np.exp(rng.uniform(np.log(20.0), np.log(135.0), n_people))
    frames_median = rng.uniform(5, 40, n_people)
    tv, vpos = vehicle_tracks(st, duration_s)
    ch = st.channel
    rows = []
    truth: dict[int, int] = {}
    for p in range(n_people):
        t = -rng.uniform(0, median_gap[p] * 2)
        while True:
            t += median_gap[p] * np.exp(rng.normal(0, np.log(2.0) / 1.2816))
            if t >= duration_s:
                break
            if t < 0:
                continue
            if is_stable[p]:
                addr = int(hw_address[p])
            else:
                addr = int(rng.integers(0, 2**48)) | (0x02 << 40)
                addr &= ~(0x01 << 40)  # unicast
            truth[addr] = p
            n_frames = max(1, int(rng.poisson(frames_median[p])))
            ft = t + np.sort(rng.uniform(0, rng.uniform(1.0, 2.0), n_frames))
            ft = ft[ft < tv[-1]]
            if not len(ft):
                continue
            xy = np.asarray(st.origin_m) + _position(start[p], vel[p], ft, st.size_m)
            k = np.searchsorted(tv, ft).clip(0, len(tv) - 1)
            for v in range(st.vehicles):
                a = vpos[v, k]
                d = np.sqrt(np.sum((xy - a[:, :2]) ** 2, axis=1) + a[:, 2] ** 2)
                rssi = ch.rssi_dbm(d) + rng.normal(0, ch.shadowing_sigma_db, len(d))
                heard = rssi > ch.sensitivity_dbm if ch.sensitivity_dbm is not None else d <= ch.comm_range_m
                if not heard.any():
                    continue
                slot = np.floor(ft[heard] / SLOT_S)
                for s_ in np.unique(slot):
                    m = slot == s_
                    i = np.flatnonzero(heard)[m]
                    rows.append((ft[i[0]], v + 1, *a[i].mean(axis=0), addr, float(rssi[heard][m].mean()),
                                 int(m.sum()), int(fingerprints[model[p]])))
    if not rows:
        return SimWorld(SlotBatch.empty(), truth, st)
    r = np.array(rows, dtype=object)
    slots = SlotBatch.from_columns(r[:, 0].astype(float), r[:, 1].astype(int), r[:, 2:5].astype(float),
                                   r[:, 5].astype(np.int64), r[:, 6].astype(float), r[:, 7].astype(int),
                                   address=r[:, 5].astype(np.int64), fingerprint=r[:, 8].astype(np.int64))
    return SimWorld(slots.sorted_by_time(), truth, st)


def simulate_sim_link(sc, n_people: int, *, duration_s: float, seed: int) -> "SimWorld":
    """One world of sim_link.world (the scenario's emission, people, channel and phone catalogue),
    heard by the same vehicles; the truth from ``World.person_of``."""
    from sim_link.world import World

    st = Setting.from_scenario(sc)
    world = World(sc, seed=seed, people=n_people, horizon_s=duration_s + 60.0)
    tv, vpos = vehicle_tracks(st, duration_s, dt_s=sc.channel.slot_s)
    slots = SlotBatch.concat([world.hear_track(v + 1, tv, vpos[v]) for v in range(st.vehicles)]).sorted_by_time()
    addrs = np.unique(slots.address)
    truth = dict(zip(addrs.tolist(), world.person_of(addrs).tolist()))
    return SimWorld(slots, truth, st)


def _position(start, vel, t, size_m) -> np.ndarray:
    """Constant velocity reflected at the area's edges (area from 0 to ``size_m``)."""
    out = []
    for c, size in enumerate(size_m):
        x = (start[c] + vel[c] * t) % (2 * size)
        out.append(np.where(x > size, 2 * size - x, x))
    return np.column_stack(out)


def score(person_of_burst: np.ndarray, truth_of_burst: np.ndarray, sure=None) -> dict:
    """Linking quality from each burst's reported person and true person (``sure``: the people
    whose every link is sure; then also the wrong bursts among theirs, ``wrong_sure``)."""
    reported, truth = np.asarray(person_of_burst), np.asarray(truth_of_burst)
    wrong = 0
    merges = 0
    wrong_sure = 0
    for p in np.unique(reported):
        tr = truth[reported == p]
        vals, counts = np.unique(tr, return_counts=True)
        wrong += len(tr) - counts.max()
        merges += len(vals) - 1
        if sure is not None and int(p) in sure:
            wrong_sure += len(tr) - counts.max()
    splits = sum(len(np.unique(reported[truth == q])) - 1 for q in np.unique(truth))
    out = dict(heard=len(np.unique(truth)), reported=len(np.unique(reported)), bursts=len(truth), wrong=wrong,
               splits=splits, merges=merges)
    if sure is not None:
        out["wrong_sure"] = wrong_sure
    return out


def evaluate(world: SimWorld) -> dict:
    """Scores of the linker and the two anchors on one world."""
    slots = world.slots
    st = world.setting
    t0 = time.perf_counter()
    linking = link(slots, st.channel, max_speed_m_s=st.max_speed_m_s, area_m2=st.area_m2,
                   tx_margin_db=st.tx_margin_db)
    elapsed = time.perf_counter() - t0
    nb = linking.n_bursts
    first = np.zeros(nb, dtype=np.int64)
    first[linking.burst_index] = np.arange(len(slots))  # any slot of each burst
    truth = np.asarray(world.person_of(slots.address[first]))
    sure = {p for p in linking.people() if linking.uncertain(p) is None}
    out = {"linker": score(linking.slots.emitter_id[first], truth, sure),
           "addresses": score(slots.address[first], truth),
           "fingerprint": score(slots.fingerprint[first], truth)}
    out["linker"]["uncertain"] = sum(linking.uncertain(p) is not None for p in linking.people())
    out["linker"]["time_ms"] = 1e3 * elapsed
    return out


def main(args: argparse.Namespace) -> int:
    from uavloc_gcs.examples import scenario_path
    from uavloc_gcs.scenario import load_scenario

    from ._progress import Progress

    sc = load_scenario(scenario_path(args.scenario))
    st = Setting.from_scenario(sc)
    rng = np.random.default_rng(args.seed)
    densities = list(args.people)
    own = args.world == "own"
    models = list(args.models) if own else [0]
    sens = "no threshold" if st.channel.sensitivity_dbm is None else f"heard above {st.channel.sensitivity_dbm:g} dBm"
    print(f"'{args.scenario}': {st.size_m[0]:g} x {st.size_m[1]:g} m, {st.vehicles} vehicles at {st.speed_m_s:g} m/s, "
          f"eta {st.channel.path_loss_exponent:g}, {sens}, transmit margin {st.tx_margin_db:g} dB; "
          f"{args.runs} worlds per row of {args.duration:g} s (seed {args.seed}); "
          + (f"own generator, {args.stable:.0%} stable addresses" if own else
             f"sim_link world, emission {sc.emission.model}, its phone catalogue ('models' 0)") + "; means per world")
    bar = Progress(len(densities) * len(models) * args.runs)
    head = (f"{'people':>6} {'models':>6} {'method':<11} {'heard':>6} {'reported':>8} {'bursts':>7} "
            f"{'wrong':>6} {'wrong %':>7} {'w.sure':>6} {'splits':>6} {'merges':>6} {'uncert':>6} {'ms':>6}")
    print(head)
    print("-" * len(head))
    for n in densities:
        for m in models:
            acc: dict[str, list[dict]] = {}
            for r in range(args.runs):
                world = (simulate(st, n, m, stable=args.stable, duration_s=args.duration, rng=rng) if own else
                         simulate_sim_link(sc, n, duration_s=args.duration, seed=args.seed * 1000 + n * 10 + r))
                bar.step(f"{n} people, {m} models")
                if len(world.slots) == 0:
                    continue
                for k, v in evaluate(world).items():
                    acc.setdefault(k, []).append(v)
            for method in ("linker", "addresses", "fingerprint"):
                rs = acc.get(method, [])
                if not rs:
                    continue
                mean = {k: float(np.mean([r.get(k, np.nan) for r in rs])) for k in rs[0]}
                wrong_pct = 100.0 * sum(r["wrong"] for r in rs) / max(sum(r["bursts"] for r in rs), 1)
                unc = f"{mean['uncertain']:6.1f}" if "uncertain" in mean else f"{'':>6}"
                wsure = f"{mean['wrong_sure']:6.1f}" if "wrong_sure" in mean else f"{'':>6}"
                ms = f"{mean['time_ms']:6.1f}" if "time_ms" in mean else f"{'':>6}"
                print(f"{n:>6} {m:>6} {method:<11} {mean['heard']:6.1f} {mean['reported']:8.1f} "
                      f"{mean['bursts']:7.1f} {mean['wrong']:6.1f} {wrong_pct:7.1f} {wsure} {mean['splits']:6.1f} "
                      f"{mean['merges']:6.1f} {unc} {ms}")
    return 0
