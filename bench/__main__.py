"""``python -m bench``: see :mod:`bench.harness`."""

from .harness import main

if __name__ == "__main__":
    main()
