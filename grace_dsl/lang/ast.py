"""The syntax tree of an .eac file: frozen dataclasses that carry their source spans.

Spans are excluded from equality so two trees that differ only in layout compare equal; this is
what lets the formatter promise ``parse(fmt(x)) == parse(x)``.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from typing import Any, Union


@dataclass(frozen=True, order=True)
class Span:
    """A region of a source file; lines and columns are 1-based, ``end_col`` is exclusive."""

    file: str
    line: int
    col: int
    end_line: int
    end_col: int

    def to(self, other: Span) -> Span:
        """The span from the start of ``self`` to the end of ``other``."""
        return Span(self.file, self.line, self.col, other.end_line, other.end_col)


NO_SPAN = Span("<builtin>", 0, 0, 0, 0)


def _span() -> Span:
    return field(default=NO_SPAN, compare=False, repr=False)


# ---- expressions --------------------------------------------------------------------------------


@dataclass(frozen=True)
class Number:
    """A numeric literal; ``unit`` is None for a bare number. ``text`` keeps the exact digits."""

    text: str
    unit: str | None = None
    span: Span = _span()


@dataclass(frozen=True)
class Name:
    id: str
    span: Span = _span()


@dataclass(frozen=True)
class String:
    value: str
    span: Span = _span()


@dataclass(frozen=True)
class Bool:
    value: bool
    span: Span = _span()


@dataclass(frozen=True)
class Unary:
    op: str  # "-", "+", "not"
    operand: Expr
    span: Span = _span()


@dataclass(frozen=True)
class Binary:
    op: str  # + - * / ^ and or  < <= > >= == !=
    left: Expr
    right: Expr
    span: Span = _span()


@dataclass(frozen=True)
class Arg:
    name: str | None
    value: Expr
    span: Span = _span()


@dataclass(frozen=True)
class Call:
    func: str
    args: tuple[Arg, ...]
    span: Span = _span()
    func_span: Span = _span()


@dataclass(frozen=True)
class Vector:
    items: tuple[Expr, ...]
    span: Span = _span()


@dataclass(frozen=True)
class Member:
    obj: Expr
    field: str
    span: Span = _span()


@dataclass(frozen=True)
class IfExpr:
    cond: Expr
    then: Expr
    orelse: Expr
    span: Span = _span()


@dataclass(frozen=True)
class Index:
    """``drawer[i]`` in an expression: a member of a repeated declaration, before unrolling."""

    obj: Expr
    index: Expr
    span: Span = _span()


Expr = Union[Number, Name, String, Bool, Unary, Binary, Call, Vector, Member, IfExpr, Index]  # noqa: UP007

COMPARISONS = ("<", "<=", ">", ">=", "==", "!=")

# A declaration's or reference's indices, before unrolling.  Names stay strings: an indexed
# name is written as a template with ``[]`` for each index (``drawer[].handle.pull``) and its
# index expressions kept beside it, so every pass after unrolling sees plain strings.
Indices = tuple[Expr, ...]
HOLE = "[]"


def fill(template: str, values: tuple[str, ...] | list[str]) -> str:
    """``fill("drawer[].pull", ["2"]) == "drawer[2].pull"``: a template's holes filled in order."""
    pieces = template.split(HOLE)
    out = pieces[0]
    for value, rest in zip(values, pieces[1:], strict=True):
        out += f"[{value}]" + rest
    return out


# ---- declarations -------------------------------------------------------------------------------


@dataclass(frozen=True)
class TypeRef:
    """``length``, ``vec3 length``, ``choice{"a", "b"}``; checked against known types later."""

    name: str
    unit: str | None = None
    choices: tuple[str, ...] | None = None
    span: Span = _span()


@dataclass(frozen=True)
class Bounds:
    lo: Expr
    hi: Expr
    span: Span = _span()


@dataclass(frozen=True)
class Param:
    name: str
    type: TypeRef
    bounds: Bounds | None
    default: Expr | None
    help: str | None = None
    doc: str = ""
    span: Span = _span()
    name_span: Span = _span()


