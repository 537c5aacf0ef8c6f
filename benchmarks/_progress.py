"""Progress of a long benchmark on stderr: redrawn in place on a terminal, otherwise one line
about every tenth of the way (so logs stay short)."""

from __future__ import annotations

import sys
import time


class Progress:
    """``p = Progress(total); p.step("what just finished")`` after each of ``total`` steps."""

    def __init__(self, total: int, stream=None):
        self.total, self.done = max(1, int(total)), 0
        self.out = stream or sys.stderr
        self.t0 = time.monotonic()

    def step(self, label: str) -> None:
        self.done += 1
        elapsed = time.monotonic() - self.t0
        if self.done >= self.total:
            text = f"  [{self.done}/{self.total}] done in {elapsed:.0f} s"
        else:
            left = elapsed / self.done * (self.total - self.done)
            text = f"  [{self.done}/{self.total}] {label}  {elapsed:.0f} s, ~{left:.0f} s left"
        if self.out.isatty():
            self.out.write("\r\x1b[2K" + text + ("\n" if self.done >= self.total else ""))
            self.out.flush()
        elif self.done >= self.total or self.done % max(1, self.total // 10) == 0:
            print(text, file=self.out, flush=True)
