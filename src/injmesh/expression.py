"""Safe size expressions: h(x, y) from text, never through ``eval``.

The same whitelist serves the command line (``--size``) and Python
(:func:`size_expression`, or a string ``size=`` given to :func:`injmesh.generate`).

Examples
--------
>>> from injmesh.expression import size_expression
>>> h = size_expression("0.02 + 0.1*x")
>>> h([[0.0, 0.0], [1.0, 2.0]])
array([0.02, 0.12])
"""

from __future__ import annotations

import ast
import math
from collections.abc import Callable
from typing import Any, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .sizing import SizeError

FloatArray = NDArray[np.float64]

__all__ = ["SizeExpression", "parse_size", "size_expression"]

_FUNCTIONS: dict[str, Callable[..., Any]] = {
    "sqrt": np.sqrt,
    "exp": np.exp,
    "log": np.log,
    "sin": np.sin,
    "cos": np.cos,
    "tan": np.tan,
    "tanh": np.tanh,
    "abs": np.abs,
    "hypot": np.hypot,
    "atan2": np.arctan2,
    "min": lambda *a: np.minimum.reduce(np.broadcast_arrays(*a)),
    "max": lambda *a: np.maximum.reduce(np.broadcast_arrays(*a)),
}
_ARITY = {"hypot": (2, 2), "atan2": (2, 2), "min": (1, 64), "max": (1, 64)}
_CONSTANTS = {"pi": math.pi, "e": math.e}
_BINARY: dict[type, Callable[[Any, Any], Any]] = {
    ast.Add: np.add,
    ast.Sub: np.subtract,
    ast.Mult: np.multiply,
    ast.Div: np.divide,
    ast.Pow: np.power,
}
_UNARY: dict[type, Callable[[Any], Any]] = {ast.UAdd: np.positive, ast.USub: np.negative}
_MAX_EXPRESSION = 2000

_REFUSED = {
    ast.Attribute: "attribute access",
    ast.Subscript: "subscripts",
    ast.Lambda: "lambda",
    ast.ListComp: "comprehensions",
    ast.SetComp: "comprehensions",
    ast.DictComp: "comprehensions",
    ast.GeneratorExp: "comprehensions",
    ast.Compare: "comparisons",
    ast.BoolOp: "boolean operators",
    ast.IfExp: "conditional expressions",
    ast.NamedExpr: "assignment",
    ast.Starred: "starred arguments",
    ast.List: "lists",
    ast.Tuple: "tuples",
    ast.Dict: "dicts",
    ast.Set: "sets",
    ast.JoinedStr: "strings",
}


