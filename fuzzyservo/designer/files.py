"""The folders the designer may read and write, nothing else.

It reads the shipped ``rigs/`` and ``studies/`` (package data), the working folder's
``rigs/``, ``studies/`` and ``out/`` (a user's own files, and the studies ``fuzzyservo
tune`` keeps there) and the output folder; it writes only to the output folder.

Every path the page names (open, save, a study's SQLite storage) goes through
:meth:`Folders.resolve`, which resolves links and ``..`` first and refuses anything
that does not land inside one of the allowed folders; a storage URL of any other
database goes through :meth:`Folders.storage_url`, which takes only the URLs the
command line (``--storage``) or a study file named.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from fuzzyservo.atomic import NAME_MAX_BYTES, shown_path
from fuzzyservo.errors import ConfigError

CONTROLLER_SUFFIXES = (".yaml", ".yml", ".fis")
#: the folders of a source (the working folder, the shipped files) the designer reads
READ_FOLDERS = ("rigs", "studies")
#: the longest name the page may give, in all (characters); per folder or file name the
#: file system's limit (:data:`fuzzyservo.atomic.NAME_MAX_BYTES`)
MAX_PATH = 1024


@dataclass(frozen=True)
class Folders:
    """Where the designer reads (``project``: the shipped ``rigs/`` and ``studies/``; ``work``:
    the working folder with the user's own) and the output folder it writes to."""

    project: Path
    output: Path
    work: Path | None = None
    #: database URLs (not SQLite files) the page may open: those the command line named
    storages: tuple[str, ...] = ()

    @classmethod
    def make(
        cls,
        project: Path,
        output: Path,
        work: Path | None = None,
        storages: tuple[str, ...] = (),
    ) -> Folders:
        return cls(
            Path(project).resolve(),
            Path(output).resolve(),
            Path(work).resolve() if work else None,
            tuple(storages),
        )

    @property
    def sources(self) -> tuple[Path, ...]:
        """The folders holding ``rigs/`` and ``studies/``, the user's first (once: in a
        checkout the working folder is often the one holding the shipped files)."""
        return (self.project,) if self.work in (None, self.project) else (self.work, self.project)

    @property
    def roots(self) -> tuple[Path, ...]:
        """The folders read from: each source's ``rigs/`` and ``studies/``, the working
        folder's ``out/`` and the output folder (nothing else of either source)."""
        runs = (self.work / "out",) if self.work is not None else ()
        return (*(s / f for s in self.sources for f in READ_FOLDERS), *runs, self.output)

    def find(self, folder: str, name: str) -> Path | None:
        """``<folder>/<name>.yaml`` in the first source that has it."""
        for source in self.sources:
            path = source / folder / f"{name}.yaml"
            if path.is_file():
                return path
        return None

    def names(self, folder: str) -> list[str]:
        """The YAML files' names in ``<folder>/`` of every source."""
        return sorted({p.stem for s in self.sources for p in (s / folder).glob("*.yaml")})

    def resolve(self, name: str, *, write: bool = False) -> Path:
        """``name`` (absolute, or relative: to the output folder when writing, else to the
        first source that has it) as a resolved path inside an allowed folder;
        :class:`ConfigError` otherwise."""
        text = str(name).strip()
        if not text:
            raise ConfigError("no file name given; type one, e.g. my_controller.yaml")
        parts = Path(text).parts
        if len(text) > MAX_PATH or any(len(os.fsencode(p)) > NAME_MAX_BYTES for p in parts):
            raise ConfigError(
                f"too long for a file name ({len(text)} characters); give a name of at most "
                f"{NAME_MAX_BYTES} bytes per folder and {MAX_PATH} characters in all",
                file=shown_path(text),
            )
        try:
            given = Path(text).expanduser()
            if given.is_absolute():
                path = given.resolve()
            elif write:
                path = (self.output / given).resolve()
            else:
                bases = [s for s in self.sources if (s / given).exists()] or [self.sources[-1]]
                path = (bases[0] / given).resolve()
        except (OSError, RuntimeError) as exc:  # a name too long, a link loop, no home folder
            raise ConfigError(
                f"not a usable file name ({getattr(exc, 'strerror', None) or exc}); give a "
                "shorter name inside the designer's folders",
                file=shown_path(text),
            ) from None
        allowed = (self.output,) if write else self.roots
        if not any(path.is_relative_to(root) for root in allowed):
            where = " or ".join(str(r) for r in allowed)
            raise ConfigError(
                f"outside the designer's folders; the designer {'writes' if write else 'reads'} "
                f"only inside {where}",
                file=shown_path(text),
            )
        return path

    def storage_url(
        self, url: str, named: tuple[str, ...] = (), study: str = ""
    ) -> tuple[str, Path | None]:
        """A study storage URL the page may open: a SQLite file inside the folders (its
        resolved path, which must exist: the designer creates no database), or a database
        URL that the command line (``--storage``) or ``named`` (the study file's own
        ``storage:``) gave, word for word (``study`` names it in the error when the
        file is missing). Returns the URL to open and the SQLite path.
        Every SQLAlchemy dialect is read as SQLAlchemy reads it, so no spelling
        (``sqlite+pysqlite:``, a ``file:`` URI, a query) gets around the check."""
        from sqlalchemy.engine import make_url
        from sqlalchemy.exc import ArgumentError

        text = url.strip()
        try:
            parsed = make_url(text)
        except (ArgumentError, ValueError):
            raise ConfigError(
                "not a storage URL; give sqlite:///path/to/study.db or a URL the designer "
                "was started with (--storage)",
                file=shown_path(text),
            ) from None
        if parsed.get_backend_name() != "sqlite":
            if text in (*self.storages, *named):
                return text, None
            raise ConfigError(
                "a database server the designer was not started with; restart it with "
                f"--storage {shown_path(text)} to open it from the page",
                file=shown_path(text),
            )
        database = parsed.database or ""
        if parsed.query or not database or database == ":memory:" or database.startswith("file:"):
            raise ConfigError(
                "give a SQLite file as sqlite:///path/to/study.db (no query, no memory or "
                "file: URI database)",
                file=shown_path(text),
            )
        path = self.resolve(database)
        if not path.is_file():
            command = f"fuzzyservo tune {study}".strip()
            raise ConfigError(f"no study database here; run '{command}' first", file=str(path))
        return f"sqlite:///{path}", path

    def controller_path(self, name: str, *, write: bool = False) -> Path:
        path = self.resolve(name, write=write)
        if path.suffix.lower() not in CONTROLLER_SUFFIXES:
            raise ConfigError(
                f"a controller file ends in {', '.join(CONTROLLER_SUFFIXES)}; rename it",
                file=shown_path(str(name)),
            )
        if not write and not path.is_file():
            raise ConfigError("file not found; check the name", file=shown_path(str(name)))
        return path

    def controller_files(self) -> list[str]:
        """Controller files the page offers: ``studies/controllers/`` and the output folder."""
        found = []
        folders = [s / "studies" / "controllers" for s in self.sources]
        for folder in (*folders, self.output):
            if folder.is_dir():
                for p in sorted(folder.rglob("*")):
                    if p.suffix.lower() in CONTROLLER_SUFFIXES and p.is_file():
                        found.append(self.label(p))
        return found

    def label(self, path: Path) -> str:
        """``path`` relative to its source folder (absolute when it is in the output folder)."""
        path = Path(path).resolve()
        for source in self.sources:
            if path.is_relative_to(source) and not path.is_relative_to(self.output):
                return str(path.relative_to(source))
        return str(path)