@dataclass(frozen=True)
class Require:
    cond: Expr
    message: str | None = None
    doc: str = ""
    span: Span = _span()


@dataclass(frozen=True)
class Let:
    name: str
    value: Expr
    doc: str = ""
    span: Span = _span()
    name_span: Span = _span()
    index: Indices = ()


@dataclass(frozen=True)
class Shape:
    name: str
    value: Expr
    at: Expr | None = None
    doc: str = ""
    span: Span = _span()
    name_span: Span = _span()
    index: Indices = ()


@dataclass(frozen=True)
class Part:
    name: str
    concept: str
    args: tuple[Arg, ...]
    at: Expr | None = None
    doc: str = ""
    span: Span = _span()
    name_span: Span = _span()
    concept_span: Span = _span()
    index: Indices = ()
    # ``match kind { "bar" => BarHandle(), ... }``: the selector and the alternatives; after
    # unrolling, one part per alternative whose ``variant`` names the part and its option
    selector: Expr | None = None
    variants: tuple[Variant, ...] = ()
    variant: tuple[str, str] | None = None  # (the variant part's name, this option)


@dataclass(frozen=True)
class Variant:
    """One alternative of a variant part: ``"knob" => RoundKnob(radius: 20mm) at POSE``.

    ``at`` is the option's own mounting: where its frame sits in the part's shared frame (the
    mounting frame on the host's surface); the part's name in it reads this option's members."""

    value: str
    concept: str
    args: tuple[Arg, ...]
    span: Span = _span()
    concept_span: Span = _span()
    at: Expr | None = None


@dataclass(frozen=True)
class FreeParam:
    """A free grasp parameter: its range may depend on the concept's parameters."""

    name: str
    lo: Expr
    hi: Expr
    default: Expr | None = None
    span: Span = _span()


@dataclass(frozen=True)
class Grasp:
    """A grasp family: a pose over free parameters, the gripper opening it needs, how the hand
    touches the part (``by pinch|hook|push|press``) and an optional symmetry axis about which
    the pose may spin (``symmetric [about v]``; the axis is in the grasp frame), and the
    condition under which it applies (``when``: a hook behind a drawer's front needs it ajar)."""

    name: str
    free: tuple[FreeParam, ...]
    pose: Expr
    width: Expr | None = None
    doc: str = ""
    span: Span = _span()
    name_span: Span = _span()
    mode: str | None = None  # as written; None means the default, pinch
    symmetric: bool = False
    about: Expr | None = None  # the symmetry axis; ``symmetric`` alone means the approach (0, 0, 1)
    mode_span: Span = _span()
    index: Indices = ()
    # ``when COND``: the family applies only where COND holds (parameters, lets and the values
    # of the concept's own moving joints); None: always
    when: Expr | None = None


@dataclass(frozen=True)
class Link:
    name: str
    members: tuple[Shape | Part | Grasp | Let | For, ...]
    doc: str = ""
    span: Span = _span()
    name_span: Span = _span()
    index: Indices = ()


@dataclass(frozen=True)
class Joint:
    name: str
    kind: str
    parent: str
    child: str
    axis: Expr | None = None
    origin: Expr | None = None
    limits: Bounds | None = None
    opens: int | None = None  # +1 or -1: the sense of rotation/translation that opens
    doc: str = ""
    span: Span = _span()
    name_span: Span = _span()
    kind_span: Span = _span()
    parent_span: Span = _span()
    child_span: Span = _span()
    index: Indices = ()
    parent_index: Indices = ()
    child_index: Indices = ()


@dataclass(frozen=True)
class Action:
    """``action open = pull along hinge [opening|closing]`` or ``action p = press toward v``."""

    name: str
    verb: str
    joint: str | None = None
    sense: str | None = None  # "opening" / "closing" / None (the verb's default)
    direction: Expr | None = None
    using: tuple[str, ...] = ()
    doc: str = ""
    span: Span = _span()
    name_span: Span = _span()
    verb_span: Span = _span()
    joint_span: Span = _span()
    index: Indices = ()
    joint_index: Indices = ()
    using_index: tuple[Indices, ...] = ()  # per ``using`` entry; () when none is indexed


