"""The documentation site: what its build generates covers the code, every page is reachable.

``mkdocs build --strict`` in .ci/run catches broken links; these checks are what a build
cannot see: a component, effect or public name the generated pages leave out, a page
missing from the navigation, a README grown back into a manual.
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"

pytestmark = pytest.mark.skipif(
    not (DOCS / "hooks.py").is_file(), reason="docs/ is not shipped with an installed package"
)


def _load(name: str):
    import sys

    sys.path.insert(0, str(DOCS))
    try:
        spec = importlib.util.spec_from_file_location(name, DOCS / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module
    finally:
        sys.path.remove(str(DOCS))


def test_component_reference_covers_every_component_effect_and_parameter():
    from fuzzyservo.components.declare import registry
    from fuzzyservo.components.effects import LIBRARY

    text = _load("gen_components").components_markdown()
    for name, component in registry().items():
        assert f"#### `{name}`" in text, f"component {name} missing from the reference"
        for p in component.params:
            assert f"| `{p.key}` |" in text, f"{name}.{p.key} missing from the reference"
    for name, effect in LIBRARY.items():
        assert f"| `{name}` | {effect.stage} |" in text, f"effect {name} missing"
        for p in effect.params:
            assert f"| `{name}` | `{p.key}` |" in text, f"effect parameter {name}.{p.key} missing"


def test_api_page_lists_every_public_name():
    import fuzzyservo

    text = _load("hooks").api_markdown()
    for name in fuzzyservo.__all__:
        module, attribute = fuzzyservo._LAZY[name]  # where the package imports it from
        assert f"::: {module}.{attribute}\n" in text, name


def test_every_page_is_in_the_navigation_and_every_markdown_link_resolves():
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    listed = {page for entry in config["nav"] for page in entry.values()}
    pages = {p.relative_to(DOCS).as_posix() for p in DOCS.glob("**/*.md")}
    assert config["docs_dir"] == "docs"
    assert pages - listed == set(), f"pages not in mkdocs.yml nav: {sorted(pages - listed)}"
    assert listed - pages == set(), f"nav entries without a page: {sorted(listed - pages)}"
    readme = (ROOT / "README.md").read_text()
    for target in re.findall(r"\]\(((?:docs/)?[\w./-]+\.md)\)", readme):
        assert (ROOT / target).is_file(), f"README links to {target}, which does not exist"


def test_readme_is_short_and_keeps_the_two_commands():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 250, f"README.md has {len(lines)} lines; the manual belongs in docs/"
    assert lines[3] == (
        "python3 -m venv .venv && . .venv/bin/activate && pip install -e . && fuzzyservo tune"
    )
    assert re.match(r"^python3 -m venv .*\[test\].*pytest", lines[4]), ".ci/run reads this line"


def test_every_figure_is_made_by_the_script_and_shown():
    """docs/img/ holds what docs/gen_figures.py writes (nothing pasted by hand), each shown."""
    made = set(_load("gen_figures").FIGURES) | {"designer"}
    shown = "".join(p.read_text() for p in [ROOT / "README.md", *DOCS.glob("**/*.md")])
    for png in sorted((DOCS / "img").glob("*.png")):
        assert png.stem in made, f"{png.name} is not made by docs/gen_figures.py"
        assert f"img/{png.name})" in shown, f"{png.name} is shown on no page"


#: what a reference page must not say: it states what holds now; history is in CHANGELOG.md
NOTEBOOK = {
    "a date": re.compile(r"\b20\d\d-\d\d-\d\d\b"),
    "an issue number": re.compile(r"\bissues? #?\d+", re.IGNORECASE),
    "'tonight'": re.compile(r"\btonight\b", re.IGNORECASE),
    "'this session'": re.compile(r"\bthis session", re.IGNORECASE),
    # 7 to 40 hex digits with a letter and a digit among them (not a word, not a number)
    "a commit hash": re.compile(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b"),
}
SNIPPET = re.compile(r'^\s*--8<--\s+"([^"]+)"\s*$', re.MULTILINE)


def _as_rendered(page: Path) -> str:
    """The page's text with the repository files it includes (pymdownx snippets) put in,
    whole (``"file:9:21"`` includes lines 9-21 of it: the check reads them all)."""
    return SNIPPET.sub(lambda m: (ROOT / m.group(1).split(":")[0]).read_text(encoding="utf-8"),
                       page.read_text(encoding="utf-8"))  # fmt: skip


def test_pages_state_what_holds_now_without_dates_issues_sessions_or_commits():
    """No page of docs/ (with the files it includes) nor the README names a date, an issue,
    a session, 'tonight' or a commit; the changelog page (CHANGELOG.md) is where history is."""
    pages = [ROOT / "README.md", *sorted(DOCS.glob("**/*.md"))]
    found = []
    for page in pages:
        if page.name == "changelog.md":
            continue
        for number, line in enumerate(_as_rendered(page).splitlines(), 1):
            found += [
                f"{page.relative_to(ROOT)}:{number}: {what}: {line.strip()[:100]}"
                for what, pattern in NOTEBOOK.items()
                if pattern.search(line)
            ]
    assert not found, "\n".join(found)


def test_the_rule_catches_what_it_is_for():
    lines = {
        "measured on 2026-11-25": "a date",
        "before issue 28": "an issue number",
        "after this session's issues": "'this session'",
        "16.2 s tonight": "'tonight'",
        "main at 2e3c8ca": "a commit hash",
    }
    for line, what in lines.items():
        assert NOTEBOOK[what].search(line), line
    clean = "a 1e-12 leakage, 10000 inputs, the effect of a facade, 1.4027173, 0x1F"
    assert not any(p.search(clean) for p in NOTEBOOK.values())


def test_calibration_page_is_a_reference_not_a_notebook():
    lines = (DOCS / "calibration.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 250, f"docs/calibration.md has {len(lines)} lines (at most 250)"


def test_metrics_table_covers_every_metric():
    from fuzzyservo.metrics import METRIC_NAMES

    text = _load("hooks").metrics_markdown()
    for name in METRIC_NAMES:
        assert f"| `{name}` |" in text, name
    assert "<!-- generated: metrics -->" in (DOCS / "getting-started.md").read_text()
