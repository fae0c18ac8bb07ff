"""One module per application; each defines ``Config`` (its schema) and ``run``."""
