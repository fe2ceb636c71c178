"""``python -m multitask.evidence.tasks``: the earlier spelling of ``multitask-tables tasks``
(``commands.tasks``), kept for one release; it says its new form in one line."""
import sys

from .cli import PROG, main

if __name__ == "__main__":
    print(f"{PROG}: warning: python -m multitask.evidence.tasks is deprecated and goes in the "
          f"next release; use: {PROG} tasks ...", file=sys.stderr)
    sys.argv[1:1] = ["tasks"]
    sys.exit(main())
