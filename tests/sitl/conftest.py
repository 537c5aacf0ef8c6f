"""Fixtures that start real autopilots (see harness.py); every test here is marked ``sitl``.

* ``sitl`` -- a factory: ``sitl("ardupilot", **kw)`` / ``sitl("px4", **kw)`` starts an instance that
  is stopped when the test ends (pass or fail); skips when the build is absent.
* ``arducopter``, ``px4`` -- one freshly booted vehicle each, ready to arm soon.
* ``autopilot`` -- parametrized over both: ``(kind, SitlProcess)``.

When a test fails, the end of each of its SITLs' output is added to the report.
"""

from __future__ import annotations

import pytest

from . import harness

_STASH = pytest.StashKey[list]()


def pytest_collection_modifyitems(config, items):
    for item in items:
        if "tests/sitl/" in item.nodeid.replace("\\", "/"):
            item.add_marker(pytest.mark.sitl)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    rep = outcome.get_result()
    if rep.failed and rep.when in ("setup", "call"):
        for s in item.stash.get(_STASH, []):
            rep.sections.append((f"{s.kind} SITL instance {s.instance} output (end; {s.workdir})", s.log_tail(60)))


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    """The 95 % circles over every whole search of the run: the coverage a single search of three
    people cannot show (each search only bounds it; see test_daemon_search.py)."""
    from . import daemon_run

    for line in daemon_run.FIELD_RESULTS:  # the searches' figures (daemon_run.field_check)
        terminalreporter.write_line(f"SITL search, {line}")
    rows = daemon_run.COVERAGE
    if rows:
        inside = sum(1 for err, r95 in rows if err <= r95)
        worst = max((err / r95 for err, r95 in rows if r95 > 0), default=float("nan"))
        terminalreporter.write_line(
            f"SITL searches: {inside} of {len(rows)} people inside their 95 % circle ({100 * inside / len(rows):.0f} %), "
            f"worst true error {worst:.2f} x its 95 % radius")


def require(kind: str) -> None:
    """Skip the calling test when the ``kind`` build is absent (one sentence says how to enable)."""
    reason = harness.skip_reason(kind)
    if reason:
        pytest.skip(reason)


@pytest.fixture
def sitl(request):
    started: list[harness.SitlProcess] = []
    request.node.stash[_STASH] = started

    def start(kind: str, **kw) -> harness.SitlProcess:
        require(kind)
        starter = harness.start_arducopter if kind == "ardupilot" else harness.start_px4
        proc = starter(**kw)
        started.append(proc)
        return proc

    yield start
    for proc in started:
        proc.stop()


@pytest.fixture
def arducopter(sitl):
    return sitl("ardupilot")


@pytest.fixture
def px4(sitl):
    return sitl("px4")


@pytest.fixture(params=["ardupilot", "px4"])
def autopilot(request, sitl):
    return request.param, sitl(request.param)
