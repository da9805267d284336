"""OpenSCENARIO parameters: declarations, ``$name`` references, ``${...}`` expressions and value
constraints (ASAM OpenSCENARIO XML 1.0-1.3).

An attribute's text is one of: a literal (``"12.5"``, ``"car"``); a parameter reference, the
whole text ``$name``; or an expression ``${...}`` (1.1 and later), evaluated here by a small
recursive-descent parser over the standard's grammar -- numbers, ``$name`` references,
``+ - * / %``, unary minus, parentheses, ``round floor ceil sqrt pow``, the comparisons
``== != < <= > >=``, ``not and or``, ``true false`` -- and nothing else (no Python ``eval``:
files are treated as possibly hostile). Division by zero, an unknown name or function, or text
that is none of these is an error naming the file, the line and the text.

A :class:`Scope` holds the parameters visible at one place (the file's, a catalog entry's
own, a maneuver's): name -> value, typed by its declaration (``double``, ``int``,
``unsignedInt``, ``unsignedShort``, ``string``, ``boolean``, ``dateTime``). A declaration's
value may itself reference the parameters declared before it; its constraints
(``ConstraintGroup``: the groups or-ed, each group's ``ValueConstraint``s and ``Range``s
and-ed) are checked once the value is known, and a violated one is an error naming the
parameter, its value and the constraint.
"""

from __future__ import annotations

import math
import re

from acc_gym.scenarios.openscenario._xml import Node, OpenScenarioError

NUMERIC = ("double", "int", "integer", "unsignedInt", "unsignedShort")
TYPES = NUMERIC + ("string", "boolean", "dateTime")
FUNCTIONS = {"round": (1, lambda x: float(math.floor(x + 0.5)) if x >= 0 else -float(math.floor(-x + 0.5))),
             "floor": (1, lambda x: float(math.floor(x))), "ceil": (1, lambda x: float(math.ceil(x))),
             "sqrt": (1, math.sqrt), "pow": (2, math.pow)}
_TOKEN = re.compile(r"\s*(?:(?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)|(?P<ref>\$[A-Za-z_][A-Za-z0-9_]*)"
                    r"|(?P<name>[A-Za-z_][A-Za-z0-9_]*)|(?P<op>==|!=|<=|>=|[-+*/%()<>,]))")
_NAME = re.compile(r"\$[A-Za-z_][A-Za-z0-9_]*")


class Scope:
    """Parameters visible at one place: ``values`` (name without ``$`` -> value), then ``parent``'s."""

    def __init__(self, values: dict | None = None, parent: "Scope | None" = None):
        self.values, self.parent = dict(values or {}), parent

    def lookup(self, name: str):
        s = self
        while s is not None:
            if name in s.values:
                return s.values[name]
            s = s.parent
        raise KeyError(name)

    def names(self) -> list[str]:
        out, s = set(), self
        while s is not None:
            out |= set(s.values)
            s = s.parent
        return sorted(out)


def _error(node: Node | None, message: str) -> OpenScenarioError:
    return node.error(message) if node is not None else OpenScenarioError(message)


