"""Applications: one module per application, found automatically by the runner.

Contract
--------
A module ``decrun/apps/<name>.py`` is an application when it defines

``Config``
    a dataclass, the schema of ``cfg.app``, with a field ``name: str = "<name>"``.
    It is stored in Hydra's ConfigStore as node ``base_app_<name>`` in group ``app``;
    ``conf/app/<name>.yaml`` starts with ``defaults: [base_app_<name>, _self_]`` and then
    sets values. Checks a type cannot express go in ``__post_init__`` and raise
    :class:`decrun.errors.ConfigError` naming the key (``app.dt: must be > 0``): the runner
    instantiates the node (``OmegaConf.to_object``) before it loads the mesh, so bad values
    fail before any work.

``run(complex, dec, solver, cfg, progress) -> decrun.runner.results.Result``
    ``complex``  the :class:`decrun.core.complex.SimplicialComplex` of the mesh (validated);
    ``dec``      ``decrun.core.dec.DEC(complex, star=cfg.operator.star)``;
    ``solver``   a fresh, unfactorized :class:`decrun.core.solvers.Solver` built from
                 ``cfg.solver`` (``factorize(A)`` once, ``solve(b)`` many times);
    ``cfg``      the app's own config node (an ``omegaconf.DictConfig`` typed by
                 ``Config``); a value from elsewhere in the config can be pulled in by
                 interpolation in the YAML, e.g. ``boundary: ${operator.boundary}``;
    ``progress`` a tqdm-like factory ``progress(iterable, total=..., desc=...)``
                 (a silent pass-through when stderr is not a terminal or in tests).

    The application returns a ``Result`` (fields, series, metrics, figures as
    ``matplotlib.figure.Figure``; see :mod:`decrun.runner.plots`) and never touches the disk.
    Numerical blow-up is a result (``stable: false``), not an exception; bad input is a
    typed :class:`decrun.errors.DecrunError`.

Mesh metadata: ``complex.meta``
    The runner sets ``complex.meta`` to the mesh source's metadata dict
    (:class:`decrun.runner.meshes.Mesh` ``.meta``) before calling ``run``. Keys an application may
    use (check with ``in``, they are optional):

    - ``clean_vertices`` (n0, d): positions before ``mesh.noise`` was added (same
      vertex order as ``complex.vertices``); absent without noise
    - ``noise_amplitude``: absolute noise standard deviation
    - ``mean_edge_length``, ``hash``, ``source``, ``label``, ``path``, ``steps``

    An application called outside the runner may find no ``meta`` attribute: use
    ``getattr(complex, "meta", {})``.

Boundary adaptations
    ``cfg.operator.boundary`` is checked against
    :data:`decrun.runner.config.BOUNDARY_ADAPTATIONS` before any work; an application that
    implements a new adaptation adds its name to that set at import time and reads it via
    an interpolation in its YAML (``boundary: ${operator.boundary}``).
"""
