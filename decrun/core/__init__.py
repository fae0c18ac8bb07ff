"""The DEC core (thesis ch. 2–4, 6.3): nothing here knows of configs, files or applications."""
