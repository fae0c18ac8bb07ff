"""One caching mechanism for derived quantities (geometry-central's ``require`` idiom).

A class that derives expensive quantities from immutable inputs (a complex from its simplices,
the DEC operators from a complex and a Hodge-star variant) inherits :class:`Cached` and asks
for each quantity with ``self.require(key, compute)``: the first request computes and stores
it, later ones return the stored object. ``key`` is any hashable, e.g. ``("star", 1)``.
"""

from __future__ import annotations

from typing import Any, Callable, Hashable

__all__ = ["Cached"]


class Cached:
    """Mixin giving ``require(key, compute)`` and ``forget(prefix=None)``."""

    def require(self, key: Hashable, compute: Callable[[], Any]) -> Any:
        """The quantity stored under ``key``, computed by ``compute()`` on first request."""
        store = self.__dict__.setdefault("_required", {})
        if key not in store:
            store[key] = compute()
        return store[key]

    def forget(self, name: str | None = None) -> None:
        """Drop cached quantities (all, or those whose key is ``name`` or starts with it)."""
        store = self.__dict__.get("_required", {})
        for key in list(store):
            head = key[0] if isinstance(key, tuple) else key
            if name is None or head == name:
                del store[key]
