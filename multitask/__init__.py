"""The paper's multi-task models, their experiment grid, tables and figures, and their use.

Read first: ``variants.VARIANTS`` (A, APr, APc, APoc, Pr, Pc, Poc), then ``fold_run.train_variant``
(one variant on one LOUO fold, fixed weights or ``gradnorm.GradNormTrainer``). To use a trained
run: ``trained_run.load_run`` (its ``predict`` labels a recording's kinematics).

* ``heads``: the progress heads (regression, classification, ordered classification);
  ``config``: the multi-task configuration (weightings, GradNorm; no TensorFlow import);
* ``grid_spec``: TOML specs, presets, the runs they expand to; ``grid_record``: grid.json and
  the check of a grid folder; ``grid_job``: one worker's job; ``grid_executors``: the local process
  pool and Dask;
* ``collect``, ``tables``, ``figures``: results of a grid as the paper's tables and figures;
  ``captions``: what the runs were trained with, for the tables' captions; ``latex``: pieces of
  paste-ready tables; ``curves``: training curves; ``paper_results``: the published numbers;
* ``paired``: paired statistics of two configurations over folds and seeds; ``claims``: the
  paper's claims as data, tested with them; ``claims_table``: ``claims.csv`` and ``claims.tex``.
* ``trained_run``, ``predictions``: a run folder loaded for use, its predictions per frame;
  ``streaming``: frame-by-frame prediction of forward models; ``run_evaluation``: saved weights
  scored like an evaluation point; ``export``: a run as a TensorFlow SavedModel;
* ``predict_cli``, ``evaluate_cli``, ``export_cli``: their commands (``run_options``: what the
  three share).
"""
from jigsaws_tools.lazy import lazy_exports

#: Public name -> the submodule defining it, imported on first use (``jigsaws_tools.lazy``).
_PUBLIC = {
    "load_run": "trained_run",
    "TrainedRun": "trained_run",
    "RecordingPrediction": "predictions",
    "StreamingPredictor": "streaming",
    "evaluate_run": "run_evaluation",
    "export_run": "export",
    "train_variant": "fold_run",
    "variant_trainer": "fold_run",
    "GradNormConfig": "config",
    "VARIANTS": "variants",
    "Variant": "variants",
    "get_variant": "variants",
}
__all__ = sorted(_PUBLIC)
__getattr__ = lazy_exports(__name__, _PUBLIC)
