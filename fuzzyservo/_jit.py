"""numba's ``njit``, with an on-disk cache that is invalidated by any kernel source change.

numba's own cache checks only the timestamp of the file that defines a function, so
a cached closed loop would go on calling the old version of a plant's ``rhs`` after
the plant changed. Here the cache folder is named after a hash of every compiled
source file and the numba version; a change anywhere gives a fresh folder. Every
module with compiled kernels imports ``njit`` from here. ``NUMBA_CACHE_DIR`` set by
the user wins.

:func:`bind_plant` compiles the closed loop once per plant: it generates a module from
the template ``simulation/_plant_loop.py``, whose statements that bind the plant slots
it declares (``PLANT_SLOTS``) give way to the plant's binding, writes it into the
cache folder, named by a hash of its text, and imports it, so numba caches it like any
other module.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import json
import os
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from functools import cache
from pathlib import Path
from types import ModuleType

import numba
from numba import njit
from numba.core import event as numba_event

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
    """True when no compiled closed loop is cached yet: the next run compiles first (minutes
    on a small machine), so the command line can say so instead of staying silent.
    (Loading a rig compiles and caches a few small kernels; they do not count.)"""
    folder = numba.config.CACHE_DIR
    return not folder or not any(Path(folder).rglob("*.closed_loop-*.nbi"))


#: the long kernels, with seconds each took to compile on one 2-core machine (the closed loop of
#: dinca_cylinder, numba 0.68): an estimate for code that plans work, never printed as a promise
#: (another machine may take several times as long); this machine's own times replace it
TYPICAL_COMPILE_S = {"plant_signals": 4.0, "closed_loop": 45.0, "signal_table": 3.0}
_TIMES_FILE = "compile_seconds.json"


def _times_path() -> Path | None:
    """Where this machine's compile times are kept: beside the fingerprinted folders (they
    outlive a source change), or in the user's ``NUMBA_CACHE_DIR``."""
    folder = numba.config.CACHE_DIR
    if not folder:
        return None
    folder = Path(folder)
    return (
        folder / _TIMES_FILE if os.environ.get("NUMBA_CACHE_DIR") else folder.parent / _TIMES_FILE
    )


def measured_compile_seconds() -> dict[str, float]:
    """Seconds each long kernel took to compile the last time this machine compiled it (the
    kernels of :data:`TYPICAL_COMPILE_S` only; empty before the first compile)."""
    path = _times_path()
    try:
        known = json.loads(path.read_text(encoding="utf-8"))
        return {k: float(known[k]) for k in TYPICAL_COMPILE_S if k in known}
    except (OSError, ValueError, TypeError, AttributeError):
        return {}


def compile_estimates() -> dict[str, float]:
    """Seconds each long kernel takes to compile: this machine's last times, else
    :data:`TYPICAL_COMPILE_S`."""
    return {**TYPICAL_COMPILE_S, **measured_compile_seconds()}


def _record_compile_time(name: str, seconds: float) -> None:
    path = _times_path()
    if path is None or name not in TYPICAL_COMPILE_S:
        return
    try:
        known = {**measured_compile_seconds(), name: round(seconds, 1)}
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps(known), encoding="utf-8")
        os.replace(tmp, path)
    except OSError:  # a read-only cache: the estimate stays the typical one
        pass


class _CompileWatch(numba_event.Listener):
    """Calls ``on_start(name)`` and ``on_end(name, seconds)`` around each top-level numba
    compilation in this process (a kernel compiled because another calls it is part of
    that one's time). numba sends these events only on a cache miss."""

    def __init__(self, on_start: Callable[[str], None], on_end: Callable[[str, float], None]):
        self.on_start_, self.on_end_ = on_start, on_end
        self.local = threading.local()

    def on_start(self, event) -> None:
        stack = self.local.__dict__.setdefault("stack", [])
        stack.append(time.perf_counter())
        if len(stack) == 1:
            self.on_start_(event.data["dispatcher"].py_func.__name__)

    def on_end(self, event) -> None:
        t0 = self.local.stack.pop()
        if not self.local.stack:
            name = event.data["dispatcher"].py_func.__name__
            seconds = time.perf_counter() - t0
            _record_compile_time(name, seconds)
            self.on_end_(name, seconds)


