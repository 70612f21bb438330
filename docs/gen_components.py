"""The component and effect reference, generated from the declarations so it cannot drift.

Every component type is declared once in ``fuzzyservo/components/library/`` (a
``Component`` with its ``Param``, ``State`` and ``Signal`` entries and its compiled code)
and every effect once in ``fuzzyservo/components/effects.py`` (``LIBRARY``). This module
turns them into Markdown. MkDocs runs it as a hook (``hooks:`` in ``mkdocs.yml``): the
marker ``<!-- generated: components -->`` in ``docs/rigs.md`` is replaced by the
reference at every build, so the site always shows what the code declares.

``python docs/gen_components.py`` prints the same Markdown.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:  # mkdocs run from a clone without an install
    sys.path.insert(0, str(ROOT))

MARKER = "<!-- generated: components -->"

# unit tokens a declaration may use; the composition resolves them per rig
_TOKENS = {
    "force": "N or N·m",
    "velocity": "m/s or rad/s",
    "position": "m or rad",
    "input": "A or V (the valve's input)",
}
_ROLES = ("fluid", "supply", "valve", "line", "accumulator", "actuator", "load")


def _unit(unit: str) -> str:
    return _TOKENS.get(unit, unit.replace("^3", "³").replace("^2", "²").replace("*", "·"))


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def _constraint(p) -> str:
    parts = []
    if p.positive:
        parts.append("> 0")
    if p.nonnegative:
        parts.append("≥ 0")
    if p.minimum is not None:
        parts.append(f"≥ {p.minimum:g}")
    if p.maximum is not None:
        parts.append(f"≤ {p.maximum:g}")
    if p.length:
        parts.append(f"{p.length} values from a {p.fmt or 'file'}")
    return ", ".join(parts)


def _modules():
    """(module, its components) for every library module, in file-name order."""
    from fuzzyservo.components import library

    for info in sorted(pkgutil.iter_modules(library.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{library.__name__}.{info.name}")
        components = getattr(module, "COMPONENTS", ())
        if components:
            yield module, components


def _component(c) -> list[str]:
    out = [f"#### `{c.type}`", "", f"{c.doc}.", "", f"*Source:* {c.source}.", ""]
    if c.params:
        out += ["| key | unit | default | allowed | what |", "|---|---|---|---|---|"]
        for p in c.params:
            default = "required" if p.default is None else f"{p.default:g}"
            out.append(
                f"| `{p.key}` | {_unit(p.unit)} | {default} | {_constraint(p)} | {_cell(p.doc)} |"
            )
        out.append("")
    if c.states:
        out += ["| state | unit | what |", "|---|---|---|"]
        out += [f"| `{s.name}` | {_unit(s.unit)} | {_cell(s.doc)} |" for s in c.states]
        out.append("")
    if c.signals:
        out += ["| signal | unit | records |", "|---|---|---|"]
        out += [f"| `{s.name}` | {_unit(s.unit)} | `{_cell(s.source)}` |" for s in c.signals]
        out.append("")
    if c.effects:
        out += ["Effects it reads: " + ", ".join(f"`{e}`" for e in c.effects) + ".", ""]
    if c.code:
        out += ['??? note "compiled code, by phase"', ""]
        for phase, functions in c.code.items():
            for function in functions if isinstance(functions, tuple) else (functions,):
                source = inspect.getsource(function.py_func)
                out += [f"    `{phase}`: returns {', '.join(function.returns)}", ""]
                out += ["    ```python"]
                out += ["    " + line for line in inspect.cleandoc(source).splitlines()]
                out += ["    ```", ""]
    return out


def components_markdown() -> str:
    """Every component type, grouped by role, then every effect of the library."""
    from fuzzyservo.components.effects import LIBRARY

    by_role: dict[str, list[tuple[object, object]]] = {role: [] for role in _ROLES}
    for module, components in _modules():
        for c in components:
            by_role.setdefault(c.role, []).append((module, c))
    out = ["## Component reference", ""]
    out += [
        "Generated from `fuzzyservo/components/library/` at every build of this site "
        "(`docs/gen_components.py`). Units are SI as the rig file's value is converted; a "
        "rig file may give any unit of the same dimension.",
        "",
    ]
    for role, entries in by_role.items():
        if not entries:
            continue
        out += [f"### {role}", ""]
        seen: set[str] = set()
        for module, c in entries:
            if module.__name__ not in seen and module.__doc__:
                seen.add(module.__name__)
                out += [f"`{module.__name__}`:", "", "```text"]
                out += inspect.cleandoc(module.__doc__).splitlines()
                out += ["```", ""]
            out += _component(c)
    out += ["## Effect reference", ""]
    out += [
        "Generated from `LIBRARY` in `fuzzyservo/components/effects.py`. Declared under "
        "`effects:` in a rig file, as `effect.key` in a study's `uncertainty:`; off (0) "
        "unless declared. Input effects act in the loop on every plant, plant effects in "
        "the components that read them.",
        "",
        "| effect | stage | formulation | source |",
        "|---|---|---|---|",
    ]
    for e in LIBRARY.values():
        out.append(f"| `{e.name}` | {e.stage} | {_cell(e.formulation)} | {_cell(e.source)} |")
    out += ["", "| effect | key | unit | what | fitted by `calibrate` |", "|---|---|---|---|---|"]
    for e in LIBRARY.values():
        for p in e.params:
            fitted = ("yes, log grid" if p.log else "yes") if p.fitted else "no (fixed)"
            signed = "; may be negative" if p.signed else ""
            out.append(
                f"| `{e.name}` | `{p.key}` | {_unit(p.unit)} | {_cell(p.doc)}{signed} | {fitted} |"
            )
    out.append("")
    for e in LIBRARY.values():  # what calibration's verdict says when it adds the effect
        if e.lookalike:
            out += [f"`{e.name}` may also be {e.lookalike}.", ""]
    return "\n".join(out)


def on_page_markdown(markdown: str, page, config, files) -> str:
    """MkDocs hook: replace the marker with the generated reference."""
    if MARKER in markdown:
        return markdown.replace(MARKER, components_markdown())
    return markdown


if __name__ == "__main__":
    print(components_markdown())
