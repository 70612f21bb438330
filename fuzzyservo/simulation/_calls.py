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

The plant's side of this contract is declared in :mod:`fuzzyservo.plants.abi`. A C call
is not inlined into the loop; the plant's own code runs as compiled as before,
and the numbers are the same to the bit (no fast-math on either side).
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from fuzzyservo.plants.abi import (
    ADVANCE,
    ARRAYS,
    END_STOP,
    JACOBIAN,
    KERNELS,
    RHS,
    SIGNALS,
    SLOTS,
    signature,
)
from fuzzyservo.plants.abi import SIGNATURES as PLANT_SIGNATURES

#: the controller's step kernel: not in a plant's table, passed on its own
STEP = SLOTS
#: every kernel the loop calls: a plant's (plants/abi.py) and the controller's step
CALLS = {**KERNELS, STEP: ("step", ("cp", "cs", "r", "y"), types.float64)}
#: each one's C signature
SIGNATURES = {**PLANT_SIGNATURES, STEP: signature(CALLS[STEP][1], CALLS[STEP][2])}


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
    _, names, result = CALLS[slot]
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
        f"def call_{CALLS[slot][0]}(typingctx, fn, {params}):\n"
        f"    return typer(typingctx, fn, {params})\n",
        scope,
    )
    return intrinsic(scope[f"call_{CALLS[slot][0]}"])


call_rhs = _caller(RHS)
call_jacobian = _caller(JACOBIAN)
call_signals = _caller(SIGNALS)
call_end_stop = _caller(END_STOP)
call_advance = _caller(ADVANCE)
call_step = _caller(STEP)


__all__ = [
    "ADVANCE",
    "ARRAYS",
    "CALLS",
    "END_STOP",
    "JACOBIAN",
    "RHS",
    "SIGNALS",
    "SIGNATURES",
    "SLOTS",
    "STEP",
    "call_advance",
    "call_end_stop",
    "call_jacobian",
    "call_rhs",
    "call_signals",
    "call_step",
]
