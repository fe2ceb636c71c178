"""The subcommands of the pre-registered plans (``...plans``), one module per subcommand, each
made as ``multitask.evidence.commands``' docstring says: ``confirm``, ``design``,
``factors`` and ``ladder``, listed in its ``STUDIES``.

May import ``..common`` and (in ``run``) ``...plans``, ``...studies``, ``...render``,
``...statistics``, ``...runs`` and ``multitask.grid``; ``multitask.evidence.cli`` imports them,
and no other wing does.
"""
