"""The core never imports the simulator (SPEC: dependencies point one way)."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module.split(".")[0])
    return names


def test_core_does_not_import_sim_link():
    offenders = []
    for py in (ROOT / "uavloc_gcs").rglob("*.py"):
        if "cli" in py.relative_to(ROOT / "uavloc_gcs").parts:
            continue  # CLI commands that run simulations (sim, demo, experiment, bench) may, lazily
        if {"sim_link", "benchmarks"} & _imports(py):
            offenders.append(str(py.relative_to(ROOT)))
    assert offenders == []


def test_file_formats_do_not_import_the_service():
    offenders = []
    for py in (ROOT / "mission_io").rglob("*.py"):
        if {"sim_link", "benchmarks"} & _imports(py):
            offenders.append(str(py.relative_to(ROOT)))
    assert offenders == []


def test_only_the_cli_imports_the_cli():
    offenders = []
    for py in (ROOT / "uavloc_gcs").rglob("*.py"):
        rel = py.relative_to(ROOT / "uavloc_gcs")
        if rel.parts[0] == "cli" or rel.name == "__main__.py":
            continue
        text = py.read_text(encoding="utf-8")
        if "from ..cli" in text or "from .cli" in text or "uavloc_gcs.cli" in text:
            offenders.append(str(rel))
    assert offenders == []
