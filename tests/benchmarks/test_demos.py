"""uavloc bench demos reads the demo's results.txt: states, reasons, given up near the truth."""

import math

from benchmarks.demos import parse_results

TEXT = """\
person                   lat          lon    95% r    at (UTC)  status      true error
--------------------------------------------------------------------------------------
P01 #1052637316    42.626778    13.286649    7.1 m  13:01:37.4  located          2.9 m
P02 #06:5c:dc:1e:e2:86    42.625720    13.291895  915.6 m  13:27:22.6  given up       423.5 m  (given up: no vehicle has the energy left for a look (vehicle 4 cannot reach home); 95 % radius 915.6 m > 15 m)
P03 #968048698     42.626940    13.285585   12.8 m  13:01:37.6  given up          9.9 m  (given up: not heard on 2 looks where it was predicted (radius 12 m))
P04 #2632195709                                         -           -  never heard           -  (never heard)
3 of 4 people located within 15 m (95 %).
"""


def test_states_reasons_and_the_given_up_near_the_truth_are_read():
    states, reasons, close, required = parse_results(TEXT)
    assert states == {"located": 1, "given up": 2, "never heard": 1}
    assert reasons == {"given up: no vehicle has the energy left for a look": 1,
                       "given up: not heard on N looks where it was predicted": 1}
    assert close == 1 and required == 15.0  # P03, 9.9 m from the truth


def test_a_results_file_without_a_table_reads_as_nothing():
    states, reasons, close, required = parse_results("No phone was heard.\n")
    assert not states and not reasons and close == 0 and math.isnan(required)


def test_people_located_farther_than_one_and_a_half_radii_are_named():
    from benchmarks.demos import located_far

    text = TEXT.replace("7.1 m  13:01:37.4  located          2.9 m", "7.1 m  13:01:37.4  located         11.0 m")
    (row,) = located_far(text)
    assert row.startswith("P01") and located_far(TEXT) == []
