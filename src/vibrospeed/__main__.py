"""``python -m vibrospeed``: same as the ``vibrospeed`` command."""

from vibrospeed.cli import main

if __name__ == "__main__":
    main()
