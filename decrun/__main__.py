"""``python -m decrun`` = the ``decrun`` command."""

from decrun.runner.cli import main

if __name__ == "__main__":
    main()
