"""The runner: the only layer that imports hydra, pymeshlab, h5py and matplotlib.

``api`` > ``command`` (the command line) | ``view`` > ``job`` (one run) > ``tracking`` >
``sweep`` | ``plots`` > ``results`` | ``mesh`` > ``io`` (docs/architecture.md; the contracts in
pyproject.toml)."""
