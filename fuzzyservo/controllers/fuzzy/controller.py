"""The fuzzy controller: a :class:`FuzzySystem` in a control law, compiled for the loop.

Forms (``e = r − y`` in the rig's feedback unit, ``ė = (e_k − e_{k−1})/T_s``):

* ``p``:  ``u = G_u · F(G_e·e)`` — seed 002's controllers (one input);
* ``pd``: ``u = G_u · F(G_e·e, G_ė·ė)`` — error and error rate, 7×7 table;
* ``pi``: ``u_k = clip(u_{k−1} + T_s · G_u · F(G_e·e [, G_ė·ė]))`` — the fuzzy output
  integrated (incremental fuzzy PI), with the integrator held inside the output limits
  so it cannot wind up.

The first sample has ė = 0. The state vector carries e_{k−1}, u_{k−1} and the
evaluator's scratch space, so the compiled loop allocates nothing.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import ClassVar, Protocol

import numpy as np

from fuzzyservo._jit import njit
from fuzzyservo.controllers.base import Controller
from fuzzyservo.controllers.fuzzy.evaluate import evaluate, pack_system
from fuzzyservo.controllers.fuzzy.system import FuzzySystem
from fuzzyservo.controllers.kinds import KIND_FUZZY
from fuzzyservo.controllers.layout import Slot, layout, pack


class Design(Protocol):
    """What a controller reads of the design it was built from
    (:class:`~fuzzyservo.controllers.fuzzy.design.FuzzyDesign`, which builds controllers
    and so imports this module; this one names only what it calls, so the two do not
    import each other)."""

    def params(self) -> dict[str, float]: ...

    def with_params(self, **values: float) -> Design: ...

    def renamed(self, name: str) -> Design: ...

    def controller(self) -> FuzzyController: ...


FORMS = ("p", "pd", "pi")
_FORM_PI = FORMS.index("pi")

#: cp: these slots, then the packed system (:func:`.evaluate.pack_system`) from ``SYSTEM`` on
FUZZY_PARAMS = layout(
    "FuzzyParams",
    Slot("form", "the index of the form in FORMS"),
    Slot("input_gain", "G_e"),
    Slot("rate_gain", "G_ė [s]"),
    Slot("output_gain", "G_u"),
    Slot("u_min", "lower output limit [V]"),
    Slot("u_max", "upper output limit [V]"),
    Slot("sample_time", "T_s [s]"),
    Slot("n_inputs", "1: error, 2: error and error rate"),
)
SYSTEM = len(FUZZY_PARAMS)
#: cs: these slots, then the evaluator's scratch space from ``SCRATCH`` on
FUZZY_STATE = layout(
    "FuzzyState",
    Slot("e_prev", "previous error"),
    Slot("u_prev", "previous command (the integrator of form pi)"),
    Slot("started", "0 before the first sample: the error rate is 0 there", flag=True),
)
SCRATCH = len(FUZZY_STATE)


@njit(cache=True)
def fuzzy_step(cp: np.ndarray, cs: np.ndarray, r: float, y: float) -> float:
    """One sample of the fuzzy control law (module docstring); updates ``cs`` in place."""
    k, st = FUZZY_PARAMS, FUZZY_STATE
    ts = cp[k.sample_time]
    e = r - y
    de = (e - cs[st.e_prev]) / ts if cs[st.started] > 0.0 else 0.0
    f = evaluate(cp, SYSTEM, cs[SCRATCH:], cp[k.input_gain] * e, cp[k.rate_gain] * de)
    if int(cp[k.form]) == _FORM_PI:
        u = cs[st.u_prev] + ts * cp[k.output_gain] * f
    else:
        u = cp[k.output_gain] * f
    u = min(max(u, cp[k.u_min]), cp[k.u_max])
    cs[st.e_prev] = e
    cs[st.u_prev] = u
    cs[st.started] = 1.0
    return u


@dataclass(frozen=True)
class FuzzyController(Controller):
    """A fuzzy controller (Mamdani or Sugeno): system, form, scaling gains and output limits [V]."""

    system: FuzzySystem
    form: str = "p"
    input_gain: float = 1.0
    rate_gain: float = 1.0
    output_gain: float = 1.0
    u_min: float = -np.inf
    u_max: float = np.inf
    name: str = "fuzzy"
    description: str = field(default="", compare=False)
    #: the design it was built from (a controller file's seven-term variables), if any:
    #: what :meth:`with_params` changes
    design: Design | None = field(default=None, compare=False, repr=False)

    kind = KIND_FUZZY
    kernel = staticmethod(fuzzy_step)
    TUNABLE: ClassVar[dict[str, str]] = {
        "gains.input": "input_gain",
        "gains.rate": "rate_gain",
        "gains.output": "output_gain",
    }

    def params(self) -> dict[str, float]:
        """The searchable numbers: its design's (:meth:`FuzzyDesign.params`), else the gains."""
        return self.design.params() if self.design is not None else super().params()

    def with_params(self, **values: float) -> FuzzyController:
        """The controller rebuilt from its design with the named numbers changed (a
        controller with no design, e.g. read from a ``.fis``, has only its gains)."""
        if self.design is None:
            return super().with_params(**values)
        return self.design.with_params(**values).controller()

    def renamed(self, name: str) -> FuzzyController:
        if self.design is not None:
            return self.design.renamed(name).controller()
        return dataclasses.replace(
            self, name=name, system=dataclasses.replace(self.system, name=name)
        )

    def __post_init__(self) -> None:
        super().__post_init__()
        if not isinstance(self.system, FuzzySystem):
            raise ValueError("a fuzzy controller needs a FuzzySystem")
        if self.form not in FORMS:
            raise ValueError(f"form must be one of {list(FORMS)}, got {self.form!r}")
        n_in = len(self.system.inputs)
        if len(self.system.outputs) != 1 or n_in > 2:
            raise ValueError(
                f"a controller maps the error (and its rate) to one command: the system has "
                f"{n_in} inputs and {len(self.system.outputs)} outputs; use a system with one "
                "or two inputs and one output (`fuzzyservo evaluate` runs any system)"
            )
        if self.form == "pd" and n_in != 2:
            raise ValueError(
                f"form 'pd' needs two inputs (error and error rate), the system has {n_in}"
            )
        if self.form == "p" and n_in != 1:
            raise ValueError(f"form 'p' needs one input (the error), the system has {n_in}")
        for attr in ("input_gain", "rate_gain", "output_gain"):
            value = getattr(self, attr)
            if not np.isfinite(value) or value == 0:
                raise ValueError(f"{attr} must be finite and non-zero, got {value}")
        self.system.check_coverage()

    def pack(self, sample_time_s: float) -> tuple[np.ndarray, np.ndarray]:
        block, scratch = pack_system(self.system)
        head = pack(
            FUZZY_PARAMS, form=FORMS.index(self.form), input_gain=self.input_gain,
            rate_gain=self.rate_gain, output_gain=self.output_gain, u_min=self.u_min,
            u_max=self.u_max, sample_time=sample_time_s, n_inputs=len(self.system.inputs),
        )  # fmt: skip
        return np.concatenate([head, block]), np.zeros(SCRATCH + scratch)

    def curve(self, e: np.ndarray, de: np.ndarray | None = None) -> np.ndarray:
        """The static map ``G_u·F(G_e·e [, G_ė·ė])`` (before limits) on arrays: control curve or surface."""
        cp, cs = self.pack(1.0)
        scratch = cs[SCRATCH:]
        e = np.asarray(e, dtype=float)
        de = (
            np.zeros_like(e)
            if de is None
            else np.broadcast_to(np.asarray(de, dtype=float), e.shape)
        )
        out = np.empty(e.shape)
        _curve(cp, scratch, e.ravel(), np.ascontiguousarray(de).ravel(), out.reshape(-1))
        return out


@njit(cache=True)
def _curve(
    cp: np.ndarray, scratch: np.ndarray, e: np.ndarray, de: np.ndarray, out: np.ndarray
) -> None:
    for k in range(e.size):
        x0 = cp[FUZZY_PARAMS.input_gain] * e[k]
        x1 = cp[FUZZY_PARAMS.rate_gain] * de[k]
        out[k] = cp[FUZZY_PARAMS.output_gain] * evaluate(cp, SYSTEM, scratch, x0, x1)
