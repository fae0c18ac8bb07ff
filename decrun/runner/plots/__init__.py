"""Figures (matplotlib, no pyplot): the drawing functions applications name in their
:class:`decrun.apps.base.Figure` descriptions. Each takes the complex ``K`` (when it needs
the mesh) and the arrays the app computed, and returns a ``matplotlib.figure.Figure``.

- :mod:`.common` — surfaces, before/after panels, per-step series, saving
- :mod:`.fields` — tangent vector fields with singularities, Hodge parts
- :mod:`.parametrization` — uv layouts and checkerboard textures
"""
