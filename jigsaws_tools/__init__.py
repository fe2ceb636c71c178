"""JIGSAWS I/O for any task defined as data (Suturing, Knot_Tying, Needle_Passing or your own),
preprocessing, annotation versions and progress labels.

Also what every command of the package shares: ``cli_common`` (``--version``, ``-v``, quiet
TensorFlow, one-line errors), ``arg_types`` (range-checked option types), ``options`` and
``task_options`` (the options that choose a release and its task); ``plots`` draws label ribbons.
"""
from .lazy import lazy_exports

#: Public name -> the submodule defining it, imported on first use (``jigsaws_tools.lazy``).
_PUBLIC = {
    "DataConfig": "dataset",
    "Dataset": "dataset",
    "Trial": "dataset",
    "load_dataset": "dataset",
    "Normalisation": "preprocessing",
    "PreprocessConfig": "preprocessing",
    "preprocess_recording": "preprocessing",
    "TaskDefinition": "task_definition",
    "load_task": "task_definition",
}
__all__ = sorted(_PUBLIC)
__getattr__ = lazy_exports(__name__, _PUBLIC)
