"""The architecture, checked rather than remembered.

The layers and forbidden imports are an import-linter contract in ``pyproject.toml``
(``lint-imports`` runs in ``.ci/run``); what import-linter cannot express is here:

- no module imports a private module (``_name``) of another subpackage: what two packages
  share is promoted to a public module or the package's ``__init__``. Private modules of
  the root package itself (``fuzzyservo._jit``) are the whole package's internals.
- YAML is parsed and written only in ``fuzzyservo.io``;
- no import cycles between subpackages or between modules.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "fuzzyservo"


def _modules() -> list[tuple[str, Path]]:
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out.append((".".join(parts), path))
    return out


def _imports(path: Path) -> list[tuple[int, str]]:
    """Every module an import statement names (function-level ones included)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.lineno, node.module))
            found += [(node.lineno, f"{node.module}.{a.name}") for a in node.names]
    return found


def _package(module: str) -> str:
    return ".".join(module.split(".")[:2])


def test_no_module_imports_another_packages_private_module() -> None:
    offenders = []
    for module, path in _modules():
        for line, name in _imports(path):
            parts = name.split(".")
            if parts[0] != "fuzzyservo" or len(parts) < 3:
                continue
            private = next((i for i, p in enumerate(parts[2:], 2) if p.startswith("_")), None)
            if private is None or parts[private].startswith("__"):
                continue
            if _package(name) != _package(module):
                offenders.append(f"{path.relative_to(PACKAGE.parent)}:{line} imports {name}")
    assert not offenders, "promote what is shared:\n" + "\n".join(offenders)


def test_yaml_is_read_and_written_only_in_io() -> None:
    offenders = [
        f"{path.relative_to(PACKAGE.parent)}:{line}"
        for module, path in _modules()
        if not module.startswith("fuzzyservo.io")
        for line, name in _imports(path)
        if name == "yaml" or name.startswith("yaml.")
    ]
    assert not offenders, offenders


def test_no_import_cycles_between_subpackages() -> None:
    grimp = pytest.importorskip("grimp")  # comes with import-linter (the test extra)
    graph = grimp.build_graph("fuzzyservo", exclude_type_checking_imports=True)
    packages = sorted({_package(m) for m in graph.modules} - {"fuzzyservo"})
    cycles = [
        (a, b)
        for i, a in enumerate(packages)
        for b in packages[i + 1 :]
        if graph.chain_exists(a, b, as_packages=True) and graph.chain_exists(b, a, as_packages=True)
    ]
    assert not cycles, cycles


def test_no_import_cycles_between_modules() -> None:
    """Module-level cycles, a package's ``__init__`` and imports made only for type
    checking included: what a package's modules share lives in a module of its own that
    the ``__init__`` re-exports, never in the ``__init__`` they import back."""
    grimp = pytest.importorskip("grimp")
    nx = pytest.importorskip("networkx")
    graph = grimp.build_graph("fuzzyservo")
    edges = nx.DiGraph()
    for module in graph.modules:
        for imported in graph.find_modules_directly_imported_by(module):
            edges.add_edge(module, imported)
    cycles = [sorted(c) for c in nx.strongly_connected_components(edges) if len(c) > 1]
    assert not cycles, cycles


MODULE_LINES = 700  # a module that grows past this holds more than one job


def test_no_module_is_over_the_line_limit() -> None:
    long = {
        str(path.relative_to(PACKAGE.parent)): n
        for _, path in _modules()
        if (n := len(path.read_text(encoding="utf-8").splitlines())) > MODULE_LINES
    }
    assert not long, f"split by job: {long}"


def test_one_name_for_each_report_step() -> None:
    """A reader who meets ``Outcome`` or ``write_outputs`` knows which one it is."""
    defined: dict[str, list[str]] = {}
    for _, path in _modules():
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if isinstance(node, ast.ClassDef | ast.FunctionDef):
                defined.setdefault(node.name, []).append(str(path.relative_to(PACKAGE.parent)))
    shared = {
        name: homes
        for name in ("Outcome", "write_outputs", "summary_data", "calibrate", "Result")
        if len(homes := defined.get(name, [])) > 1
    }
    assert not shared, shared


# what io may not import: the modules that simulate, fit, analyse or score (io reads and
# writes; the domain packages compute, fuzzyservo.workflows joins the two)
COMPUTING = (
    "fuzzyservo.simulation",
    "fuzzyservo.analysis.margins",
    "fuzzyservo.analysis.frequency",
    "fuzzyservo.analysis.compare",
    "fuzzyservo.tuning.runner",
    "fuzzyservo.tuning.objective",
    "fuzzyservo.tuning.pipeline",
    "fuzzyservo.calibration.search",
    "fuzzyservo.calibration.candidates",
    "fuzzyservo.calibration.summary",
    "fuzzyservo.calibration.null",
    "fuzzyservo.components.nn_fit",
    "fuzzyservo.controllers.fuzzy.evaluate",
    "fuzzyservo.codegen._check",
    "fuzzyservo.codegen._fmu",
)


def test_io_imports_nothing_that_computes() -> None:
    grimp = pytest.importorskip("grimp")
    graph = grimp.build_graph("fuzzyservo", exclude_type_checking_imports=True)
    offenders = sorted(
        f"{module} imports {imported}"
        for module in graph.find_descendants("fuzzyservo.io") | {"fuzzyservo.io"}
        for imported in graph.find_modules_directly_imported_by(module)
        if imported.startswith(COMPUTING)
    )
    assert not offenders, offenders
