"""The finite-difference Jacobian of a composed right-hand side, column by column, with
only the statements that a state reaches re-evaluated.

The integrator (``simulation/_plant_loop.py``) needs ``J = ∂f/∂x`` once per control
interval. Evaluating ``f`` once per state costs ``n`` right-hand sides; but a perturbed
shaft angle reaches no derivative of a motor, and a perturbed chamber pressure leaves the
friction and the loads as they were. :func:`jacobian_source` reads the composed body
(straight-line code with ``if`` blocks), gives every assignment its own name (static
single assignment, an ``if`` block one unit), follows which states each name depends
on, and writes ``plant_jacobian``: the body once at ``x``, then for each state ``j``
only the statements that depend on ``x[j]``, re-run at ``x[j] + δ_j`` and reading every
other value from the first pass. Each entry is the same floating-point expression, on
the same operands, as the full forward difference ``(f(x + δ_j·e_j) − f(x))/δ_j``
(``δ_j`` the loop's increment), so the Jacobian, and every result, is identical to the
bit; an entry no statement connects is ``(f_i − f_i)/δ_j``: 0, or NaN where ``f_i`` is
not finite, as the difference gives. The first pass is ``f(x)`` itself, which the
integrator needs at the same point, so it is written out too. Code this analysis cannot
follow (a state vector read whole, a derivative read before it is set) gets no
``plant_jacobian``, and the loop's column-by-column default serves.
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass

# the loop's forward-difference increment δ_j = this · max(|x_j|, typical_j)
# (simulation/_plant_loop.py: plant_jacobian's default uses the same constant)
_SQRT_EPS = "1.4901161193847656e-08"
_OURS = re.compile(r"__v\d+|^_dx\d+$|^_d\d+$|^_xp\d+$")


@dataclass(frozen=True)
class _Statement:
    """One top-level statement in single-assignment form."""

    node: ast.stmt  # names replaced by their versions
    copies: tuple[tuple[str, str], ...]  # (new version, previous) set before it runs
    writes: tuple[str, ...]  # the versions it sets
    reads: frozenset[str]  # the versions it reads (its own writes excluded)
    states: frozenset[int]  # the states it depends on


class _Unsupported(Exception):
    pass


def jacobian_source(body: list[str], n: int) -> str | None:
    """Source of ``plant_jacobian(x, u, f_ext, p, f0, typical, jac, ftmp)`` for the
    right-hand side whose body is ``body`` (it reads ``x``, writes ``dx[0..n-1]``): it
    writes ``f0 = f(x)`` (its first pass) and ``jac``. ``None`` when the body is beyond
    this analysis (the loop's default then serves)."""
    try:
        statements, final = _single_assignment(ast.parse("\n".join(body)), n)
    except _Unsupported:
        return None
    lines: list[str] = []
    for s in statements:
        lines += [f"{new} = {prev}" for new, prev in s.copies]
        lines += ast.unparse(s.node).splitlines()
    lines += [f"f0[{i}] = {row}" for i, row in enumerate(final)]
    for j in range(n):
        lines.append(f"# column {j}: the statements x[{j}] reaches, at x[{j}] + d")
        lines.append(f"_d{j} = {_SQRT_EPS} * max(abs(x[{j}]), typical[{j}])")
        moved: set[str] = set()
        column: list[str] = []
        for s in statements:
            if j not in s.states:
                continue
            rename = {v: f"{v}_c{j}" for v in (s.reads & moved) | set(s.writes)}
            column += [f"{new}_c{j} = {rename.get(prev, prev)}" for new, prev in s.copies]
            node = _Rename(rename, j).visit(_copy(s.node))
            column += ast.unparse(ast.fix_missing_locations(node)).splitlines()
            moved.update(s.writes)
        if column:
            lines.append(f"_xp{j} = x[{j}] + _d{j}")
            lines += column
        for i in range(n):
            row = final[i]
            moved_row = f"{row}_c{j}" if row in moved else row
            lines.append(f"jac[{i}, {j}] = ({moved_row} - {row}) / _d{j}")
    text = "\n".join("    " + line for line in lines)
    return _SOURCE.format(body=text)


def _copy(node: ast.stmt) -> ast.stmt:
    return ast.parse(ast.unparse(node)).body[0]


def _single_assignment(tree: ast.Module, n: int) -> tuple[list[_Statement], list[str]]:
    """The body's statements with each assignment given its own version, and the final
    version of each derivative ``dx[i]`` (named ``_dx<i>``)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Name) and _OURS.search(node.id):
            raise _Unsupported(f"{node.id} clashes with the generated names")
    tree = _Derivatives().visit(tree)
    indexed = {
        id(node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name)
    }
    for node in ast.walk(tree):
        if isinstance(node, ast.Name) and node.id in ("x", "dx") and id(node) not in indexed:
            raise _Unsupported(f"{node.id} used whole")
        if isinstance(node, ast.Subscript) and not isinstance(node.ctx, ast.Load):
            raise _Unsupported("an array written")
    if not all(isinstance(s, ast.Assign | ast.AugAssign | ast.If) for s in tree.body):
        raise _Unsupported("a statement other than an assignment or an if block")
    current: dict[str, str] = {}  # name -> its version now
    states: dict[str, frozenset[int]] = {}  # version -> states it depends on
    counter = 0
    out: list[_Statement] = []
    for stmt in tree.body:
        written = _stored(stmt)
        partial = set(written) if not isinstance(stmt, ast.Assign) else set()
        if any(name.startswith("_dx") and name not in current for name in _loaded(stmt)):
            raise _Unsupported("a derivative read before it is set")
        loaded = {name for name in _loaded(stmt) if name in current}
        new: dict[str, str] = {}
        for name in written:
            counter += 1
            new[name] = f"{name}__v{counter}"
        copies = tuple(
            (new[name], current[name]) for name in written if name in partial and name in current
        )
        # a name this statement sets reads its new version inside (after the copy)
        inside = {**{name: current[name] for name in loaded}, **{k: new[k] for k in partial}}
        node = _Versions(inside, new).visit(stmt)
        reads = frozenset(current[name] for name in loaded if name not in partial)
        reads |= frozenset(prev for _, prev in copies)
        deps = frozenset().union(*(states[v] for v in reads), _state_reads(stmt))
        for name in written:
            states[new[name]] = deps
        current.update(new)
        out.append(_Statement(node, copies, tuple(new.values()), reads, deps))
    final = []
    for i in range(n):
        if f"_dx{i}" not in current:
            raise _Unsupported(f"dx[{i}] is never set")
        final.append(current[f"_dx{i}"])
    return out, final


class _Derivatives(ast.NodeTransformer):
    """``dx[i]`` becomes the name ``_dx<i>``; a state may be read only as ``x[i]``."""

    def visit_Subscript(self, node: ast.Subscript) -> ast.AST:
        if isinstance(node.value, ast.Name) and node.value.id in ("x", "dx"):
            if not (isinstance(node.slice, ast.Constant) and isinstance(node.slice.value, int)):
                raise _Unsupported("a state or derivative indexed by a variable")
            if node.value.id == "dx":
                return ast.copy_location(ast.Name(f"_dx{node.slice.value}", node.ctx), node)
            if not isinstance(node.ctx, ast.Load):
                raise _Unsupported("a state written")
            return node
        return self.generic_visit(node)


def _stored(stmt: ast.stmt) -> list[str]:
    names: list[str] = []
    for node in ast.walk(stmt):
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store) and node.id not in names:
            names.append(node.id)
    return names


def _loaded(stmt: ast.stmt) -> set[str]:
    return {
        node.id
        for node in ast.walk(stmt)
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Load)
    }


def _state_reads(stmt: ast.stmt) -> frozenset[int]:
    return frozenset(
        node.slice.value
        for node in ast.walk(stmt)
        if isinstance(node, ast.Subscript)
        and isinstance(node.value, ast.Name)
        and node.value.id == "x"
    )


class _Versions(ast.NodeTransformer):
    """Loads by ``loads`` (name -> version), stores by ``stores``."""

    def __init__(self, loads: dict[str, str], stores: dict[str, str]) -> None:
        self.loads, self.stores = loads, stores

    def visit_Name(self, node: ast.Name) -> ast.AST:
        table = self.stores if isinstance(node.ctx, ast.Store) else self.loads
        return ast.copy_location(ast.Name(table.get(node.id, node.id), node.ctx), node)


class _Rename(ast.NodeTransformer):
    """Versions by ``rename``; ``x[j]`` becomes the perturbed ``_xp<j>``."""

    def __init__(self, rename: dict[str, str], j: int) -> None:
        self.rename, self.j = rename, j

    def visit_Name(self, node: ast.Name) -> ast.AST:
        return ast.copy_location(ast.Name(self.rename.get(node.id, node.id), node.ctx), node)

    def visit_Subscript(self, node: ast.Subscript) -> ast.AST:
        if (
            isinstance(node.value, ast.Name)
            and node.value.id == "x"
            and isinstance(node.slice, ast.Constant)
            and node.slice.value == self.j
        ):
            return ast.copy_location(ast.Name(f"_xp{self.j}", ast.Load()), node)
        return self.generic_visit(node)


_SOURCE = '''

@njit(cache=True)
def plant_jacobian(x, u, f_ext, p, f0, typical, jac, ftmp):
    """f0 = dx/dt at x and ∂(dx/dt)/∂x by forward differences, each column re-running
    only the statements its state reaches (generated by fuzzyservo.plants._jacobian)."""
{body}
'''
