"""Short, stable labels for people: P01, P02, ... in the order they were first heard.

The order is the order in which each emitter's first slot reached the store (its first row id),
so the live terminal view, the live map and the final files all agree, and a resumed search
keeps its labels. People never heard (simulations only) are labelled after everyone heard, by
emitter id. A label is always shown with the emitter id: "P03 #17".
"""

from __future__ import annotations

import sqlite3
from pathlib import Path
from typing import Iterable


def label_text(index: int) -> str:
    """'P01' for index 0; three digits from the hundredth person on."""
    return f"P{index + 1:02d}"


class PersonLabels:
    """{emitter id: 'Pnn'}, filled from the store's slots (``refresh``) or directly (``add``)."""

    def __init__(self, store_path: str | Path | None = None):
        self.store_path = Path(store_path) if store_path is not None else None
        self._labels: dict[int, str] = {}
        self._rowid = 0

    def add(self, emitter_ids: Iterable[int]) -> None:
        """Label the ids not labelled yet, in the given order."""
        for eid in emitter_ids:
            eid = int(eid)
            if eid not in self._labels:
                self._labels[eid] = label_text(len(self._labels))

    def refresh(self) -> "PersonLabels":
        """Label the emitters whose first slot was committed since the last call (cheap: it reads
        only the new rows). A missing or not yet created store changes nothing."""
        if self.store_path is None or not self.store_path.exists():
            return self
        try:
            conn = sqlite3.connect(f"file:{self.store_path}?mode=ro", uri=True, timeout=1.0)
        except sqlite3.Error:
            return self
        try:
            try:  # a sensor that reports fingerprints hears addresses, not people: those are
                # labelled as the people they are linked into appear (add), not one per address
                rows = conn.execute(
                    "SELECT emitter_id, MIN(rowid) AS first, MIN(t_s) FROM slots WHERE rowid > ? AND fingerprint = 0 "
                    "GROUP BY emitter_id ORDER BY first, emitter_id", (self._rowid,)).fetchall()
            except sqlite3.OperationalError:  # a store from before the field world: no fingerprints
                rows = conn.execute(
                    "SELECT emitter_id, MIN(rowid) AS first, MIN(t_s) FROM slots WHERE rowid > ? "
                    "GROUP BY emitter_id ORDER BY first, emitter_id", (self._rowid,)).fetchall()
            last = conn.execute("SELECT MAX(rowid) FROM slots").fetchone()[0]
        except sqlite3.Error:  # the schema is not there yet
            return self
        finally:
            conn.close()
        self.add(int(r[0]) for r in rows)
        if last is not None:
            self._rowid = max(self._rowid, int(last))
        return self

    def get(self, emitter_id: int) -> str:
        """The label, or '' when the person is not known yet."""
        return self._labels.get(int(emitter_id), "")

    def name(self, emitter_id: int) -> str:
        """'P03 #17' (or '#17' before the person has a label)."""
        lab = self.get(emitter_id)
        return f"{lab} #{int(emitter_id)}" if lab else f"#{int(emitter_id)}"

    def as_dict(self) -> dict[int, str]:
        return dict(self._labels)

    def __len__(self) -> int:
        return len(self._labels)
