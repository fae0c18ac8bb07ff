"""``python -m decrun`` = the ``decrun`` command."""

from decrun.runner.failures import console_main

if __name__ == "__main__":
    console_main()
