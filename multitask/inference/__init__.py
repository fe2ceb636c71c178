"""A trained run in use: loaded, labelling recordings, streaming, rescored, exported.

* ``trained_run``: ``load_run`` and ``TrainedRun`` (read first);
* ``run_record``: a run's config.json and data folder, read without TensorFlow;
* ``predictions``: a recording's predictions per 5 Hz sample and per 30 Hz frame;
* ``streaming``: frame-by-frame prediction of forward models;
* ``evaluation``: saved weights scored like a training evaluation point;
* ``export``: a run as a TensorFlow SavedModel;
* ``predict_cli``, ``evaluate_cli``, ``export_cli``: ``multitask-predict``, ``-evaluate`` and
  ``-export``; ``options``: what the three share; ``output_folders``: the folders evaluation and
  export write whole, checked before TensorFlow loads.

May import ``multitask.models`` (and the packages below ``multitask``); not ``grid`` or
``evidence``.
"""
