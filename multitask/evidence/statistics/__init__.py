"""The statistics the studies test with (the second wing of ``multitask.evidence``).

* ``paired``: paired statistics over LOUO folds: a configuration or a contrast of several
  (``ConfigId``, ``Contrast``), the exact sign-flip test and the interval that inverts it, power,
  Holm's correction (read first);
* ``design``: what a design of folds x seeds can detect: the variance of a per-fold difference
  split into the seeds' part and the folds' part with their intervals, and the test's power as
  seeds or folds grow;
* ``time_baseline``: the tables' rows of a trial's progress stage read from its time alone
  (de Boer et al.; the model: ``multitask.models.time_baseline``), fitted on the training folds
  and scored like the progress heads: the row a head must beat.

May import ``..runs`` (and ``multitask.grid``, ``multitask.models``, ``jigsaws_tools``,
``rnn_seg``); not ``..render``, ``..studies`` or ``..commands`` (``tests/test_packaging.py``
checks it).
"""
