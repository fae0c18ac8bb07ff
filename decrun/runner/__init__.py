"""The runner: the only layer that imports hydra, pymeshlab, h5py and matplotlib.

``cli`` (the command) > ``run`` (one run) > ``context``, ``failures``, ``hints``, ``plugins``,
``progress``, ``config`` > ``sweep`` | ``plots`` > ``results`` | ``mesh`` (docs/architecture.md;
the contracts in pyproject.toml)."""
