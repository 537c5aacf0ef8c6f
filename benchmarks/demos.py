"""``uavloc bench demos``: how often the search gives people up, and why, over many demo runs.

Runs ``uavloc demo --no-web`` (the real command: fake vehicles over UDP, the daemon, the results)
once per world seed and reads each run's ``results.txt``: the people reported, their state, the
daemon's reason for every person not located, and the true error the simulation knows. Printed
per scenario: runs, exit codes, people present / heard / located / given up, the given-up rate
(given up over reported), the reasons grouped without their numbers, the people given up
although their estimate was within the required accuracy of the truth (issue 26: "given up while
still there", a person given up 9.9 m from where it was), the people reported located farther from
the truth than 1.5x their 95 % radius (issue 42: the worst thing uavloc can say), and each run's CPU
time and peak memory (its processes together: the demo, the fake fleet, the fitting worker).
``--burners N`` runs N CPU-bound processes beside the demos (a busy laptop in the field).

The anchor is the truth of the simulation: a person given up with an estimate that close was
there to be located; one given up for lack of energy was not given up on the evidence.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing as mp
import os
import re
import subprocess
import sys
import tempfile
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

from uavloc_gcs.cli._inputs import number

from ._progress import Progress

# a table row of results.txt: "P03 #22:df:be:bc:c1:cb   lat  lon  95% r  at  status  true error  (reason)"
ROW = re.compile(r"^P\d+\s+#\S+\s+.*?\s(located|given up|heard|never heard)\s+(-|[\d.]+ m)(?:\s+\((.*)\))?\s*$")
# a located row's 95 % radius: "P01 #1052637316    42.626778    13.286649    7.1 m  13:01:37.4  located  2.9 m"
RADIUS = re.compile(r"^P\d+\s+#\S+\s+\S+\s+\S+\s+([\d.]+) m\s")
FAR = 1.5  # a located person farther from the truth than this many 95 % radii is a defect
REQUIRED = re.compile(r"located within ([\d.]+) m")


def _scenarios(text: str) -> tuple[str, ...]:
    """--scenario: comma-separated shipped names or files, each of which must exist."""
    from uavloc_gcs.examples import scenario_names, scenario_path

    names = tuple(s.strip() for s in text.split(",") if s.strip())
    if not names:
        raise argparse.ArgumentTypeError(f"expected comma-separated scenarios, got {text!r}")
    for s in names:
        if not scenario_path(s).is_file():
            raise argparse.ArgumentTypeError(f"{s!r} is neither a file nor a shipped scenario "
                                             f"({', '.join(scenario_names())})")
    return names


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--runs", type=number(int, min=1, max=200), default=20,
                        help="demo runs per scenario, world seeds 1..N (default 20, as issue 26 asks)")
    parser.add_argument("--scenario", type=_scenarios, default="paper,field",
                        help="comma-separated shipped scenarios or files (default paper,field)")
    parser.add_argument("--people", type=number(int, min=1, max=1000), help="people per world (default: the scenario's)")
    parser.add_argument("--jobs", type=number(int, min=1, max=8), default=1,
                        help="demos at once (default 1: each uses most of a core; more load the machine)")
    parser.add_argument("--keep", metavar="DIR", help="keep every run's output under DIR (default: a temporary directory)")
    parser.add_argument("--burners", type=number(int, min=0, max=16), default=0,
                        help="CPU-bound processes running beside the demos (default 0; 2 on a 2-core machine is a busy one)")


@dataclass
class Run:
    scenario: str
    seed: int
    rc: int
    wall_s: float
    states: Counter = field(default_factory=Counter)
    reasons: Counter = field(default_factory=Counter)
    given_up_close: int = 0  # given up with the estimate within the required accuracy of the truth
    required_m: float = math.nan
    problem: str = ""
    located_far: list = field(default_factory=list)  # rows of people located farther than FAR x their radius
    cpu_s: float = math.nan  # user + system CPU of the demo and the processes it waited for
    peak_mb: float = math.nan  # the largest resident set among them [MB]


def _kind(reason: str) -> str:
    """A reason without its numbers and details: "given up: not heard on N looks"."""
    return re.sub(r"\d+(\.\d+)?", "N", reason.split(" (")[0].split(";")[0]).strip() or "no statement"


def parse_results(text: str) -> tuple[Counter, Counter, int, float]:
    """(states, reasons of the not located, given up within the required accuracy, required m)
    from a demo's results.txt."""
    states, reasons = Counter(), Counter()
    close = 0
    m = REQUIRED.search(text)
    required = float(m.group(1)) if m else math.nan
    for line in text.splitlines():
        row = ROW.match(line)
        if not row:
            continue
        state, err, reason = row.groups()
        states[state] += 1
        if state == "given up":
            reasons[_kind(reason or "")] += 1
            if err != "-" and float(err.split()[0]) <= required:
                close += 1
    return states, reasons, close, required


def located_far(text: str, far: float = FAR) -> list[str]:
    """The table rows of people reported located farther from the truth than ``far`` x their radius."""
    out = []
    for line in text.splitlines():
        row, rad = ROW.match(line), RADIUS.match(line)
        if row and rad and row.group(1) == "located" and row.group(2) != "-":
            if float(row.group(2).split()[0]) > far * float(rad.group(1)):
                out.append(line.strip())
    return out


