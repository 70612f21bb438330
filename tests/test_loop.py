"""One loop: the compiled loop and the scipy reference share the sample logic, and the
integrator has the order its tableau promises (ROS34PW2: 3; Rang & Angermann 2005).
"""

from __future__ import annotations

import ctypes
import dataclasses
import itertools
import os
import subprocess
import sys

import numpy as np
import pytest
from scipy.linalg import expm
from support import controller_named, rig_named

from fuzzyservo.components.effects import EffectParams
from fuzzyservo.params import pack
from fuzzyservo.rig import Actuator
from fuzzyservo.simulation import _loop, bind, simulate
from fuzzyservo.simulation._loop import workspace
from fuzzyservo.simulation.reference import simulate_reference


def test_reference_and_compiled_flag_the_same_saturation_at_a_negative_limit() -> None:
    """The composed servo lift, P 4 V/V, `steps`: lowering by 100 mm drives the amplifier
    to its −10 mA limit. Both paths flag the same samples and agree on every signal
    (position to 0.01 mm, pressures to 0.5 bar: the compiled tolerance, closed_loop.py)."""
    rig = rig_named("servo_lift")
    p4 = controller_named("p_servo_lift")
    fast = simulate(rig, p4, "steps", duration_s=3.4)
    ref = simulate_reference(rig, p4, "steps", duration_s=3.4, rtol=1e-7)
    low = fast.actuator <= rig.actuator.lower
    assert low.sum() >= 5  # the step down saturates at the negative limit
    np.testing.assert_array_equal(fast.saturated, ref.saturated)
    assert ref.saturated[low].all()
    np.testing.assert_allclose(fast.signals["y"], ref.signals["y"], atol=1e-5)
    for k in ("p_s", "p_a", "p_b"):
        np.testing.assert_allclose(fast.signals[k], ref.signals[k], atol=0.5e5)
    # the command is 4 V/V · 33.3 V/m of the position: 0.01 mm is 1.3 mV
    np.testing.assert_allclose(fast.command, ref.command, atol=1.4e-3)


def test_reference_runs_transport_delay_like_the_compiled_loop() -> None:
    rig = rig_named("dinca_cylinder").with_effect("transport_delay", delay=0.015)
    p10 = controller_named("p_k10")
    fast = simulate(rig, p10, "steps", duration_s=3.0)
    ref = simulate_reference(rig, p10, "steps", duration_s=3.0, rtol=1e-7)
    np.testing.assert_array_equal(fast.saturated, ref.saturated)
    np.testing.assert_allclose(fast.signals["y"], ref.signals["y"], atol=1e-5)


def test_saturation_flag_whatever_the_limits_sign() -> None:
    """Both limits negative (an offset converter): the flag must still fire at each."""
    rig = rig_named("dinca_cylinder")
    act = rig.actuator
    shifted = dataclasses.replace(
        rig, actuator=Actuator(act.name, act.gain, -0.030, -0.001, act.unit)
    )
    p10 = controller_named("p_k10")
    fast = simulate(shifted, p10, "steps", duration_s=2.5)
    ref = simulate_reference(shifted, p10, "steps", duration_s=2.5, rtol=1e-6)
    np.testing.assert_array_equal(fast.saturated, ref.saturated)
    assert fast.saturated.any()


# ------------------------------------------------------------------ integrator order

# x' = A·x, a lightly damped oscillator and a fast decaying mode (stiffness ratio 1e3)
_A = np.array([[-0.5, 10.0, 0.0], [-10.0, -0.5, 0.0], [0.0, 1.0, -1000.0]])
_LINEAR = """
from fuzzyservo._jit import njit


@njit(cache=True, inline="always")
def plant_rhs(x, u, load, p, dx):
    dx[0] = -0.5 * x[0] + 10.0 * x[1]
    dx[1] = -10.0 * x[0] - 0.5 * x[1]
    dx[2] = x[1] - 1000.0 * x[2]


@njit(cache=True)
def plant_signals(x, u, load, p, out):
    for i in range(x.size):
        out[i] = x[i]


@njit(cache=True)
def plant_in_end_stop(x, p):
    return False
"""


@dataclasses.dataclass(frozen=True)
class _NoParams(EffectParams):
    pass


