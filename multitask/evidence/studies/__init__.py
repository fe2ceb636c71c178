"""The studies: each reads runs (``..runs``), tests them (``..statistics``) and writes its files
with the renderers (``..render``); ``..commands`` holds the subcommand of each (the fourth wing
of ``multitask.evidence``).

* ``paper``: a grid's evidence as the paper shows it: runs, per-fold and summary tables, Tables
  I-III, the ablation, the claims, per-gesture scores and the figures (read first); and the
  tables of runs trained one by one;
* ``claims``: the paper's claims (and its conjectures') as data, each tested with paired
  statistics; ``claims_table``: ``claims.csv``, ``claims.tex`` and its method note;
* ``width``: model A against APoc across LSTM widths, one grid per width;
* ``architectures``: the LSTM widths, ED-TCN and MS-TCN side by side: the cross-architecture
  table, the claims on TCN backbones and Table II with measured rows;
* ``execution``: an execution path (fused loops, bfloat16) against its reference grid,
  equivalent / different / inconclusive against a margin;
* ``tasks``: the JIGSAWS tasks side by side, from each task's tables.
* ``method``: another method's scores beside archived baselines, paired by fold;
* ``release``: a grid's kept predictions as per-split files.

A new study is a module here and its subcommand in ``..commands`` (how: ``..commands``); the
pre-registered plans (the confirmatory analysis, its design, the factor study) are the next
wing, ``..plans``.

May import ``..runs``, ``..statistics`` and ``..render`` (and ``multitask.grid``,
``multitask.models``, ``jigsaws_tools``, ``rnn_seg``); not ``..plans`` or ``..commands``
(``tests/test_packaging.py`` checks it).
"""
