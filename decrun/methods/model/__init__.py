"""Declarative DEC models: the language, its compiler and integrators (no Hydra, no files).

A model is data — fields with their form degree and duality, constants, equations over DEC
operators, an integrator, metrics — compiled against a mesh's :class:`decrun.core.dec.DEC`:

- :mod:`.language`   text → expression tree (Python's parser, a node whitelist; never eval)
- :mod:`.kinds`      primal/dual k-forms, numbers, vector fields
- :mod:`.operators`  the operator table: degree rules, discrete definitions, matrices
- :mod:`.discrete`   the operators DEC does not have (∧, ♯, ♭, averages, interior, Lie)
- :mod:`.compiler`   typed trees → closures and linear blocks
- :mod:`.initial`    initial and border values sampled from expressions
- :mod:`.solve`      linear systems with fixed values and kernels
- :mod:`.system`     a whole model compiled: :func:`compile_model`
- :mod:`.integrators` time integrators; :mod:`.stepper` the stepper for ``run_steps``
"""

from decrun.methods.model.language import ModelError
from decrun.methods.model.system import CompiledModel, FieldSpec, ModelSpec, compile_model

__all__ = ["ModelError", "CompiledModel", "FieldSpec", "ModelSpec", "compile_model"]