def _integrate(steps: int, t_end: float = 1.0) -> np.ndarray:
    """``steps`` steps of equal size: each interval is one accepted step (tol = 1e30)."""
    loop = bind(_LINEAR)
    p = pack(_NoParams())
    x = np.array([1.0, 0.0, 0.5])
    work, mats, piv = workspace(3)
    ones = np.ones(3)
    h = t_end / steps
    for _ in range(steps):
        status, _, taken = loop.integrate_interval(
            p, 0.0, x, 0.0, 0.0, h, h, 1e30, ones, ones, work, mats, piv
        )
        assert status == 0 and taken == 1
    return x


def test_every_plant_runs_the_one_compiled_loop_through_its_kernel_table() -> None:
    """The loop is compiled once, for every plant: a plant is bound by its kernels'
    addresses (simulation/binding.py), not by a loop compiled for it."""
    from fuzzyservo.simulation import _plant_loop
    from fuzzyservo.simulation._calls import ADVANCE, END_STOP, JACOBIAN, RHS, SIGNALS

    loop = bind(_LINEAR)
    assert bind(_LINEAR) is loop
    assert all(loop.fn[s] != 0 for s in (RHS, SIGNALS, END_STOP))
    assert loop.fn[JACOBIAN] == 0 and loop.fn[ADVANCE] == 0  # the loop's defaults serve
    plant = rig_named("dinca_cylinder").plant
    assert bind(plant.binding).fn[JACOBIAN] != 0  # numba's kernels: the composition's own
    assert bind(plant).fn[RHS] != 0
    assert len(_plant_loop.closed_loop.overloads) <= 1  # one compiled loop for both
    with pytest.raises(ValueError, match="plant_signals"):
        bind("def plant_rhs(): pass\ndef plant_in_end_stop(): pass")


def test_ros34pw2_is_third_order_on_a_linear_system() -> None:
    exact = expm(_A) @ np.array([1.0, 0.0, 0.5])
    errors = [np.max(np.abs(_integrate(n) - exact)) for n in (40, 80, 160, 320)]
    orders = [np.log2(a / b) for a, b in itertools.pairwise(errors)]
    # the finite-difference Jacobian is exact for a linear map up to rounding, and a
    # W-method keeps its order with it; the observed order tends to 3 from above
    assert orders[-1] == pytest.approx(3.0, abs=0.25), (errors, orders)
    assert errors[-1] < 1e-5


def test_transformed_stages_take_the_step_of_the_tableau() -> None:
    # one step written straight from Rang & Angermann's tableau (k-form, exact J = _A):
    # (I − hγJ)·k_i = h·J·(x + Σ a_ij k_j) + h·J·Σ γ_ij k_j, x1 = x + Σ b_i k_i
    h, x0 = 0.05, np.array([1.0, 0.0, 0.5])
    w = np.eye(3) - h * _loop._GAMMA * _A
    k = np.zeros((_loop._STAGES, 3))
    for i in range(_loop._STAGES):
        stage = x0 + _loop._A[i, :i] @ k[:i]
        k[i] = np.linalg.solve(w, h * _A @ stage + h * _A @ (_loop._G[i, :i] @ k[:i]))
    x = x0.copy()
    work, mats, piv = workspace(3)
    ones = np.ones(3)
    status, _, taken = bind(_LINEAR).integrate_interval(
        pack(_NoParams()), 0.0, x, 0.0, 0.0, h, h, 1e30, ones, ones, work, mats, piv
    )
    assert status == 0 and taken == 1
    # the finite-difference J differs from _A by rounding (~1e-5 in its entries)
    np.testing.assert_allclose(x, x0 + _loop._B @ k, rtol=0.0, atol=1e-6)


def test_the_transformed_coefficients_do_not_depend_on_the_cpu() -> None:
    """The loop's coefficients (A·Γ⁻¹ .. (b − b̂)·Γ⁻¹) are the same to the bit whichever
    kernels OpenBLAS picks for the CPU. They were np.linalg.inv and @, and OpenBLAS's
    AVX-512 and AVX2 kernels gave coefficients one ULP apart: a stick-slip record moved
    by 14 µm and 0.5 bar between machines (tests/test_examples.py). The SSE kernels
    forced here run on any x86-64; numpy with another BLAS ignores the variable."""
    names = ("_A_U", "_C_U", "_M_U", "_E_U")
    code = (
        "from fuzzyservo.simulation import _loop; "
        f"print(repr([getattr(_loop, n).tolist() for n in {names!r}]))"
    )
    here = repr([getattr(_loop, n).tolist() for n in names])
    for core in ("Nehalem", "Sandybridge"):
        env = {**os.environ, "OPENBLAS_CORETYPE": core}
        out = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env
        )
        assert out.stdout.strip() == here, core


