"""A vehicle told to stop at a point beside or behind it must arrive, not orbit it.

Regression: the coordinated turn used the whole acceleration budget laterally at constant speed,
so RTL at 25 m/s to a home inside the 125 m turn circle circled home for ever.
"""

import numpy as np
import pytest

from sim_link.vehicles.flight import Kinematics


@pytest.mark.parametrize("target", [(0.0, 50.0), (0.0, 10.0), (-30.0, 5.0), (200.0, 100.0), (-5.0, -60.0)])
def test_stops_at_a_target_beside_or_behind(target):
    k = Kinematics(max_accel_m_s2=5.0, pos=np.array([0.0, 0.0, 100.0]), vel=np.array([25.0, 0.0, 0.0]))
    goal = np.array([*target, 100.0])
    speeds = []
    for _ in range(int(60 / 0.05)):
        k.step(0.05, goal, 25.0, stop_at_target=True)
        speeds.append(k.ground_speed_m_s)
        if np.hypot(*(k.pos[:2] - goal[:2])) < 1.0 and k.ground_speed_m_s < 0.5:
            break
    else:
        pytest.fail(f"still {np.hypot(*(k.pos[:2] - goal[:2])):.0f} m away at {k.ground_speed_m_s:.1f} m/s")
    accel = np.abs(np.diff(speeds)) / 0.05
    assert accel.max() <= 5.0 + 1e-6
