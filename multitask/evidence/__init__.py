"""A grid's runs as evidence: tables, figures, training curves and tested claims, one study at a
time (``multitask-tables STUDY``).

Six wings, in the order the evidence flows, each importing only those before it:

1. ``runs/``: the runs read: gathered one row per run (**``collect``**), each checked against
   the grid's spec and itself, the one rule of what a table may pool;
2. ``statistics/``: paired statistics over folds and seeds (**``paired``**), the time-only
   progress baseline;
3. ``render/``: tables and figures as files: the paper's Tables I-III (**``tables``**), LaTeX,
   Markdown, captions, the paper's figures, training curves, confusion matrices;
4. ``studies/``: what each study concludes: the paper's tables and claims (**``paper``**), the
   width study, architectures side by side, an execution path against its reference, the
   tasks side by side; each reads with ``runs``, tests with ``statistics`` and writes with
   ``render``;
5. ``plans/``: the pre-registered plans, each read, analysed and reported: the confirmatory
   analysis (**``confirm``**), its exploratory analyses, what its design could detect, the
   factor study;
6. ``commands/``: ``multitask-tables``' subcommands, one light module per study (a plan's in
   ``commands/plans/``).

``cli`` is ``multitask-tables``: a subcommand per study of ``commands.STUDIES``, and the flag
forms of earlier versions for one release; ``tasks`` is the earlier ``python -m
multitask.evidence.tasks``, likewise. **To add a study**: ``commands/__init__.py``.

May import every other wing of ``multitask`` (``models``, ``grid``, ``inference``); none of them
imports this one. Inside, imports flow ``runs <- statistics <- render <- studies <- plans <-
commands <- cli`` (``tests/test_packaging.py`` checks both).
"""
