"""When an iterative planner stops: the iteration and time limits shared by EPSO/PSO and GA."""

from __future__ import annotations

import time


def limit_reached(iterations_done: int, max_iter: int | None, deadline: float) -> str | None:
    """Why the search must stop before its next iteration, or None to go on.

    ``deadline`` is a ``time.perf_counter()`` value; ``max_iter`` None means no iteration limit.
    """
    if max_iter is not None and iterations_done >= max_iter:
        return "iteration limit reached"
    if time.perf_counter() >= deadline:
        return "time limit reached"
    return None
