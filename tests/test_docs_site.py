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
