"""Shared drawing helpers: map pictures (matplotlib, Agg) and terminal pictures/tables.

``maps`` draws on a local-metre axes (east/north of the scenario frame) so every picture of the
project -- scan preview, estimates with error circles, planned routes, daemon snapshots -- looks
the same. ``terminal`` turns the same geometry into a character grid and formats tables.
"""
