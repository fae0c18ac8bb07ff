"""The runner: the only layer that imports hydra, pymeshlab, h5py and matplotlib."""
