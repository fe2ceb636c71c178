"""The paper's multi-task models, their experiment grid, tables and figures.

Read first: ``variants.VARIANTS`` (A, APr, APc, APoc, Pr, Pc, Poc), then ``fold_run.train_variant``
(one variant on one LOUO fold, fixed weights or ``gradnorm.GradNormTrainer``).

* ``heads``: the progress heads (regression, classification, ordered classification);
  ``config``: the multi-task configuration (weightings, GradNorm; no TensorFlow import);
* ``grid_spec``: TOML specs, presets, the runs they expand to; ``grid_job``: one worker's job;
  ``grid_executors``: the local process pool and Dask;
* ``collect``, ``tables``, ``figures``: results of a grid as the paper's tables and figures;
  ``captions``: what the runs were trained with, for the tables' captions; ``latex``: pieces of
  paste-ready tables; ``curves``: training curves; ``paper_results``: the published numbers.
"""
from importlib import import_module

#: Public name -> the submodule defining it.
_PUBLIC = {
    "train_variant": "fold_run",
    "variant_trainer": "fold_run",
    "GradNormConfig": "config",
    "VARIANTS": "variants",
    "Variant": "variants",
    "get_variant": "variants",
}
__all__ = sorted(_PUBLIC)


def __getattr__(name: str):
    """Import a public name's module on first use, so light submodules (``collect, tables``) do not
    pull in TensorFlow."""
    if name in _PUBLIC:
        return getattr(import_module(f".{_PUBLIC[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
