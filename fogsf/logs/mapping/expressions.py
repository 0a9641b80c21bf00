"""Arithmetic over a log's columns, as the column map writes it (docs/logs.md, "Column map").

An expression is parsed by Python's `ast` and only a whitelist of nodes is evaluated, with
numpy over whole columns in float64; nothing is ever passed to `eval`. Allowed: numbers,
column names (a name that is not an identifier in backquotes: `gx[dps]`), + - * / **, unary
- and +, parentheses, abs() sqrt() sin() cos(); for a *condition* (the map's `valid`) also
the comparisons == != < <= > >=, `and`, `or`, `not`. A sub-expression that divides by zero
or gives NaN/Inf is refused with the first row where it does (`EvaluationError`).
"""

from __future__ import annotations

import ast
import math
import re
import unicodedata
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field

import numpy as np

FUNCTIONS: dict[str, Callable[[Value], Value]] = {
    "abs": np.abs, "sqrt": np.sqrt, "sin": np.sin, "cos": np.cos}
_BINARY = {ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply,
           ast.Div: np.divide, ast.Pow: np.power}
_COMPARE = {ast.Eq: np.equal, ast.NotEq: np.not_equal, ast.Lt: np.less,
            ast.LtE: np.less_equal, ast.Gt: np.greater, ast.GtE: np.greater_equal}
ALLOWED = ("numbers, column names (`in backquotes` when not an identifier), + - * / **, "
           "unary -, parentheses, abs() sqrt() sin() cos(), unwrap(COUNTER, PERIOD)")
ALLOWED_CONDITION = f"{ALLOWED}, == != < <= > >=, and, or, not"
BACKQUOTED = re.compile(r"`([^`]*)`")
MAX_DEPTH = 100  # operators nested deeper than this are refused (no map needs them)

Value = np.ndarray | float


class ExpressionError(ValueError):
    """An expression that does not parse, or uses something outside the whitelist."""


class EvaluationError(ValueError):
    """An expression that divides by zero or gives NaN/Inf at data row `row` (0-based)."""

    def __init__(self, row: int, detail: str) -> None:
        self.row = row
        self.detail = detail
        super().__init__(detail)


@dataclass(frozen=True)
class Expression:
    """A parsed, checked expression: `names` are the columns it reads, in order."""

    text: str
    tree: ast.expr
    names: tuple[str, ...]
    aliases: tuple[tuple[str, str], ...]  # (placeholder identifier, backquoted column name)
    # what unwrap() carries from one block of rows to the next (its last value, its offset)
    carry: dict = field(default_factory=dict, compare=False, hash=False, repr=False)

    @property
    def is_name(self) -> bool:
        """The expression is one column, as it is (a rename)."""
        return isinstance(self.tree, ast.Name)

    @property
    def is_constant(self) -> bool:
        return not self.names

    @property
    def is_condition(self) -> bool:
        """Its value is true/false (a comparison, and/or/not), not a number."""
        return _is_condition(self.tree)

    def evaluate(self, columns: Mapping[str, np.ndarray], n: int) -> np.ndarray:
        """The value at each of `n` rows, float64 (a condition gives 1.0 and 0.0)."""
        env = {alias: columns[name] for alias, name in self.aliases}
        env.update({k: columns[column_named(k, columns) or k] for k in self.names})
        with np.errstate(all="ignore"):
            v = _Evaluator(env, dict(self.aliases), self.carry).value(self.tree)
        return np.broadcast_to(np.asarray(v, dtype=np.float64), (n,)).copy()


def column_named(name: str, columns: Collection[str]) -> str | None:
    """The column an expression's `name` reads: the column of that name, else the one whose
    name Python reads as `name` (identifiers are NFKC-normalised: a micro sign is a mu)."""
    if name in columns:
        return name
    return next((c for c in columns if unicodedata.normalize("NFKC", c) == name), None)


def parse_expression(text: str, condition: bool = False) -> Expression:
    """`text` parsed and checked against the whitelist (`condition`: comparisons and
    and/or/not allowed too); ExpressionError names what is wrong and what is allowed."""
    source, aliases = _unquote(text)
    try:
        tree = ast.parse(source.strip(), mode="eval").body
    except (RecursionError, MemoryError):
        raise ExpressionError("nested too deeply") from None
    except SyntaxError as e:
        hint = ("; a column name that is not an identifier goes in backquotes, e.g. "
                "`gx[dps]` * 2" if "`" not in text else "")
        raise ExpressionError(f"syntax error ({e.msg}){hint}") from None
    names: list[str] = []
    _check(tree, condition, names, dict(aliases))
    if _is_condition(tree) and not condition:
        raise ExpressionError(f"a comparison gives true/false, only for valid; allowed: "
                              f"{ALLOWED}")
    return Expression(text, tree, tuple(dict.fromkeys(names)), tuple(aliases))


