"""``uavloc bench looks``: the look-planning rules, switched on and off on the same worlds.

Flies the paper's MLE-EPSO (M) mission (``sim_link.experiments.run_task``: scan, MLE, EPSO
replanning, return) on paired worlds with each variant of the rules that place a look:

- ``default``: as shipped;
- ``no-inside-cut``: a repeated look from a vehicle already inside the look radius keeps the whole
  radius (``search.aiming.INSIDE_LOOK_FRACTION = None``), so it may be planned at the vehicle's own
  position -- seen on PX4 SITL as three looks of zero length and a person given up;
- ``no-shrink``: every look keeps the whole look radius, even after looks that heard a person
  without locating them (``search.targets.LOOK_SHRINK = 1``; by default each such look halves
  the next radius);
- ``no-settle``: a person who was mirror-ambiguous is located as soon as the estimator stops
  calling it ambiguous (mirror under 5 %), not when the mirror holds under 1 %
  (``search.judging.AMBIGUITY_SETTLED_MASS = None``);
- ``radial``: a repeated look is planned about the estimate itself, so a vehicle near home flies
  out to the near edge of its disk and back along one line (``search.aiming.SIDEWAYS_LOOK_FRACTION
  = None``; by default it goes beside the person, across that line);
- ``cap4``: a person is given up after 4 looks (``search.judging.MAX_LOOKS = 4``; by default only
  two looks that heard nothing, or no energy for a look, give a person up);
- ``edge-reach``: a look may pass at the edge of the range of the predicted position, out of
  hearing of much of the predicted 95 % circle (``estimation.access.REACH_WHOLE_CIRCLE = False``);
- ``heard-tracks``: the estimator's silences only where the vehicle heard some other phone, which
  is all the daemon knows of where it listened (``missionsim.LISTENING = "heard"``; by default the
  whole flight);
- ``no-silences``: no silences at all (``missionsim.LISTENING = "none"``);
- ``bounds-not-in-cov``: the hearing constraints move and reweigh candidates but add no
  information to their covariance (``estimation.modes.BOUNDS_IN_COVARIANCE = False``);
- ``no-bounded-mirror``: a candidate the hearing constraints moved gets no mirror starts of its
  own (``estimation.modes.MIRROR_AFTER_BOUNDS = False``);
- ``bound-cap``: the hearing constraints shrink a candidate's standard deviation by at most 1.5x
  in any direction (``estimation.modes.BOUND_SHRINK_MAX = 1.5``; by default no cap);
- ``turn-mixture``: a second motion model in which the person turned since the oldest data
  (``estimation.estimate.TURN_MIXTURE = True``; off by default);
- ``tail-1``, ``tail-4``: the maneuver offsets' prior a multivariate t with 1 or 4 degrees of
  freedom (``estimation.estimate.MANEUVER_TAIL_DOF``; by default Gaussian);
- ``turn-tail``: ``turn-mixture`` and ``tail-4`` together;
- the turn models, shipped on since 2026-11-25 (the variants ``turn-jump``, ``merge-twins``,
  ``turn-200``, ``turns`` and ``turns-200`` that switched them on are gone): ``no-turn-jump``, no
  models in which the person turned once at one of the longest gaps in the data
  (``estimation.estimate.TURN_JUMP = False``); ``turn-600``, a turn every 600 s (the maneuver
  time) on average in their prior instead of 200 s (``estimation.estimate.TURN_TIME_S = None``);
  ``split-twins``, only modes of different motion models that meet at the reference time are one
  candidate (``estimation.estimate.TWINS_ACROSS_MODELS_ONLY = True``); ``no-turns``, all three:
  the estimator as it was before;
- ``turn-grid``: the turn models start from the whole start grid instead of the main
  model's modes (``estimation.estimate.TURN_STARTS_FROM_MAIN = False``);
- ``turn-mirrors``: the turn models also start from their own best mode's mirrors
  (``estimation.estimate.TURN_MIRRORS = True``);
- ``cover-mirror``: a second mode holding over 5 % of the mass is covered by reaching over its
  whole 95 % circle, not by the 95 % circle of the two modes' mixture
  (``estimation.estimate.MIXTURE_RADIUS = False``).

``uavloc bench localize --switch`` runs the estimator's switches of this list in the localization
benchmark (given twice, both).

Printed per variant: people heard and located, located inside their own 95 % radius, mean
completion time with its 95 % CI, and the ratio to the clairvoyant plan's completion time (the
anchor: the same planner told every person's true position after the scan), plus the paired
difference of completion times against ``default``.
"""

