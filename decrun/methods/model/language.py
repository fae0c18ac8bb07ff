"""The model language: text → expression tree, parsed and never evaluated as Python.

An expression is parsed with Python's own parser (:func:`ast.parse` builds a syntax tree and
runs nothing) and then rebuilt node by node into the small tree below; any syntax node that is
not on the whitelist — attribute access, subscripts, lambdas, comprehensions, keyword arguments,
strings, comparisons, dunder names, calls of anything but a plain name — is a one-line
:class:`ModelError` naming the config key. Nothing from the YAML is ever executed, imported or
passed to ``eval``/``exec``/``compile``.

Grammar (what the whitelist admits)::

    expr   := number | name | call | expr OP expr | -expr | +expr | (expr)
    OP     := + - * / **   and  ^ (the wedge product ∧, binding like *: a ^ b + c is (a ∧ b) + c)
    call   := name "(" expr {"," expr} ")"

Unicode spellings are accepted and rewritten before parsing: ``⋆ → star``, ``δ →
codifferential``, ``Δ → laplacian``, ``∧ → ^`` (wedge), ``♯ → sharp``, ``♭ → flat``, ``∂ₜ → dt``;
a prefix symbol may be followed by a name without parentheses (``Δu`` is ``laplacian(u)``).

Equations (one string each)::

    dt(u) = <expr>           evolution (first order in time)
    v = <expr>               definition, evaluated every step in dependency order
    solve(<expr> = <expr>)   a linear solve for the one unknown field of the left side
    solve(<expr> = <expr>, <expr> = <expr>, …)
                             linear equations solved together (one block system) for as many
                             unknown fields of their left sides (a mixed, saddle-point problem)
"""

from __future__ import annotations

import ast
import math
import re
from dataclasses import dataclass
from typing import Union

from decrun.errors import ConfigError

__all__ = ["ModelError", "Number", "Name", "Call", "Binary", "Negate", "Node", "Equation", "parse_expression",
           "parse_equation", "names_in", "MAX_EXPRESSION_LENGTH", "to_text"]

#: longest expression accepted (characters): a model line, not a program
MAX_EXPRESSION_LENGTH = 4000
#: deepest tree accepted
MAX_DEPTH = 200


class ModelError(ConfigError):
    """A model that cannot be read or type-checked: one line naming the key and the term."""


@dataclass(frozen=True)
class Number:
    value: float


@dataclass(frozen=True)
class Name:
    name: str


@dataclass(frozen=True)
class Call:
    function: str
    args: tuple


@dataclass(frozen=True)
class Binary:
    op: str  # + - * / ** ^
    left: "Node"
    right: "Node"


@dataclass(frozen=True)
class Negate:
    operand: "Node"


Node = Union[Number, Name, Call, Binary, Negate]

#: ^ (the wedge) is read as Python's @, which binds like * — Python's own ^ binds looser than + and
#: would read a ^ b + c as a ∧ (b + c); an @ the user writes is refused before the rewrite
_BINARY = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**", ast.MatMult: "^"}

#: unicode symbol → ASCII name (prefix operators)
_PREFIX = {"⋆": "star", "★": "star", "δ": "codifferential", "Δ": "laplacian", "♯": "sharp", "♭": "flat",
           "∂ₜ": "dt", "∂_t": "dt"}
_IDENT = r"[A-Za-z_][A-Za-z0-9_]*"


_TOKEN = re.compile(r"\s*(∂ₜ|∂_t|[⋆★δΔ♯♭]|(?:(?![δΔ])[^\W\d])\w*|\d+\.?\d*(?:[eE][-+]?\d+)?|\.\d+(?:[eE][-+]?\d+)?|\*\*|\S)")


