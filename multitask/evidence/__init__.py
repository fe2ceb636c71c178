"""A grid's runs as the paper's evidence: tables, figures, training curves and tested claims.

* ``collect``: finished runs gathered into one row per run, fold and configuration (read first);
* ``checks``: each run folder checked against the grid's spec as the grid checks it (recorded
  settings only: no data, no TensorFlow); ``metrics_file``: each run's metrics.json checked
  against itself and its run; ``pooling``: the one rule for which runs a table may pool;
* ``tables``, ``latex``, ``captions``: the paper's Tables I-III and the ablation, as CSV and
  paste-ready LaTeX with captions read from the runs; ``markdown``: the READMEs' Markdown
  tables; ``paper_results``: the published numbers;
* ``figures``, ``curves``: the paper's figures and training curves; ``confusion``: per-gesture
  precision, recall, F1 and confusion matrices;
* ``paired``: paired statistics over folds and seeds; ``claims``: the paper's claims as data,
  tested with them; ``claims_table``: ``claims.csv``, ``claims.tex`` and its method note
  ``claims_note.tex``;
* ``confirm``: a pre-registered confirmatory analysis, run as its plan file says; ``exploratory``:
  the exploratory analyses its plan names, apart from its rows; ``confirm_report``: both written
  out, with ``confirm.md``, the outcome in the plan's words;
* ``width``: the width study, model A against APoc across grids of several LSTM widths;
* ``architectures``: the LSTM widths, ED-TCN and MS-TCN side by side, one grid each: the
  cross-architecture table, the claims on TCN backbones and Table II with measured rows;
* ``execution``: an execution path (fused loops, bfloat16) against its reference grid, paired by
  fold, equivalent / different / inconclusive against a margin;
* ``standalone``: tables of runs trained one by one; ``tasks``: the JIGSAWS tasks side by side;
* ``cli``: ``multitask-tables``; ``drawing``: what it is making, said while it works.

May import every other wing of ``multitask`` (``models``, ``grid``, ``inference``); none of them
imports this one.
"""
