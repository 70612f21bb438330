"""How a plant's kernels are called as C functions: the contract between a plant and the
compiled closed loop, declared once.

The loop (``simulation/_plant_loop.py``) is compiled once per install and reaches a
plant's kernels through a table of their addresses, one entry per slot below (0 where a
plant has none). Each kernel is a C function whose arguments follow its Python form
(:data:`KERNELS`): an array argument becomes its data pointer followed by its shape
(int64), every other argument a double. A plant's kernels are compiled to this ABI by
numba (``cfunc``, ``simulation/binding.py``) or, for a composition where a C compiler is
present, by it from the components' own equations translated to C (:mod:`.native`);
:func:`c_prototype` writes the same signature in C for the latter.
"""

from __future__ import annotations

from numba import types

#: the slots of a plant's kernel table
RHS, JACOBIAN, SIGNALS, END_STOP, ADVANCE = range(5)
SLOTS = 5
#: each slot's kernel as the plant's kernels module defines it: (name, arguments, result)
KERNELS: dict[int, tuple[str, tuple[str, ...], types.Type]] = {
    RHS: ("plant_rhs", ("x", "u", "f_ext", "p", "dx"), types.void),
    JACOBIAN: (
        "plant_jacobian",
        ("x", "u", "f_ext", "p", "f0", "typical", "jac", "ftmp"),
        types.void,
    ),
    SIGNALS: ("plant_signals", ("x", "u", "f_ext", "p", "out"), types.void),
    END_STOP: ("plant_in_end_stop", ("x", "p"), types.int64),
    ADVANCE: ("plant_advance", ("x", "u", "f_ext", "p", "duration"), types.int64),
}
#: the arguments that are arrays (float64), and their dimensions; any other is a double
ARRAYS = {
    "x": 1, "p": 1, "dx": 1, "f0": 1, "typical": 1, "jac": 2, "ftmp": 1, "out": 1, "cp": 1,
    "cs": 1,
}  # fmt: skip

_PTR = types.CPointer(types.float64)


def c_parameters(name: str) -> list[str]:
    """The C parameter names of a kernel's Python argument ``name``: an array's data
    pointer ``<name>`` and its shape ``<name>_n0`` (``<name>_n1``), else ``<name>``."""
    return [name, *(f"{name}_n{d}" for d in range(ARRAYS.get(name, 0)))]


def c_arguments(names: tuple[str, ...]) -> list[types.Type]:
    """The C arguments of a kernel's Python arguments ``names`` (numba types)."""
    out: list[types.Type] = []
    for name in names:
        if name in ARRAYS:
            out += [_PTR] + [types.int64] * ARRAYS[name]
        else:
            out.append(types.float64)
    return out


def signature(names: tuple[str, ...], result: types.Type) -> types.Type:
    """The C signature (a numba signature) of a kernel of arguments ``names``."""
    return result(*c_arguments(names))


#: each slot's C signature
SIGNATURES = {slot: signature(args, result) for slot, (_, args, result) in KERNELS.items()}

_C_TYPES = {types.void: "void", types.int64: "int64_t", types.float64: "double"}


def c_prototype(slot: int, name: str) -> str:
    """The C prototype of slot ``slot``'s kernel named ``name`` (``int64_t`` from
    ``<stdint.h>``), its parameters named by :func:`c_parameters`."""
    _, args, result = KERNELS[slot]
    params = [
        ("double *" if i == 0 and arg in ARRAYS else "int64_t " if i else "double ") + param
        for arg in args
        for i, param in enumerate(c_parameters(arg))
    ]
    return f"{_C_TYPES[result]} {name}({', '.join(params)})"


__all__ = [
    "ADVANCE",
    "ARRAYS",
    "END_STOP",
    "JACOBIAN",
    "KERNELS",
    "RHS",
    "SIGNALS",
    "SIGNATURES",
    "SLOTS",
    "c_arguments",
    "c_parameters",
    "c_prototype",
    "signature",
]
