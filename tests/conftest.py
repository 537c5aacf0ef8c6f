"""Suite-wide setup."""

import signal

# Several tests stop a child uavloc with SIGINT, as Ctrl-C in a terminal would. A suite started in
# the background by a non-interactive shell (`( pytest & )`, some CI runners) inherits SIGINT
# ignored, children inherit that across exec, and Python then leaves it ignored: those children
# would never stop. Give the suite, and so its children, the terminal's default.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)
