"""numba's ``njit``, with an on-disk cache that is invalidated by any kernel source change.

numba's own cache checks only the timestamp of the file that defines a function, so
a cached closed loop would go on calling the old version of a plant's ``rhs`` after
the plant changed. Here the cache folder is named after a hash of every compiled
source file and the numba version; a change anywhere gives a fresh folder. Every
module with compiled kernels imports ``njit`` from here. ``NUMBA_CACHE_DIR`` set by
the user wins.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

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
    """True when no compiled kernel is cached yet: the next run compiles first (about a
    minute on a small machine), so the command line can say so instead of staying silent."""
    folder = numba.config.CACHE_DIR
    return not folder or not any(Path(folder).rglob("*.nbi"))


__all__ = ["cache_is_cold", "njit"]
