"""``uavloc route INSTANCE.json``: plan routes for a routing instance (see planning/jsonio.py)."""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys

from ._inputs import number


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "route",
        help="plan follow-up routes (EPSO/PSO/GA or the OR-Tools/PyVRP anchors) for an instance",
        description="Assign people to vehicles and order them to minimize the time the last vehicle "
                    "is home, passing within each person's access disk, within each vehicle's energy. "
                    "Writes the plan as JSON to stdout or --out and a summary to stderr.",
    )
    p.add_argument("instance", help="instance JSON (speed_m_s, t0_s, vehicles, targets), or a shipped one by name: "
                                    "route_paper")
    p.add_argument("--solver", default="epso", choices=["epso", "pso", "ga", "ortools", "pyvrp"])
    p.add_argument("--time-limit", type=number(float, above=0, max=86400, unit="s"), default=1.0, metavar="S",
                   help="search time [s] (default 1)")
    p.add_argument("--seed", type=number(int, min=0, max=2**32 - 1), default=0, metavar="N",
                   help="random seed (default 0)")
    p.add_argument("--no-local-search", action="store_true",
                   help="plain optimizer as in the paper (EPSO/PSO/GA only)")
    p.add_argument("--out", metavar="FILE", help="write the plan JSON here instead of stdout")
    p.add_argument("--png", metavar="FILE", help="draw the routes with their disks (.png or .svg)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ..errors import ConfigError, FileFormatError, Interrupted
    from ..examples import shipped_path
    from ..planning import solve
    from ..planning.jsonio import dumps_result, loads_problem
    from ..atomicfile import atomic_write_text

    from ._output import check_not_input, check_output_file

    for option, path in (("--out", args.out), ("--png", args.png)):
        if path is not None:
            check_output_file(path, option)
            check_not_input(path, option, {"the routing instance being read": args.instance})
    if args.out is not None and args.png is not None and Path(args.out).absolute() == Path(args.png).absolute():
        raise ConfigError(f"--out and --png both name {args.out}; give the plan and the picture different names")
    if args.png and Path(args.png).suffix.lower() not in (".png", ".svg"):
        raise ConfigError(f"--png {args.png}: the picture must end in .png or .svg")
    instance = shipped_path(args.instance, ".json")
    try:
        text = instance.read_text(encoding="utf-8")
    except OSError as err:
        raise FileFormatError(f"cannot read: {err.strerror}", path=args.instance) from None
    except UnicodeDecodeError:
        raise FileFormatError("is not a text file; a routing instance is JSON (see examples/route_paper.json)",
                              path=args.instance) from None
    problem = loads_problem(text, path=args.instance)
    with _interrupt_noted() as stopped:
        result = solve(problem, method=args.solver, rng=args.seed, time_limit_s=args.time_limit,
                       local_search=not args.no_local_search)
    if stopped:
        # OR-Tools swallows the KeyboardInterrupt in its distance callback and returns what it had
        raise Interrupted(f"stopped by Ctrl-C during the {args.solver} search; no plan written")
    out = dumps_result(result, args.solver)
    if args.png:  # before the JSON: a picture that fails leaves nothing half-written
        from ..render.routes import save_plan_picture

        save_plan_picture(problem, result.plan, args.png, title=f"Route plan ({args.solver})")
    if args.out:
        atomic_write_text(args.out, out)
    else:
        sys.stdout.write(out)
    plan = result.plan
    gap = plan.makespan_s / plan.lower_bound_s - 1 if plan.lower_bound_s > 0 else 0.0
    print(f"{args.solver}: makespan {plan.makespan_s:.2f} s (lower bound {plan.lower_bound_s:.2f} s, "
          f"gap {100 * gap:.1f} %), {len(problem.targets)} people on {len(problem.vehicles)} vehicles, "
          f"{result.runtime_s:.2f} s", file=sys.stderr)
    for r in plan.routes:
        print(f"  {r.vehicle_id}: {len(r.target_ids)} people, {r.duration_s:.1f} s, {r.energy_j / 1000:.1f} kJ"
              f"  {' '.join(r.target_ids)}", file=sys.stderr)
    if not result.success:
        print(f"warning: {result.message}", file=sys.stderr)
        return 1
    return 0


@contextlib.contextmanager
def _interrupt_noted():
    """Yield a list that holds the signal number once Ctrl-C was pressed; Python's own handling
    (KeyboardInterrupt) goes on as usual."""
    stopped: list[int] = []

    def on_int(signum, frame):
        stopped.append(signum)
        signal.default_int_handler(signum, frame)

    try:
        previous = signal.signal(signal.SIGINT, on_int)
    except ValueError:  # not the main thread: nothing to note
        yield stopped
        return
    try:
        yield stopped
    finally:
        signal.signal(signal.SIGINT, previous)