from __future__ import annotations

from uavloc_gcs.cli._inputs import number
import argparse
import math
import re
import sys
from collections import Counter
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from ._progress import Progress


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--runs", type=number(int, min=1), default=10, help="paired worlds per variant (default 10; 40 for the README)")
    parser.add_argument("--people", type=number(int, min=1, max=1000), default=20, help="people per world (default 20)")
    parser.add_argument("--seed", type=number(int, min=0), default=0, help="experiment seed (default 0, as `uavloc experiment`)")
    parser.add_argument("--scenario", default="paper",
                        help="scenario file, or a shipped one by name: paper, field, small (default paper; field: "
                             "the same area with phones that send probe bursts)")
    parser.add_argument("--variants", default="default",
                        help=f"comma-separated, of {', '.join(VARIANTS)}; 'all' for every one (default: default, "
                             "the shipped rules; each variant costs about one default run)")
    parser.add_argument("--jobs", type=number(int, min=1, max=64), default=2, help="worker processes (default 2)")


# variant -> (module, switch, its value in that variant); "default" changes nothing
SWITCHES = {
    "no-inside-cut": ("aiming", "INSIDE_LOOK_FRACTION", None),
    "no-shrink": ("targets", "LOOK_SHRINK", 1.0),
    "no-settle": ("judging", "AMBIGUITY_SETTLED_MASS", None),
    "radial": ("aiming", "SIDEWAYS_LOOK_FRACTION", None),
    "cap4": ("judging", "MAX_LOOKS", 4),
    "edge-reach": ("access", "REACH_WHOLE_CIRCLE", False),
    "heard-tracks": ("missionsim", "LISTENING", "heard"),
    "no-silences": ("missionsim", "LISTENING", "none"),
    "bounds-not-in-cov": ("modes", "BOUNDS_IN_COVARIANCE", False),
    "no-bounded-mirror": ("modes", "MIRROR_AFTER_BOUNDS", False),
    "bound-cap": ("modes", "BOUND_SHRINK_MAX", 1.5),
    "turn-mixture": ("estimate", "TURN_MIXTURE", True),
    "tail-1": ("estimate", "MANEUVER_TAIL_DOF", 1.0),
    "tail-4": ("estimate", "MANEUVER_TAIL_DOF", 4.0),
    "no-turn-jump": ("estimate", "TURN_JUMP", False),
    "turn-600": ("estimate", "TURN_TIME_S", None),
    "split-twins": ("estimate", "TWINS_ACROSS_MODELS_ONLY", True),
    "turn-grid": ("estimate", "TURN_STARTS_FROM_MAIN", False),
    "turn-mirrors": ("estimate", "TURN_MIRRORS", True),
    "cover-mirror": ("estimate", "MIXTURE_RADIUS", False),
}
# variant -> the switches it turns together
COMBINED = {"turn-tail": ("turn-mixture", "tail-4"), "no-turns": ("no-turn-jump", "split-twins", "turn-600")}
VARIANTS = ("default", *SWITCHES, *COMBINED)
_SHIPPED: dict = {}  # the switches' shipped values, read once per worker before any change


def switch_modules() -> dict:
    """The modules SWITCHES names, by the names it uses (the switches are their module globals)."""
    from sim_link.experiments import missionsim
    from uavloc_gcs.estimation import access, estimate, modes
    from uavloc_gcs.search import aiming, judging, policy, targets

    return {"policy": policy, "aiming": aiming, "judging": judging, "targets": targets, "access": access, "missionsim": missionsim,
            "estimate": estimate, "modes": modes}


