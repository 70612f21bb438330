"""MkDocs hooks (``hooks:`` in ``mkdocs.yml``): the pages generated from the code at build time.

* ``<!-- generated: components -->`` (docs/rigs.md): every component and effect, from
  their declarations (:mod:`gen_components`);
* ``<!-- generated: metrics -->`` (docs/getting-started.md): every metric with its definition
  and unit, from :data:`fuzzyservo.metrics.METRIC_DOCS`;
* ``<!-- generated: api -->`` (docs/api.md): one mkdocstrings entry per name of
  ``fuzzyservo.__all__``, at the module that defines it (the package imports them lazily,
  so a static reader would not find them on the package itself).
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import gen_components

API_MARKER = "<!-- generated: api -->"
METRICS_MARKER = "<!-- generated: metrics -->"


def metrics_markdown() -> str:
    """A table of every metric a run is scored by: name, definition and unit, over steps."""
    from fuzzyservo.metrics import METRIC_DOCS, METRIC_NAMES

    rows = ["| metric | definition [unit]; over the steps or samples |", "|---|---|"]
    for name in METRIC_NAMES:
        text = METRIC_DOCS[name].replace("|", r"\|")  # |r - y| inside a table cell
        rows.append(f"| `{name}` | {text} |")
    return "\n".join(rows)


def api_markdown() -> str:
    import fuzzyservo

    lazy = fuzzyservo._LAZY
    out = []
    for name in sorted(fuzzyservo.__all__, key=str.lower):
        module, attribute = lazy[name]
        out += [f"::: {module}.{attribute}", ""]
    return "\n".join(out)


def on_page_markdown(markdown: str, page, config, files) -> str:
    markdown = gen_components.on_page_markdown(markdown, page, config, files)
    if METRICS_MARKER in markdown:
        markdown = markdown.replace(METRICS_MARKER, metrics_markdown())
    if API_MARKER in markdown:
        markdown = markdown.replace(API_MARKER, api_markdown())
    return markdown