def split_top_level(text: str, sep: str = ",") -> list[str]:
    """`text` split at each `sep` outside parentheses and backquotes (the --columns rule:
    a comma inside a function call or a `quoted name` does not end a pair)."""
    parts, depth, quoted, start = [], 0, False, 0
    for i, ch in enumerate(text):
        if ch == "`":
            quoted = not quoted
        elif not quoted and ch == "(":
            depth += 1
        elif not quoted and ch == ")":
            depth = max(depth - 1, 0)
        elif not quoted and depth == 0 and ch == sep:
            parts.append(text[start:i])
            start = i + 1
    parts.append(text[start:])
    return parts


def _unquote(text: str) -> tuple[str, list[tuple[str, str]]]:
    """Backquoted names replaced by placeholder identifiers: (source, [(placeholder, name)])."""
    if text.count("`") % 2:
        raise ExpressionError("a backquote (`) without its pair")
    prefix = "_q"
    while prefix in text:
        prefix += "_"
    aliases: list[tuple[str, str]] = []

    def sub(m: re.Match[str]) -> str:
        if not m.group(1).strip():
            raise ExpressionError("an empty `` column name")
        aliases.append((f"{prefix}{len(aliases)}", m.group(1)))
        return f" {aliases[-1][0]} "

    return BACKQUOTED.sub(sub, text), aliases


def _is_condition(node: ast.expr) -> bool:
    return isinstance(node, ast.Compare | ast.BoolOp) or (
        isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not))


def _forbidden(node: ast.AST, condition: bool) -> ExpressionError:
    what = {ast.Call: f"the function {ast.unparse(getattr(node, 'func', node))}()",
            ast.Attribute: "an attribute (.)",
            ast.Subscript: "a subscript ([ ])", ast.Compare: "a comparison",
            ast.BoolOp: "and/or", ast.Name: "a name"}.get(type(node))
    if what is None:
        what = (f"the operator {_OP_TEXT.get(type(node.op), type(node.op).__name__)}"
                if isinstance(node, ast.BinOp | ast.UnaryOp)
                else repr(ast.unparse(node)) if isinstance(node, ast.expr)
                else type(node).__name__)
    only = " (only in valid)" if isinstance(node, ast.Compare | ast.BoolOp) else ""
    return ExpressionError(f"{what} is not allowed{only}; allowed: "
                           f"{ALLOWED_CONDITION if condition else ALLOWED}")


_OP_TEXT = {ast.FloorDiv: "//", ast.Mod: "%", ast.MatMult: "@", ast.BitAnd: "&",
            ast.BitOr: "|", ast.BitXor: "^", ast.LShift: "<<", ast.RShift: ">>",
            ast.Invert: "~", ast.Not: "not"}


def _check(node: ast.expr, condition: bool, names: list[str], aliases: dict[str, str],
           depth: int = 0) -> None:
    """Raise ExpressionError at the first node outside the whitelist; collect the names."""
    if depth > MAX_DEPTH:
        raise ExpressionError(f"nested more than {MAX_DEPTH} deep")
    if isinstance(node, ast.Constant):
        if isinstance(node.value, bool) or not isinstance(node.value, int | float):
            raise ExpressionError(f"{node.value!r} is not a number; allowed: "
                                  f"{ALLOWED_CONDITION if condition else ALLOWED}")
        if (abs(node.value) > 1e300 if isinstance(node.value, int)
                else not math.isfinite(node.value)):
            raise ExpressionError("a number beyond float64's range")
        return
    if isinstance(node, ast.Name):
        names.append(aliases.get(node.id, node.id))
        return
    kids: list[ast.expr]
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        kids = [node.left, node.right]
    elif isinstance(node, ast.UnaryOp) and (isinstance(node.op, ast.USub | ast.UAdd)
                                            or condition and isinstance(node.op, ast.Not)):
        kids = [node.operand]
    elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
          and node.func.id == "unwrap"):
        if len(node.args) != 2 or node.keywords:
            raise ExpressionError("unwrap() takes two arguments: unwrap(t_us, 2**32)")
        period = node.args[1]
        if any(isinstance(n, ast.Name) for n in ast.walk(period)):
            raise ExpressionError("unwrap()'s period is a number (2**32), not a column")
        kids = list(node.args)
    elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
          and node.func.id in FUNCTIONS):
        if len(node.args) != 1 or node.keywords:
            raise ExpressionError(f"{node.func.id}() takes one argument")
        kids = [node.args[0]]
    elif condition and isinstance(node, ast.Compare) and all(
            type(op) in _COMPARE for op in node.ops):
        kids = [node.left, *node.comparators]
    elif condition and isinstance(node, ast.BoolOp):
        kids = list(node.values)
    else:
        raise _forbidden(node, condition)
    for kid in kids:
        _check(kid, condition, names, aliases, depth + 1)


