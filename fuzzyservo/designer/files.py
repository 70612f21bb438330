"""The folders the designer may read and write: the project and the output folder, nothing else.

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
    """The project folder (rigs/, studies/) and the output folder the designer writes to."""

    project: Path
    output: Path

    @classmethod
    def make(cls, project: Path, output: Path) -> Folders:
        return cls(Path(project).resolve(), Path(output).resolve())

    @property
    def roots(self) -> tuple[Path, Path]:
        return (self.project, self.output)

    def resolve(self, name: str, *, write: bool = False) -> Path:
        """``name`` (absolute, or relative: to the output folder when writing, else to the
        project) as a resolved path inside an allowed folder; :class:`ConfigError` otherwise."""
        text = str(name).strip()
        if not text:
            raise ConfigError("no file name given; type one, e.g. my_controller.yaml")
        given = Path(text).expanduser()
        base = self.output if write else self.project
        path = (given if given.is_absolute() else base / given).resolve()
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
        for folder in (self.project / "studies" / "controllers", self.output):
            if folder.is_dir():
                for p in sorted(folder.rglob("*")):
                    if p.suffix.lower() in CONTROLLER_SUFFIXES and p.is_file():
                        found.append(self.label(p))
        return found

    def label(self, path: Path) -> str:
        """``path`` relative to the project (or absolute when it is in the output folder only)."""
        path = Path(path).resolve()
        if path.is_relative_to(self.project):
            return str(path.relative_to(self.project))
        return str(path)
