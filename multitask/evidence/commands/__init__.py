"""``multitask-tables``' subcommands, one module per study, named as its subcommand; a
pre-registered plan's in ``plans/`` (``STUDIES``: each subcommand and its module).

A study's module is light (its work is imported when it runs, so that ``--help`` answers at
once) and holds: its docstring, the subcommand's ``--help`` (what it does and writes, then an
example); ``SUMMARY``, its line in ``multitask-tables --help``; ``add_arguments(parser)``; and
``run(args)``, which does the work, usually a function of ``..studies`` (or ``..plans``)
called through ``common.publish`` (its files written into ``--out`` together, listed in a
manifest). ``common`` holds the options and steps every study shares.

**Adding a study** (e.g. ``method``):

1. its work in ``studies/method.py`` (a pre-registered plan's: in ``plans/``): read runs with
   ``..runs``, pair and test with ``..statistics``, write CSV, LaTeX, Markdown and figures with
   ``..render``; a function ``write_method(..., out) -> list[Path]`` writing into ``out``;
2. its command in ``commands/method.py`` (a plan's: in ``commands/plans/``), a copy of the
   closest study's (``execution.py``: grids in, CSV files out; ``pair.py``: a result printed),
   its docstring, ``SUMMARY``, options and ``run`` adapted;
3. ``"method": "method"`` added to ``STUDIES`` below (a plan's: ``"confirm": "plans.confirm"``),
   and a line each in docs/PACKAGES.md and docs/COMMANDS.md.

``tests/test_cli.py`` then checks its help and options; ``tests/test_documented_commands.py``
parses the commands the docs show.

May import (in ``run``) ``..plans``, ``..studies``, ``..render``, ``..statistics``, ``..runs``
and ``multitask.grid``; ``..cli`` imports this wing, and no other wing imports it.
"""

#: The subcommands, in the order ``multitask-tables --help`` lists them, each with its module
#: (its path in this package).
STUDIES = {"paper": "paper", "runs": "runs", "pair": "pair", "archive": "archive",
           "width": "width", "architectures": "architectures", "execution": "execution",
           "confirm": "plans.confirm", "design": "plans.design", "tasks": "tasks",
           "score": "score", "release": "release", "factors": "plans.factors",
           "ladder": "plans.ladder"}