def watch_compiles(
    on_start: Callable[[str], None], on_end: Callable[[str, float], None]
) -> Callable[[], None]:
    """Report every kernel this process compiles from now on (see :class:`_CompileWatch`);
    the compile times are kept for :func:`compile_estimates`. Returns a function that stops it."""
    watch = _CompileWatch(on_start, on_end)
    numba_event.register("numba:compile", watch)
    return lambda: numba_event.unregister("numba:compile", watch)


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


_TEMPLATE = _PACKAGE / "simulation" / "_plant_loop.py"


def _loop_source(binding: str) -> str:
    """The source of the closed-loop module bound to one plant: the template
    ``simulation/_plant_loop.py`` statement by statement, its own docstring replaced by
    one naming it, and the statements that bind its plant slots (the names its
    ``PLANT_SLOTS`` declares) replaced by ``binding``, Python source that defines or
    imports each of those names. The template is read as a syntax tree, not imported
    (it sits above this module), and every other statement is copied unchanged.
    """
    text = _TEMPLATE.read_text(encoding="utf-8")
    lines = text.splitlines()
    tree = ast.parse(text)
    slots = _declared(tree, "PLANT_SLOTS")
    bound = _bound_names(ast.parse(binding).body)
    missing = slots - bound
    if missing:
        raise ValueError(f"a plant binding must define {sorted(missing)}; it does not")
    # a default the binding defines gives way to it too
    slots |= _declared(tree, "PLANT_DEFAULTS") & bound
    out = [
        f'"""The closed loop of {_TEMPLATE.name}, bound to one plant (generated by '
        f'{__name__}.bind_plant)."""'
    ]
    body = tree.body
    done = 0  # template lines copied or replaced so far
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
        done = body[0].end_lineno  # the template's docstring
        body = body[1:]
    placed = False
    for node in body:
        first = min([node.lineno] + [d.lineno for d in getattr(node, "decorator_list", [])])
        if _bound_names([node]) & slots:
            if not placed:
                out += ["", "# the plant's binding", binding.strip("\n"), ""]
                placed = True
        else:
            out += lines[done : first - 1] + lines[first - 1 : node.end_lineno]
        done = node.end_lineno
    return "\n".join(out) + "\n"


def _declared(tree: ast.Module, name: str) -> set[str]:
    """The names the template lists in ``<name> = (...)`` (``PLANT_SLOTS``: what a
    binding must define; ``PLANT_DEFAULTS``: what it may define instead of the template)."""
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == name for t in node.targets
        ):
            return set(ast.literal_eval(node.value))
    raise ValueError(f"{_TEMPLATE} declares no {name}")


def _bound_names(statements: list[ast.stmt]) -> set[str]:
    """The module-level names a list of statements binds (imports, defs, assignments)."""
    names: set[str] = set()
    for node in statements:
        if isinstance(node, ast.Import | ast.ImportFrom):
            names |= {(a.asname or a.name).partition(".")[0] for a in node.names}
        elif isinstance(node, ast.FunctionDef | ast.ClassDef):
            names.add(node.name)
        elif isinstance(node, ast.Assign):
            names |= {t.id for t in node.targets if isinstance(t, ast.Name)}
    return names


@cache
def bind_plant(binding: str) -> ModuleType:
    """The closed-loop module compiled for one plant.

    ``binding`` is Python source that defines (or imports) ``plant_rhs``,
    ``plant_signals`` and ``plant_in_end_stop`` (``PLANT_SLOTS`` of
    ``simulation/_plant_loop.py``); :func:`_loop_source` generates the module from the
    template and it. The same binding gives the same file, so numba's cache of the compiled loop
    survives between processes.
    """
    source = _loop_source(binding)
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


__all__ = [
    "bind_plant",
    "cache_is_cold",
    "compile_estimates",
    "measured_compile_seconds",
    "njit",
    "watch_compiles",
]
