"""``python -m coopsim.tasks.carry``: see :mod:`coopsim.tasks.carry.cli`."""
from .cli import main

if __name__ == "__main__":
    raise SystemExit(main())
