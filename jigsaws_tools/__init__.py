"""JIGSAWS I/O for any task defined as data (Suturing, Knot_Tying, Needle_Passing or your own),
preprocessing, annotation versions and progress labels.

Read first: ``dataset`` (trials, LOUO splits, the cache), then ``release`` (the reader) and
``task_definition`` (tasks as data). ``cli/``: the ``jigsaws-tools`` command and the conventions
every command of the project shares; ``plots`` draws label ribbons.

Imports: numpy, scipy, pandas, matplotlib and the standard library; no other package of the
project (it is the bottom layer: ``jigsaws_tools -> rnn_seg -> baseline -> multitask``). Only
``cli.common.import_tensorflow`` loads TensorFlow, for the commands that train. Warnings go
through ``logging`` at their level, each said once per command (``messages``).
"""
from .lazy import lazy_exports
from .messages import install

install()       # warnings as "WARNING: ..." where the application configures no logging

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
