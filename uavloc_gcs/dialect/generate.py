"""Regenerate ``uavloc_mavlink.py`` from ``uavloc.xml`` with pymavlink's mavgen.

The dialect includes ``common.xml``; it is taken from the installed pymavlink (not copied into
this repository). Run: ``python -m uavloc_gcs.dialect.generate``.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
XML = HERE / "uavloc.xml"
OUTPUT = HERE / "uavloc_mavlink.py"


def generate(output: Path = OUTPUT) -> Path:
    """Run mavgen (Python3, MAVLink 2, validated) on the dialect XML; return the written file."""
    import pymavlink
    from pymavlink.generator import mavgen, mavparse

    defs = Path(pymavlink.__file__).resolve().parent / "dialects" / "v20"
    with tempfile.TemporaryDirectory() as tmp:
        for name in ("common.xml", "standard.xml", "minimal.xml"):
            shutil.copy(defs / name, Path(tmp) / name)
        xml = Path(tmp) / XML.name
        shutil.copy(XML, xml)
        out_base = Path(tmp) / "gen"
        opts = mavgen.Opts(
            output=str(out_base), wire_protocol=mavparse.PROTOCOL_2_0, language="Python3",
            validate=True, strict_units=False,
        )
        if not mavgen.mavgen(opts, [str(xml)]):
            raise RuntimeError(f"mavgen failed on {XML}")
        text = (Path(tmp) / "gen.py").read_text(encoding="utf-8")
    # mavgen writes the temporary input path into the header; keep the output reproducible.
    text = text.replace(str(Path(tmp)) + os.sep, "")
    output.write_text(text, encoding="utf-8")
    return output


if __name__ == "__main__":  # pragma: no cover
    print(generate())