def _normalize(text: str) -> str:
    """Rewrite the unicode spellings into the ASCII grammar (see the module docstring): a chain
    of prefix operators — the symbols ``⋆ δ Δ ♯ ♭ ∂ₜ`` and ``d`` without parentheses — applies
    to the name, call or parenthesized group after it: ``Δu`` is ``laplacian(u)``, ``⋆d⋆(d u)``
    is ``star(d(star(d(u))))``."""
    text = text.replace("∧", "^").replace("·", "*").replace("−", "-")
    if not any(symbol in text for symbol in _PREFIX) and not re.search(r"\bd\s+[A-Za-z_(]", text):
        return text
    tokens = _TOKEN.findall(text)
    out, i = [], 0

    def operand(i: int) -> tuple[str, int]:
        """The text of the operand starting at token i (after a prefix chain), and the next index."""
        chain = []
        while i < len(tokens) and (tokens[i] in _PREFIX or (tokens[i] == "d" and i + 1 < len(tokens)
                                                                 and tokens[i + 1] != "(")):
            chain.append(_PREFIX.get(tokens[i], tokens[i]))
            i += 1
        if i >= len(tokens):
            return " ".join(chain), i
        if tokens[i] == "(":
            end = _matching(tokens, i)
            inner = _normalize(" ".join(tokens[i + 1:end]))
            body, i = f"({inner})", end + 1
        elif tokens[i][:1].isidentifier():
            body, i = tokens[i], i + 1
            if i < len(tokens) and tokens[i] == "(":
                end = _matching(tokens, i)
                body += "(" + _normalize(" ".join(tokens[i + 1:end])) + ")"
                i = end + 1
        else:
            body, i = tokens[i], i + 1
        for name in reversed(chain):
            body = f"{name}({body})"
        return body, i

    while i < len(tokens):
        if tokens[i] in _PREFIX or (tokens[i] == "d" and i + 1 < len(tokens) and tokens[i + 1] != "("):
            body, i = operand(i)
            out.append(body)
        else:
            out.append(tokens[i])
            i += 1
    return " ".join(out)


def _matching(tokens: list[str], start: int) -> int:
    """Index of the ")" closing the "(" at ``start`` (the last token when unbalanced)."""
    depth = 0
    for j in range(start, len(tokens)):
        depth += tokens[j] == "("
        depth -= tokens[j] == ")"
        if depth == 0:
            return j
    return len(tokens) - 1


def _short(text: str, limit: int = 80) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 1] + "…"


def parse_expression(text, where: str) -> Node:
    """The tree of one expression; ``where`` (``app.equations[0]``) names it in errors.

    Numbers (int or float) are expressions too. Raises :class:`ModelError` for anything the
    grammar does not admit."""
    if isinstance(text, bool):
        raise ModelError(f"{where}: expected an expression or a number, got {text!r}")
    if isinstance(text, (int, float)):
        return _number(text, where, repr(text))
    if not isinstance(text, str):
        raise ModelError(f"{where}: expected an expression (a string), got {type(text).__name__}")
    if len(text) > MAX_EXPRESSION_LENGTH:
        raise ModelError(f"{where}: the expression is {len(text)} characters long (at most "
                         f"{MAX_EXPRESSION_LENGTH}); split it into definitions")
    if "@" in text:
        raise ModelError(f"{where}: the operator @ is not part of the model language (in {_short(text)!r}); write "
                         "numbers, names, operator calls such as laplacian(u), and + - * / ** ^")
    source = _normalize(text).strip().replace("^", "@")
    if not source:
        raise ModelError(f"{where}: the expression is empty")
    try:
        tree = ast.parse(source, mode="eval")
    except SyntaxError as error:
        raise ModelError(f"{where}: cannot parse {_short(text)!r} ({error.msg})") from None
    except (RecursionError, MemoryError, ValueError):
        raise ModelError(f"{where}: cannot parse {_short(text)!r} (nested too deeply)") from None
    return _convert(tree.body, where, text, 0)


def _number(value, where: str, shown: str) -> Number:
    """A finite number (a literal such as 1e400 is inf to Python's parser, and 10**400 has no
    float): anything else is refused."""
    try:
        number = float(value)
    except OverflowError:
        number = float("inf")
    if not math.isfinite(number):
        raise ModelError(f"{where}: a number in {shown!r} is not finite ({_short(str(value), 30)}); write a finite "
                         "number")
    return Number(number)