def _one(scenario: str, seed: int, people: int | None, root: Path) -> Run:
    out = root / f"{Path(scenario).stem}-seed{seed}"
    out.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "uavloc_gcs", "demo", "--no-web", "--scenario", scenario, "--seed", str(seed),
           "--base-port", "0", "--out", str(out)]
    if people is not None:
        cmd += ["--people", str(people)]
    t0 = time.monotonic()
    with open(out / "demo.stdout", "w") as so, open(out / "demo.stderr", "w") as se:
        proc = subprocess.Popen(cmd, stdout=so, stderr=se, text=True)
        # wait4: this run's own CPU and peak memory, with the processes it waited for (fleet, fitter)
        _pid, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    run = Run(scenario, seed, proc.returncode, time.monotonic() - t0, cpu_s=usage.ru_utime + usage.ru_stime,
              peak_mb=usage.ru_maxrss / 1024.0)
    results = out / "results.txt"
    if not results.exists():
        tail = ((out / "demo.stderr").read_text().strip().splitlines() or ["no output"])[-1]
        run.problem = f"no results.txt (exit {proc.returncode}: {tail})"
        return run
    text = results.read_text()
    run.states, run.reasons, run.given_up_close, run.required_m = parse_results(text)
    run.located_far = located_far(text)
    return run


def _burn(stop) -> None:
    while not stop.is_set():
        sum(range(10_000))


def main(args: argparse.Namespace) -> int:
    if args.keep:  # before the first demo: a directory that cannot be written
        from uavloc_gcs.cli._output import check_output_dir

        check_output_dir(args.keep, "--keep")
    scenarios = list(args.scenario)
    jobs = [(s, seed) for s in scenarios for seed in range(1, args.runs + 1)]
    bar = Progress(len(jobs))
    stop = mp.Event()
    burners = [mp.Process(target=_burn, args=(stop,), daemon=True) for _ in range(args.burners)]
    for b in burners:
        b.start()
    try:
        with tempfile.TemporaryDirectory(prefix="uavloc-bench-demos-") as tmp:
            root = Path(args.keep) if args.keep else Path(tmp)
            root.mkdir(parents=True, exist_ok=True)
            runs: list[Run] = []
            with ThreadPoolExecutor(args.jobs) as pool:
                for run in pool.map(lambda j: _one(j[0], j[1], args.people, root), jobs):
                    runs.append(run)
                    bar.step(f"{run.scenario} seed {run.seed}: exit {run.rc}, {run.wall_s:.0f} s")
    finally:
        stop.set()
        for b in burners:
            b.join(timeout=5)
    print(f"uavloc demo --no-web, world seeds 1..{args.runs}" + (f", {args.people} people" if args.people else "")
          + (f", beside {args.burners} CPU-bound processes" if args.burners else ""))
    head = (f"{'scenario':10s} {'runs':>4s} {'exit 0':>6s} {'wall s':>7s} {'CPU s':>6s} {'peak MB':>7s} "
            f"{'reported':>8s} {'never heard':>11s} {'located':>7s} {'given up':>8s} {'given-up rate':>13s} "
            f"{'given up <= req':>15s} {'located > 1.5 r':>15s}")
    print(head)
    print("-" * len(head))
    failed = 0
    for s in scenarios:
        rs = [r for r in runs if r.scenario == s]
        ok = [r for r in rs if not r.problem]
        failed += len(rs) - len(ok)
        st = sum((r.states for r in ok), Counter())
        reported = st["located"] + st["given up"] + st["heard"]
        rate = st["given up"] / reported if reported else math.nan
        wall = sum(r.wall_s for r in rs) / max(len(rs), 1)
        cpu = sum(r.cpu_s for r in rs) / max(len(rs), 1)
        peak = max((r.peak_mb for r in rs), default=math.nan)
        print(f"{Path(s).stem:10s} {len(rs):4d} {sum(r.rc == 0 for r in rs):6d} {wall:7.0f} {cpu:6.0f} {peak:7.0f} "
              f"{reported:8d} {st['never heard']:11d} {st['located']:7d} {st['given up']:8d} {rate:13.3f} "
              f"{sum(r.given_up_close for r in ok):15d} {sum(len(r.located_far) for r in ok):15d}")
    for s in scenarios:
        reasons = sum((r.reasons for r in runs if r.scenario == s), Counter())
        if reasons:
            print(f"\n{Path(s).stem}: why the given up were given up")
            for why, n in reasons.most_common():
                print(f"  {n:4d}  {why}")
    far = [(r, row) for r in runs for row in r.located_far]
    if far:
        print(f"\nlocated farther from the truth than {FAR:g}x their 95 % radius:")
        for r, row in far:
            print(f"  {Path(r.scenario).stem} seed {r.seed}: {row}")
    for r in runs:
        if r.problem:
            print(f"{r.scenario} seed {r.seed}: {r.problem}", file=sys.stderr)
    print("\n'given up <= req': given up although the estimate was within the required accuracy of the "
          "truth (a person there to be located); 'located > 1.5 r': reported located farther from the truth "
          "than 1.5x their 95 % radius; CPU s: mean per run, the demo with its fleet and fitting processes; "
          "peak MB: the largest resident set of any of them, over all runs")
    return 1 if failed or far else 0
