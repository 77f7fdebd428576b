"""``python -m coopsim.tasks.handover``: see :mod:`coopsim.tasks.handover.cli`."""
from .cli import main

if __name__ == "__main__":
    raise SystemExit(main())
