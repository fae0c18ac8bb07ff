"""Wording of the model language's messages: articles that agree with the number after them, and
the hints that match what a newcomer meant (issue 48, item 11)."""

from __future__ import annotations

from decrun.methods.model.language import Binary, Call, Name, Node, Number, to_text

__all__ = ["article", "hint"]


def article(number: int) -> str:
    """"a" or "an" before a number read aloud in English: an 8-form, an 11-form, an 18-form;
    a 0-, 1-, 2-, 3-form."""
    spoken = str(abs(int(number)))
    return "an" if spoken.startswith("8") or spoken in ("11", "18") else "a"


def hint(node: Node | None, where: str) -> str:
    """What a newcomer most likely meant by a term that does not type-check, as a clause to add
    to its message (``where``: the config key), else ``""``:

    - ``u ^ 3`` (a wedge whose right side is a number): a power, ``u**3``;
    - ``integral(1)`` (the integral of a number): the mesh's area, the built-in ``area``."""
    if isinstance(node, Binary) and node.op == "^" and isinstance(node.right, Number):
        base = to_text(node.left)
        base = base if isinstance(node.left, (Name, Call, Number)) else f"({base})"
        return f"; ^ is the wedge product ∧, not a power: write {base}**{to_text(node.right)}"
    if isinstance(node, Call) and node.function == "integral" and len(node.args) == 1 and \
            isinstance(node.args[0], Number):
        example = f"`{where}=area`" if where.startswith(("app.metrics.", "app.parts.")) else "area"
        return (f"; the mesh's area (volume on a tetrahedral mesh) is the built-in number area ({example}), and the "
                "mean of f is integral(f)/area")
    return ""