def _refuse(node: ast.AST, where: str, text: str, what: str | None = None) -> ModelError:
    kind = what or {ast.Attribute: "attribute access", ast.Subscript: "subscripts", ast.Lambda: "lambdas",
                    ast.ListComp: "comprehensions", ast.GeneratorExp: "comprehensions",
                    ast.SetComp: "comprehensions", ast.DictComp: "comprehensions", ast.Compare: "comparisons",
                    ast.BoolOp: "boolean operators", ast.IfExp: "conditional expressions",
                    ast.NamedExpr: "assignments", ast.Starred: "star arguments",
                    ast.JoinedStr: "strings", ast.List: "lists", ast.Tuple: "tuples", ast.Dict: "dicts",
                    ast.Set: "sets", ast.Await: "await", ast.Yield: "yield"}.get(type(node), type(node).__name__)
    return ModelError(f"{where}: {kind} are not part of the model language (in {_short(text)!r}); write "
                      "numbers, names, operator calls such as laplacian(u), and + - * / ** ^")


def _convert(node: ast.AST, where: str, text: str, depth: int) -> Node:
    if depth > MAX_DEPTH:
        raise ModelError(f"{where}: the expression is nested more than {MAX_DEPTH} levels deep")
    if isinstance(node, ast.Constant):
        value = node.value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _refuse(node, where, text, "strings and other constants" if isinstance(value, str) else
                          f"the constant {value!r}")
        return _number(value, where, _short(text))
    if isinstance(node, ast.Name):
        if node.id.startswith("_"):
            raise ModelError(f"{where}: names starting with '_' are not part of the model language "
                             f"({node.id!r} in {_short(text)!r})")
        return Name(node.id)
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        return Binary(_BINARY[type(node.op)], _convert(node.left, where, text, depth + 1),
                      _convert(node.right, where, text, depth + 1))
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        operand = _convert(node.operand, where, text, depth + 1)
        if isinstance(node.op, ast.UAdd):
            return operand
        if isinstance(operand, Number):
            return Number(-operand.value)
        return Negate(operand)
    if isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name):
            raise _refuse(node.func, where, text, "calls of anything but an operator name")
        if node.func.id.startswith("_"):
            raise ModelError(f"{where}: names starting with '_' are not part of the model language "
                             f"({node.func.id!r} in {_short(text)!r})")
        if node.keywords:
            raise _refuse(node, where, text, "keyword arguments")
        for arg in node.args:
            if isinstance(arg, ast.Starred):
                raise _refuse(arg, where, text)
        return Call(node.func.id, tuple(_convert(arg, where, text, depth + 1) for arg in node.args))
    if isinstance(node, ast.BinOp):
        raise _refuse(node, where, text, f"the operator {type(node.op).__name__}")
    if isinstance(node, ast.UnaryOp):
        raise _refuse(node, where, text, f"the operator {type(node.op).__name__}")
    raise _refuse(node, where, text)


@dataclass(frozen=True)
class Equation:
    """One equation of a model.

    ``kind``: ``evolution`` (``dt(target) = rhs``), ``definition`` (``target = rhs``),
    ``solve`` (``solve(lhs = rhs)``: ``target`` is set when the unknown is resolved, see
    :mod:`decrun.methods.model.system`) or ``system`` (``solve(l1 = r1, l2 = r2, …)``: linear
    equations solved together for as many unknowns, one block system; ``lhs``/``rhs`` are the
    first pair); ``where``: its config key; ``text``: as written."""

    kind: str
    target: str
    lhs: Node | None
    rhs: Node
    where: str
    text: str
    #: a ``system`` (``solve(l1 = r1, l2 = r2, …)``): its (left, right) pairs, and its unknowns once
    #: resolved (``target`` is then the first)
    pairs: tuple = ()
    targets: tuple = ()


def _split_top_level(text: str, where: str) -> tuple[str, str]:
    """``(left, right)`` around the one top-level ``=`` of an equation."""
    depth, positions = 0, []
    for i, char in enumerate(text):
        if char in "([":
            depth += 1
        elif char in ")]":
            depth -= 1
        elif char == "=" and depth == 0:
            neighbours = text[i - 1: i] + text[i + 1: i + 2]
            if "=" in neighbours or "<" in neighbours or ">" in neighbours or "!" in neighbours:
                raise ModelError(f"{where}: comparisons are not part of the model language (in {_short(text)!r})")
            positions.append(i)
    if len(positions) != 1:
        raise ModelError(f"{where}: an equation has one '=' (e.g. 'dt(u) = k * laplacian(u)', 'v = d(u)' or "
                         f"'solve(laplacian(phi) = f)'), got {len(positions)} in {_short(text)!r}")
    return text[: positions[0]], text[positions[0] + 1:]


