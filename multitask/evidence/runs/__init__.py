"""Reading a grid's runs: what a table may use, checked, one row per run (the first wing of
``multitask.evidence``).

* ``collect``: a grid's finished runs gathered into one row per run, then per fold and per
  configuration; missing, unfinished or self-contradicting runs are an error naming each (read
  first);
* ``checks``: each run folder checked against the grid's spec as the grid checks it (recorded
  settings only: no data, no TensorFlow); ``metrics_file``: each run's metrics.json checked
  against itself and its run;
* ``pooling``: the one rule for which runs a table may pool (every setting that changes a result
  but the seed and the held-out user), and which architecture a run is;
* ``standalone``: runs trained one by one (no grid), read from their own config.json.
* ``method``: another method's prediction folders, checked and scored as a grid's runs are
  scored (``multitask-tables score``).

May import ``multitask.grid`` and ``multitask.models`` (and ``jigsaws_tools``, ``rnn_seg``); no
other wing of ``multitask.evidence`` (``tests/test_packaging.py`` checks it).
"""
