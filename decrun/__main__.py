"""``python -m decrun`` = the ``decrun`` command."""

from decrun.cli import main

if __name__ == "__main__":
    main()
