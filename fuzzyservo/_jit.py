"""numba's ``njit``, with an on-disk cache that is invalidated by any kernel source change.

numba's own cache checks only the timestamp of the file that defines a function, so
a cached closed loop would go on calling the old version of a plant's ``rhs`` after
the plant changed. Here the cache folder is named after a hash of every compiled
source file and the numba version; a change anywhere gives a fresh folder. Every
module with compiled kernels imports ``njit`` from here. ``NUMBA_CACHE_DIR`` set by
the user wins.

:func:`bind_plant` compiles the closed loop once per plant: it writes a copy of
``simulation/_plant_loop.py`` whose binding block names one plant's kernels (or holds
the source generated for a composition) into the cache folder, named by a hash of its
text, and imports it, so numba caches it like any other module.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
import tempfile
from functools import cache
from pathlib import Path
from types import ModuleType

import numba
from numba import njit

_PACKAGE = Path(__file__).resolve().parent
_KERNEL_DIRS = ("components", "controllers", "plants", "simulation")


def _fingerprint() -> str:
    digest = hashlib.sha256(numba.__version__.encode())
    for folder in _KERNEL_DIRS:
        for path in sorted((_PACKAGE / folder).rglob("*.py")):
            digest.update(path.relative_to(_PACKAGE).as_posix().encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "fuzzyservo" / "numba" / _fingerprint()


if not os.environ.get("NUMBA_CACHE_DIR"):
    try:
        folder = _cache_dir()
        folder.mkdir(parents=True, exist_ok=True)
        numba.config.CACHE_DIR = str(folder)
    except OSError:  # read-only home: numba falls back to __pycache__ or no cache
        pass


def cache_is_cold() -> bool:
    """True when no compiled closed loop is cached yet: the next run compiles first (about a
    minute on a small machine), so the command line can say so instead of staying silent.
    (Loading a rig compiles and caches a few small kernels; they do not count.)"""
    folder = numba.config.CACHE_DIR
    return not folder or not any(Path(folder).rglob("*.closed_loop-*.nbi"))


_BEGIN = "# >>> plant binding\n"
_END = "# <<< plant binding\n"


def _generated_dir() -> Path:
    base = Path(numba.config.CACHE_DIR) if numba.config.CACHE_DIR else None
    for folder in (base, Path(tempfile.gettempdir()) / "fuzzyservo-generated"):
        if folder is None:
            continue
        try:
            (folder / "generated").mkdir(parents=True, exist_ok=True)
            return folder / "generated"
        except OSError:
            continue
    raise OSError("no writable folder for generated kernels; set NUMBA_CACHE_DIR")


@cache
def bind_plant(binding: str) -> ModuleType:
    """The closed-loop module compiled for one plant.

    ``binding`` is Python source that defines (or imports) ``plant_rhs``,
    ``plant_signals`` and ``plant_in_end_stop``; it replaces the binding block of
    ``simulation/_plant_loop.py``. The same binding gives the same file, so numba's
    cache of the compiled loop survives between processes.
    """
    template = (_PACKAGE / "simulation" / "_plant_loop.py").read_text(encoding="utf-8")
    start = template.index(_BEGIN) + len(_BEGIN)
    end = template.index(_END)
    source = template[:start] + binding.rstrip() + "\n\n" + template[end:]
    digest = hashlib.sha256((_fingerprint() + source).encode()).hexdigest()[:16]
    name = f"fuzzyservo_loop_{digest}"
    if name in sys.modules:
        return sys.modules[name]
    path = _generated_dir() / f"{name}.py"
    if not path.exists() or path.read_text(encoding="utf-8") != source:
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(source, encoding="utf-8")
        os.replace(tmp, path)  # atomic: parallel workers never read half a file
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


__all__ = ["bind_plant", "cache_is_cold", "njit"]