def _fly(job):
    """One mission under one variant (in a worker process: the switches are module globals, so
    each job first puts back the shipped values, then sets its own switch)."""
    variant, scenario_file, people, seed, run = job
    from sim_link.experiments.paper import REFERENCE, ExperimentConfig, Task, run_task, world_seed
    from uavloc_gcs.scenario import load_scenario

    modules = switch_modules()
    if not _SHIPPED:
        _SHIPPED.update({(m, name): getattr(modules[m], name) for m, name, _ in SWITCHES.values()})
    for (m, name), value in _SHIPPED.items():
        setattr(modules[m], name, value)
    for one in COMBINED.get(variant, (variant,)):
        if one in SWITCHES:
            m, name, value = SWITCHES[one]
            setattr(modules[m], name, value)
    cfg = ExperimentConfig(load_scenario(scenario_file), people=(people,), runs=run + 1, seed=seed,
                           methods=(REFERENCE,), error_people=0)
    res = run_task(cfg, Task(REFERENCE, people, run, world_seed(seed, people, run)))
    heard = [p for p in res.persons if p.heard]
    located = [p for p in heard if p.located]
    inside = [p for p in located if p.error_m <= p.claimed_radius_m]
    why = [_kind(p.reason) for p in heard if not p.located]
    return (variant, run, len(heard), len(located), len(inside), res.completion_time_s, res.oracle_completion_time_s,
            why, len(res.persons))


def _pm(ci: float) -> str:
    """'' for no interval (one run), else ' ± x.x'."""
    return f" ± {ci:5.1f}" if math.isfinite(ci) else ""


def _kind(reason: str) -> str:
    """A policy statement without its numbers and details: "given up: not heard on N looks"."""
    return re.sub(r"\d+(\.\d+)?", "N", reason.split(" (")[0]).strip() or "no statement"


def main(args: argparse.Namespace) -> int:
    from sim_link.experiments import mean_ci95
    from uavloc_gcs.examples import scenario_path

    variants = [v.strip() for v in args.variants.split(",") if v.strip()]
    if variants == ["all"]:
        variants = list(VARIANTS)
    bad = [v for v in variants if v not in VARIANTS]
    if bad:
        print(f"uavloc bench looks: unknown variant {bad[0]!r}; expected one of {', '.join(VARIANTS)}",
              file=sys.stderr)
        return 2
    scenario_file = str(scenario_path(args.scenario))
    jobs = [(v, scenario_file, args.people, args.seed, r) for v in variants for r in range(args.runs)]
    bar = Progress(len(jobs))
    rows = []
    with ProcessPoolExecutor(max(1, args.jobs)) as pool:
        for row in pool.map(_fly, jobs):
            rows.append(row)
            bar.step(f"{row[0]} run {row[1]}")
    print(f"look rules on '{args.scenario}', MLE-EPSO (M), {args.people} people, {args.runs} paired worlds (seed {args.seed})")
    w = max(14, *(len(v) for v in variants))
    head = (f"{'variant':{w}s} {'heard/present':>14s} {'located/heard':>14s} {'inside r95':>11s} {'completion s':>16s} "
            f"{'/ clairvoyant':>13s} {'vs default s':>15s}")
    print(head)
    print("-" * len(head))
    by = {v: sorted((r for r in rows if r[0] == v), key=lambda r: r[1]) for v in variants}
    for v in variants:
        rs = by[v]
        heard, located, inside, present = (sum(r[k] for r in rs) for k in (2, 3, 4, 8))
        m, ci, _ = mean_ci95([r[5] for r in rs])
        oracle = [r[6] for r in rs if math.isfinite(r[6])]
        ratio = m / float(np.mean(oracle)) if oracle else math.nan
        paired = ""
        if v != "default" and "default" in by:
            d, dci, _ = mean_ci95([a[5] - b[5] for a, b in zip(rs, by["default"])])
            paired = f"{d:+7.1f}" + _pm(dci)
        print(f"{v:{w}s} {f'{heard}/{present}':>14s} {f'{located}/{heard}':>14s} {inside / max(located, 1):11.3f} "
              f"{f'{m:8.1f}' + _pm(ci):>16s} {ratio:13.3f} {paired:>15s}")
    if args.runs < 2:
        print("(one run per variant: no confidence interval; --runs 2 or more gives one)")
    for v in variants:
        why = Counter(k for r in by[v] for k in r[7])
        if why:
            print(f"not located, {v}: " + "; ".join(f"{n} {k}" for k, n in why.most_common()))
    return 0


if __name__ == "__main__":  # pragma: no cover
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_arguments(p)
    raise SystemExit(main(p.parse_args()))