def evaluate(text: str, scope: Scope, node: Node | None = None):
    """The value of an expression's body (the text inside ``${...}``): a float or a bool."""
    toks, pos = [], 0
    while pos < len(text):
        if text[pos:].strip() == "":
            break
        m = _TOKEN.match(text, pos)
        if not m:
            raise _error(node, f"cannot read the expression ${{{text}}} at {text[pos:].strip()!r}")
        kind = m.lastgroup
        toks.append((kind, m.group(kind)))
        pos = m.end()
    toks.append(("end", ""))
    i = 0

    def peek():
        return toks[i]

    def take(kind=None, value=None):
        nonlocal i
        k, v = toks[i]
        if (kind and k != kind) or (value is not None and v != value):
            raise _error(node, f"in the expression ${{{text}}}: expected {value or kind}, found {v or 'the end'!r}")
        i += 1
        return v

    def num(x):
        if isinstance(x, bool):
            return 1.0 if x else 0.0
        return x

    def primary():
        k, v = peek()
        if k == "num":
            take()
            return float(v)
        if k == "ref":
            take()
            try:
                val = scope.lookup(v[1:])
            except KeyError:
                raise _error(node, f"the expression ${{{text}}} uses {v}, which is not declared") from None
            if isinstance(val, str):
                try:
                    return float(val)
                except ValueError:
                    raise _error(node, f"the expression ${{{text}}} uses {v} = {val!r}, which is not a number") \
                        from None
            return val
        if k == "op" and v == "(":
            take()
            x = disj()
            take("op", ")")
            return x
        if k == "name":
            if v in ("true", "false"):
                take()
                return v == "true"
            if v not in FUNCTIONS:
                raise _error(node, f"the expression ${{{text}}} calls {v!r}, not one of OpenSCENARIO's functions "
                                   f"({', '.join(FUNCTIONS)})")
            take()
            arity, fn = FUNCTIONS[v]
            take("op", "(")
            args = [num(disj())]
            while peek() == ("op", ","):
                take()
                args.append(num(disj()))
            take("op", ")")
            if len(args) != arity:
                raise _error(node, f"in the expression ${{{text}}}: {v} takes {arity} argument(s), got {len(args)}")
            try:
                return fn(*args)
            except (ValueError, OverflowError):
                raise _error(node, f"in the expression ${{{text}}}: {v}{tuple(args)} is undefined") from None
        raise _error(node, f"in the expression ${{{text}}}: unexpected {v or 'end'!r}")

    def unary():
        if peek() == ("op", "-"):
            take()
            return -num(unary())
        return primary()

    def product():
        x = unary()
        while peek()[0] == "op" and peek()[1] in "*/%":
            op = take()
            y = num(unary())
            x = num(x)
            if op in "/%" and y == 0:
                raise _error(node, f"in the expression ${{{text}}}: division by zero")
            x = x * y if op == "*" else (x / y if op == "/" else math.fmod(x, y))
        return x

    def total():
        x = product()
        while peek()[0] == "op" and peek()[1] in "+-":
            op = take()
            y = num(product())
            x = num(x) + y if op == "+" else num(x) - y
        return x

    def relation():
        x = total()
        if peek()[0] == "op" and peek()[1] in ("==", "!=", "<", "<=", ">", ">="):
            op = take()
            y, x = num(total()), num(x)
            return {"==": x == y, "!=": x != y, "<": x < y, "<=": x <= y, ">": x > y, ">=": x >= y}[op]
        return x

    def negation():
        if peek() == ("name", "not"):
            take()
            return not bool(negation())
        return relation()

    def conj():
        x = negation()
        while peek() == ("name", "and"):
            take()
            y = negation()
            x = bool(x) and bool(y)
        return x

    def disj():
        x = conj()
        while peek() == ("name", "or"):
            take()
            y = conj()
            x = bool(x) or bool(y)
        return x

    out = disj()
    if peek()[0] != "end":
        raise _error(node, f"in the expression ${{{text}}}: unexpected {peek()[1]!r}")
    if isinstance(out, float) and not math.isfinite(out):
        raise _error(node, f"the expression ${{{text}}} is not finite ({out})")
    return out


def resolve(text: str, scope: Scope, node: Node | None = None):
    """An attribute's text with parameters resolved: a literal string as it is, a ``$name``'s
    value, an ``${...}`` expression's value."""
    t = text.strip()
    if t.startswith("${") and t.endswith("}"):
        return evaluate(t[2:-1], scope, node)
    if t.startswith("$") and _NAME.fullmatch(t):
        try:
            return scope.lookup(t[1:])
        except KeyError:
            raise _error(node, f"parameter {t} is not declared") from None
    return text


def convert(value, ptype: str, what: str, node: Node | None = None):
    """``value`` (text, number or bool) as an OpenSCENARIO ``ptype``."""
    if ptype == "double":
        return _number(value, what, node)
    if ptype in ("int", "integer", "unsignedInt", "unsignedShort"):
        x = _number(value, what, node)
        n = int(math.floor(x + 0.5)) if x >= 0 else -int(math.floor(-x + 0.5))
        if ptype != "int" and ptype != "integer" and n < 0:
            raise _error(node, f"{what} must be a non-negative integer ({ptype}), got {value!r}")
        return n
    if ptype == "boolean":
        if isinstance(value, bool):
            return value
        s = str(value).strip()
        if s in ("true", "false"):
            return s == "true"
        if s in ("1", "0"):
            return s == "1"
        raise _error(node, f"{what} must be true or false, got {value!r}")
    if ptype in ("string", "dateTime"):
        return value if isinstance(value, str) else _text(value)
    raise _error(node, f"{what}: unknown parameter type {ptype!r} (OpenSCENARIO's: {', '.join(TYPES)})")


