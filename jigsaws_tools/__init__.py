"""JIGSAWS I/O for any task defined as data (Suturing, Knot_Tying, Needle_Passing or your own),
preprocessing, annotation versions and progress labels."""
from .dataset import DataConfig, Dataset, Trial, load_dataset
from .preprocessing import Normalisation, PreprocessConfig, preprocess_recording
from .task_definition import TaskDefinition, load_task

__all__ = ["DataConfig", "Dataset", "Trial", "load_dataset", "Normalisation", "PreprocessConfig",
           "TaskDefinition", "load_task", "preprocess_recording"]
