"""Results of a search stopped before its end (SIGINT/SIGTERM), marked partial in every file:
people.csv and results.txt begin with the sentence, people.geojson carries it as a top-level
``partial`` member (the KML and result.png say it in their titles, see service/run.py)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Sequence

from ..atomicfile import atomic_write_text

TITLE_MARK = " (PARTIAL: stopped before its end)"


def mark_partial(files: Sequence[Path], text: str) -> None:
    """Mark the written result ``files`` partial with the sentence ``text``."""
    for path in map(Path, files):
        if path.name == "people.csv":
            atomic_write_text(path, f"# {text}\n" + path.read_text())
        elif path.name == "results.txt":
            atomic_write_text(path, f"{text}\n" + path.read_text())
        elif path.name == "people.geojson":
            doc = json.loads(path.read_text())
            doc["partial"] = text
            atomic_write_text(path, json.dumps(doc))
