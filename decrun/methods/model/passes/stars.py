"""The stars pass: every ⋆_k the model's trees read exists for the configured star variant,
checked before any work."""

from __future__ import annotations

from typing import TYPE_CHECKING

from decrun.methods.model.compiler import Compiler
from decrun.methods.model.language import ModelError, to_text

if TYPE_CHECKING:
    pass


def _check_stars(compiler: Compiler, dec, trees) -> None:
    """Every ⋆_k the model reads exists for the configured variant (before any work)."""
    degrees = dec.star_variant.form_degrees
    if degrees is None:
        return
    if hasattr(dec.star_variant, "calculus"):  # ⋆1 of its intrinsic triangulation (check_intrinsic)
        degrees = (*degrees, 1)
    for where, tree in trees:
        for k, term in compiler.star_degrees(tree, where).items():
            if k not in degrees:
                raise ModelError(f"{where}: {to_text(term)} needs ⋆_{k}, but operator={dec.star_variant.name} provides "
                                 f"⋆ on {list(degrees)}-forms only; use `operator=mixed_area` (or leave that term out)")
