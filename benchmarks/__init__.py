"""Benchmarks: speed and quality against named anchors, run with ``uavloc bench ...``."""
