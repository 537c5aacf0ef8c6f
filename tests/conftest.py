"""Suite-wide setup."""

import os
import signal

# Several tests stop a child uavloc with SIGINT, as Ctrl-C in a terminal would. A suite started in
# the background by a non-interactive shell (`( pytest & )`, some CI runners) inherits SIGINT
# ignored, children inherit that across exec, and Python then leaves it ignored: those children
# would never stop. Give the suite, and so its children, the terminal's default.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


# SIGTERM stops the suite, as it would stop any program: a daemon running inside a test installs
# its own SIGTERM handler (it sends the fleet home and writes partial results) and used to swallow
# the signal, so `kill PYTEST` ended one test and the run went on. The daemon's handler calls this
# one after its own (service/run.py, ``uavloc_chain``), which stops the session like Ctrl-C.
_SUITE_PID = os.getpid()


def _stop_the_suite(signum, _frame=None):
    if os.getpid() != _SUITE_PID:  # a forked child (a fake fleet, a worker): die as by default
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)
        return
    raise KeyboardInterrupt(f"the test run was stopped by {signal.Signals(signum).name}")


_stop_the_suite.uavloc_chain = True
if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
    signal.signal(signal.SIGTERM, _stop_the_suite)
