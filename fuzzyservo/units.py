"""Physical units: parse a unit expression into an SI factor and a dimension.

Rig files write every number in the unit its source used (``l/(min*sqrt(bar))``,
``cm3/(s*sqrt(bar))``, ``mA/V``); this module turns them into SI and checks that the
dimension is the one the parameter needs, so ``bar`` given for a length is an error,
not a silent factor of 1e5.

Grammar: products (``*`` or ``·``) and quotients of unit names, parentheses, integer or
fractional powers written ``^`` or ``**`` (``m^3``), a digit suffix (``cm3``, ``m2``) or a
superscript (``m²``, as the metric tables print them), and ``sqrt(...)``. Dimensionless
is ``1`` or ``-``.
"""

from __future__ import annotations

import ast
import math
import re
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache

# Base dimensions: length, mass, time, current, angle (kept apart so rad/s and Hz differ)
_BASES = ("m", "kg", "s", "A", "rad")


@dataclass(frozen=True)
class Unit:
    """A scale factor to SI and a dimension vector over (m, kg, s, A, rad)."""

    factor: float
    dims: tuple[Fraction, ...]

    def __mul__(self, other: Unit) -> Unit:
        return Unit(
            self.factor * other.factor,
            tuple(a + b for a, b in zip(self.dims, other.dims, strict=True)),
        )

    def __truediv__(self, other: Unit) -> Unit:
        return Unit(
            self.factor / other.factor,
            tuple(a - b for a, b in zip(self.dims, other.dims, strict=True)),
        )

    def __pow__(self, n: Fraction) -> Unit:
        return Unit(self.factor ** float(n), tuple(a * n for a in self.dims))

    def exponents(self) -> dict[str, Fraction]:
        """Each SI base unit (m, kg, s, A, rad) this unit holds, with its exponent."""
        return {name: p for name, p in zip(_BASES, self.dims, strict=True) if p != 0}

    def dimension_text(self) -> str:
        parts = [name if p == 1 else f"{name}^{p}" for name, p in self.exponents().items()]
        return "*".join(parts) or "1"


def _u(
    factor: float, m: float = 0, kg: float = 0, s: float = 0, a: float = 0, rad: float = 0
) -> Unit:
    return Unit(factor, tuple(Fraction(x).limit_denominator(8) for x in (m, kg, s, a, rad)))


_ONE = _u(1.0)
_N = _u(1.0, m=1, kg=1, s=-2)
_PA = _u(1.0, m=-1, kg=1, s=-2)
_V = _u(1.0, m=2, kg=1, s=-3, a=-1)

_NAMED: dict[str, Unit] = {
    # length
    "m": _u(1.0, m=1),
    "cm": _u(1e-2, m=1),
    "mm": _u(1e-3, m=1),
    "um": _u(1e-6, m=1),
    # volume
    "l": _u(1e-3, m=3),
    "L": _u(1e-3, m=3),
    "ml": _u(1e-6, m=3),
    "cc": _u(1e-6, m=3),
    # mass
    "kg": _u(1.0, kg=1),
    "g": _u(1e-3, kg=1),
    # time
    "s": _u(1.0, s=1),
    "ms": _u(1e-3, s=1),
    "min": _u(60.0, s=1),
    "h": _u(3600.0, s=1),
    "Hz": _u(1.0, s=-1),
    # angle
    "rad": _u(1.0, rad=1),
    "deg": _u(math.pi / 180.0, rad=1),
    "rev": _u(2.0 * math.pi, rad=1),
    "rpm": _u(2.0 * math.pi / 60.0, rad=1, s=-1),
    # force, torque, pressure
    "N": _N,
    "daN": _N.__mul__(_u(10.0)),
    "kN": _N.__mul__(_u(1e3)),
    # gravitational force units of load cells and test machines (standard g = 9.80665 m/s²)
    "kgf": _N.__mul__(_u(9.80665)),
    "tf": _N.__mul__(_u(9806.65)),  # tonne-force
    "lbf": _N.__mul__(_u(4.4482216152605)),
    "Pa": _PA,
    "kPa": _PA.__mul__(_u(1e3)),
    "MPa": _PA.__mul__(_u(1e6)),
    "GPa": _PA.__mul__(_u(1e9)),
    "bar": _PA.__mul__(_u(1e5)),
    # electrical
    "A": _u(1.0, a=1),
    "mA": _u(1e-3, a=1),
    "V": _V,
    "mV": _V.__mul__(_u(1e-3)),
    "W": _u(1.0, m=2, kg=1, s=-3),
    "kW": _u(1e3, m=2, kg=1, s=-3),
    # dimensionless
    "1": _ONE,
    "-": _ONE,
    "%": _u(1e-2),
    "pct": _u(1e-2),
}

