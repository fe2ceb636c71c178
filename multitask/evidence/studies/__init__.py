"""The studies: each reads runs (``..runs``), tests them (``..statistics``) and writes its files
with the renderers (``..render``) (the fourth wing of ``multitask.evidence``;
``multitask-tables``, ``..cli``, runs them).

* ``claims``: the paper's claims (and its conjectures') as data, each tested with paired
  statistics; ``claims_table``: ``claims.csv``, ``claims.tex`` and its method note;
* ``width``: model A against APoc across LSTM widths, one grid per width;
* ``architectures``: the LSTM widths, ED-TCN and MS-TCN side by side: the cross-architecture
  table, the claims on TCN backbones and Table II with measured rows;
* ``execution``: an execution path (fused loops, bfloat16) against its reference grid,
  equivalent / different / inconclusive against a margin;
* ``confirm``: a pre-registered confirmatory analysis, run as its plan file says;
  ``exploratory``: the exploratory analyses its plan names, apart from its rows;
  ``confirm_report``: both written out, with ``confirm.md``, the outcome in the plan's words;
* ``tasks``: the JIGSAWS tasks side by side, from each task's tables.

May import ``..runs``, ``..statistics`` and ``..render`` (and ``multitask.grid``,
``multitask.models``, ``jigsaws_tools``, ``rnn_seg``) (``tests/test_packaging.py`` checks
it).
"""
