"""Write out a kernel's short constant-count loops before numba compiles it (one source, no copies).

A kernel that keeps one vector accumulator per window of a group (``acc[j]``, ``j`` below
``DELAY``) is fast only when every ``acc[j]`` is its own register: LLVM does not fully unroll
such loops once their bodies hold a few accumulators, and a tuple or array of accumulators
then lives in memory.  :func:`written_out` keeps the loops in the source and compiles what a
hand-unrolled copy would be:

* ``for j in range(<constant>):`` is replaced by its body once per value, ``j`` a literal in
  each copy (bounds are evaluated with the given constants; other loops stay loops);
* a *register list* ``acc = [<expr> for j in range(<constant>)]`` becomes the locals
  ``acc_0, acc_1, ...`` and ``acc[0]`` (a literal index, as the written-out loops give) reads
  or writes ``acc_0``.

The result is compiled with the function's own file and line numbers, so numba's cache and
tracebacks point at the source as written.  Read as plain Python, the source computes the
same thing (lists and loops).
"""

from __future__ import annotations

import ast
import copy
import inspect
import textwrap
from collections.abc import Callable

__all__ = ["written_out"]


_OPERATORS = {ast.Add: int.__add__, ast.Sub: int.__sub__, ast.Mult: int.__mul__}


def _value(node: ast.AST, constants: dict) -> int | None:
    """An integer expression of literals, ``constants`` and + - * (None for anything else)."""
    if isinstance(node, ast.Constant) and isinstance(node.value, int):
        return node.value
    if isinstance(node, ast.Name):
        return constants.get(node.id)
    if isinstance(node, ast.BinOp) and type(node.op) in _OPERATORS:
        left, right = _value(node.left, constants), _value(node.right, constants)
        return None if left is None or right is None else _OPERATORS[type(node.op)](left, right)
    return None


def _constant_range(node: ast.AST, constants: dict) -> range | None:
    """``range(...)`` with constant bounds as a Python range, else None (a loop at run time)."""
    if not (isinstance(node, ast.Call) and getattr(node.func, "id", None) == "range" and not node.keywords):
        return None
    bounds = [_value(a, constants) for a in node.args]
    return None if None in bounds else range(*bounds)


class _Substitute(ast.NodeTransformer):
    """Replace the loads of one name by a literal."""

    def __init__(self, name: str, value: int) -> None:
        self.name, self.value = name, value

    def visit_Name(self, node: ast.Name) -> ast.AST:
        if node.id == self.name and isinstance(node.ctx, ast.Load):
            return ast.copy_location(ast.Constant(self.value), node)
        return node


class _WriteOut(ast.NodeTransformer):
    """Constant-count ``for`` loops written out, innermost first."""

    def __init__(self, constants: dict) -> None:
        self.constants = constants

    def visit_For(self, node: ast.For) -> ast.AST | list[ast.stmt]:
        node = self.generic_visit(node)
        values = _constant_range(node.iter, self.constants)
        if values is None or node.orelse or not isinstance(node.target, ast.Name):
            return node
        body = [_Substitute(node.target.id, v).visit(copy.deepcopy(s)) for v in values for s in node.body]
        return self.generic_visit(ast.Module(body=body, type_ignores=[])).body or [ast.Pass()]


class _Registers(ast.NodeTransformer):
    """Register lists ``x = [e for j in range(k)]`` to locals ``x_0 .. x_(k-1)``."""

    def __init__(self, constants: dict) -> None:
        self.constants = constants
        self.names: set[str] = set()

    def visit_Assign(self, node: ast.Assign) -> ast.AST | list[ast.stmt]:
        value = node.value
        if (
            len(node.targets) == 1
            and isinstance(node.targets[0], ast.Name)
            and isinstance(value, ast.ListComp)
            and len(value.generators) == 1
            and isinstance(value.generators[0].target, ast.Name)
            and not value.generators[0].ifs
        ):
            values = _constant_range(value.generators[0].iter, self.constants)
            if values is not None:
                name, var = node.targets[0].id, value.generators[0].target.id
                self.names.add(name)
                out = []
                for v in values:
                    elt = self.visit(_Substitute(var, v).visit(copy.deepcopy(value.elt)))
                    out.append(ast.copy_location(ast.Assign([ast.Name(f"{name}_{v}", ast.Store())], elt), node))
                return out
        return self.generic_visit(node)

    def visit_Subscript(self, node: ast.Subscript) -> ast.AST:
        node = self.generic_visit(node)
        if isinstance(node.value, ast.Name) and node.value.id in self.names:
            if not (isinstance(node.slice, ast.Constant) and isinstance(node.slice.value, int)):
                raise SyntaxError(f"register list {node.value.id!r} indexed by a run-time value (line {node.lineno})")
            return ast.copy_location(ast.Name(f"{node.value.id}_{node.slice.value}", node.ctx), node)
        return node


def written_out(fn: Callable, constants: dict) -> Callable:
    """``fn`` recompiled with its constant-count loops and register lists written out.

    ``constants`` gives the values of the names loop bounds may use (e.g. ``{"DELAY": 4}``).
    Register lists are recognised by assignment order, so one must be assigned before it is
    indexed.  Returns a plain Python function (decorators dropped) for the caller to compile.
    """
    tree = ast.parse(textwrap.dedent(inspect.getsource(fn)))
    tree.body[0].decorator_list = []
    tree = _WriteOut(constants).visit(tree)
    tree = ast.fix_missing_locations(_Registers(constants).visit(tree))
    ast.increment_lineno(tree, fn.__code__.co_firstlineno - 1)
    scope: dict = {}
    exec(compile(tree, fn.__code__.co_filename, "exec"), fn.__globals__, scope)
    return scope[fn.__name__]
