"""The paper's multi-task models, their experiment grid, the evidence they give, and their use.

Four wings, one folder each (read the first file named in each):

* ``models/``: the paper's variants (**``variants``**: A, APr, APc, APoc, Pr, Pc, Poc), the
  progress heads, GradNorm, one variant on one LOUO fold (``fold_run``) and their configuration;
* ``grid/``: the experiment grid: specs and presets (**``spec``**), jobs, executors (processes or
  Dask), the grid folder's record, scores archives, ``multitask-grid``;
* ``evidence/``: a grid's runs as the paper's evidence: collected (**``collect``**), Tables I-III,
  LaTeX, captions, the published numbers, figures, training curves, paired statistics, the
  claims, ``multitask-tables``;
* ``inference/``: a trained run in use: loaded (**``trained_run.load_run``**), its predictions,
  streaming, evaluation, export, and ``multitask-predict`` / ``-evaluate`` / ``-export``.

``train_cli`` is ``multitask-train``, ``training.train`` the same from Python. Imports flow one way: ``models <- grid <- evidence`` and
``models <- inference <- evidence``; ``models`` imports no other wing, ``grid`` and ``inference``
import only ``models``, ``evidence`` any of the three (``tests/test_packaging.py`` checks it).
Outside the package, ``multitask`` imports ``jigsaws_tools``, ``rnn_seg`` and ``baseline``.
"""
from jigsaws_tools.lazy import lazy_exports

#: Public name -> the submodule defining it, imported on first use (``jigsaws_tools.lazy``).
_PUBLIC = {
    "load_run": "inference.trained_run",
    "TrainedRun": "inference.trained_run",
    "RecordingPrediction": "inference.predictions",
    "StreamingPredictor": "inference.streaming",
    "evaluate_run": "inference.evaluation",
    "export_run": "inference.export",
    "train": "training",
    "train_variant": "models.fold_run",
    "variant_trainer": "models.fold_run",
    "GradNormConfig": "models.config",
    "VARIANTS": "models.variants",
    "Variant": "models.variants",
    "get_variant": "models.variants",
}
__all__ = sorted(_PUBLIC)
__getattr__ = lazy_exports(__name__, _PUBLIC)
