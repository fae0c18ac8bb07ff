"""Figures (matplotlib, no pyplot): the drawing functions applications name in their
:class:`decrun.apps.base.Figure` descriptions. Each takes the complex ``K`` (when it needs
the mesh) and the arrays the app computed, and returns a ``matplotlib.figure.Figure``.

- :mod:`.common` — surfaces, before/after panels, per-step series, saving
- :mod:`.fields` — tangent vector fields with singularities, Hodge parts
- :mod:`.parametrization` — uv layouts and checkerboard textures
- :mod:`.sphere` — longitude–latitude maps of fields on a sphere (and error maps), resampled by
  :mod:`.lonlat`
"""

#: figure kinds → drawing functions (``Figure.of_kind``): apps name a kind, never a runner module
FIGURE_KINDS = {
    "surface": "decrun.runner.plots.common.mesh_values",
    "series": "decrun.runner.plots.common.plot_series",
    "recorded_series": "decrun.runner.plots.common.recorded_series",
    "before_after": "decrun.runner.plots.common.before_after",
    "snapshots": "decrun.runner.plots.snapshots.snapshot_grid",
    "animation": "decrun.runner.plots.snapshots.animation",
    "vector_field": "decrun.runner.plots.fields.field_figure",
    "hodge_parts": "decrun.runner.plots.fields.hodge_parts_figure",
    "uv_layout": "decrun.runner.plots.parametrization.uv_layout",
    "checkerboard": "decrun.runner.plots.parametrization.checkerboard",
    "eigenforms": "decrun.runner.plots.spectrum.eigenforms_figure",
    "values_arrows": "decrun.runner.plots.fields.values_and_arrows",
    "sphere_map": "decrun.runner.plots.sphere.sphere_map",
    "error_map": "decrun.runner.plots.sphere.error_map",
}

