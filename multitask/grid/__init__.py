"""The experiment grid: a spec's runs, trained resumably by local processes or on Dask.

* ``spec``: TOML specs, presets and the runs they expand to (read first);
* ``job``: one worker's job; ``executors``: the local process pool (or this process alone) and
  Dask, lost workers;
* ``progress``: what the grid shows while it trains (runs done / running / queued, ETAs);
* ``record`` and ``folder``: the grid folder's ``grid.json`` and the check of its runs;
* ``archive``: a grid's scores archive, to commit or carry to another machine;
  ``kept_predictions``: the runs' test predictions it keeps, compressed, and their reader;
* ``cli``: ``multitask-grid``.

May import ``multitask.models`` (and the packages below ``multitask``); not ``evidence`` or
``inference``.
"""
