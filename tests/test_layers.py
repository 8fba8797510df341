"""The core never imports the research packages: an installed mjjoint needs none of them.

Core: simulation, coupling, recordings, identify, diagnosis, report, cli (every module outside
``mjjoint.benchmark``, ``mjjoint.experiments`` and ``mjjoint.datasets``). The research packages
may use the core, never the reverse; a piece both need belongs in the core.
"""
from __future__ import annotations

import ast
from importlib.util import find_spec
from pathlib import Path

PACKAGE = Path(find_spec("mjjoint").origin).parent  # found, not imported: the scan reads source only
RESEARCH = ("benchmark", "experiments", "datasets")


def module_name(path: Path) -> tuple[str, ...]:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return parts[:-1] if parts[-1] == "__init__" else parts


def imported(source: str, package: tuple[str, ...]) -> set[str]:
    """Every module an ``import`` statement of ``source`` names, at any depth, relative ones
    resolved against ``package`` (the package the module lies in)."""
    names = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0:
                base = (node.module,)
            else:
                base = (*package[:len(package) - node.level + 1], *([node.module] if node.module else []))
            names.update(".".join((*base, alias.name)) for alias in node.names)  # `from . import x`
            names.add(".".join(base))
    return names


def research(name: str) -> bool:
    parts = name.split(".")
    return parts[0] == "mjjoint" and len(parts) > 1 and parts[1] in RESEARCH


def core_modules() -> list[Path]:
    return [p for p in sorted(PACKAGE.rglob("*.py")) if not research(".".join(module_name(p)))]


def test_the_core_imports_no_research_package():
    offending = set()
    for path in core_modules():
        package = module_name(path) if path.name == "__init__.py" else module_name(path)[:-1]
        offending |= {f"{'.'.join(module_name(path))} imports {name}"
                      for name in imported(path.read_text(encoding="utf-8"), package) if research(name)}
    assert not offending, sorted(offending)


def test_the_scan_sees_every_way_of_importing():
    """The scan itself (one that saw nothing would pass the test above): relative imports from
    a core subpackage, ``from .. import``, and an import inside a function are all caught."""
    source = "\n".join(["from ..benchmark import cases", "from .. import datasets",
                        "def f():\n    import mjjoint.experiments.lab", "from ..identify import fit"])
    found = sorted(n for n in imported(source, ("mjjoint", "report")) if research(n))
    assert found == ["mjjoint.benchmark", "mjjoint.benchmark.cases", "mjjoint.datasets",
                     "mjjoint.experiments.lab"]
    names = {".".join(module_name(p)) for p in core_modules()}
    assert {"mjjoint.sim", "mjjoint.cli.fit", "mjjoint.diagnosis.loop"} <= names
    assert not any(research(n) for n in names)
