"""A model's values at one state and time: what a step reads first, the rest when read.

The definitions, solves and systems of a model (``CompiledModel.order``) run in their order. A
step (an integrator's stage) reads only what the evolution equations and the solves read; a
definition nothing but a metric or a recorded field reads (Halfar's ``H_exact``, ``ice``,
``H_error``) is *deferred*: an :class:`Environment` computes it when it is first read, by running
the deferred items in the model's order up to it. The values are the same closures on the same
inputs, so they are the same numbers; a record or a metric asks for the complete environment
(``CompiledModel.environment(…, complete=True)``, as does a static model's single evaluation),
and a name nothing defines is a ``KeyError`` as before.
"""

from __future__ import annotations

from collections import deque
from typing import Any

__all__ = ["Environment", "environment", "evaluate_item", "deferred_names"]


def evaluate_item(env: dict, what: str, item: Any) -> None:
    """Put the value(s) of one ``order`` item (``definition``, ``solve``, ``system`` or
    ``newton``) into ``env``."""
    if what == "definition":
        name, closure = item
        env[name] = closure(env)
    elif what == "system":
        env.update(item.solve(env))
    elif what == "newton":
        env[item.unknown] = item.solve(env)
    else:
        env[item.unknown] = item.system.solve(item.rhs(env), item.fixed_values)


class Environment(dict):
    """name → value, with the deferred ``order`` items (``pending``, in order) computed when a
    name they make is first read."""

    def __init__(self, values: dict, pending: list):
        super().__init__(values)
        self._pending = deque(pending)

    def __missing__(self, name: str):
        while self._pending:
            evaluate_item(self, *self._pending.popleft())
            if dict.__contains__(self, name):
                return dict.__getitem__(self, name)
        raise KeyError(name)


def deferred_names(model) -> frozenset[str]:
    """The definitions of ``model`` that no evolution equation, solve or system reads directly: only
    metrics, records or other definitions read them (a deferred one that an eager definition reads is
    computed right then, by :class:`Environment`)."""
    compiler = model.compiler
    read: set[str] = set()
    for equation in model.equations:
        if equation.kind != "definition":
            sides = [equation.lhs, equation.rhs, *(side for pair in equation.pairs for side in pair)]
            for side in sides:
                if side is not None:
                    read |= compiler.reads(side)
    return frozenset(item[0] for what, item in model.order if what == "definition" and item[0] not in read)


def environment(model, values: dict, complete: bool) -> dict:
    """``values`` (built-ins, constants, inputs, the state, ``t``) with ``model.order`` run on
    them: every item (in ``values`` itself) when ``complete``, when the model is static (its
    definitions run once: nothing to save) or when nothing is deferred; else an
    :class:`Environment` with all but the :func:`deferred_names` (computed when read)."""
    cached = getattr(model, "_deferred", None)
    if cached is None or cached[0] != len(model.order):  # the order is complete once compiled
        deferred = deferred_names(model)
        pending = [(what, item) for what, item in model.order if what == "definition" and item[0] in deferred]
        eager = [(what, item) for what, item in model.order if not (what == "definition" and item[0] in deferred)]
        cached = model._deferred = (len(model.order), eager, pending)
    _, eager, pending = cached
    if complete or not pending or model.is_static:
        for what, item in model.order:
            evaluate_item(values, what, item)
        return values
    env = Environment(values, pending)
    for what, item in eager:
        evaluate_item(env, what, item)
    return env