def _split_commas(text: str) -> list[str]:
    """The members of ``l1 = r1, l2 = r2`` around the top-level commas (a call's own commas,
    inside parentheses, stay)."""
    depth, start, out = 0, 0, []
    for i, char in enumerate(text):
        if char in "([":
            depth += 1
        elif char in ")]":
            depth -= 1
        elif char == "," and depth == 0:
            out.append(text[start:i])
            start = i + 1
    out.append(text[start:])
    return out


def parse_equation(text, where: str) -> Equation:
    """One equation string → :class:`Equation` (see the module docstring for the forms)."""
    if not isinstance(text, str):
        raise ModelError(f"{where}: an equation is a string such as 'dt(u) = k * laplacian(u)', got {text!r}")
    if len(text) > MAX_EXPRESSION_LENGTH:
        raise ModelError(f"{where}: the equation is {len(text)} characters long (at most {MAX_EXPRESSION_LENGTH})")
    source = _normalize(text).strip()
    match = re.fullmatch(r"solve\s*\((.*)\)", source, flags=re.S)
    if match:
        members = _split_commas(match.group(1))
        pairs = []
        for member in members:
            left, right = _split_top_level(member, where)
            pairs.append((parse_expression(left, where), parse_expression(right, where)))
        if len(pairs) > 1:
            return Equation("system", "", pairs[0][0], pairs[0][1], where, text, tuple(pairs))
        return Equation("solve", "", pairs[0][0], pairs[0][1], where, text)
    left, right = _split_top_level(source, where)
    lhs, rhs = parse_expression(left, where), parse_expression(right, where)
    if isinstance(lhs, Call) and lhs.function == "dt":
        if len(lhs.args) != 1 or not isinstance(lhs.args[0], Name):
            raise ModelError(f"{where}: the left side of an evolution equation is dt(<field>), got {_short(left)!r}")
        return Equation("evolution", lhs.args[0].name, lhs, rhs, where, text)
    if isinstance(lhs, Name):
        return Equation("definition", lhs.name, lhs, rhs, where, text)
    raise ModelError(f"{where}: the left side must be dt(<field>) (evolution), a name (definition), or the "
                     f"equation solve(<left> = <right>) (a linear solve); got {_short(left)!r}")


def names_in(node: Node) -> set[str]:
    """Every name the tree reads (not function names)."""
    if isinstance(node, Name):
        return {node.name}
    if isinstance(node, Call):
        return set().union(*(names_in(arg) for arg in node.args)) if node.args else set()
    if isinstance(node, Binary):
        return names_in(node.left) | names_in(node.right)
    if isinstance(node, Negate):
        return names_in(node.operand)
    return set()


_PRECEDENCE = {"+": 1, "-": 1, "*": 2, "/": 2, "^": 2, "**": 4}


def to_text(node: Node) -> str:
    """The tree written back as text (fully parenthesized where precedence needs it): what
    error messages show of a term."""
    if isinstance(node, Number):
        value = node.value
        return str(int(value)) if value.is_integer() and abs(value) < 1e15 else repr(value)
    if isinstance(node, Name):
        return node.name
    if isinstance(node, Call):
        return f"{node.function}({', '.join(to_text(arg) for arg in node.args)})"
    if isinstance(node, Negate):
        inner = to_text(node.operand)
        return f"-{inner}" if isinstance(node.operand, (Name, Call, Number)) else f"-({inner})"
    if isinstance(node, Binary):
        def side(child, right=False):
            text = to_text(child)
            if isinstance(child, Binary) and (_PRECEDENCE[child.op] < _PRECEDENCE[node.op] or
                                              (right and _PRECEDENCE[child.op] == _PRECEDENCE[node.op]
                                               and (node.op in "-/" or "^" in (node.op, child.op)))):
                return f"({text})"
            if isinstance(child, Negate) and node.op != "+":
                return f"({text})"
            return text
        op = " ^ " if node.op == "^" else f" {node.op} "
        return side(node.left) + op + side(node.right, True)
    raise TypeError(node)
