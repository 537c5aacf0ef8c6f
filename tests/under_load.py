"""Run the test suite several times in a row beside CPU-bound processes (issue 29: tests that hold
under load). Each burner spins one core for the whole time; each run is a fresh pytest process.

    python -m tests.under_load                          # the fast suite, 3 runs, 2 burners
    python -m tests.under_load --runs 3 --burners 2 -- -m "not sitl"
    python -m tests.under_load --runs 1 -- tests/test_e2e_daemon.py

Prints one line per run (result, wall time) and exits 1 if any run failed.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FAST = ["-m", "not slow and not sitl"]


def _burn(stop) -> None:
    x = 0
    while not stop.is_set():
        for _ in range(100_000):
            x = (x * 1_103_515_245 + 12_345) & 0xFFFFFFFF


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tests.under_load", description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3, help="pytest runs in a row (default 3)")
    ap.add_argument("--burners", type=int, default=2, help="CPU-bound processes beside them (default 2)")
    ap.add_argument("pytest_args", nargs="*", help="arguments for pytest after `--` (default: the fast suite)")
    a = ap.parse_args(argv)
    if a.runs < 1 or a.burners < 0:
        ap.error("--runs must be at least 1 and --burners 0 or more")
    args = a.pytest_args or FAST
    stop = mp.Event()
    burners = [mp.Process(target=_burn, args=(stop,), daemon=True) for _ in range(a.burners)]
    for b in burners:
        b.start()
    failed = 0
    try:
        for k in range(1, a.runs + 1):
            t0 = time.monotonic()
            rc = subprocess.call([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *args], cwd=ROOT)
            wall = time.monotonic() - t0
            failed += rc != 0
            print(f"under load ({a.burners} burners): run {k}/{a.runs} {'passed' if rc == 0 else f'FAILED (exit {rc})'} "
                  f"in {wall / 60:.1f} min", flush=True)
    finally:
        stop.set()
        for b in burners:
            b.join(timeout=5)
            if b.is_alive():
                b.terminate()
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
