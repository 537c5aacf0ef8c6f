"""``uavloc bench field``: the search for real phones, against the plans a team could fly instead.

Paired worlds of the field scenario (phones that send probe-request bursts under changing random
addresses, a receiver that hears above its sensitivity; ``examples/field.toml``), ``--people``
people each, the paper's area and four vehicles. Each world is searched in the in-process mission
simulator (``sim_link.experiments.missionsim``: the daemon's policy, estimator and planner) by:

- ``uavloc``: what the product flies: the scan planned for the POD target
  (``search.pod_target``, ``search.pod_plan.scan_for``: lanes, speed and passes, keeping part of
  the energy for the looks), then orbit looks at the people heard and extra passes over the cells
  whose achieved POD is below the target (``search.coverage``);
- ``paper`` (anchor a): the paper's plan, its scan at 25 m/s and fly-by looks, no passes;
  with ``--elicitation`` (an on-board access point) also the comparison of orbit looks against
  fly-bys;
- ``lawnmower`` (anchor b): a conventional parallel-track search: the lane spacing, speed and
  passes that reach the same POD target with all the energy (``uavloc plan --pod``), no
  adaptivity: the vehicles fly home after it and the people are what the scan's data gives;
- ``clairvoyant`` (anchor c): the completion time of the same planner told every person's true
  position after uavloc's scan (``missionsim.oracle_completion_time_s``), a lower bound on the
  time better estimation alone could reach.

Printed per plan: people heard and located of those present (located: 95 % radius within the
scenario's required accuracy), the share of those present located by 15, 30 and 60 minutes of
mission time, the located who are inside their own 95 % circle, completion time
(mean ± 95 % CI), its ratio to the clairvoyant time, energy per vehicle, achieved POD over the area
(from the flown tracks), and why the people heard were not located. The issue's goal for this
scenario with 20 people: at least 95 % of the people present located, POD at least 0.95, in less
time than the lawnmower.
"""

from __future__ import annotations

import argparse
import math
import re
from collections import Counter
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from uavloc_gcs.cli._inputs import number

from ._progress import Progress

PLANS = ("uavloc", "paper", "lawnmower")
BY_MINUTES = (15, 30, 60)  # the share of the people present located by these times (issue 41 item 5)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--runs", type=number(int, min=1), default=3, help="paired worlds (default 3)")
    parser.add_argument("--people", type=number(int, min=1, max=200), default=20, help="people per world (default 20)")
    parser.add_argument("--pod", type=number(float, min=0.05, max=0.99), default=0.95,
                        help="POD target of uavloc's scan and of the lawnmower (default 0.95)")
    parser.add_argument("--scenario", default="field",
                        help="scenario file, or a shipped one by name (default field)")
    parser.add_argument("--seed", type=number(int, min=0), default=0, help="first world's seed (default 0)")
    parser.add_argument("--jobs", type=number(int, min=1, max=64), default=2, help="worker processes (default 2)")
    parser.add_argument("--elicitation", type=number(float, min=0.0, max=1000.0), default=None, metavar="HZ",
                        help="an on-board access point that makes phones in range answer at HZ frames a second "
                             "(emission.elicitation_rate_hz; default: the scenario's)")
    parser.add_argument("--mimicry", type=number(float, min=0.0, max=1.0), default=None, metavar="SHARE",
                        help="share of phones that know a network the access point offers and join it "
                             "(emission.mimicry_share; default: the scenario's)")
    parser.add_argument("--join", choices=("scan", "in-reach"), default=None,
                        help="when a phone starts answering the access point: at its next burst within reach "
                             "(scan) or on entering reach (in-reach, the model before issue 39's two mechanisms) "
                             "(emission.elicitation_join; default: the scenario's)")
    parser.add_argument("--packs", type=_packs, default=(1,), metavar="N[,N...]",
                        help="packs per vehicle (fleet.batteries) of uavloc's and the lawnmower's rows, a comma list, "
                             "e.g. 1,3 (default 1; the paper's plan flies one)")
    parser.add_argument("--plans", type=_plans, default=PLANS, metavar="NAME[,NAME...]",
                        help=f"which plans to fly, a comma list of {', '.join(PLANS)} (default all)")
    parser.add_argument("--findmy", type=_shares, default=None, metavar="SHARE[,SHARE...]",
                        help="share of phones sending Find My BLE beacons (emission.findmy_share), a comma list: "
                             "one set of rows per share on the same worlds, e.g. 0,0.25 (default: the scenario's)")
    parser.add_argument("--look-height", type=number(float, min=1.0, max=500.0), default=None, metavar="M",
                        help="orbit looks fly at M metres (search.look_height_m; default: the scenario's)")
    parser.add_argument("--trapped", action="store_true",
                        help="people who cannot move (simulation.motion = static, people.max_speed_m_s = 0)")
    parser.add_argument("--time-limit", type=number(float, min=1.0, max=1440.0), default=None, metavar="MIN",
                        help="the search's time limit in minutes (search.time_limit_s): the scan is planned within "
                             "it and at it every vehicle flies home from where it is (default: the scenario's, "
                             "else the simulator's 60 min)")


