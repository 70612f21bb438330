"""How the compiled loop calls a plant's and a controller's kernels: through their
addresses.

The loop (:mod:`._plant_loop`) is compiled once per install, for every plant and
controller. A plant's kernels (its right-hand side, Jacobian, signals, end stops, and a
stepped plant's own solver) and a controller's step are compiled on their own, each as a
C function (a numba ``cfunc``, :mod:`.binding`). The loop reaches a plant's through a
table of their addresses, ``fn`` (int64, one entry per slot below, 0 where a plant has
none), and the controller's through its address. Each call here is an intrinsic that
turns an address into a C function of the kernel's signature and calls it: every array
argument is passed as its data pointer followed by its shape, every number as itself.
:data:`SIGNATURES` is that C signature per kernel, the one place both sides read it.

A C call is not inlined into the loop; the plant's own code runs as compiled as before,
and the numbers are the same to the bit (no fast-math on either side).
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.extending import intrinsic

#: the slots of a plant's kernel table ``fn``
RHS, JACOBIAN, SIGNALS, END_STOP, ADVANCE = range(5)
SLOTS = 5
#: the controller's step kernel: not in a plant's table, passed on its own
STEP = SLOTS
#: each kernel as the plant (or controller) writes it: (name, arguments, what it returns)
KERNELS = {
    RHS: ("plant_rhs", ("x", "u", "f_ext", "p", "dx"), types.void),
    JACOBIAN: (
        "plant_jacobian",
        ("x", "u", "f_ext", "p", "f0", "typical", "jac", "ftmp"),
        types.void,
    ),
    SIGNALS: ("plant_signals", ("x", "u", "f_ext", "p", "out"), types.void),
    END_STOP: ("plant_in_end_stop", ("x", "p"), types.int64),
    ADVANCE: ("plant_advance", ("x", "u", "f_ext", "p", "duration"), types.int64),
    STEP: ("step", ("cp", "cs", "r", "y"), types.float64),
}
#: the arguments that are arrays, and their dimensions (every other argument is a float64)
ARRAYS = {
    "x": 1, "p": 1, "dx": 1, "f0": 1, "typical": 1, "jac": 2, "ftmp": 1, "out": 1, "cp": 1,
    "cs": 1,
}  # fmt: skip

_PTR = types.CPointer(types.float64)


def _c_arguments(names: tuple[str, ...]) -> list[types.Type]:
    out: list[types.Type] = []
    for name in names:
        if name in ARRAYS:
            out += [_PTR] + [types.int64] * ARRAYS[name]
        else:
            out.append(types.float64)
    return out


#: each slot's C signature: an array is (double *data, int64 size[, int64 columns])
SIGNATURES = {slot: result(*_c_arguments(args)) for slot, (_, args, result) in KERNELS.items()}


def _lower(context, builder, signature, values):
    """The call: the address cast to the C function, arrays as data pointer and shape."""
    c_args: list[ir.Value] = []
    for ty, value in zip(signature.args[1:], values[1:], strict=True):
        if isinstance(ty, types.Array):
            array = context.make_array(ty)(context, builder, value)
            c_args.append(array.data)
            c_args += [builder.extract_value(array.shape, d) for d in range(ty.ndim)]
        else:
            c_args.append(context.cast(builder, value, ty, types.float64))
    returns = signature.return_type != types.none
    result = context.get_value_type(signature.return_type) if returns else ir.VoidType()
    function = builder.inttoptr(
        values[0], ir.FunctionType(result, [a.type for a in c_args]).as_pointer()
    )
    out = builder.call(function, c_args)
    return out if returns else context.get_dummy_value()


def _checked(args: tuple[types.Type, ...], names: tuple[str, ...]) -> None:
    for ty, name in zip(args, names, strict=True):
        want = ARRAYS.get(name)
        if want is not None and not (
            isinstance(ty, types.Array) and ty.ndim == want and ty.dtype == types.float64
        ):
            raise TypeError(f"plant call: {name} must be a {want}-d float64 array, got {ty}")


def _caller(slot: int):
    """The intrinsic ``call(address, *arguments)`` of one slot's kernel."""
    _, names, result = KERNELS[slot]
    if result == types.void:
        result = types.none

    def typer(typingctx, fn, *args):
        _checked(args, names)

        def codegen(context, builder, signature, values):
            return _lower(context, builder, signature, values)

        return result(types.int64, *args), codegen

    # numba reads the typer's own signature: one with the slot's arity, by name
    params = ", ".join(names)
    scope = {"typer": typer}
    exec(
        f"def call_{KERNELS[slot][0]}(typingctx, fn, {params}):\n"
        f"    return typer(typingctx, fn, {params})\n",
        scope,
    )
    return intrinsic(scope[f"call_{KERNELS[slot][0]}"])


call_rhs = _caller(RHS)
call_jacobian = _caller(JACOBIAN)
call_signals = _caller(SIGNALS)
call_end_stop = _caller(END_STOP)
call_advance = _caller(ADVANCE)
call_step = _caller(STEP)
