"""A plant FMU's C functions called from compiled code.

A model-exchange plant FMU (:mod:`fuzzyservo.plants.fmu`) is integrated by the closed
loop's own solver: each right-hand side sets the continuous states and the command on
the FMU instance and reads the state derivatives back, through the FMI C functions the
FMU's shared library exports. A co-simulation one is stepped: its inputs set, one
``doStep`` over the interval (:func:`do_step`), its outputs read. Their addresses and the instance's are numbers known only once
the library is loaded, so they travel in the parameter vector ``p`` (its last
:data:`HANDLES` entries, float64 holds every user-space address exactly) and the
calls are made through them: :func:`call3`, :func:`call4` and :func:`call5` turn an
address into a C function of that many arguments (pointers and ``size_t``). Nothing
here holds an address, so the compiled loop is cached like any other.

The FMI 2.0 and 3.0 functions used differ only in the trailing ``size_t`` of 3.0's
``fmi3SetFloat64``/``fmi3GetFloat64`` (the number of values, arrays included).
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from fuzzyservo._jit import njit

#: the handle block at the end of ``p``: the FMI version (2 or 3), the instance, then each
#: function's address, and a co-simulation's time (the start of its next step)
H_VERSION, H_INSTANCE, H_SET_STATES, H_GET_DERIVATIVES, H_SET_REAL, H_GET_REAL, H_TIME = range(7)
HANDLES = 7
#: the C functions of each FMI version, in the order of the handle block after the instance
FUNCTIONS = {
    2: ("fmi2SetContinuousStates", "fmi2GetDerivatives", "fmi2SetReal", "fmi2GetReal"),
    3: (
        "fmi3SetContinuousStates",
        "fmi3GetContinuousStateDerivatives",
        "fmi3SetFloat64",
        "fmi3GetFloat64",
    ),
}
#: a co-simulation FMU's: ``doStep`` where model exchange has its two state functions
FUNCTIONS_CS = {
    2: ("fmi2DoStep", "fmi2DoStep", "fmi2SetReal", "fmi2GetReal"),
    3: ("fmi3DoStep", "fmi3DoStep", "fmi3SetFloat64", "fmi3GetFloat64"),
}


def _caller(n: int):
    """An intrinsic ``callN(fn, a1, ..., aN)``: the C function at address ``fn`` called with
    ``N`` 64-bit integers, the first ``N - 1`` as pointers and the last as ``size_t`` or,
    for five, the third as ``size_t`` too (FMI's ``(instance, vr, nvr, values, nValues)``);
    returns its ``int`` status."""

    def typer(typingctx, fn, *args):
        sig = types.int32(*([types.int64] * (n + 1)))

        def codegen(context, builder, signature, values):
            ptr, size = ir.IntType(8).as_pointer(), ir.IntType(64)
            kinds = [ptr] * n  # (instance, array, size_t[, array[, size_t]])
            kinds[2] = size
            if n == 5:
                kinds[4] = size
            fnty = ir.FunctionType(ir.IntType(32), kinds)
            function = builder.inttoptr(values[0], fnty.as_pointer())
            args = [
                builder.inttoptr(v, k) if k is ptr else v
                for v, k in zip(values[1:], kinds, strict=True)
            ]
            return builder.call(function, args)

        return sig, codegen

    # numba reads the typer's signature: fix its arity
    if n == 3:

        def call(typingctx, fn, a, b, c):
            return typer(typingctx, fn, a, b, c)
    elif n == 4:

        def call(typingctx, fn, a, b, c, d):
            return typer(typingctx, fn, a, b, c, d)
    else:

        def call(typingctx, fn, a, b, c, d, e):
            return typer(typingctx, fn, a, b, c, d, e)

    call.__name__ = f"call{n}"
    return intrinsic(call)


call3 = _caller(3)  # fmiXSetContinuousStates(instance, x, nx), fmiXGet...Derivatives
call4 = _caller(4)  # fmi2SetReal/fmi2GetReal(instance, vr, nvr, values)
call5 = _caller(5)  # fmi3SetFloat64/fmi3GetFloat64(instance, vr, nvr, values, nValues)


@intrinsic
def _step2(typingctx, fn, instance, t, h):
    """``fmi2DoStep(instance, t, h, fmi2True)`` at address ``fn``."""
    sig = types.int32(types.int64, types.int64, types.float64, types.float64)

    def codegen(context, builder, signature, values):
        ptr, f64, i32 = ir.IntType(8).as_pointer(), ir.DoubleType(), ir.IntType(32)
        fnty = ir.FunctionType(i32, [ptr, f64, f64, i32])
        function = builder.inttoptr(values[0], fnty.as_pointer())
        inst = builder.inttoptr(values[1], ptr)
        return builder.call(function, [inst, values[2], values[3], ir.Constant(i32, 1)])

    return sig, codegen


@intrinsic
def _step3(typingctx, fn, instance, t, h, flags, last):
    """``fmi3DoStep(instance, t, h, true, &flags[0], &flags[1], &flags[2], last)`` at address
    ``fn``: ``flags`` three ``bool`` (event handling needed, terminate, early return)."""
    sig = types.int32(types.int64, types.int64, types.float64, types.float64, types.int64,
                      types.int64)  # fmt: skip

    def codegen(context, builder, signature, values):
        ptr, f64, i32, i8 = (ir.IntType(8).as_pointer(), ir.DoubleType(), ir.IntType(32),
                             ir.IntType(8))  # fmt: skip
        fnty = ir.FunctionType(i32, [ptr, f64, f64, i8, ptr, ptr, ptr, f64.as_pointer()])
        function = builder.inttoptr(values[0], fnty.as_pointer())
        inst = builder.inttoptr(values[1], ptr)
        base = builder.inttoptr(values[4], ptr)
        flags = [builder.gep(base, [ir.Constant(ir.IntType(64), k)]) for k in range(3)]
        last = builder.inttoptr(values[5], f64.as_pointer())
        args = [inst, values[2], values[3], ir.Constant(i8, 1), *flags, last]
        return builder.call(function, args)

    return sig, codegen


@njit(cache=True, inline="always")
def _handle(p: np.ndarray, which: int) -> int:
    return np.int64(p[p.size - HANDLES + which])


@njit(cache=True)
def reals(p: np.ndarray, which: int, vr: np.ndarray, values: np.ndarray, n_values: int) -> int:
    """``values`` (``n_values`` numbers, arrays flattened) into the variables ``vr``
    (``which`` = :data:`H_SET_REAL`), or those variables' values into ``values``
    (:data:`H_GET_REAL`)."""
    fn, inst = _handle(p, which), _handle(p, H_INSTANCE)
    if _handle(p, H_VERSION) == 2:
        return call4(fn, inst, vr.ctypes.data, vr.size, values.ctypes.data)
    return call5(fn, inst, vr.ctypes.data, vr.size, values.ctypes.data, n_values)


@njit(cache=True)
def set_point(
    p: np.ndarray,
    x: np.ndarray,
    nx: int,
    vr_in: np.ndarray,
    inputs: np.ndarray,
    at: np.ndarray,
    u: float,
    load: float,
) -> int:
    """The instance set to the plant's states ``x[:nx]`` and its inputs: ``inputs`` (the
    flattened values of the input variables ``vr_in``, the ones not driven at their
    start) with the command at ``inputs[at[0]]`` and the load at ``inputs[at[1]]``
    (an index of -1: not mapped)."""
    xs = np.ascontiguousarray(x[:nx])
    status = call3(_handle(p, H_SET_STATES), _handle(p, H_INSTANCE), xs.ctypes.data, nx)
    return max(status, set_inputs(p, vr_in, inputs, at, u, load))


@njit(cache=True)
def derivatives(p: np.ndarray, dx: np.ndarray, nx: int) -> int:
    """The state derivatives at the point last set, into ``dx[:nx]``."""
    out = np.empty(nx)
    status = call3(_handle(p, H_GET_DERIVATIVES), _handle(p, H_INSTANCE), out.ctypes.data, nx)
    dx[:nx] = out
    return status


@njit(cache=True)
def do_step(p: np.ndarray, duration: float) -> int:
    """One co-simulation step of ``duration`` seconds from the time the handle block
    keeps (:data:`H_TIME`), which it then advances; the ``doStep`` address is in the
    slot model exchange keeps :data:`H_SET_STATES` in."""
    at = p.size - HANDLES + H_TIME
    t = p[at]
    fn, inst = _handle(p, H_SET_STATES), _handle(p, H_INSTANCE)
    if _handle(p, H_VERSION) == 2:
        status = _step2(fn, inst, t, duration)
    else:
        flags = np.zeros(3, dtype=np.uint8)
        last = np.zeros(1)
        status = _step3(fn, inst, t, duration, flags.ctypes.data, last.ctypes.data)
        if flags[1] != 0 or flags[2] != 0:  # terminate or return early: the step is not done
            status = max(status, 3)
    p[at] = t + duration
    return status


@njit(cache=True)
def set_inputs(
    p: np.ndarray, vr_in: np.ndarray, inputs: np.ndarray, at: np.ndarray, u: float, load: float
) -> int:
    """The instance's inputs set (:func:`set_point` without states)."""
    if vr_in.size == 0:
        return 0
    buffer = inputs.copy()
    if at[0] >= 0:
        buffer[at[0]] = u
    if at[1] >= 0:
        buffer[at[1]] = load
    return reals(p, H_SET_REAL, vr_in, buffer, buffer.size)
