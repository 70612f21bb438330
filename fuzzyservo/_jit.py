"""numba's ``njit``, with an on-disk cache keyed by each kernel's own source and what it
imports, and the modules generated at run time (a plant's kernels).

numba's own cache checks only the file that defines a function, so a cached closed loop
would go on calling the old version of a function from another file after that file
changed. Here a compiled function's cache is stamped with a hash of its own file and of
every file of this package (or generated module) it imports, directly or through others,
and the numba version (:class:`KernelCacheLocator`): editing one component's file
recompiles the kernels whose modules import it, and no others. Entries live in one folder,
``~/.cache/fuzzyservo/numba`` (``XDG_CACHE_HOME`` moves it; ``NUMBA_CACHE_DIR`` set by the
user wins). numba writes every entry to a temporary file and renames it, so processes
that share the folder never read half a file; an entry that cannot be read (corrupt,
truncated) is compiled again and rewritten (:func:`_guard_corrupt_entries`).

:func:`load_generated` imports a module generated from source text (a plant's kernels,
the C entry points the loop calls them by), written into the cache folder under a name
that is the hash of its text, so numba caches it like any other module.
"""

from __future__ import annotations

import ast
import ctypes
import functools
import hashlib
import importlib.util
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager, nullcontext
from pathlib import Path
from types import ModuleType
from typing import Any

import numba
from numba import njit
from numba.core import caching
from numba.core import event as numba_event

_PACKAGE = Path(__file__).resolve().parent
#: generated modules' names start with this (:func:`load_generated`)
GENERATED_PREFIX = "fuzzyservo_gen_"


def _cache_root() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "fuzzyservo" / "numba"


if not os.environ.get("NUMBA_CACHE_DIR"):
    try:
        folder = _cache_root()
        folder.mkdir(parents=True, exist_ok=True)
        numba.config.CACHE_DIR = str(folder)
    except OSError:  # read-only home: numba falls back to __pycache__ or no cache
        pass


def _module_file(name: str) -> Path | None:
    """The file of a module of this package or a generated one, by its dotted name."""
    if name.startswith(GENERATED_PREFIX) and "." not in name:
        try:
            path = _generated_dir() / f"{name}.py"
        except OSError:
            return None
        return path if path.is_file() else None
    if name != "fuzzyservo" and not name.startswith("fuzzyservo."):
        return None
    base = _PACKAGE.parent.joinpath(*name.split("."))
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


def _imports(path: Path) -> set[Path]:
    """The files of this package's (or generated) modules that ``path`` imports."""
    try:
        tree = ast.parse(path.read_bytes())
    except (OSError, SyntaxError, ValueError):
        return set()
    found: set[Path] = set()
    for node in ast.walk(tree):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            # ``from a.b import c``: c may be a module of a.b, else a name in it
            names = [f"{node.module}.{a.name}" for a in node.names] + [node.module]
        for name in names:
            file = _module_file(name)
            if file is not None:
                found.add(file)
    return found


@functools.cache
def _closure_stamp(path: str, mtime_ns: int, size: int) -> str:
    """A hash of ``path``'s text, of every package or generated file it imports directly
    or through others, and of the numba version: a kernel's cache stamp."""
    seen: set[Path] = set()
    todo = [Path(path)]
    while todo:
        file = todo.pop()
        if file in seen:
            continue
        seen.add(file)
        todo += sorted(_imports(file) - seen)
    digest = hashlib.sha256(numba.__version__.encode())
    for file in sorted(seen):
        digest.update(str(file).encode())
        digest.update(file.read_bytes())
    return digest.hexdigest()


def kernel_stamp(path: str | Path) -> str:
    """The cache stamp of the kernels defined in ``path`` (:func:`_closure_stamp`)."""
    st = os.stat(path)
    return _closure_stamp(str(Path(path).resolve()), st.st_mtime_ns, st.st_size)


class KernelCacheLocator(caching.UserProvidedCacheLocator):
    """numba's cache locator for this package's kernels and generated modules: the
    cache folder numba is given, and a stamp that is :func:`kernel_stamp` (the file and what
    it imports), not the file alone. Any other function is left to numba's own locators."""

    def get_source_stamp(self) -> str:
        return kernel_stamp(self._py_file)

    @classmethod
    def from_function(cls, py_func, py_file):
        path = Path(py_file).resolve()
        ours = _PACKAGE in path.parents or path.name.startswith(GENERATED_PREFIX)
        return super().from_function(py_func, py_file) if ours else None


def _install_locator() -> None:
    """Put :class:`KernelCacheLocator` before numba's own locators (numba's
    ``CACHE_LOCATOR_CLASSES`` setting), unless the user chose them
    (``NUMBA_CACHE_LOCATOR_CLASSES``)."""
    if numba.config.CACHE_LOCATOR_CLASSES:
        return
    defaults = [cls.__name__ for cls in caching.CacheImpl._locator_classes]
    numba.config.CACHE_LOCATOR_CLASSES = ",".join(
        [f"{__name__}.{KernelCacheLocator.__name__}", *defaults]
    )


