"""Compile once: the closed loop is compiled once for every plant, a kernel's cache entry is
keyed by its own source and what it imports, and an entry that cannot be read is compiled
again, never trusted (issue 56)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fuzzyservo import _jit

ROOT = Path(__file__).resolve().parents[1]

# one short run in a new process; prints what it compiled, one JSON list
_RUN = """
import json, sys
from fuzzyservo._jit import watch_compiles
from fuzzyservo.io.controllers import load_controller
from fuzzyservo.io.rigs import load_rig
from fuzzyservo.simulation import simulate

done = []
watch_compiles(lambda what: None, lambda what, s: done.append(what))
rig = load_rig(sys.argv[1])
result = simulate(rig, load_controller(sys.argv[2]), duration_s=0.05)
print(json.dumps({"compiled": done, "status": result.status}))
"""


def _run(package: Path, cache: Path, rig: str, kernels: str = "numba") -> dict:
    env = {"PYTHONPATH": str(package), "NUMBA_CACHE_DIR": str(cache), "PATH": "/usr/bin:/bin",
           "FUZZYSERVO_KERNELS": kernels}  # fmt: skip
    done = subprocess.run(
        [sys.executable, "-c", _RUN, str(ROOT / "rigs" / f"{rig}.yaml"),
         str(ROOT / "studies" / "controllers" / "p_k10.yaml")],
        capture_output=True, text=True, env=env, cwd=package, timeout=900, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["status"] == "ok"
    return out


@pytest.mark.slow
def test_editing_one_component_recompiles_only_the_kernels_that_use_it(tmp_path) -> None:
    """A copy of the package, run in new processes with one cache, its plants' kernels
    compiled by numba (``FUZZYSERVO_KERNELS=numba``: no C compiler): a second rig compiles
    its plant's kernels and nothing of the loop; editing the cylinder's file then
    recompiles the plant kernels of the rigs that use it, and neither the loop, the
    controller's step nor a rig without a cylinder. With the C compiler, the edit (a
    comment) leaves the translated C as it was: nothing is built again."""
    package = tmp_path / "pkg"
    shutil.copytree(ROOT / "fuzzyservo", package / "fuzzyservo",
                    ignore=shutil.ignore_patterns("__pycache__"))  # fmt: skip
    cache = tmp_path / "cache"
    first = _run(package, cache, "dinca_cylinder")["compiled"]
    assert "the closed loop (once per install)" in first
    assert any(w.startswith("the plant's kernels") for w in first)
    assert any(w.startswith("the controller's step") for w in first)

    other = _run(package, cache, "ehs160_motor")["compiled"]  # a motor: a new composition
    assert other and all(w.startswith("the plant's kernels") for w in other), other

    assert _run(package, cache, "dinca_cylinder")["compiled"] == []  # all cached

    cylinders = package / "fuzzyservo" / "components" / "library" / "cylinders.py"
    cylinders.write_text(cylinders.read_text() + "\n# edited\n")
    again = _run(package, cache, "dinca_cylinder")["compiled"]
    assert again and all(w.startswith("the plant's kernels") for w in again), again
    assert _run(package, cache, "ehs160_motor")["compiled"] == []  # no cylinder in it

    if _jit.c_compiler() is not None:
        native = _run(package, cache, "dinca_cylinder", "")["compiled"]
        assert native and all(w.startswith("the plant's kernels") for w in native), native
        cylinders.write_text(cylinders.read_text() + "\n# edited again\n")
        assert _run(package, cache, "dinca_cylinder", "")["compiled"] == []


def test_a_kernel_s_stamp_follows_its_imports_and_nothing_else(tmp_path, monkeypatch) -> None:
    """The cache stamp of a generated kernels module changes with a package file it
    imports (through another), and not with one it does not import."""
    import numba

    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))
    plant = _jit.load_generated("from fuzzyservo.components.library.cylinders import motion\n")
    entry = _jit.load_generated(f"from {plant.__name__} import motion\n")
    cylinders = Path(_jit._module_file("fuzzyservo.components.library.cylinders"))
    valves = Path(_jit._module_file("fuzzyservo.components.valves"))
    closure = set(_imports_closure(Path(entry.__file__)))
    assert cylinders in closure and Path(plant.__file__) in closure
    assert valves not in closure
    loop = Path(_jit._module_file("fuzzyservo.simulation._plant_loop"))
    assert cylinders not in set(_imports_closure(loop))


def _imports_closure(path: Path) -> list[Path]:
    seen, todo = set(), [path]
    while todo:
        file = todo.pop()
        if file not in seen:
            seen.add(file)
            todo += _jit._imports(file)
    return sorted(seen)


def test_an_unreadable_cache_entry_is_compiled_again_not_trusted(tmp_path) -> None:
    """A kernel's index and data files overwritten with garbage (a truncated write, a disk
    fault): the next process compiles it again, gives the same answer, and rewrites them."""
    source = tmp_path / "kernel_mod.py"
    source.write_text(
        "from fuzzyservo._jit import njit\n\n@njit(cache=True)\ndef twice(x):\n    return 2.0 * x\n"
    )
    cache = tmp_path / "cache"
    code = (
        "import sys; sys.path.insert(0, sys.argv[1]); import kernel_mod; "
        "print(kernel_mod.twice(21.0), kernel_mod.twice.stats.cache_hits.get("
        "kernel_mod.twice.signatures[0], 0))"
    )
    env = {"NUMBA_CACHE_DIR": str(cache), "PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT)}

    def run() -> list[str]:
        done = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True,
                              text=True, env=env, timeout=300, check=False)  # fmt: skip
        assert done.returncode == 0, done.stderr[-2000:]
        return done.stdout.split()

    assert run() == ["42.0", "0"]  # compiled
    assert run() == ["42.0", "1"]  # read from the cache
    entries = [p for p in cache.rglob("kernel_mod.twice-*") if p.suffix in (".nbi", ".nbc")]
    assert {p.suffix for p in entries} == {".nbi", ".nbc"}
    for kind in (".nbc", ".nbi"):
        for path in entries:
            if path.suffix == kind:
                path.write_bytes(b"\x80\x04garbage, not a pickle")
        assert run() == ["42.0", "0"], kind  # compiled again
        assert run() == ["42.0", "1"], kind  # and the rewritten entry is read


@pytest.mark.parametrize("name", ["dinca_cylinder", "ehs160_motor", "hydroprax_pdcv", "servo_lift"])
def test_the_c_compiled_kernels_give_numba_s_run_to_the_bit(name, monkeypatch) -> None:
    """A composition's kernels built by the C compiler (plants/native.py) and by numba give
    the same run, every signal to the bit (the loop's own Jacobian against the
    composition's: the same numbers, plants/_jacobian.py)."""
    from support import controller_named, rig_named

    from fuzzyservo.plants import native
    from fuzzyservo.simulation import binding, simulate

    if _jit.c_compiler() is None:
        pytest.skip("no C compiler: numba compiles every plant's kernels")
    rig = rig_named(name)
    controller = controller_named("p_k10" if name == "dinca_cylinder" else "open_loop")
    plant = rig.plant.for_params(rig.params)
    assert native.native_kernels(plant) is not None
    with_c = simulate(rig, controller, duration_s=2.0)
    monkeypatch.setattr(binding, "_BOUND", {})
    monkeypatch.setenv(native.KERNELS_VARIABLE, "numba")
    with_numba = simulate(rig, controller, duration_s=2.0)
    assert binding.bind(plant).fn[binding.JACOBIAN] != 0  # numba's: the composition's own
    assert with_c.status == with_numba.status
    assert with_c.integration_steps == with_numba.integration_steps
    for key, values in with_numba.signals.items():
        assert np.array_equal(with_c.signals[key], values, equal_nan=True), key
