"""A grid's runs as evidence: tables, figures, training curves and tested claims.

Four wings, in the order the evidence flows, each importing only those before it:

1. ``runs/``: the runs read: gathered one row per run (**``collect``**), each checked against
   the grid's spec and itself, the one rule of what a table may pool;
2. ``statistics/``: paired statistics over folds and seeds (**``paired``**), the time-only
   progress baseline;
3. ``render/``: tables and figures as files: the paper's Tables I-III (**``tables``**), LaTeX,
   Markdown, captions, the paper's figures, training curves, confusion matrices;
4. ``studies/``: what a study concludes: the paper's claims, the width study, architectures side
   by side, an execution path against its reference, a confirmatory analysis, the tasks side by
   side; each reads with ``runs``, tests with ``statistics`` and writes with ``render``.

``cli`` is ``multitask-tables``.

May import every other wing of ``multitask`` (``models``, ``grid``, ``inference``); none of them
imports this one. Inside, imports flow ``runs <- statistics <- render <- studies <- cli``
(``tests/test_packaging.py`` checks both).
"""
