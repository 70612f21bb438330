"""A composed plant as C99: its right-hand side and signals, translated from the same
Python the compiled loop runs.

A composition's binding (:mod:`fuzzyservo.plants.composed`) is a sequence of calls of the
components' phase functions; those are ordinary Python in a small subset (numbers,
``if``/``for``/``while``, ``math``, ``min``/``max``/``abs``, calls of other such functions,
tuple returns). :func:`plant_c_sources` translates that binding and every function it
reaches into C, so the equations exist once, in the components, and the C cannot drift
from what the loop integrates:

* ``P``, ``X`` (an instance's records) and ``p``, ``x``, ``dx``, ``out`` (vectors) are
  ``double`` arrays; a record's field is its position in the record (``P.stroke`` →
  ``P[2]``); ``p[E.<field>]`` and module constants are resolved to numbers here;
* every other value is a ``double`` (a loop counter a ``long``), an index is cast to
  ``long``; a function that returns a tuple writes its values through pointers, one
  translated copy per combination of argument kinds;
* ``min``/``max`` keep Python's order rules, ``//`` and ``%`` Python's floor rules.

What falls outside the subset raises :class:`TranslationError` naming the function and
the line, so an export fails before it writes anything. The C has no globals and no
allocation: ``plant_rhs(x, u, f_ext, p, dx)`` and ``plant_signals(x, u, f_ext, p, out)``.
"""

from __future__ import annotations

import ast
import copy
import inspect
import math
import textwrap
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from fuzzyservo.plants import PlantModel

NUM, INT, ARR = "num", "int", "arr"  # kinds of value; a record's kind is ("rec", fields)
_MATH = {
    "sqrt": "sqrt", "exp": "exp", "log": "log", "sin": "sin", "cos": "cos", "tan": "tan",
    "tanh": "tanh", "atan": "atan", "atan2": "atan2", "fabs": "fabs", "floor": "floor",
    "ceil": "ceil", "copysign": "copysign", "pow": "pow", "isfinite": "isfinite",
    "isnan": "isnan", "sinh": "sinh", "cosh": "cosh", "log10": "log10", "hypot": "hypot",
}  # fmt: skip
_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}
_COMPARE = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!="}

_PRELUDE = """\
static inline double fs_min(double a, double b) { return b < a ? b : a; }
static inline double fs_max(double a, double b) { return b > a ? b : a; }
static inline double fs_floordiv(double a, double b) { return floor(a / b); }
static inline double fs_mod(double a, double b)
{
    double r = fmod(a, b);
    return (r != 0.0 && ((r < 0.0) != (b < 0.0))) ? r + b : r;
}
static inline double fs_sign(double a) { return a > 0.0 ? 1.0 : (a < 0.0 ? -1.0 : a); }
"""


class TranslationError(ValueError):
    """Python a plant's C cannot be generated from; the message names function and line."""


def _number(value: float) -> str:
    if math.isnan(value):
        return "NAN"
    if math.isinf(value):
        return "INFINITY" if value > 0 else "(-INFINITY)"
    text = repr(float(value))
    return f"({text})" if text.startswith("-") else text


@dataclass
class _Function:
    """One function translated for one combination of argument kinds."""

    name: str
    outputs: int  # 0: returns one double (or nothing), n: writes n values through pointers
    text: str = ""


@dataclass
class _Unit:
    """Everything translated so far: the functions, by (function, kinds)."""

    functions: dict[tuple[int, tuple[Any, ...]], _Function] = field(default_factory=dict)
    order: list[_Function] = field(default_factory=list)

    def function(self, fn: Any, kinds: tuple[Any, ...]) -> _Function:
        key = (id(fn), kinds)
        if key not in self.functions:
            py = getattr(fn, "py_func", fn)
            tree = ast.parse(textwrap.dedent(inspect.getsource(py))).body[0]
            if not isinstance(tree, ast.FunctionDef):
                raise TranslationError(f"{py.__qualname__}: not a function definition")
            n_out = _outputs(tree)
            made = _Function(f"fs_{py.__name__}_{len(self.functions)}", n_out)
            self.functions[key] = made  # before the body: recursion is refused below
            writer = _Writer(self, py, tree, kinds, made)
            made.text = writer.function()
            self.order.append(made)
        return self.functions[key]


