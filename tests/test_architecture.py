"""The layout is the architecture (issue 19 items 3 and 4): no rig imports another rig or the
CLI, the shared layers name no rig, the CLI names none."""

import ast
from pathlib import Path

import pytest

from platcal.rig import rig_names

SRC = Path(__file__).resolve().parents[1] / "src" / "platcal"
RIGS = sorted(rig_names())


def imports(path: Path, package: str) -> set[str]:
    """Dotted modules a file imports (relative imports resolved against ``package``)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                out.add(".".join(base + ([node.module] if node.module else [])))
            else:
                out.add(node.module or "")
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return out


def module_imports(folder: Path):
    for f in sorted(folder.rglob("*.py")):
        rel = f.relative_to(SRC.parent).with_suffix("")
        package = ".".join(rel.parts[:-1]) if f.name != "__init__.py" else ".".join(rel.parts[:-1])
        yield f, imports(f, package)


@pytest.mark.parametrize("rig", RIGS)
def test_no_rig_imports_another_rig_or_the_cli(rig):
    others = [r for r in RIGS if r != rig]
    bad = [(f.name, m) for f, mods in module_imports(SRC / "rigs" / rig) for m in mods
           if any(m == f"platcal.rigs.{o}" or m.startswith(f"platcal.rigs.{o}.") for o in others)
           or m == "platcal.cli"]
    assert not bad, f"rig {rig} imports another rig or the CLI: {bad}"


@pytest.mark.parametrize("layer", ["model", "estimation", "study"])
def test_shared_layers_name_no_rig(layer):
    bad = [(f.name, m) for f, mods in module_imports(SRC / layer) for m in mods if m.startswith("platcal.rigs")]
    assert not bad, f"{layer}/ imports a rig: {bad}"
    for f in (SRC / layer).rglob("*.py"):
        text = f.read_text()
        assert not any(f"'{r}'" in text or f'"{r}"' in text for r in RIGS), f"{f.name} names a rig"


def test_the_cli_names_no_rig():
    text = (SRC / "cli.py").read_text()
    named = [r for r in RIGS if r in text]
    assert not named, f"cli.py names {named}: a rig declares its own options and defaults"


def test_the_import_check_would_see_a_cross_rig_import(tmp_path):
    """The check itself: a relative import of another rig is resolved and caught."""
    f = tmp_path / "m.py"
    f.write_text(f"from ..{RIGS[0]}.record import x\n")
    assert f"platcal.rigs.{RIGS[0]}.record" in imports(f, f"platcal.rigs.{RIGS[1]}")
