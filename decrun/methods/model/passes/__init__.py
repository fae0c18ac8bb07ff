"""The passes of the model compiler, one module each, run in this order by
:func:`decrun.methods.model.system.compile_model`:

- :mod:`.parse`    equation strings → :class:`~decrun.methods.model.language.Equation` trees
- :mod:`.resolve`  names checked; the field each equation computes (solve and system unknowns)
- :mod:`.order`    definitions and solves in dependency order (cycles refused)
- :mod:`.types`    the kind of every name: declared forms, definitions inferred in order
- :mod:`.bind`     values on the mesh: built-ins, constants, initial and Dirichlet values
- :mod:`.lower`    equations into closures, factorized solves (:mod:`.solves`, :mod:`.systems`)
                   and Newton solves
- :mod:`.metrics`  the declared metrics compiled (numbers)
- :mod:`.stars`    every ⋆_k read exists for the configured star variant
"""