class _Evaluator:
    """Evaluates a checked tree; every sub-expression's first bad row is named."""

    def __init__(self, env: Mapping[str, np.ndarray], aliases: Mapping[str, str],
                 carry: dict | None = None) -> None:
        self.env = env
        self.aliases = aliases
        self.carry = {} if carry is None else carry

    def text(self, node: ast.expr) -> str:
        s = ast.unparse(node)
        for alias, name in self.aliases.items():
            s = re.sub(rf"\b{re.escape(alias)}\b", f"`{name}`", s)
        return s

    def value(self, node: ast.expr) -> Value:
        v = self._value(node)
        if not _is_condition(node):
            bad = ~np.isfinite(v)
            if np.any(bad):
                raise EvaluationError(_first(bad), f"{self.text(node)} is {_at(v, bad)}")
        return v

    def _value(self, node: ast.expr) -> Value:  # noqa: PLR0911 - one return per node type
        if isinstance(node, ast.Constant):
            assert isinstance(node.value, int | float)  # checked
            return float(node.value)
        if isinstance(node, ast.Name):
            return self.env[node.id]
        if isinstance(node, ast.BinOp):
            a, b = self.value(node.left), self.value(node.right)
            if isinstance(node.op, ast.Div) and np.any(np.asarray(b) == 0):
                raise EvaluationError(_first(np.asarray(b) == 0),
                                      f"division by zero: {self.text(node.right)} is 0")
            return _BINARY[type(node.op)](_num(a), _num(b))
        if isinstance(node, ast.UnaryOp):
            a = self.value(node.operand)
            if isinstance(node.op, ast.Not):
                return np.logical_not(a)
            return -_num(a) if isinstance(node.op, ast.USub) else _num(a)
        if isinstance(node, ast.Call):
            assert isinstance(node.func, ast.Name)  # checked
            if node.func.id == "unwrap":
                return self._unwrap(node)
            return FUNCTIONS[node.func.id](_num(self.value(node.args[0])))
        if isinstance(node, ast.Compare):
            return self._compare(node)
        assert isinstance(node, ast.BoolOp)  # checked
        join = np.logical_and if isinstance(node.op, ast.And) else np.logical_or
        out = self.value(node.values[0])
        for kid in node.values[1:]:
            out = join(out, self.value(kid))
        return out

    def _unwrap(self, node: ast.Call) -> np.ndarray:
        """A counter that wraps at PERIOD (a 32-bit us clock: 2**32) made to count on: a step
        down by more than half the period is a wrap. What it carries to the next block of
        rows: its last value and offset (keyed by the call's place in the tree)."""
        x = np.atleast_1d(np.asarray(_num(self.value(node.args[0])), dtype=np.float64))
        period = float(np.asarray(self.value(node.args[1])))
        if not period > 0:
            raise EvaluationError(0, f"unwrap()'s period is {period:g}, not > 0")
        key = (node.lineno, node.col_offset)
        last, offset = self.carry.get(key, (None, 0.0))
        prev = np.empty_like(x)
        if x.size:
            prev[0] = x[0] if last is None else last
            prev[1:] = x[:-1]
        wraps = np.cumsum((x - prev) < -period / 2.0)
        out = x + offset + period * wraps
        if x.size:
            self.carry[key] = (float(x[-1]), offset + period * float(wraps[-1]))
        return out

    def _compare(self, node: ast.Compare) -> Value:
        left = self.value(node.left)
        out: Value = True
        for op, right_node in zip(node.ops, node.comparators, strict=True):
            right = self.value(right_node)
            out = np.logical_and(out, _COMPARE[type(op)](_num(left), _num(right)))
            left = right
        return out


def _num(v: Value) -> np.ndarray | float:
    """A true/false value as 1.0/0.0, for arithmetic on it."""
    a = np.asarray(v)
    return a.astype(np.float64) if a.dtype == bool else v


def _first(mask: np.ndarray | np.bool_) -> int:
    return int(np.flatnonzero(np.atleast_1d(mask))[0])


def _at(v: Value, bad: np.ndarray | np.bool_) -> str:
    x = float(np.atleast_1d(v)[_first(bad)])
    return "NaN" if np.isnan(x) else "Inf" if x > 0 else "-Inf"
