"""Public home of :class:`SimplicialComplex` (implemented in :mod:`decrun.core.complex`)."""

from decrun.core.complex import SimplicialComplex  # noqa: F401

__all__ = ["SimplicialComplex"]