# ------------------------------------------------------------------ controller kinds


def test_controller_kinds_are_unique_and_each_reaches_its_kernel() -> None:
    from fuzzyservo.controllers.classical import PI, PIDF, OpenLoop, P
    from fuzzyservo.controllers.fmu import FmuController
    from fuzzyservo.controllers.fuzzy.controller import FuzzyController
    from fuzzyservo.controllers.kinds import KINDS
    from fuzzyservo.simulation.binding import controller_entry

    f64 = ctypes.POINTER(ctypes.c_double)
    entry = ctypes.CFUNCTYPE(
        ctypes.c_double, f64, ctypes.c_int64, f64, ctypes.c_int64, ctypes.c_double,
        ctypes.c_double,
    )  # fmt: skip

    classes = (OpenLoop, P, PI, FuzzyController, PIDF, FmuController)  # an FMU: stepped
    assert len(set(KINDS.values())) == len(KINDS)
    assert sorted(c.kind for c in classes) == sorted(KINDS.values())
    for name in ("p_k10", "pi_dinca", "open_loop", "flc2_reshaped", "pidf_faster"):
        ctrl = controller_named(name)
        cp, cs = ctrl.init(0.01)
        u_python, _ = ctrl.step((cp, cs), 6.5, 6.2)
        # the step kernel through the address the loop calls it by
        state = cs.copy()
        step = entry(controller_entry(ctrl))
        u_loop = step(cp.ctypes.data_as(f64), cp.size, state.ctypes.data_as(f64), state.size,
                      6.5, 6.2)  # fmt: skip
        assert u_loop == u_python


# Import cycles (issue 10's in controllers among them) are checked for every module by
# tests/test_architecture.py; annotations-only imports (TYPE_CHECKING) do not count.


# ------------------------------------------------------------------ Jacobian


@pytest.mark.parametrize("name", ["ehs160_motor", "dinca_cylinder"])
def test_the_composed_jacobian_is_the_forward_difference_to_the_bit(name: str) -> None:
    """The loop's Jacobian (plants/_jacobian.py: each column re-runs only the statements
    its state reaches) equals the whole-rhs forward differences exactly, away from rest
    (all states moved), with the spool of ``valve_lag`` (seed 002) among the columns."""
    from fuzzyservo.simulation import _plant_loop
    from fuzzyservo.simulation.closed_loop import prepare

    rig = rig_named(name)
    prep = prepare(rig, controller_named("p_k10"), duration_s=0.1)
    assert "def plant_jacobian" in rig.plant.binding  # the composition's own, not the default
    loop = bind(rig.plant.binding)  # numba's kernels, with the composition's Jacobian
    rng = np.random.default_rng(1)
    x = prep.x0 + 0.05 * prep.typical * rng.standard_normal(prep.x0.size)
    a = prep.null + 0.3 * rig.actuator.rated
    n = x.size
    f0, jac, ftmp = np.empty(n), np.empty((n, n)), np.empty(n)
    _plant_loop.loop_jacobian(loop.fn, x, a, 0.0, prep.p, prep.null, f0, prep.typical, jac, ftmp)
    base = loop.rhs_with_inputs(x, a, 0.0, prep.p, prep.null)
    expected = np.empty((n, n))
    for j in range(n):
        dj = 1.4901161193847656e-08 * max(abs(x[j]), prep.typical[j])
        moved = x.copy()
        moved[j] = x[j] + dj
        expected[:, j] = (loop.rhs_with_inputs(moved, a, 0.0, prep.p, prep.null) - base) / dj
    np.testing.assert_array_equal(f0, base)
    np.testing.assert_array_equal(jac, expected)
    assert np.count_nonzero(jac) < n * n  # there is structure to skip