def _outputs(tree: ast.FunctionDef) -> int:
    """How many values the function returns (0 for a single value or none)."""
    counts = {
        len(node.value.elts) if isinstance(node.value, ast.Tuple) else 0
        for node in ast.walk(tree)
        if isinstance(node, ast.Return) and node.value is not None
    }
    if len(counts) > 1 and counts != {0}:
        tuples = counts - {0}
        return max(tuples)  # a tuple return through a call: checked where it is written
    return counts.pop() if counts else 0


class _Writer:
    """The C of one function body (or of the binding's plant functions)."""

    def __init__(
        self,
        unit: _Unit,
        py: Callable[..., Any] | None,
        tree: ast.FunctionDef,
        kinds: tuple[Any, ...],
        made: _Function | None,
        env: dict[str, Any] | None = None,
    ) -> None:
        self.unit, self.py, self.tree, self.made = unit, py, tree, made
        self.globals = env if env is not None else (py.__globals__ if py else {})
        args = [a.arg for a in tree.args.args]
        if len(args) != len(kinds):
            raise self.error(tree, f"called with {len(kinds)} argument(s), takes {len(args)}")
        self.kinds: dict[str, Any] = dict(zip(args, kinds, strict=True))
        self.args = args
        self.declared: set[str] = set(args)
        self.lines: list[str] = []

    @property
    def where(self) -> str:
        return self.py.__qualname__ if self.py else "the composed plant"

    def error(self, node: ast.AST, problem: str) -> TranslationError:
        line = getattr(node, "lineno", 0)
        if self.py is not None:
            line += self.py.__code__.co_firstlineno - 1
            where = f"{self.py.__module__}.{self.py.__qualname__} (line {line})"
        else:
            where = f"the composed plant's binding (line {line})"
        return TranslationError(f"{where}: {problem}; C cannot be generated for this plant")

    # ------------------------------------------------------------------ function
    def function(self) -> str:
        assert self.made is not None
        params = [self._param(a) for a in self.args]
        params += [f"double *restrict r{i}" for i in range(self.made.outputs)]
        ret = "void" if self.made.outputs or not self._returns_value() else "double"
        self.ret = ret
        body = self.block(self.tree.body, 1)
        locals_ = sorted(n for n, k in self.kinds.items() if n not in self.args and k == NUM)
        counters = sorted(n for n, k in self.kinds.items() if n not in self.args and k == INT)
        head = []
        if locals_:
            head.append("    double " + ", ".join(f"{n} = 0.0" for n in locals_) + ";")
        if counters:
            head.append("    long " + ", ".join(f"{n} = 0" for n in counters) + ";")
        signature = f"static {ret} {self.made.name}({', '.join(params) or 'void'})"
        return "\n".join([signature, "{", *head, *body, "}"])

    def _returns_value(self) -> bool:
        return any(isinstance(n, ast.Return) and n.value is not None for n in ast.walk(self.tree))

    def _param(self, name: str) -> str:
        kind = self.kinds[name]
        if kind == NUM:
            return f"double {name}"
        if kind == INT:
            return f"long {name}"
        return f"const double *{name}"

    # ------------------------------------------------------------------ statements
    def block(self, statements: list[ast.stmt], depth: int) -> list[str]:
        out: list[str] = []
        for st in statements:
            out += self.statement(st, depth)
        return out

    def statement(self, st: ast.stmt, depth: int) -> list[str]:
        pad = "    " * depth
        if isinstance(st, ast.Expr) and isinstance(st.value, ast.Constant):
            return []  # a docstring
        if isinstance(st, ast.Pass):
            return []
        if isinstance(st, ast.Return):
            return [pad + line for line in self._return(st)]
        if isinstance(st, ast.Assign):
            if len(st.targets) != 1:
                raise self.error(st, "chained assignment")
            return [pad + line for line in self.assign(st.targets[0], st.value, st)]
        if isinstance(st, ast.AnnAssign) and st.value is not None:
            return [pad + line for line in self.assign(st.target, st.value, st)]
        if isinstance(st, ast.AugAssign):
            target = self.target(st.target, NUM)
            op = type(st.op)
            if op in _BINOPS:
                return [f"{pad}{target} {_BINOPS[op]}= {self.expr(st.value)};"]
            value = self.expr(ast.BinOp(st.target, st.op, st.value))
            return [f"{pad}{target} = {value};"]
        if isinstance(st, ast.If):
            out = [f"{pad}if ({self.condition(st.test)}) {{", *self.block(st.body, depth + 1)]
            orelse = st.orelse
            while len(orelse) == 1 and isinstance(orelse[0], ast.If):
                nested = orelse[0]
                out.append(f"{pad}}} else if ({self.condition(nested.test)}) {{")
                out += self.block(nested.body, depth + 1)
                orelse = nested.orelse
            if orelse:
                out += [f"{pad}}} else {{", *self.block(orelse, depth + 1)]
            return [*out, f"{pad}}}"]
        if isinstance(st, ast.While):
            if st.orelse:
                raise self.error(st, "while ... else")
            test = self.condition(st.test)
            return [f"{pad}while ({test}) {{", *self.block(st.body, depth + 1), f"{pad}}}"]
        if isinstance(st, ast.For):
            return self._for(st, depth)
        if isinstance(st, ast.Break):
            return [f"{pad}break;"]
        if isinstance(st, ast.Continue):
            return [f"{pad}continue;"]
        raise self.error(st, f"{type(st).__name__} statements are not translated")

    def _for(self, st: ast.For, depth: int) -> list[str]:
        pad = "    " * depth
        it = st.iter
        if (
            st.orelse
            or not isinstance(st.target, ast.Name)
            or not (isinstance(it, ast.Call) and isinstance(it.func, ast.Name))
            or it.func.id != "range"
            or not 1 <= len(it.args) <= 3
        ):
            raise self.error(st, "only `for name in range(...)` loops are translated")
        name = st.target.id
        self.kinds.setdefault(name, INT)
        if self.kinds[name] != INT:
            raise self.error(st, f"loop counter {name!r} is also used as a number")
        bounds = [f"(long)({self.expr(a)})" for a in it.args]
        start, stop = ("0", bounds[0]) if len(bounds) == 1 else (bounds[0], bounds[1])
        step = bounds[2] if len(bounds) == 3 else "1"
        if step != "1" and not (isinstance(it.args[2], ast.Constant) and it.args[2].value > 0):
            raise self.error(st, "a range with a step must have a positive constant step")
        head = f"{pad}for ({name} = {start}; {name} < {stop}; {name} += {step}) {{"
        return [head, *self.block(st.body, depth + 1), f"{pad}}}"]

    def _return(self, st: ast.Return) -> list[str]:
        assert self.made is not None
        n = self.made.outputs
        value = st.value
        if n == 0:
            if value is None:
                return ["return;"]
            return [f"return {self.expr(value)};"]
        if isinstance(value, ast.Tuple):
            if len(value.elts) != n:
                raise self.error(st, f"returns {len(value.elts)} values here, {n} elsewhere")
            temps = [f"double _t{i} = {self.expr(e)};" for i, e in enumerate(value.elts)]
            writes = [f"*r{i} = _t{i};" for i in range(n)]
            return ["{", *temps, *writes, "return;", "}"]
        if isinstance(value, ast.Call):
            call = self.call(value, [f"r{i}" for i in range(n)])
            return [f"{call};", "return;"]
        raise self.error(st, "a function returning a tuple must return a tuple or a call")

    def assign(self, target: ast.expr, value: ast.expr, st: ast.stmt) -> list[str]:
        if isinstance(target, ast.Tuple):
            if isinstance(value, ast.Call):
                pointers = [f"&{self.target(t, NUM)}" for t in target.elts]
                return [f"{self.call(value, pointers)};"]
            if isinstance(value, ast.Tuple) and len(value.elts) == len(target.elts):
                temps = [f"double _t{i} = {self.expr(e)};" for i, e in enumerate(value.elts)]
                names = [self.target(t, NUM) for t in target.elts]
                return ["{", *temps, *(f"{n} = _t{i};" for i, n in enumerate(names)), "}"]
            raise self.error(st, "unpacking of something other than a call or a tuple")
        record = self._record_fields(value)
        if record is not None and isinstance(target, ast.Name):
            assert isinstance(value, ast.Call)
            name = target.id
            if name in self.declared:
                raise self.error(st, f"record {name!r} assigned twice")
            self.kinds[name] = ("rec", record)
            self.declared.add(name)
            entries = ", ".join(self.expr(a) for a in value.args)
            return [f"const double {name}[{max(len(value.args), 1)}] = {{{entries or '0.0'}}};"]
        if (
            isinstance(target, ast.Name)
            and isinstance(value, ast.Call)
            and _dotted(value.func) in ("np.empty", "np.zeros")
        ):
            size = self._constant(value.args[0])
            self.kinds[target.id] = ARR
            self.declared.add(target.id)
            return [f"double {target.id}[{int(size)}] = {{0.0}};"]
        return [f"{self.target(target, NUM)} = {self.expr(value)};"]

    def target(self, node: ast.expr, kind: str) -> str:
        if isinstance(node, ast.Name):
            known = self.kinds.get(node.id)
            if known is None:
                self.kinds[node.id] = kind
                self.declared.add(node.id)
            elif known not in (NUM, INT):
                raise self.error(node, f"{node.id!r} is assigned a number and an array")
            return node.id
        if isinstance(node, ast.Subscript):
            return self.expr(node)
        raise self.error(node, f"cannot assign to {ast.unparse(node)}")

    # ------------------------------------------------------------------ expressions
    def condition(self, node: ast.expr) -> str:
        return self.expr(node)

    def expr(self, node: ast.expr) -> str:
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool):
                return "1.0" if node.value else "0.0"
            if isinstance(node.value, int | float):
                return _number(float(node.value))
            raise self.error(node, f"constant {node.value!r}")
        if isinstance(node, ast.Name):
            if node.id in self.kinds:
                return node.id
            return _number(self._global_number(node))
        if isinstance(node, ast.Attribute):
            return self._attribute(node)
        if isinstance(node, ast.Subscript):
            base = node.value
            if not (isinstance(base, ast.Name) and self.kinds.get(base.id) == ARR):
                raise self.error(node, f"indexing {ast.unparse(base)}, not a vector")
            return f"{base.id}[(long)({self.expr(node.slice)})]"
        if isinstance(node, ast.BinOp):
            left, right = self.expr(node.left), self.expr(node.right)
            op = type(node.op)
            if op in _BINOPS:
                return f"({left} {_BINOPS[op]} {right})"
            if op is ast.Pow:
                if isinstance(node.right, ast.Constant) and node.right.value == 2:
                    return f"({left} * {left})"
                return f"pow({left}, {right})"
            if op is ast.FloorDiv:
                return f"fs_floordiv({left}, {right})"
            if op is ast.Mod:
                return f"fs_mod({left}, {right})"
            raise self.error(node, f"operator {op.__name__}")
        if isinstance(node, ast.UnaryOp):
            operand = self.expr(node.operand)
            if isinstance(node.op, ast.USub):
                return f"(-{operand})"
            if isinstance(node.op, ast.UAdd):
                return operand
            if isinstance(node.op, ast.Not):
                return f"(!({operand}))"
            raise self.error(node, f"operator {type(node.op).__name__}")
        if isinstance(node, ast.BoolOp):
            joiner = " && " if isinstance(node.op, ast.And) else " || "
            return "(" + joiner.join(f"({self.expr(v)})" for v in node.values) + ")"
        if isinstance(node, ast.Compare):
            parts, left = [], node.left
            for op, right in zip(node.ops, node.comparators, strict=True):
                if type(op) not in _COMPARE:
                    raise self.error(node, f"comparison {type(op).__name__}")
                parts.append(f"({self.expr(left)} {_COMPARE[type(op)]} {self.expr(right)})")
                left = right
            return "(" + " && ".join(parts) + ")"
        if isinstance(node, ast.IfExp):
            test, yes, no = self.expr(node.test), self.expr(node.body), self.expr(node.orelse)
            return f"(({test}) ? ({yes}) : ({no}))"
        if isinstance(node, ast.Call):
            return self.call(node, [])
        raise self.error(node, f"{type(node).__name__} expressions are not translated")

    def _attribute(self, node: ast.Attribute) -> str:
        base = node.value
        if isinstance(base, ast.Name) and base.id in self.kinds:
            kind = self.kinds[base.id]
            if isinstance(kind, tuple) and kind[0] == "rec":
                if node.attr not in kind[1]:
                    raise self.error(node, f"record {base.id} has no field {node.attr!r}")
                return f"{base.id}[{kind[1].index(node.attr)}]"
            raise self.error(node, f"attribute of {base.id}, which is not a record")
        return _number(self._global_number(node))

    def _global_number(self, node: ast.expr) -> float:
        """A module-level constant the code reads (``E.<field>``, ``math.pi``, ``_K``)."""
        path = _dotted(node)
        if path is None:
            raise self.error(node, f"{ast.unparse(node)} is not a name")
        head, *rest = path.split(".")
        if head not in self.globals:
            raise self.error(node, f"{path}: unknown name")
        value = self.globals[head]
        for attr in rest:
            value = getattr(value, attr)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.error(node, f"{path} is not a number ({type(value).__name__})")
        return float(value)

    def _constant(self, node: ast.expr) -> float:
        if isinstance(node, ast.Constant) and isinstance(node.value, int | float):
            return float(node.value)
        return self._global_number(node)

    def _record_fields(self, value: ast.expr) -> tuple[str, ...] | None:
        """The fields when ``value`` builds a record (``_c3(p[26], ...)``)."""
        if not (isinstance(value, ast.Call) and isinstance(value.func, ast.Name)):
            return None
        thing = self.globals.get(value.func.id)
        fields = getattr(thing, "_fields", None)
        return tuple(fields) if isinstance(thing, type) and fields is not None else None

    def kind_of(self, node: ast.expr) -> Any:
        if isinstance(node, ast.Name) and node.id in self.kinds:
            kind = self.kinds[node.id]
            return NUM if kind == INT else kind
        return NUM

    def call(self, node: ast.Call, pointers: list[str]) -> str:
        """A call: a math function or builtin (a value), or a translated function, its
        outputs written through ``pointers``."""
        if node.keywords:
            raise self.error(node, "keyword arguments")
        path = _dotted(node.func) or ""
        args = [self.expr(a) if self.kind_of(a) == NUM else a.id for a in node.args]  # type: ignore[attr-defined]
        if pointers and (path.startswith(("math.", "np.")) or path in _BUILTINS):
            raise self.error(node, f"{path} returns one value, not {len(pointers)}")
        if path.startswith(("math.", "np.")):
            name = path.split(".", 1)[1]
            if name == "sign":
                return f"fs_sign({args[0]})"
            if name in ("minimum", "fmin"):
                return f"fs_min({args[0]}, {args[1]})"
            if name in ("maximum", "fmax"):
                return f"fs_max({args[0]}, {args[1]})"
            if name == "abs":
                return f"fabs({args[0]})"
            if name not in _MATH:
                raise self.error(node, f"{path} is not translated")
            return f"{_MATH[name]}({', '.join(args)})"
        if path in _BUILTINS:
            return _BUILTINS[path](self, node, args)
        fn = self.globals.get(path) if "." not in path else None
        if fn is None or not callable(fn):
            raise self.error(node, f"call of {path or ast.unparse(node.func)}: unknown function")
        kinds = tuple(self.kind_of(a) for a in node.args)
        made = self.unit.function(fn, kinds)
        if made.text == "" and made is not self.made:
            raise self.error(node, f"{path} calls itself (recursion is not translated)")
        if made.outputs != len(pointers):
            if made.outputs == 0 or pointers:
                raise self.error(
                    node, f"{path} returns {made.outputs or 1} value(s), {len(pointers)} taken"
                )
            raise self.error(node, f"{path} returns {made.outputs} values; unpack them")
        return f"{made.name}({', '.join([*args, *pointers])})"


