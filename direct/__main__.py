"""``python -m direct``: the ``direct`` command line (see :mod:`direct.cli`)."""

from .cli import main

if __name__ == "__main__":
    raise SystemExit(main())