def _numbers(text: str, cast, lo: float, hi: float, what: str, rule: str) -> tuple:
    """A comma list of numbers in [lo, hi] (an argparse type): one sentence naming the rule if not."""
    try:
        out = tuple(cast(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what} separated by commas, got {text!r}") from None
    if not out or any(not lo <= n <= hi for n in out):
        raise argparse.ArgumentTypeError(f"{rule}, got {text!r}")
    return out


def _packs(text: str) -> tuple[int, ...]:
    return _numbers(text, int, 1, 10, "whole numbers of packs", "packs per vehicle must be 1 to 10")


def _shares(text: str) -> tuple[float, ...]:
    return _numbers(text, float, 0.0, 1.0, "shares between 0 and 1", "a share of phones is between 0 and 1")


def _plans(text: str) -> tuple[str, ...]:
    out = tuple(x.strip() for x in text.split(",") if x.strip())
    bad = [x for x in out if x not in PLANS]
    if not out or bad:
        raise argparse.ArgumentTypeError(f"unknown plan {', '.join(bad) or repr(text)}; choose from {', '.join(PLANS)}")
    return out


def label(plan: str, packs: int, findmy: float | None = None) -> str:
    """A row's name: the plan, with its packs when more than one and the share of phones sending
    BLE beacons when --findmy names it."""
    out = plan if packs == 1 else f"{plan} {packs} packs"
    if findmy is not None:
        out += " wifi" if findmy == 0 else f" +ble {100 * findmy:.0f}%"
    return out


def overrides(args: argparse.Namespace) -> dict:
    """The scenario sections ``--elicitation`` and ``--trapped`` replace."""
    out: dict = {}
    emission = {}
    if getattr(args, "elicitation", None) is not None:
        emission["elicitation_rate_hz"] = float(args.elicitation)
    if getattr(args, "mimicry", None) is not None:
        emission["mimicry_share"] = float(args.mimicry)
    if getattr(args, "join", None) is not None:
        emission["elicitation_join"] = args.join
    if emission:
        out["emission"] = emission
    if getattr(args, "look_height", None) is not None:
        out.setdefault("search", {})["look_height_m"] = float(args.look_height)
    if getattr(args, "time_limit", None) is not None:
        out.setdefault("search", {})["time_limit_s"] = 60.0 * float(args.time_limit)
    if getattr(args, "trapped", False):
        out["people"] = {"max_speed_m_s": 0.0}
        out["simulation"] = {"motion": "static"}
    return out


def scenario_for(plan: str, sc, pod_target: float):
    """The scenario each plan flies: uavloc's and the lawnmower's with the POD target."""
    if plan == "paper":
        return sc.replace(search={"pod_target": None})
    return sc.replace(search={"pod_target": pod_target})


def _fly(job):
    """One mission of one plan on one world (in a worker: the switches are module globals)."""
    plan, scenario_file, people, seed, pod_target, changes, packs, findmy = job
    from sim_link.experiments import missionsim
    from sim_link.world import World
    from uavloc_gcs.scenario import load_scenario
    from uavloc_gcs.search import coverage as coverage_mod, orbit, pod_plan

    shipped = {"rounds": coverage_mod.MAX_PASS_ROUNDS, "orbits": orbit.ORBIT_LOOKS, "share": pod_plan.SEARCH_SCAN_SHARE}
    sc = load_scenario(scenario_file)
    if changes:
        sc = sc.replace(**changes)
    sc = sc.replace(simulation={"people": people, "seed": seed})
    if packs > 1:
        sc = sc.replace(fleet={"batteries": int(packs)})
    if findmy is not None:
        sc = sc.replace(emission={"findmy_share": float(findmy)})
    sc = scenario_for(plan, sc, pod_target)
    try:
        if plan != "uavloc":  # the POD accumulator measures; no passes are added
            coverage_mod.MAX_PASS_ROUNDS = 0
        if plan == "paper":
            orbit.ORBIT_LOOKS = False
        if plan == "lawnmower":
            pod_plan.SEARCH_SCAN_SHARE = 1.0
        world = World(sc, seed=seed)
        res = missionsim.simulate_mission(sc, world, seed=seed, oracle=plan == "uavloc",
                                          adaptive=plan != "lawnmower", coverage=True)
    finally:
        coverage_mod.MAX_PASS_ROUNDS, orbit.ORBIT_LOOKS = shipped["rounds"], shipped["orbits"]
        pod_plan.SEARCH_SCAN_SHARE = shipped["share"]
    heard = [p for p in res.persons if p.heard]
    located = [p for p in heard if p.located]
    inside = [p for p in located if p.error_m <= p.claimed_radius_m]
    why = [_kind(p.reason) for p in heard if not p.located]
    senders = [] if world.beacons is None else [res.persons[i] for i in world.beacons.senders]
    ble15 = (len(senders), sum(p.located and p.fix_t_s <= 900.0 and p.error_m <= sc.people.required_accuracy_m
                               for p in senders))
    return {"plan": plan, "label": label(plan, packs, findmy), "seed": seed, "present": len(res.persons), "heard": len(heard), "located": len(located),
            "inside": len(inside), "fix_s": [float(p.fix_t_s) for p in located],
            "within_m": [float(p.error_m) for p in located], "time_s": res.completion_time_s, "oracle_s": res.oracle_completion_time_s,
            "energy_kj": float(np.mean(res.energy_j)) / 1e3, "pod": res.pod_overall, "why": why,
            "ble15": ble15, "required_m": float(sc.people.required_accuracy_m),
            "failsafe": res.failsafe_returns, "limited": bool(res.time_limited),
            # every circle reported (duplicates included), and each person heard's own: (located,
            # 95 % radius, holds the truth); issue 41 item 6 asks that they hold it 95 % of the time
            "claims": [tuple(c) for c in res.claims],
            "judged": [(bool(p.located), float(p.claimed_radius_m), bool(p.error_m <= p.claimed_radius_m))
                       for p in heard if math.isfinite(p.error_m) and math.isfinite(p.claimed_radius_m)],
            "foreign": [float(p.foreign_share) for p in located if math.isfinite(p.foreign_share)]}


def _kind(reason: str) -> str:
    """A policy statement without its numbers and details: "given up: not located after N orbit looks"."""
    return re.sub(r"\d+(\.\d+)?", "N", reason.split(" (")[0].split(";")[0]).strip() or "no statement"


def _pm(ci: float) -> str:
    return f" ± {ci:.0f}" if math.isfinite(ci) else ""


def _mmss(t: float) -> str:
    if not math.isfinite(t):
        return "-"
    m, s = divmod(int(round(t)), 60)
    return f"{m}:{s:02d}"


def table(rows: list[dict], runs: int) -> list[str]:
    """The printed table: one line per plan and one for the clairvoyant anchor."""
    from sim_link.experiments import mean_ci95

    out = []
    head = (f"{'plan':16s} {'heard':>9s} {'located':>9s} {'located %':>9s} {'by 15/30/60 min':>15s} "
            f"{'inside r95':>10s} {'time m:s':>14s} {'/ clairv.':>9s} {'kJ/vehicle':>10s} {'POD':>5s}")
    out += [head, "-" * len(head)]
    oracle = [r["oracle_s"] for r in rows if r.get("label", r["plan"]) == "uavloc" and math.isfinite(r["oracle_s"])]
    if not oracle:
        oracle = [r["oracle_s"] for r in rows if r["plan"] == "uavloc" and math.isfinite(r["oracle_s"])]
    t_oracle = float(np.mean(oracle)) if oracle else math.nan
    for plan in dict.fromkeys(r.get("label", r["plan"]) for r in rows):
        rs = [r for r in rows if r.get("label", r["plan"]) == plan]
        if not rs:
            continue
        present, heard, located, inside = (sum(r[k] for r in rs) for k in ("present", "heard", "located", "inside"))
        m, ci, _ = mean_ci95([r["time_s"] for r in rs])
        t = _mmss(m) + (_pm(ci) + " s" if runs > 1 and math.isfinite(ci) else "")
        pod = float(np.mean([r["pod"] for r in rs]))
        fixes = [t for r in rs for t in r.get("fix_s", [])]
        by = "/".join(f"{100.0 * sum(f <= m * 60.0 for f in fixes) / max(present, 1):.0f}" for m in BY_MINUTES) + " %"
        out.append(f"{plan:16s} {f'{heard}/{present}':>9s} {f'{located}/{present}':>9s} "
                   f"{100.0 * located / max(present, 1):8.0f}% {by:>15s} {inside / max(located, 1):10.2f} {t:>14s} "
                   f"{m / t_oracle if t_oracle else math.nan:9.2f} {np.mean([r['energy_kj'] for r in rs]):10.1f} "
                   f"{pod:5.2f}")
    out.append(f"{'clairvoyant':16s} {'':>9s} {'':>9s} {'':>9s} {'':>15s} {'':>10s} {_mmss(t_oracle):>14s} {1.0:9.2f}")
    return out


def foreign_lines(rows: list[dict]) -> list[str]:
    """Per plan that located someone: the share of the located people's bursts another phone sent
    (a reported person is judged as the phone that sent most of their bursts:
    sim_link.experiments.truth.person_results)."""
    out = []
    for plan in dict.fromkeys(r["label"] for r in rows):
        shares = [f for r in rows if r["label"] == plan for f in r.get("foreign", [])]
        if shares:
            out.append(f"bursts of another phone in a located person, {plan}: {100 * float(np.mean(shares)):.1f} % "
                       f"on average, {sum(f > 0.02 for f in shares)} of {len(shares)} above 2 % "
                       f"(worst {100 * max(shares):.0f} %; issue 41's goal: at most 2 %)")
    return out


def circle_lines(rows: list[dict]) -> list[str]:
    """Per plan, how many of the people heard and not located had the truth inside the 95 % circle
    reported for them (the circle a team would search)."""
    out = []
    for plan in dict.fromkeys(r["label"] for r in rows):
        c = [ok for r in rows if r["label"] == plan for located, _, ok in r.get("judged", []) if not located]
        if c:
            out.append(f"heard, not located, {plan}: {sum(c)} of {len(c)} inside the 95 % circle reported "
                       "(issue 41's goal: 95 %)")
    return out


def claims_lines(rows: list[dict]) -> list[str]:
    """Per plan, every circle reported at the end (a phone under several addresses may be reported
    as several people; each is judged against the phone that sent most of its bursts)."""
    out = []
    for plan in dict.fromkeys(r["label"] for r in rows):
        mine = [r for r in rows if r["label"] == plan and "claims" in r]
        c = [x for r in mine for x in r["claims"]]
        if not c:
            continue
        heard = sum(r["heard"] for r in mine)
        out.append(f"every circle reported, {plan}: {len(c)} {'person' if len(c) == 1 else 'people'} reported for "
                   f"{heard} phone{'' if heard == 1 else 's'} heard; circles that hold the phone behind them: "
                   f"{sum(ok for _, _, ok in c)} of {len(c)}")
    return out


CIRCLES_M = (15.0, 30.0, 50.0, 100.0)  # the circles a team on the ground could search, at the end


def narrowed_lines(rows: list[dict]) -> list[str]:
    """Per plan, the people present whose 95 % circle at the end was at most 15 / 30 / 50 / 100 m
    and held the truth: the figure nearest to "located" where 15 m is out of reach."""
    out = []
    for plan in dict.fromkeys(r["label"] for r in rows):
        mine = [r for r in rows if r["label"] == plan and "judged" in r]
        if not mine:
            continue
        present = sum(r["present"] for r in mine)
        n = [sum(rad <= c and ok for r in mine for _, rad, ok in r["judged"]) for c in CIRCLES_M]
        out.append(f"people within a 95 % circle that holds them at the end, {plan}: "
                   + " / ".join(f"{k} of {present} within {c:g} m" for k, c in zip(n, CIRCLES_M)))
    return out


def main(args: argparse.Namespace) -> int:
    from uavloc_gcs.examples import scenario_path
    from uavloc_gcs.scenario import load_scenario

    scenario_file = str(scenario_path(args.scenario))
    seeds = [args.seed + k for k in range(args.runs)]
    changes = overrides(args)
    shares = args.findmy if getattr(args, "findmy", None) is not None else (None,)
    jobs = [(plan, scenario_file, args.people, s, args.pod, changes, p, f) for s in seeds for plan in args.plans
            for p in (args.packs if plan != "paper" else (1,)) for f in shares]
    bar = Progress(len(jobs))
    rows = []
    with ProcessPoolExecutor(max(1, args.jobs)) as pool:
        for row in pool.map(_fly, jobs):
            rows.append(row)
            bar.step(f"{row['label']} world {row['seed']}")
    ap = ""
    if args.elicitation:
        em = load_scenario(scenario_file).replace(**changes).emission
        ap = (f", access point {args.elicitation:g} Hz joined by {100 * em.mimicry_share:.0f} % of the phones "
              + ("at a burst within reach" if em.elicitation_join == "scan" else "on entering reach"))
    extra = "".join([ap,
                     f", looks at {args.look_height:g} m" if getattr(args, "look_height", None) is not None else "",
                     ", trapped (static) people" if args.trapped else ""])
    print(f"the search for real phones on '{args.scenario}'{extra}: {args.people} people, {args.runs} paired world(s) "
          f"(seeds {seeds[0]}-{seeds[-1]}), POD target {args.pod:g}")
    for line in table(rows, args.runs):
        print(line)
    for plan in dict.fromkeys(r["label"] for r in rows):
        n, ok = (sum(r.get("ble15", (0, 0))[k] for r in rows if r["label"] == plan) for k in (0, 1))
        if n:
            print(f"phones sending BLE beacons, {plan}: {ok} of {n} located within "
                  f"{rows[0].get('required_m', 15):g} m of the truth by 15 min (issue 39's goal: 95 %)")
    for line in foreign_lines(rows):
        print(line)
    for line in circle_lines(rows) + claims_lines(rows) + narrowed_lines(rows):
        print(line)
    for plan in dict.fromkeys(r["label"] for r in rows):
        why = Counter(k for r in rows if r["label"] == plan for k in r["why"])
        if why:
            print(f"heard, not located, {plan}: " + "; ".join(f"{n} {k}" for k, n in why.most_common(4)))
    cut = {plan: sum(r.get("failsafe", 0) for r in rows if r["label"] == plan) for plan in dict.fromkeys(r["label"] for r in rows)}
    if any(cut.values()):  # the simulator's battery failsafe (missionsim.Vehicle.failsafe): the plan overran a pack
        print("flights cut by the battery failsafe at the reserve (plans that overran a pack): "
              + ", ".join(f"{plan} {n}" for plan, n in cut.items() if n))
    ended = {plan: sum(r.get("limited", False) for r in rows if r["label"] == plan)
             for plan in dict.fromkeys(r["label"] for r in rows)}
    if any(ended.values()):  # missionsim: at the limit every vehicle flies home from where it is
        from sim_link.experiments.missionsim import DEFAULT_MAX_TIME_S

        given = load_scenario(scenario_file).replace(**changes).search.time_limit_s
        limit = given if given is not None else DEFAULT_MAX_TIME_S
        print(f"searches ended by the time limit ({limit / 60:g} min; then every vehicle home from where it "
              "was, nothing more heard): " + ", ".join(f"{plan} {n} of {args.runs}" for plan, n in ended.items() if n))
    most = max(args.packs)
    u = [r for r in rows if r["label"] == label("uavloc", most, shares[-1])]
    lm = [r for r in rows if r["label"] == label("lawnmower", most, shares[-1])]
    if not u or not lm:
        return 0
    located = sum(r["located"] for r in u) / max(1, sum(r["present"] for r in u))
    pod = float(np.mean([r["pod"] for r in u]))
    faster = float(np.mean([r["time_s"] for r in u])) < float(np.mean([r["time_s"] for r in lm]))
    met = located >= 0.95 and pod >= args.pod and faster
    print(f"Goal (>= 95 % of people present located, POD >= {args.pod:g}, faster than the lawnmower): "
          f"{'met' if met else 'not met'}: uavloc located {100 * located:.0f} % with POD {pod:.2f}, "
          f"{'faster' if faster else 'not faster'} than the lawnmower.")
    return 0


if __name__ == "__main__":  # pragma: no cover
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_arguments(p)
    raise SystemExit(main(p.parse_args()))