def _guard_corrupt_entries() -> None:
    """An index or data file numba cannot unpickle (a truncated write by a killed process,
    a disk fault) reads as a cache miss: the kernel is compiled again and the entry
    rewritten, never trusted, never an error. An entry that cannot be written (a full disk,
    a file-size limit, a read-only folder) is left out: the kernel runs, compiled in memory."""
    cls = caching.IndexDataCacheFile
    if getattr(cls, "_fuzzyservo_guarded", False):
        return
    load_index, load_data, save = cls._load_index, cls._load_data, cls.save

    def _save(self, key, data):
        try:
            save(self, key, data)
        except OSError:
            pass

    def _load_index(self):
        try:
            return load_index(self)
        except Exception:
            return {}

    def _load_data(self, name):
        try:
            return load_data(self, name)
        except OSError:
            raise
        except Exception as error:  # any unreadable entry: load() reads an OSError as a miss
            raise OSError(f"unreadable cache entry {name}") from error

    cls._load_index, cls._load_data, cls.save = _load_index, _load_data, _save
    cls._fuzzyservo_guarded = True


_install_locator()
_guard_corrupt_entries()


#: what the long compiles are, as the compile lines name them (any other kernel by its name)
STEPS = {
    "closed_loop": "the closed loop (once per install)",
    "closed_loop_batch": "the batched closed loop (once per install)",
    "signal_table": "the signal table (once per install)",
    "integrate_interval": "the plant integrator (once per install)",
}


class _CompileWatch(numba_event.Listener):
    """Calls ``on_start(what)`` and ``on_end(what, seconds)`` around each top-level compile
    in this process: a step (:func:`compile_step`) in which numba compiled anything, or a
    compile numba makes outside any step. A compile inside another is part of that one's
    time. numba sends these events only on a cache miss."""

    def __init__(self, on_start: Callable[[str], None], on_end: Callable[[str, float], None]):
        self.on_start_, self.on_end_ = on_start, on_end
        self.local = threading.local()

    def on_start(self, event) -> None:
        stack = self.local.__dict__.setdefault("stack", [])
        stack.append(time.perf_counter())
        if len(stack) == 1:
            name = _name(event.data["dispatcher"])
            self.on_start_(STEPS.get(name, f"kernel {name}"))

    def on_end(self, event) -> None:
        t0 = self.local.stack.pop()
        if not self.local.stack:
            name = _name(event.data["dispatcher"])
            self.on_end_(STEPS.get(name, f"kernel {name}"), time.perf_counter() - t0)


def _name(dispatcher: object) -> str:
    py = getattr(dispatcher, "py_func", None) or getattr(dispatcher, "_pyfunc", None)
    return getattr(py, "__name__", str(dispatcher))


_WATCHES: list[_CompileWatch] = []


def watch_compiles(
    on_start: Callable[[str], None], on_end: Callable[[str, float], None]
) -> Callable[[], None]:
    """Report every compile this process makes from now on, one call each at its start and
    end, named by what it compiles (:class:`_CompileWatch`). Returns a function that stops it."""
    watch = _CompileWatch(on_start, on_end)
    numba_event.register("numba:compile", watch)
    _WATCHES.append(watch)

    def stop() -> None:
        numba_event.unregister("numba:compile", watch)
        _WATCHES.remove(watch)

    return stop


class compile_step:
    """``with compile_step("the plant's kernels of X"): ...``: every compile inside the block
    is reported as this one step (:func:`watch_compiles`), its start at the first compile,
    its end when the block ends; nothing when nothing compiled. :meth:`compiled` marks the
    step compiled where numba sends no event (a ``cfunc`` compiled, its callees cached)."""

    def __init__(self, what: str) -> None:
        self.what = what
        self._events: _StepEvents | None = None

    def __enter__(self) -> compile_step:
        self._t0 = time.perf_counter()
        self._started = False
        _STEP_STACK.__dict__.setdefault("steps", []).append(self)
        if _WATCHES:
            self._events = _StepEvents(self)
            numba_event.register("numba:compile", self._events)
            for watch in _WATCHES:  # compiles inside the step are not top-level
                watch.local.__dict__.setdefault("stack", []).append(self._t0)
        return self

    def compiled(self) -> None:
        if self._events is not None and not self._started:
            self._started = True
            for watch in _WATCHES:
                watch.on_start_(self.what)

    def __exit__(self, *exc: object) -> None:
        _STEP_STACK.steps.pop()
        if self._events is None:
            return
        numba_event.unregister("numba:compile", self._events)
        for watch in _WATCHES:
            watch.local.stack.pop()
        if self._started:
            seconds = time.perf_counter() - self._t0
            for watch in _WATCHES:
                watch.on_end_(self.what, seconds)


_STEP_STACK = threading.local()


