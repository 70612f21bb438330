"""The folders the designer may read and write, nothing else: the shipped files (package
data), the working folder (a user's own ``rigs/`` and ``studies/``) and the output folder.

Every path the page names (open, save, a study's SQLite storage) goes through
:meth:`Folders.resolve`, which resolves links and ``..`` first and refuses anything
that does not land inside one of the allowed folders.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from fuzzyservo.errors import ConfigError

CONTROLLER_SUFFIXES = (".yaml", ".yml", ".fis")


@dataclass(frozen=True)
class Folders:
    """Where the designer reads (``project``: the shipped ``rigs/`` and ``studies/``; ``work``:
    the working folder with the user's own) and the output folder it writes to."""

    project: Path
    output: Path
    work: Path | None = None

    @classmethod
    def make(cls, project: Path, output: Path, work: Path | None = None) -> Folders:
        return cls(
            Path(project).resolve(), Path(output).resolve(), Path(work).resolve() if work else None
        )

    @property
    def sources(self) -> tuple[Path, ...]:
        """The folders holding ``rigs/`` and ``studies/``, the user's first (once: in a
        checkout the working folder is often the one holding the shipped files)."""
        return (self.project,) if self.work in (None, self.project) else (self.work, self.project)

    @property
    def roots(self) -> tuple[Path, ...]:
        return (*self.sources, self.output)

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
        given = Path(text).expanduser()
        if given.is_absolute():
            path = given.resolve()
        elif write:
            path = (self.output / given).resolve()
        else:
            bases = [s for s in self.sources if (s / given).exists()] or [self.sources[-1]]
            path = (bases[0] / given).resolve()
        allowed = (self.output,) if write else self.roots
        if not any(path.is_relative_to(root) for root in allowed):
            where = " or ".join(str(r) for r in allowed)
            raise ConfigError(
                f"outside the designer's folders; the designer {'writes' if write else 'reads'} "
                f"only inside {where}",
                file=text,
            )
        return path

    def controller_path(self, name: str, *, write: bool = False) -> Path:
        path = self.resolve(name, write=write)
        if path.suffix.lower() not in CONTROLLER_SUFFIXES:
            raise ConfigError(
                f"a controller file ends in {', '.join(CONTROLLER_SUFFIXES)}; rename it",
                file=str(name),
            )
        if not write and not path.is_file():
            raise ConfigError("file not found; check the name", file=str(name))
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