@dataclass(frozen=True)
class For:
    """``for i in lo..hi { ... }``: its members once for each integer lo <= i < hi, unrolled
    by the compiler (``grace_dsl/compiler/expand.py``) before any other pass sees them."""

    var: str
    lo: Expr
    hi: Expr
    members: tuple[Member_, ...]
    span: Span = _span()
    var_span: Span = _span()


Member_ = Union[Param, Require, Let, Shape, Part, Link, "Joint", Grasp, Action, For]


@dataclass(frozen=True)
class Concept:
    """A ``concept`` or a ``primitive`` (a concept whose geometry the runtime provides)."""

    name: str
    kind: str  # "concept" | "primitive"
    members: tuple[Member_, ...]
    doc: str = ""
    span: Span = _span()
    name_span: Span = _span()
    # Filled by unrolling (``compiler/expand.py``): when a declaration exists, per name, as
    # (count parameter, k) meaning ``count > k`` or (choice parameter, option) meaning ``==``;
    # and each variant part's choice parameter with its options' part names.
    masks: tuple[tuple[str, tuple[tuple[str, int | str], ...]], ...] = ()
    variants: tuple[tuple[str, tuple[str, tuple[tuple[str, str], ...]]], ...] = ()


@dataclass(frozen=True)
class Use:
    """``use a.b`` (every concept of module a.b) or ``use a.b.{X, Y}``."""

    module: tuple[str, ...]
    names: tuple[str, ...] | None
    span: Span = _span()
    name_spans: tuple[Span, ...] = field(default=(), compare=False, repr=False)
    module_span: Span = _span()


@dataclass(frozen=True)
class Module:
    path: str
    uses: tuple[Use, ...]
    concepts: tuple[Concept, ...]


def names_in(e: Expr) -> Iterator[Name]:
    """Every name an expression mentions, without recursion."""
    stack: list[Any] = [e]
    while stack:
        node = stack.pop()
        if isinstance(node, Name):
            yield node
        stack += _children(node)


def dotted_names_in(e: Expr) -> Iterator[str]:
    """Every name an expression mentions, and every ``a.b`` read of one (``handle.length``)."""
    stack: list[Any] = [e]
    while stack:
        node = stack.pop()
        if isinstance(node, Name):
            yield node.id
        elif isinstance(node, Member) and isinstance(node.obj, Name):
            yield f"{node.obj.id}.{node.field}"
        stack += _children(node)


def _children(node: Any) -> list[Any]:
    """The sub-expressions of one expression node."""
    if isinstance(node, Unary):
        return [node.operand]
    if isinstance(node, Binary):
        return [node.left, node.right]
    if isinstance(node, Call):
        return [a.value for a in node.args]
    if isinstance(node, Vector):
        return list(node.items)
    if isinstance(node, Member):
        return [node.obj]
    if isinstance(node, IfExpr):
        return [node.cond, node.then, node.orelse]
    if isinstance(node, Index):
        return [node.obj, node.index]
    return []


def rebuild(node: Any, kids: list[Any]) -> Any:
    """``node`` with its sub-expressions (in ``_children`` order) replaced by ``kids``."""
    if isinstance(node, Unary):
        return replace(node, operand=kids[0])
    if isinstance(node, Binary):
        return replace(node, left=kids[0], right=kids[1])
    if isinstance(node, Call):
        return replace(
            node, args=tuple(replace(a, value=v) for a, v in zip(node.args, kids, strict=True))
        )
    if isinstance(node, Vector):
        return replace(node, items=tuple(kids))
    if isinstance(node, Member):
        return replace(node, obj=kids[0])
    if isinstance(node, IfExpr):
        return replace(node, cond=kids[0], then=kids[1], orelse=kids[2])
    if isinstance(node, Index):
        return replace(node, obj=kids[0], index=kids[1])
    return node