def mark_compiled() -> None:
    """Mark the innermost :class:`compile_step` of this thread compiled (a compile numba
    does not see: a C build)."""
    steps = getattr(_STEP_STACK, "steps", None)
    if steps:
        steps[-1].compiled()


class _StepEvents(numba_event.Listener):
    def __init__(self, step: compile_step) -> None:
        self.step = step
        self.thread = threading.get_ident()

    def on_start(self, event) -> None:
        if threading.get_ident() == self.thread:
            self.step.compiled()

    def on_end(self, event) -> None:
        pass


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


@contextmanager
def exclusive(key: str) -> Iterator[None]:
    """Hold the inter-process lock ``key`` (a file beside the cache) for the block: of
    processes that would compile the same kernel at once (a study's workers, the test
    suite's), one compiles and the others wait, then read its cache entry. Without file
    locks (not POSIX) or a writable folder, the block runs unlocked."""
    try:
        import fcntl

        folder = _generated_dir().parent / "locks"
        folder.mkdir(exist_ok=True)
        handle = open(folder / f"{key}.lock", "a")
    except (ImportError, OSError):
        yield
        return
    with handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def first_call(dispatcher: Any) -> AbstractContextManager[None]:
    """:func:`exclusive` around a compiled function's first call in this process (it may
    compile or read the cache), nothing around any later call."""
    if dispatcher.signatures:
        return nullcontext()
    return exclusive(f"{Path(dispatcher.py_func.__code__.co_filename).stem}.{dispatcher.__name__}")


def load_generated(source: str) -> ModuleType:
    """The module whose text is ``source``, imported from the cache folder's ``generated/``
    under a name that is a hash of the text (the same text, the same module, in this
    process and every other, so numba's cache of its kernels survives). Written
    atomically: parallel workers never read half a file."""
    digest = hashlib.sha256(source.encode()).hexdigest()[:20]
    name = f"{GENERATED_PREFIX}{digest}"
    if name in sys.modules:
        return sys.modules[name]
    with _LOAD_LOCK:
        if name in sys.modules:
            return sys.modules[name]
        path = _generated_dir() / f"{name}.py"
        if not path.exists() or path.read_text(encoding="utf-8") != source:
            tmp = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.tmp")
            tmp.write_text(source, encoding="utf-8")
            os.replace(tmp, path)
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        try:
            with exclusive(name):  # its kernels compile on import: once, not once per process
                spec.loader.exec_module(module)
        except BaseException:
            del sys.modules[name]
            raise
        return module


_LOAD_LOCK = threading.RLock()


def c_compiler() -> str | None:
    """The system C compiler (``$CC``, else cc, gcc or clang on PATH), or None."""
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return shutil.which(name)
    return None


#: how :func:`build_c` compiles: C99, -O2, never a*b+c contracted into one rounding (an
#: FMA: clang contracts by default where the target has it), for the baseline of the target
#: (no -march): the same numbers as numba's kernels on any CPU
C_FLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-shared", "-fPIC")


def build_c(files: dict[str, str]) -> ctypes.CDLL | None:
    """The shared library built from the C ``files`` (name -> text; every ``.c`` compiled),
    loaded: built once into the cache folder's ``native/`` under a hash of the texts, the
    compiler and its flags, then read from there by every process (built under
    :func:`exclusive`, renamed into place when complete). None when there is no C compiler
    or the build fails: the caller falls back to numba."""
    cc = c_compiler()
    if cc is None:
        return None
    digest = hashlib.sha256(repr((cc, C_FLAGS, sorted(files.items()))).encode())
    name = f"native_{digest.hexdigest()[:20]}"
    try:
        folder = _generated_dir().parent / "native"
        folder.mkdir(exist_ok=True)
    except OSError:
        return None
    library = folder / f"{name}.so"
    with exclusive(name):
        if not library.is_file():
            with tempfile.TemporaryDirectory(dir=folder) as tmp:
                for file, text in files.items():
                    (Path(tmp) / file).write_text(text, encoding="utf-8")
                sources = [str(Path(tmp) / f) for f in files if f.endswith(".c")]
                built = Path(tmp) / "lib.so"
                try:
                    done = subprocess.run(
                        [cc, *C_FLAGS, f"-I{tmp}", "-o", str(built), *sources, "-lm"],
                        capture_output=True, text=True, timeout=120, check=False,
                    )  # fmt: skip
                except (OSError, subprocess.SubprocessError):
                    return None
                if done.returncode != 0 or not built.is_file():
                    return None
                os.replace(built, library)
                mark_compiled()
    try:
        return ctypes.CDLL(str(library))
    except OSError:
        return None


__all__ = [
    "C_FLAGS",
    "GENERATED_PREFIX",
    "STEPS",
    "KernelCacheLocator",
    "build_c",
    "c_compiler",
    "compile_step",
    "exclusive",
    "first_call",
    "kernel_stamp",
    "load_generated",
    "mark_compiled",
    "njit",
    "watch_compiles",
]
