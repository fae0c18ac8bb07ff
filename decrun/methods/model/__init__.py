"""Declarative DEC models: the language, its compiler and integrators (no Hydra, no files).

A model is data — fields with their form degree and duality, constants, equations over DEC
operators, an integrator, metrics — compiled against a mesh's :class:`decrun.core.dec.DEC` by
named passes (:func:`compile_model` runs them in this order):

- :mod:`.language`   parse: text → expression tree (Python's parser, a node whitelist; never eval)
- :mod:`.passes`     one module per pass: parse, resolve names and unknowns, order, type definitions,
                     bind values to the mesh, lower every equation, metrics, stars
- :mod:`.system`     the model as data, :class:`CompiledModel` and :func:`compile_model`, the chain of
                     the passes
- :mod:`.kinds`      the types: primal/dual k-forms, numbers, vector fields
- :mod:`.typed`      the typed tree: each node with its kind, built once by the kind pass and read
                     by every later pass (:attr:`CompiledModel.typed`)
- :mod:`.operators`  the operator registry: one entry per operator — typing rule, discrete
                     definition, evaluation or matrix, derivative rule — plugins through the
                     entry-point group ``decrun.operators``; :mod:`.discrete` the operators DEC lacks
- :mod:`.compiler`   kinds of trees, the evaluator (trees → closures), linear blocks and their
                     lagged (Picard) linearization
- :mod:`.lowering`   the evolution split into mass, constant linear blocks and explicit terms, once
                     per model (:attr:`CompiledModel.evolution`)
- :mod:`.jacobian`   the derivative pass: exact sparse Jacobians from the derivative rules
- :mod:`.problem`    the model as M y' = f(y, t) over its free unknowns (:attr:`CompiledModel.problem`),
                     the interface the Runge–Kutta steppers step
- :mod:`.solve`      linear systems with fixed values and kernels; :mod:`.nonlinear` Newton solves
- :mod:`.initial`    initial and border values sampled from expressions
- :mod:`.integrators` the integrator registry (``SCHEMES``) and the schemes written there;
                     :mod:`.implicit_newton` implicit Euler / Crank–Nicolson by Newton;
                     :mod:`.runge_kutta`, :mod:`.tableaux`, :mod:`.newton` the tableau steppers;
                     :mod:`.stepper` the stepper for ``run_steps``
- :mod:`.explain`    the typed trees and blocks as text (``app.explain=true``)
"""

from decrun.methods.model.language import ModelError
from decrun.methods.model.system import CompiledModel, FieldSpec, ModelSpec, compile_model

__all__ = ["ModelError", "CompiledModel", "FieldSpec", "ModelSpec", "compile_model"]
