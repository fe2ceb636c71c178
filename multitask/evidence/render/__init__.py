"""Tables and figures as files: CSV, paste-ready LaTeX, Markdown, PNG and PDF (the third wing of
``multitask.evidence``, the tools the studies write with).

* ``tables``: the paper's Tables I-III and the annotation ablation, compared side by side, as
  CSV and LaTeX (read first); ``paper_results``: the numbers the paper publishes;
  ``captions``: what a caption states about the runs behind a table, read from the runs;
* ``latex``: numbers, escaping and the packages a table needs; ``markdown``: the READMEs'
  Markdown tables;
* ``figures``: the paper's figures (per-gesture accuracy, example ribbons, progress, per-fold
  accuracy, GradNorm weights) and ``save``, the one way a figure is written; ``curves``: training
  curves; ``confusion``: per-gesture precision, recall and F1 and the confusion matrices;
* ``drawing``: what ``multitask-tables`` is drawing, said while it works.

May import ``..runs`` and ``..statistics`` (and ``multitask.grid``, ``multitask.models``,
``jigsaws_tools``, ``rnn_seg``); not ``..studies`` or ``..commands``: a renderer knows how to
write a table, not which study asks (``tests/test_packaging.py`` checks it).
"""
