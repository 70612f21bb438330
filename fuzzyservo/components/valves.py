"""Proportional-valve flow maps: the measured characteristic, the 4-way metering edges and
a feed-forward neural network (seed 003). Pure compiled maps, no integration.

Network layout (seed 003 §2-5, Fig. 7): inputs (P_S, U_C, P_A, P_B), one hidden layer of
:data:`NN_HIDDEN` tanh units, linear outputs (Q_A, Q_B). Its parameters travel as one
flat float vector of :data:`NN_SIZE` entries, in this order:

    input offset (4), input scale (4), W1 (5×4, row-major), b1 (5),
    W2 (2×5, row-major), b2 (2), output offset (2), output scale (2)

    z = (x − offset_in) / scale_in;  h = tanh(W1·z + b1);  y = offset_out + scale_out·(W2·h + b2)
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.components.declare import phase
from fuzzyservo.components.effects import E, port_pressure
from fuzzyservo.components.orifice import signed_sqrt_flow

NN_INPUTS = 4
NN_HIDDEN = 5
NN_OUTPUTS = 2
NN_SIZE = (
    2 * NN_INPUTS
    + NN_HIDDEN * NN_INPUTS
    + NN_HIDDEN
    + NN_OUTPUTS * NN_HIDDEN
    + NN_OUTPUTS
    + 2 * NN_OUTPUTS
)
# offsets of the blocks inside the flat vector
NN_IN_OFFSET = 0
NN_IN_SCALE = NN_INPUTS
NN_W1 = 2 * NN_INPUTS
NN_B1 = NN_W1 + NN_HIDDEN * NN_INPUTS
NN_W2 = NN_B1 + NN_HIDDEN
NN_B2 = NN_W2 + NN_OUTPUTS * NN_HIDDEN
NN_OUT_OFFSET = NN_B2 + NN_OUTPUTS
NN_OUT_SCALE = NN_OUT_OFFSET + NN_OUTPUTS


@njit(cache=True, inline="always")
def polynomial_flow(
    u: float, u_max: float, c0: float, c1: float, c2: float, c3: float, c4: float
) -> float:
    """Measured flow characteristic Q(U) = c4·U⁴ + c3·U³ + c2·U² + c1·U + c0 [m³/s]
    (seed 003 eq. 7), with ``u`` [V] clipped to ±``u_max`` where it was measured."""
    uc = min(max(u, -u_max), u_max)
    return (((c4 * uc + c3) * uc + c2) * uc + c1) * uc + c0


@njit(cache=True, inline="always")
def metering_edges(
    c_pa: float,
    c_at: float,
    c_pb: float,
    c_bt: float,
    ps: float,
    pt: float,
    pa: float,
    pb: float,
    r_line: float,
    p_lam: float,
) -> tuple[float, float, float, float]:
    """Flows of a 4-way valve's edges P→A, A→T, P→B, B→T [m³/s] for their coefficients
    ``c_*`` [m³/(s·√Pa)] (the regularised orifice law of each edge).

    ``pa``, ``pb`` are the pressures at the actuator side of ports A and B; with a
    laminar line of resistance ``r_line`` > 0 between port and chamber (the
    ``line_resistance`` effect) each port's pressure is solved from its flow balance
    (:func:`~fuzzyservo.components.effects.port_pressure`) first.
    """
    if r_line > 0.0:
        pa = port_pressure(c_pa, ps, c_at, pt, pa, r_line, p_lam)
        pb = port_pressure(c_pb, ps, c_bt, pt, pb, r_line, p_lam)
    return (
        _edge(c_pa, ps - pa, p_lam),
        _edge(c_at, pa - pt, p_lam),
        _edge(c_pb, ps - pb, p_lam),
        _edge(c_bt, pb - pt, p_lam),
    )


@phase("q_pa", "q_at", "q_pb", "q_bt", "q_va", "q_vb", "q_supply", "q_tank")
def four_edges(
    p: Any,
    c_pa: float,
    c_pb: float,
    p_s: float,
    p_t: float,
    p_a_port: float,
    p_b_port: float,
    p_lam: float,
) -> tuple[float, float, float, float, float, float, float, float]:
    """A 4-way valve's edges as a phase: P→A and B→T open with ``c_pa``, P→B and A→T
    with ``c_pb`` (:func:`metering_edges`); the flows out of ports A and B, from P, to T."""
    q_pa, q_at, q_pb, q_bt = metering_edges(
        c_pa, c_pb, c_pb, c_pa, p_s, p_t, p_a_port, p_b_port, p[E.line_resistance_pa_s_m3], p_lam
    )
    return q_pa, q_at, q_pb, q_bt, q_pa - q_at, q_pb - q_bt, q_pa + q_pb, q_at + q_bt


@njit(cache=True, inline="always")
def _edge(coeff: float, dp: float, p_lam: float) -> float:
    """One edge's flow; a closed edge (a lapped spool's far side) costs no square root."""
    return 0.0 if coeff == 0.0 else signed_sqrt_flow(coeff, dp, p_lam)


@njit(cache=True, inline="always")
def nn_forward(
    w: np.ndarray, start: int, x0: float, x1: float, x2: float, x3: float
) -> tuple[float, float]:
    """The 4-5-2 tanh/linear network whose flat vector starts at ``w[start]`` (module
    docstring layout); inputs and outputs in the units the network was trained in."""
    z0 = (x0 - w[start + NN_IN_OFFSET]) / w[start + NN_IN_SCALE]
    z1 = (x1 - w[start + NN_IN_OFFSET + 1]) / w[start + NN_IN_SCALE + 1]
    z2 = (x2 - w[start + NN_IN_OFFSET + 2]) / w[start + NN_IN_SCALE + 2]
    z3 = (x3 - w[start + NN_IN_OFFSET + 3]) / w[start + NN_IN_SCALE + 3]
    y0 = w[start + NN_B2]
    y1 = w[start + NN_B2 + 1]
    for j in range(NN_HIDDEN):
        r = start + NN_W1 + NN_INPUTS * j
        h = math.tanh(
            w[r] * z0 + w[r + 1] * z1 + w[r + 2] * z2 + w[r + 3] * z3 + w[start + NN_B1 + j]
        )
        y0 += w[start + NN_W2 + j] * h
        y1 += w[start + NN_W2 + NN_HIDDEN + j] * h
    return (
        w[start + NN_OUT_OFFSET] + w[start + NN_OUT_SCALE] * y0,
        w[start + NN_OUT_OFFSET + 1] + w[start + NN_OUT_SCALE + 1] * y1,
    )


@njit(cache=True)
def nn_forward_batch(w: np.ndarray, inputs: np.ndarray, out: np.ndarray) -> None:
    """:func:`nn_forward` for every row of ``inputs`` (n×4); writes ``out`` (n×2)."""
    for i in range(inputs.shape[0]):
        q0, q1 = nn_forward(w, 0, inputs[i, 0], inputs[i, 1], inputs[i, 2], inputs[i, 3])
        out[i, 0] = q0
        out[i, 1] = q1
