"""Terminal pictures and tables."""

import numpy as np

from uavloc_gcs.render.terminal import Layer, char_map, format_table


def test_char_map_puts_things_where_they_are():
    square = np.array([[0, 0], [1000, 0], [1000, 500], [0, 500]])
    text = char_map([Layer(square, ".", "ring", name="area"),
                     Layer(np.array([[0, 250], [1000, 250]]), "*", "line", name="lane"),
                     Layer(np.array([[0, 0]]), "H", "points", name="home")], width=42)
    lines = text.splitlines()
    grid = [line[1:-1] for line in lines if line.startswith("|") and line.endswith("|")]
    assert len({len(g) for g in grid}) == 1 and len(grid[0]) == 40
    assert grid[-1][0] == "H"  # south-west corner, north up
    assert set(grid[0]) == {"."}  # the north edge
    middle = grid[len(grid) // 2]
    assert middle.count("*") == len(middle)  # the lane across the middle
    # About 25 m per column -> 500 m tall is ~10 rows of 50 m.
    assert 9 <= len(grid) <= 12
    assert "m" in lines[-2] and "north up" in lines[-2]
    assert lines[-1] == ". area   * lane   H home"


def test_char_map_respects_max_height():
    tall = np.array([[0, 0], [10, 5000]])
    grid = [line for line in char_map([Layer(tall, "*")], max_height=20).splitlines() if line.startswith("|")]
    assert len(grid) <= 20


def test_format_table_aligns_numbers_right():
    out = format_table(["name", "km"], [["uav1", 2.5], ["uav10", 12.25]]).splitlines()
    assert out[0] == "name      km"
    assert out[2] == "uav1     2.5"
    assert out[3] == "uav10  12.25"
