"""A signal that arrives while the fake fleet's process is being spawned (CI, 2026-11-27:
``test_a_signal_stops_the_demo_and_its_fleet[15-starting]``) must not leave the child to die on a
half-sent start-up pickle (``EOFError: Ran out of input`` on the demo's stderr)."""

import signal
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]

# The signal is sent from inside multiprocessing's spawn, after the child exists and before the
# parent has written its start-up data: the window a SIGTERM from outside hits only by chance.
SCRIPT = textwrap.dedent("""
    import os, signal, sys
    import multiprocessing.util as util
    from uavloc_gcs.errors import Interrupted
    from uavloc_gcs.scenario import load_scenario
    from uavloc_gcs.cli._fleet import start_fleet_process

    def on_term(signum, _frame):
        raise Interrupted("stopped by SIGTERM", signal=signum)
    signal.signal(signal.SIGTERM, on_term)

    spawn = util.spawnv_passfds
    def spawn_then_signal(path, args, passfds):
        pid = spawn(path, args, passfds)
        if any("spawn_main" in str(a) for a in args):  # the fleet, not multiprocessing's resource tracker
            print("child", pid, flush=True)
            os.kill(os.getpid(), signal.SIGTERM)
        return pid
    util.spawnv_passfds = spawn_then_signal
    try:
        start_fleet_process(load_scenario(sys.argv[1]), seed=1, speedup=20.0, base_port=0)
    except Interrupted:
        print("interrupted", flush=True)
        sys.exit(143)
    print("not interrupted", flush=True)
""")


def test_a_signal_while_the_fleet_is_spawned_stops_it_without_a_child_traceback(tmp_path):
    proc = subprocess.run([sys.executable, "-c", SCRIPT, str(ROOT / "examples" / "small.toml")],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 143, proc.stdout + proc.stderr
    assert "interrupted" in proc.stdout.splitlines()
    assert "Traceback" not in proc.stderr, proc.stderr
    child = int(next(line for line in proc.stdout.splitlines() if line.startswith("child")).split()[1])
    assert not Path(f"/proc/{child}").exists() or \
        Path(f"/proc/{child}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"


# Ctrl-C reaches the whole process group: here it reaches the fleet's child while it is still
# starting (importing), before its own SIG_IGN; the parent goes on and the fleet starts.
SCRIPT_CTRL_C = SCRIPT.replace("os.kill(os.getpid(), signal.SIGTERM)", "os.kill(pid, signal.SIGINT)").replace(
    'print("not interrupted", flush=True)', 'print("not interrupted", flush=True); fleet.stop()').replace(
    "    start_fleet_process(", "    fleet = start_fleet_process(")


def test_ctrl_c_reaching_the_fleet_while_it_starts_leaves_no_child_traceback(tmp_path):
    proc = subprocess.run([sys.executable, "-c", SCRIPT_CTRL_C, str(ROOT / "examples" / "small.toml")],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "not interrupted" in proc.stdout.splitlines()
    assert "Traceback" not in proc.stderr and "KeyboardInterrupt" not in proc.stderr, proc.stderr
