"""Fit the burst model's parameters to labelled probe-request captures.

``python -m sim_link.world.calibrate DIR`` reads every ``*.csv`` in DIR -- one labelled device per
file, with at least the columns ``Timestamp`` (s), ``MAC Address`` and ``Channel`` (the sniffer's
channel), as in the per-device CSVs of the Politecnico di Milano "MAC de-randomization" lab
datasets (e.g. github.com/amanzargari/Network-Measurement-Lab-MAC_De-randomization,
``Data/MAC_derand_*-dataset``) -- and prints, per device and pooled, the figures
:mod:`.emission`'s constants come from. No capture data ships with uavloc; only the fitted
constants do.

A burst is a run of frames with no gap over :data:`BURST_SPLIT_S`; a gap over :data:`SESSION_SPLIT_S`
separates two capture sessions and is not a gap between bursts.
"""

from __future__ import annotations

import argparse
import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

BURST_SPLIT_S = 2.0
SESSION_SPLIT_S = 3 * 3600.0
LONG_SILENCE_S = 1800.0


@dataclass(frozen=True)
class DeviceFit:
    name: str
    bursts: int
    gap_median_s: float
    gap_p90_s: float
    long_silences: int
    gaps: int
    frames_median: float
    frames_log_sd: float
    frames_max: int
    spacing_s: float  # median time between frames of a burst
    frames_per_address: float  # median over bursts of frames per address
    channel_counts: dict


def fit_device(name: str, t_s, address, channel) -> DeviceFit:
    """The figures of one device's frames (any order)."""
    order = np.argsort(np.asarray(t_s, dtype=float), kind="stable")
    t = np.asarray(t_s, dtype=float)[order]
    addr = np.asarray(address)[order]
    ch = np.asarray(channel, dtype=int)[order]
    start = np.nonzero(np.concatenate([[True], np.diff(t) > BURST_SPLIT_S]))[0]
    end = np.append(start[1:], len(t))
    n = end - start
    gaps = np.diff(t[start])
    gaps = gaps[gaps <= SESSION_SPLIT_S]
    multi = n > 1
    spacing = (t[end - 1] - t[start])[multi] / (n[multi] - 1)
    per_addr = [np.mean(np.unique(addr[a:b], return_counts=True)[1]) for a, b in zip(start, end)]
    chans, counts = np.unique(ch, return_counts=True)
    return DeviceFit(
        name, len(start), float(np.median(gaps)) if gaps.size else np.nan,
        float(np.quantile(gaps, 0.9)) if gaps.size else np.nan, int(np.sum(gaps > LONG_SILENCE_S)), len(gaps),
        float(np.median(n)), float(np.log(n).std()), int(n.max()),
        float(np.median(spacing)) if spacing.size else np.nan, float(np.median(per_addr)),
        {int(c): int(k) for c, k in zip(chans, counts)},
    )


def read_device_csv(path: Path) -> DeviceFit:
    with open(path, newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if r.get("Timestamp")]
    return fit_device(path.stem, [float(r["Timestamp"]) for r in rows], [r["MAC Address"] for r in rows],
                      [int(float(r["Channel"] or 0)) for r in rows])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m sim_link.world.calibrate", description=__doc__.splitlines()[0])
    ap.add_argument("directory", type=Path, help="folder of per-device labelled CSV files")
    args = ap.parse_args(argv)
    fits = [read_device_csv(p) for p in sorted(args.directory.glob("*.csv"))]
    print(f"{'device':28s} bursts gap-med  gap-p90 long  frames(med sd max) spacing frames/addr")
    for f in fits:
        print(f"{f.name[-28:]:28s} {f.bursts:6d} {f.gap_median_s:7.1f} {f.gap_p90_s:8.1f} {f.long_silences:4d}  "
              f"{f.frames_median:5.0f} {f.frames_log_sd:4.2f} {f.frames_max:3d}  {1e3 * f.spacing_s:5.0f} ms "
              f"{f.frames_per_address:6.1f}")
    total = {}
    for f in fits:
        for c, k in f.channel_counts.items():
            total[c] = total.get(c, 0) + k
    n = sum(total.values())
    med, p90 = [f.gap_median_s for f in fits], [f.gap_p90_s for f in fits]
    print(f"per-device gap medians {min(med):.0f}-{max(med):.0f} s,",
          f"p90 {min(p90):.0f}-{max(p90):.0f} s")
    print("long silences (> 30 min) per gap", f"{sum(f.long_silences for f in fits) / sum(f.gaps for f in fits):.4f}")
    print("frames per burst, per-device medians", f"{min(f.frames_median for f in fits):.0f}-"
          f"{max(f.frames_median for f in fits):.0f}, median log-sd {np.median([f.frames_log_sd for f in fits]):.2f}, "
          f"max {max(f.frames_max for f in fits)}")
    print("frame spacing, median over devices", f"{1e3 * np.median([f.spacing_s for f in fits]):.0f} ms")
    print("frames by sniffer channel", {c: round(k / n, 3) for c, k in sorted(total.items())})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