#: characters of a unit expression (the longest in use has about 20)
MAX_UNIT_CHARS = 100

_TOKEN_WITH_POWER = re.compile(r"\b([A-Za-z]+)([23])\b")


def _evaluate(node: ast.AST, text: str) -> Unit:
    if isinstance(node, ast.Expression):
        return _evaluate(node.body, text)
    if isinstance(node, ast.Name):
        if node.id not in _NAMED:
            known = ", ".join(sorted(k for k in _NAMED if k.isalpha()))
            raise ValueError(f"unknown unit {node.id!r} in {text!r}; known units: {known}")
        return _NAMED[node.id]
    if isinstance(node, ast.Constant) and node.value == 1:
        return _ONE
    if isinstance(node, ast.BinOp):
        if isinstance(node.op, ast.Mult):
            return _evaluate(node.left, text) * _evaluate(node.right, text)
        if isinstance(node.op, ast.Div):
            return _evaluate(node.left, text) / _evaluate(node.right, text)
        if isinstance(node.op, ast.Pow):
            return _evaluate(node.left, text) ** _power(node.right, text)
    if (
        isinstance(node, ast.Call)
        and isinstance(node.func, ast.Name)
        and node.func.id == "sqrt"
        and len(node.args) == 1
    ):
        return _evaluate(node.args[0], text) ** Fraction(1, 2)
    raise ValueError(f"cannot read unit {text!r}: write it like 'l/(min*sqrt(bar))' or 'm^3/s'")


def _power(node: ast.AST, text: str) -> Fraction:
    if isinstance(node, ast.Constant) and isinstance(node.value, int | float):
        return Fraction(node.value).limit_denominator(8)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        return -_power(node.operand, text)
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div):
        return _power(node.left, text) / _power(node.right, text)
    raise ValueError(f"cannot read the power in unit {text!r}")


@lru_cache(maxsize=512)
def parse_unit(text: str) -> Unit:
    """Parse a unit expression such as ``'l/(min*mA*sqrt(bar))'`` into a :class:`Unit`.

    Raises ``ValueError`` naming the unknown unit or the unreadable expression.
    """
    expr = str(text).strip()
    if expr in _NAMED:
        return _NAMED[expr]
    if len(expr) > MAX_UNIT_CHARS:  # Python's parser would run out of stack on a long one
        raise ValueError(
            f"cannot read a unit of {len(expr):,} characters (at most {MAX_UNIT_CHARS}): write "
            "it like 'l/(min*sqrt(bar))' or 'm^3/s'"
        )
    expr = expr.replace("^", "**").replace("·", "*").replace("%", "pct")
    expr = expr.replace("²", "**2").replace("³", "**3")
    expr = _TOKEN_WITH_POWER.sub(lambda m: f"{m.group(1)}**{m.group(2)}", expr)
    try:
        tree = ast.parse(expr, mode="eval")
    except SyntaxError as exc:
        raise ValueError(
            f"cannot read unit {text!r}: write it like 'l/(min*sqrt(bar))' or 'm^3/s'"
        ) from exc
    return _evaluate(tree, text)


def to_si(value: float, unit: str, expected: str) -> float:
    """Convert ``value`` given in ``unit`` to the SI unit ``expected``.

    Raises ``ValueError`` when the two units do not have the same dimension.
    """
    given = parse_unit(unit)
    target = parse_unit(expected)
    if given.dims != target.dims:
        raise ValueError(
            f"unit {unit!r} ({given.dimension_text()}) does not fit a quantity in "
            f"{expected!r} ({target.dimension_text()}); give it in {expected!r} or an equivalent unit"
        )
    return float(value) * given.factor / target.factor