class SizeExpression:
    """A size h(x, y) parsed from text; call it with an ``(n, 2)`` array of points.

    Only numbers, ``x``, ``y``, ``pi``, ``e``, ``+ - * / **``, unary ``+``/``-``, parentheses
    and the functions ``sqrt exp log sin cos tan tanh abs hypot atan2 min max`` are allowed
    (``min``/``max`` are element-wise over their arguments).  The expression is checked once
    against this whitelist and then evaluated by walking its syntax tree with NumPy: it is never
    handed to ``eval``.  Numbers are float64, so ``9**9**9`` overflows to ``inf`` (and is then
    rejected as a size) instead of hanging.

    Parameters
    ----------
    text : str
        The expression.

    Raises
    ------
    ValueError
        Invalid syntax, or a construct outside the whitelist; the message names it.

    Examples
    --------
    >>> h = SizeExpression("min(0.05 + 0.2 * sqrt(x**2 + y**2), 0.2)")
    >>> h([[0, 0], [3, 4]])
    array([0.05, 0.2 ])
    """

    def __init__(self, text: str) -> None:
        if len(text) > _MAX_EXPRESSION:
            raise ValueError(f"size expression is longer than {_MAX_EXPRESSION} characters")
        try:
            tree = ast.parse(text.strip(), mode="eval")
        except SyntaxError as exc:
            raise ValueError(f"size expression {text!r} is not valid: {exc.msg}") from None
        except (RecursionError, MemoryError):
            raise ValueError(f"size expression {text[:40]!r}... is nested too deeply") from None
        self.text = text
        self._tree = tree.body
        self.uses_xy = False
        self._check(self._tree)

    def __repr__(self) -> str:
        return f"SizeExpression({self.text!r})"

    def _check(self, node: ast.AST) -> None:
        what = _REFUSED.get(type(node))
        if what is not None:
            raise ValueError(f"size expression: {what} not allowed ({ast.unparse(node)!r})")
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                kind = "strings" if isinstance(node.value, (str, bytes)) else repr(node.value)
                raise ValueError(f"size expression: {kind} not allowed ({ast.unparse(node)!r})")
        elif isinstance(node, ast.Name):
            if node.id in ("x", "y"):
                self.uses_xy = True
            elif node.id not in _CONSTANTS:
                raise ValueError(
                    f"size expression: unknown name {node.id!r}; use x, y, pi, e and the functions "
                    f"{', '.join(_FUNCTIONS)}"
                )
        elif isinstance(node, ast.BinOp):
            if type(node.op) not in _BINARY:
                raise ValueError(
                    f"size expression: operator {type(node.op).__name__} not allowed "
                    f"({ast.unparse(node)!r}); use + - * / **"
                )
            self._check(node.left)
            self._check(node.right)
        elif isinstance(node, ast.UnaryOp):
            if type(node.op) not in _UNARY:
                raise ValueError(f"size expression: {ast.unparse(node)!r} not allowed")
            self._check(node.operand)
        elif isinstance(node, ast.Call):
            fname = node.func.id if isinstance(node.func, ast.Name) else None
            if fname not in _FUNCTIONS:
                called = fname or ast.unparse(node.func)
                raise ValueError(
                    f"size expression: function {called!r} not allowed; allowed: "
                    f"{', '.join(_FUNCTIONS)}"
                )
            if node.keywords:
                raise ValueError(f"size expression: keyword arguments not allowed in {fname}()")
            lo, hi = _ARITY.get(fname, (1, 1))
            if not lo <= len(node.args) <= hi:
                want = str(lo) if lo == hi else f"{lo} or more"
                raise ValueError(
                    f"size expression: {fname}() takes {want} argument(s), got {len(node.args)}"
                )
            for arg in node.args:
                self._check(arg)
        else:
            raise ValueError(
                f"size expression: {type(node).__name__} not allowed ({ast.unparse(node)!r})"
            )

    def _eval(self, node: ast.AST, x: FloatArray, y: FloatArray) -> Any:
        if isinstance(node, ast.Constant):
            try:
                return np.float64(cast(float, node.value))
            except OverflowError:  # an int beyond float range
                return np.float64(math.inf)
        if isinstance(node, ast.Name):
            return x if node.id == "x" else y if node.id == "y" else np.float64(_CONSTANTS[node.id])
        if isinstance(node, ast.BinOp):
            return _BINARY[type(node.op)](self._eval(node.left, x, y), self._eval(node.right, x, y))
        if isinstance(node, ast.UnaryOp):
            return _UNARY[type(node.op)](self._eval(node.operand, x, y))
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
            return _FUNCTIONS[node.func.id](*(self._eval(a, x, y) for a in node.args))
        raise ValueError(f"size expression: cannot evaluate {ast.unparse(node)!r}")  # unreachable

    def __call__(self, p: ArrayLike) -> FloatArray:
        q = np.asarray(p, dtype=float).reshape(-1, 2)
        with np.errstate(all="ignore"):
            h = self._eval(self._tree, q[:, 0], q[:, 1])
        return np.broadcast_to(np.asarray(h, dtype=float), (len(q),)).copy()


def parse_size(text: str) -> float | SizeExpression:
    """Turn the text of ``--size`` into a number or a function of ``x`` and ``y``.

    Parameters
    ----------
    text : str
        A number (``0.05``) or an expression (``0.02 + 0.1 * hypot(x, y)``); see
        :class:`SizeExpression` for what is allowed.

    Returns
    -------
    float or SizeExpression
        A float when the text does not mention ``x`` or ``y``.

    Raises
    ------
    ValueError
        Refused or invalid expression, or a constant size that is not positive and finite
        (a :class:`~injmesh.SizeError`).

    Examples
    --------
    >>> parse_size("1/20")
    0.05
    >>> parse_size("__import__('os')")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: size expression: function '__import__' not allowed; allowed: sqrt, exp, ...
    """
    text = str(text).strip()
    if not text:
        raise ValueError("size is empty")
    expr = SizeExpression(text)
    if expr.uses_xy:
        return expr
    value = float(expr(np.zeros((1, 2)))[0])
    if not (math.isfinite(value) and value > 0):
        raise SizeError(f"size must be a positive finite length, got {text} = {value:g}")
    return value


def size_expression(text: str) -> SizeExpression:
    """A size function h(p) from an expression in ``x`` and ``y``, as ``--size`` takes it.

    Parameters
    ----------
    text : str
        For example ``"0.02 + 0.1*hypot(x, y)"``; see :class:`SizeExpression` for what is
        allowed.  A constant expression gives a constant h.

    Returns
    -------
    SizeExpression
        Callable on ``(n, 2)`` points, returning ``(n,)`` values.

    Raises
    ------
    ValueError
        Invalid syntax or a construct outside the whitelist; the message names it.
    SizeError
        A constant expression that is not a positive finite length.

    Examples
    --------
    >>> import injmesh
    >>> h = injmesh.size_expression("0.02 + 0.1*x")
    >>> h([[0.5, 0.0]])
    array([0.07])
    """
    if not isinstance(text, str):
        raise TypeError(f"a size expression must be a str, got {type(text).__name__}")
    parse_size(text)  # the same checks as the command line, constants included
    return SizeExpression(text.strip())
