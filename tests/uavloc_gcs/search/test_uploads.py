"""When a new plan is worth an upload to a vehicle flying looks (search/uploads.py)."""

import numpy as np

from uavloc_gcs.search.uploads import UPLOAD_COST_S, decide_upload, route_time_s


def _decide(old_t, old_p, new_t, new_p, *, since=0, flying=True, cost=5.0):
    return decide_upload(flying_look=flying, uploads_since_look=since, position_xy_m=(0.0, 0.0),
                         old_targets=old_t, old_points_xy_m=np.array(old_p, float), new_targets=new_t,
                         new_points_xy_m=np.array(new_p, float), speed_m_s=10.0, cost_s=cost,
                         move_tolerance_m=15.0, same_tolerance_m=10.0)


def test_first_look_mission_is_always_sent():
    assert _decide((), [], (7,), [[100, 0]], flying=False).upload


def test_small_shifts_are_not_worth_a_restarted_leg():
    d = _decide((7, 8), [[100, 0], [200, 0]], (7, 8), [[100, 12], [200, -12]])
    assert not d.upload and "costs" in d.reason
    assert not _decide((7,), [[100, 0]], (7,), [[103, 0]]).upload  # within the same-route tolerance


def test_a_new_person_or_a_look_point_moved_beyond_the_tolerance_is_uploaded():
    assert _decide((7,), [[100, 0]], (7, 9), [[100, 0], [300, 50]]).upload
    assert _decide((7,), [[100, 0]], (7,), [[100, 40]]).upload


def test_a_shorter_route_is_uploaded_only_when_it_saves_more_than_the_upload_costs():
    old = [[400, 0], [400, 400]]  # person 8 located meanwhile: the new route skips that detour
    d = _decide((7, 8), old, (7,), [[400, 0]])
    assert d.upload and "saves" in d.reason
    assert not _decide((7, 8), old, (7,), [[400, 0]], cost=1e4).upload


def test_never_more_than_once_between_two_looks():
    assert not _decide((7,), [[100, 0]], (7, 9), [[100, 0], [300, 50]], since=1).upload


def test_measured_costs_are_known_for_both_autopilots_and_route_time_is_straight_line():
    assert set(UPLOAD_COST_S) == {"ardupilot", "px4"} and all(c > 0 for c in UPLOAD_COST_S.values())
    assert route_time_s((0, 0), [[30, 40], [30, 0]], 10.0) == 9.0