def _min_max(which: str) -> Callable[[_Writer, ast.Call, list[str]], str]:
    def write(writer: _Writer, node: ast.Call, args: list[str]) -> str:
        if len(args) < 2:
            raise writer.error(node, f"{which}() of one argument (an iterable)")
        out = args[0]
        for a in args[1:]:
            out = f"fs_{which}({out}, {a})"
        return out

    return write


def _one(template: str) -> Callable[[_Writer, ast.Call, list[str]], str]:
    def write(writer: _Writer, node: ast.Call, args: list[str]) -> str:
        if len(args) != 1:
            raise writer.error(node, f"{template.split('(')[0] or 'float'}() of {len(args)} args")
        return template.format(args[0])

    return write


_BUILTINS: dict[str, Callable[[_Writer, ast.Call, list[str]], str]] = {
    "min": _min_max("min"),
    "max": _min_max("max"),
    "abs": _one("fabs({})"),
    "float": _one("((double)({}))"),
    "int": _one("((double)(long)({}))"),
    "bool": _one("((double)(({}) != 0.0))"),
}


def _dotted(node: ast.expr) -> str | None:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        base = _dotted(node.value)
        return None if base is None else f"{base}.{node.attr}"
    return None


def _jacobian(module: ast.Module, unit: _Unit, env: dict[str, Any]) -> list[str]:
    """``plant_jacobian(x, u, f_ext, p, f0, typical, jac, jac_n1, ftmp)`` in C, where the
    binding has one (plants/_jacobian.py: straight-line code); ``jac[i, j]`` is row-major
    with ``jac_n1`` columns. None of it where the binding has none."""
    tree = next(
        (s for s in module.body if isinstance(s, ast.FunctionDef) and s.name == "plant_jacobian"),
        None,
    )
    if tree is None:
        return []
    tree = copy.deepcopy(tree)
    tree.body = [
        st
        for st in tree.body
        if not (isinstance(st, ast.Expr) and isinstance(st.value, ast.Constant))  # docstring
    ]
    tree = ast.fix_missing_locations(_RowMajor().visit(tree))
    tree.args.args.insert(7, ast.arg("jac_n1"))
    writer = _Writer(unit, None, tree, (ARR, NUM, NUM, ARR, ARR, ARR, ARR, INT, ARR), None, env)
    lines = writer.block(tree.body, 1)
    locals_ = sorted(n for n, k in writer.kinds.items() if n not in writer.args and k == NUM)
    head = ["    double " + ", ".join(f"{n} = 0.0" for n in locals_) + ";"] if locals_ else []
    return [
        _JACOBIAN_PROTOTYPE,
        "{",
        *head,
        *lines,
        "}",
        "",
    ]