def _text(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(float(value)) if isinstance(value, float) and not value.is_integer() else str(
        int(value) if isinstance(value, float) else value)


def _number(value, what: str, node: Node | None) -> float:
    if isinstance(value, bool):
        return 1.0 if value else 0.0
    if isinstance(value, (int, float)):
        x = float(value)
    else:
        try:
            x = float(str(value).strip())
        except ValueError:
            raise _error(node, f"{what} must be a number, got {value!r}") from None
    if not math.isfinite(x):
        raise _error(node, f"{what} must be finite, got {value!r}")
    return x


RULES = {"equalTo": lambda a, b: a == b, "greaterThan": lambda a, b: a > b, "lessThan": lambda a, b: a < b,
         "greaterOrEqual": lambda a, b: a >= b, "lessOrEqual": lambda a, b: a <= b,
         "notEqualTo": lambda a, b: a != b}


def compare(rule: str, a, b, node: Node | None = None, what: str = "rule") -> bool:
    """OpenSCENARIO's Rule: ``a rule b``."""
    if rule not in RULES:
        raise _error(node, f"{what} {rule!r} is not one of OpenSCENARIO's rules ({', '.join(RULES)})")
    return RULES[rule](a, b)


def declare(decls: Node | None, scope: Scope, overrides: dict | None = None) -> Scope:
    """A new scope under ``scope`` with the ``ParameterDeclarations`` ``decls`` (None: none),
    each value taken from ``overrides`` (name -> value, e.g. a catalog reference's assignments
    or the command line's) where given; constraints checked."""
    new = Scope(parent=scope)
    overrides = dict(overrides or {})
    if decls is None:
        if overrides:
            name = sorted(overrides)[0]
            raise OpenScenarioError(f"parameter {name!r} is assigned but not declared")
        return new
    pending = []
    for d in decls.findall("ParameterDeclaration"):
        name = d.attrib.get("name")
        ptype = d.attrib.get("parameterType", "string")
        if not name:
            raise d.error("a ParameterDeclaration needs a name")
        if ptype not in TYPES:
            raise d.error(f"parameter {name!r}: unknown parameterType {ptype!r} (OpenSCENARIO's: {', '.join(TYPES)})")
        if name in overrides:
            raw = overrides.pop(name)
            if isinstance(raw, str):
                raw = resolve(raw, new, d)
        else:
            if "value" not in d.attrib:
                raise d.error(f"parameter {name!r} has no value")
            raw = resolve(d.attrib["value"], new, d)
        new.values[name] = convert(raw, ptype, f"parameter {name!r}", d)
        pending.append((d, name, ptype))
    if overrides:
        name = sorted(overrides)[0]
        raise decls.error(f"parameter {name!r} is assigned but not declared here "
                          f"(declared: {', '.join(new.values) or 'none'})")
    for d, name, ptype in pending:
        check_constraints(d, name, ptype, new)
    return new


def check_constraints(d: Node, name: str, ptype: str, scope: Scope) -> None:
    """The declaration ``d``'s ConstraintGroups against the parameter's value (or-ed groups)."""
    groups = d.findall("ConstraintGroup")
    if not groups:
        return
    value = scope.values[name]
    failed = []
    for g in groups:
        ok = True
        for c in g.children:
            if c.tag == "ValueConstraint":
                rule = c.attrib.get("rule", "")
                raw = resolve(c.attrib.get("value", ""), scope, c)
                ref = convert(raw, ptype, f"parameter {name!r}'s constraint value", c)
                good = compare(rule, value, ref, c, "ValueConstraint rule")
                desc = f"{rule} {ref!r}"
            elif c.tag == "Range":
                lo = convert(resolve(c.attrib.get("lowerLimit", ""), scope, c), "double", "Range lowerLimit", c)
                hi = convert(resolve(c.attrib.get("upperLimit", ""), scope, c), "double", "Range upperLimit", c)
                good = lo <= float(value) <= hi
                desc = f"in [{lo!r}, {hi!r}]"
            else:
                raise c.error(f"<{c.tag}> in a ConstraintGroup is not an OpenSCENARIO constraint")
            if not good:
                ok = False
                failed.append((c, desc))
                break
        if ok:
            return
    c, desc = failed[0]
    others = "" if len(failed) == 1 else f" (and every other of its {len(groups)} constraint groups)"
    raise c.error(f"parameter {name!r} = {value!r} violates its constraint: {desc}{others}")
