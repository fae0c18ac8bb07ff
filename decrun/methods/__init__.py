"""The thesis' methods as pure functions of (complex, operators, arrays): no Hydra, no config keys, no files."""