_JACOBIAN_PROTOTYPE = (
    "void plant_jacobian(const double *x, double u, double f_ext, const double *p, "
    "double *f0, const double *typical, double *jac, long jac_n1, double *ftmp)"
)
_END_STOP_PROTOTYPE = "double plant_in_end_stop(const double *x, const double *p)"


class _RowMajor(ast.NodeTransformer):
    """``jac[i, j]`` → ``jac[i * jac_n1 + j]``."""

    def visit_Subscript(self, node: ast.Subscript) -> ast.AST:
        self.generic_visit(node)
        if (
            isinstance(node.value, ast.Name)
            and node.value.id == "jac"
            and isinstance(node.slice, ast.Tuple)
        ):
            i, j = node.slice.elts
            row = ast.BinOp(i, ast.Mult(), ast.Name("jac_n1", ast.Load()))
            node.slice = ast.BinOp(row, ast.Add(), j)
        return node


def plant_c_sources(
    plant: PlantModel, name: str = "plant_model", *, end_stop: bool = False
) -> dict[str, str]:
    """``<name>.h`` and ``<name>.c``: ``plant_rhs`` and ``plant_signals`` of the
    composition ``plant`` in C99 (module docstring), with ``end_stop`` its
    ``plant_in_end_stop`` too (nonzero beyond a stop) and, where it has one, its
    ``plant_jacobian``, each declared in the header; raises :class:`TranslationError` naming the function and
    line that falls outside the translated subset."""
    if not plant.components:
        raise TranslationError(
            f"{plant.description}: only a plant composed from components can be written as C"
        )
    module = ast.parse(plant.binding)
    env: dict[str, Any] = {}
    exec(compile(ast.Module(body=[s for s in module.body if not isinstance(s, ast.FunctionDef)],
                            type_ignores=[]), "<binding>", "exec"), env)  # fmt: skip
    unit = _Unit()
    bodies = {}
    for fn_name in ("plant_rhs", "plant_signals"):
        tree = next(s for s in module.body if isinstance(s, ast.FunctionDef) and s.name == fn_name)
        writer = _Writer(unit, None, tree, (ARR, NUM, NUM, ARR, ARR), None, env)
        body = writer.block(tree.body, 1)
        locals_ = sorted(n for n, k in writer.kinds.items() if n not in writer.args and k == NUM)
        head = ["    double " + ", ".join(f"{n} = 0.0" for n in locals_) + ";"] if locals_ else []
        bodies[fn_name] = [*head, *body]
    stop: list[str] = []
    declared: list[str] = []  # beyond plant_rhs and plant_signals, for the header
    if end_stop:
        tree = next(
            s
            for s in module.body
            if isinstance(s, ast.FunctionDef) and s.name == "plant_in_end_stop"
        )
        made = _Function("plant_in_end_stop", 0)
        stop = [
            _Writer(unit, None, tree, (ARR, ARR), made, env).function().replace("static ", "", 1)
        ]
        declared.append(_END_STOP_PROTOTYPE)
        jacobian = _jacobian(module, unit, env)
        if jacobian:
            declared.append(_JACOBIAN_PROTOTYPE)
        stop += jacobian
    n, ns = len(plant.states), len(plant.signals)
    guard = name.upper()
    more = "".join(f"{line};\n" for line in declared)
    header = f"""/* {plant.description}: generated by fuzzyservo (do not edit) */
#ifndef {guard}_H
#define {guard}_H

#define {guard}_NX {n}
#define {guard}_NS {ns}

/* dx/dt at the state x, the input u and the external load f_ext, parameters p */
void plant_rhs(const double *x, double u, double f_ext, const double *p, double *dx);
/* the plant's signals (outputs) there */
void plant_signals(const double *x, double u, double f_ext, const double *p, double *out);
{more}
#endif
"""
    signature = "void {}(const double *x, double u, double f_ext, const double *p, double *{})"
    source = "\n".join(
        [
            f"/* {plant.description}: generated by fuzzyservo from the components' equations",
            "   (do not edit; regenerate with `fuzzyservo export RIG --fmu`) */",
            "#include <math.h>",
            f'#include "{name}.h"',
            "",
            _PRELUDE,
            *(f.text + "\n" for f in unit.order),
            signature.format("plant_rhs", "dx"),
            "{",
            *bodies["plant_rhs"],
            "}",
            "",
            signature.format("plant_signals", "out"),
            "{",
            *bodies["plant_signals"],
            "}",
            "",
            *stop,
        ]
    )
    return {f"{name}.h": header, f"{name}.c": source}
