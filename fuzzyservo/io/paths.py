"""Finding the project's files: a path as given, or a bare name under ``rigs/``, ``studies/`` …"""

from __future__ import annotations

from pathlib import Path

from fuzzyservo.errors import ConfigError


def project_root() -> Path:
    """The checkout holding ``rigs/`` and ``studies/`` (the package's parent folder)."""
    return Path(__file__).resolve().parent.parent.parent


def search_dirs() -> list[Path]:
    """Where bare names are looked up: the working folder, then the checkout."""
    return [Path.cwd(), project_root()]


def find_file(name: str, folder: str, what: str, *, relative_to: Path | None = None) -> Path:
    """``name`` as a path (also relative to ``relative_to``'s folder), or a bare name
    looked up as ``<folder>/<name>.yaml`` in :func:`search_dirs`.

    Raises :class:`ConfigError` listing the known names when nothing matches.
    """
    given = Path(name)
    candidates = [given] if relative_to is None else [relative_to.parent / given, given]
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    if given.suffix in (".yaml", ".yml", ".fis") or "/" in name:
        raise ConfigError(f"{what} file not found; check the path", file=name)
    for base in search_dirs():
        candidate = base / folder / f"{name}.yaml"
        if candidate.is_file():
            return candidate
    known = sorted({p.stem for base in search_dirs() for p in (base / folder).glob("*.yaml")})
    raise ConfigError(f"no {what} named {name!r}; known: {', '.join(known) or 'none'}", file=name)
